"""Open a report in headless Chromium and check its viewers the way a reader would.

    python -m neurender.report.browser results/report.html --screenshots results/report_screenshots

Checks, per viewer: it mounts, draws (its canvases are not blank), and every control
(slider, menu, checkbox) changes what it draws; and for the page: no console errors. A
screenshot of each viewer is written to the screenshots folder. Needs Chromium and its
driver (Debian: ``apt-get install chromium chromium-driver``) and ``selenium``.
"""

from __future__ import annotations

import argparse
import base64
import dataclasses
import io as _io
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: Chromium's flags for a machine without network or display (its background services
#: would try to reach Google), WebGL through SwiftShader.
FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
    "--window-size=1280,1000",
)


@dataclasses.dataclass
class ViewerCheck:
    id: str
    kind: str
    drawn: bool
    controls: dict[str, bool]
    screenshot: str


def _driver():
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    options = Options()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def _pixels(driver, viewer) -> np.ndarray:
    """Every canvas of a viewer as one RGB array (read back through toDataURL)."""
    urls = driver.execute_script(
        "return Array.from(arguments[0].querySelectorAll('canvas')).map(c => c.toDataURL());",
        viewer,
    )
    images = [
        np.asarray(Image.open(_io.BytesIO(base64.b64decode(u.split(",", 1)[1]))).convert("RGB"))
        for u in urls
    ]
    return np.concatenate([im.reshape(-1, 3) for im in images]) if images else np.zeros((0, 3))


def _drawn(pixels: np.ndarray) -> bool:
    """More than a blank: several distinct colours on a visible share of the pixels."""
    if len(pixels) == 0:
        return False
    background = np.median(pixels, axis=0)
    return (np.abs(pixels - background).sum(1) > 24).mean() > 0.01


def _move(driver, control) -> None:
    """Set a control to another value as a reader would and fire its event."""
    driver.execute_script(
        """const c = arguments[0];
        if (c.type === 'range') { c.value = (Number(c.value) === Number(c.max)) ? c.min : c.max;
          c.dispatchEvent(new Event('input')); }
        else if (c.type === 'checkbox') {
          c.checked = !c.checked; c.dispatchEvent(new Event('change')); }
        else { c.selectedIndex = (c.selectedIndex + 1) % c.options.length;
          c.dispatchEvent(new Event('change')); }""",
        control,
    )


def check_report(
    report: Path, screenshots: Path, timeout: float = 120.0
) -> tuple[list[ViewerCheck], list[str]]:
    """Every viewer's checks and the page's console errors."""
    screenshots.mkdir(parents=True, exist_ok=True)
    driver = _driver()
    try:
        driver.get(report.resolve().as_uri())
        deadline = time.monotonic() + timeout
        has_viewers = driver.execute_script("return document.querySelector('div.viewer') !== null")
        state = "return document.body.dataset.viewers || ''"
        while has_viewers and driver.execute_script(state) not in ("ready", "failed"):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{report}: viewers did not mount within {timeout:.0f} s")
            time.sleep(0.2)
        checks = []
        for viewer in driver.find_elements("css selector", "div.viewer"):
            driver.execute_script("arguments[0].scrollIntoView();", viewer)
            before = _pixels(driver, viewer)
            changed = {}
            for k, control in enumerate(viewer.find_elements("css selector", "input, select")):
                _move(driver, control)
                time.sleep(0.3)  # images decode and canvases redraw asynchronously
                after = _pixels(driver, viewer)
                # The label's own text, without a readout of the value beside the control.
                label = driver.execute_script(
                    "const p = arguments[0].parentElement, t = p.firstChild;"
                    "return (t.nodeType === Node.TEXT_NODE ? t : p).textContent.trim();",
                    control,
                )
                label = label or f"control {k}"
                changed[label] = after.shape != before.shape or bool(np.any(after != before))
                before = after
            shot = screenshots / f"{viewer.get_attribute('id')}.png"
            shot.write_bytes(viewer.screenshot_as_png)
            checks.append(
                ViewerCheck(
                    viewer.get_attribute("id"),
                    viewer.get_attribute("data-kind"),
                    _drawn(before),
                    changed,
                    str(shot),
                )
            )
        errors = [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        return checks, errors
    finally:
        driver.quit()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path)
    parser.add_argument("--screenshots", type=Path, default=Path("results/report_screenshots"))
    args = parser.parse_args(argv)
    checks, errors = check_report(args.report, args.screenshots)
    ok = not errors
    for c in checks:
        good = c.drawn and all(c.controls.values())
        ok &= good
        status = "ok  " if good else "FAIL"
        print(
            f"{status} {c.id} ({c.kind}): drawn={c.drawn} controls={c.controls} -> {c.screenshot}"
        )
    for e in errors:
        print(f"console error: {e}")
    if not checks:
        print(f"{args.report}: no interactive viewers in the report")
    return 0 if ok and checks else 1


if __name__ == "__main__":
    sys.exit(main())
