"""A report made small enough to share: every embedded PNG reduced to a palette.

``python -m neurender.report.publish results/report.html shared.html --max-mb 10`` writes a
copy of a report (:mod:`neurender.report.build`) whose figures and viewer frames are PNGs
of at most ``--colours`` colours (PIL's median cut for opaque images, its octree for images
with alpha; no dithering, so flat plot colours stay flat). The page is otherwise the same
file: it opens from disk, its viewers run, its tables and numbers are untouched. GIFs, the
viewers' meshes and SH arrays and the viewers' code are kept as they are.

When the palette alone does not bring the page under ``--max-mb``, the figures (never the
viewer frames, whose pixels the viewers magnify by their own ``scale``) are resampled to
``FIGURE_SCALES`` of their size in turn, each shown at its original width; a page still
over the budget is an error that names both sizes.
"""

from __future__ import annotations

import argparse
import base64
import io as _io
import json
import re
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from neurender import io
from neurender.report.build import script_json
from neurender.viewer_data import b64_bytes

#: Resampling factors of the figures tried in turn when the palette alone is too large.
FIGURE_SCALES = (1.0, 0.75, 0.5)
#: A figure's ``<img>`` with a PNG data URI (groups: before ``src``, the base64, the rest).
_FIGURE = re.compile(r'(<img )src="data:image/png;base64,([A-Za-z0-9+/=]+)"')
#: A viewer's embedded JSON (:func:`neurender.report.build`'s ``<script>`` of its data).
_VIEWER = re.compile(r'(<script type="application/json" id="[^"]+">)(.*?)(</script>)', re.S)
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def palette_png(data: bytes, colours: int = 256, scale: float = 1.0) -> bytes:
    """A PNG's image with at most ``colours`` colours (``2 <= colours <= 256``), resampled
    by ``scale`` (Lanczos; ``1.0``: the same pixels), as a PNG; the input itself where
    that is not smaller (at ``scale == 1``). An image of at most ``colours`` colours keeps
    its pixels exactly."""
    if not 2 <= colours <= 256:
        raise ValueError(f"colours = {colours}: expected 2 to 256")
    image = Image.open(_io.BytesIO(data))
    image = image.convert("RGBA" if _has_alpha(image) else "RGB")
    if scale != 1.0:
        size = (max(1, round(image.width * scale)), max(1, round(image.height * scale)))
        image = image.resize(size, Image.Resampling.LANCZOS)
    out = _io.BytesIO()
    present = image.getcolors(colours)
    if present is not None:  # few enough colours: a palette of exactly those
        indices, palette, alpha = _exact_palette(image, [colour for _, colour in present])
        reduced = Image.fromarray(indices, "P")
        reduced.putpalette(palette)
        reduced.save(out, "PNG", optimize=True, **({"transparency": alpha} if alpha else {}))
    else:
        method = Image.Quantize.FASTOCTREE if image.mode == "RGBA" else Image.Quantize.MEDIANCUT
        reduced = image.quantize(colours, method=method, dither=Image.Dither.NONE)
        reduced.save(out, "PNG", optimize=True)
    smaller = out.getvalue()
    return smaller if scale != 1.0 or len(smaller) < len(data) else data


def _exact_palette(
    image: Image.Image, colours: list[tuple[int, ...]]
) -> tuple[np.ndarray, list[int], bytes]:
    """An RGB or RGBA image's ``(H, W)`` uint8 indices into ``colours`` (its every colour),
    the flat RGB palette and, for RGBA, the palette's alpha bytes (PNG's ``tRNS``)."""
    pixels = np.asarray(image)
    channels = pixels.shape[-1]
    weights = 256 ** np.arange(channels, dtype=np.int64)
    table = np.array(colours, np.int64) @ weights
    order = np.argsort(table)
    indices = order[np.searchsorted(table[order], pixels.astype(np.int64) @ weights)]
    rgb = [int(v) for colour in colours for v in colour[:3]]
    alpha = bytes(colour[3] for colour in colours) if channels == 4 else b""
    return indices.astype(np.uint8), rgb, alpha


def _has_alpha(image: Image.Image) -> bool:
    return image.mode in ("RGBA", "LA") or (image.mode == "P" and "transparency" in image.info)


def _is_png(text: str) -> bool:
    return base64.b64decode(text[:12]).startswith(_PNG_SIGNATURE)


def _reduce_viewer_frames(json_text: str, colours: int) -> str:
    """A viewer's JSON with every PNG of its ``frames`` and ``overlay`` reduced."""
    data = json.loads(json_text)
    for key in ("frames", "overlay"):
        for name, images in data.get(key, {}).items():
            data[key][name] = [
                b64_bytes(palette_png(base64.b64decode(b), colours)) if _is_png(b) else b
                for b in images
            ]
    return script_json(data)


def _figures(html: str, colours: int, scale: float) -> str:
    """Every figure's PNG reduced (and resampled by ``scale``, shown at its width)."""

    def one(match: re.Match) -> str:
        data = base64.b64decode(match.group(2))
        width = Image.open(_io.BytesIO(data)).width
        reduced = b64_bytes(palette_png(data, colours, scale))
        shown = f'width="{width}" ' if scale != 1.0 else ""
        return f'{match.group(1)}{shown}src="data:image/png;base64,{reduced}"'

    return _FIGURE.sub(one, html)


def publish(html: str, max_bytes: int, colours: int = 256) -> str:
    """``html`` (a report page) with its PNGs reduced until the page's UTF-8 size is at
    most ``max_bytes`` (see the module's docstring); a ``ValueError`` when the smallest
    figures tried leave it larger."""
    viewers = _VIEWER.sub(
        lambda m: m.group(1) + _reduce_viewer_frames(m.group(2), colours) + m.group(3), html
    )
    for scale in FIGURE_SCALES:
        page = _figures(viewers, colours, scale)
        size = len(page.encode("utf-8"))
        if size <= max_bytes:
            return page
    raise ValueError(
        f"the report is {size / 1e6:.1f} MB with {colours}-colour PNGs and its figures at "
        f"{FIGURE_SCALES[-1]:g} of their size; the budget is {max_bytes / 1e6:.1f} MB: "
        "raise --max-mb"
    )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m neurender.report.publish", description=__doc__.splitlines()[0]
    )
    parser.add_argument("report", type=Path, help="a report page, e.g. results/report.html")
    parser.add_argument("out", type=Path, help="the page to write")
    parser.add_argument("--max-mb", type=float, default=10.0, help="size budget (10^6 bytes)")
    parser.add_argument("--colours", type=int, default=256, help="colours per PNG (2 to 256)")
    args = parser.parse_args(argv)
    if not args.report.is_file():
        parser.error(f"{args.report}: no such report (make one: snakemake results/report.html)")
    html = args.report.read_text(encoding="utf-8")
    try:
        page = publish(html, int(args.max_mb * 1e6), args.colours)
    except ValueError as error:
        parser.error(f"{args.report}: {error}")
    with io.atomic_path(args.out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    before, after = len(html.encode("utf-8")), len(page.encode("utf-8"))
    print(f"{args.out}: {after / 1e6:.1f} MB (from {before / 1e6:.1f} MB)", file=sys.stderr)


if __name__ == "__main__":
    main()
