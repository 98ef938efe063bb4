"""The report's viewers in a real browser (headless Chromium): each kind mounts, draws, and
reacts to every control, with no console errors. Skipped where Chromium, its driver or
selenium is missing (CI installs them). The smoke report's own viewers are checked the
same way by ``python -m neurender.report.browser results/report.html`` in CI.
"""

from __future__ import annotations

import io as _io
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from neurender import sh, viewer_data
from neurender.geometry import grid_faces
from neurender.report import browser, build

pytestmark = pytest.mark.skipif(
    shutil.which("chromium") is None
    or shutil.which("chromedriver") is None
    or pytest.importorskip("selenium", reason="needs selenium") is None,
    reason="needs Chromium and chromedriver (apt-get install chromium chromium-driver)",
)


def _prt_viewer(path: Path) -> None:
    n, k = 12, 16
    t = np.linspace(-1, 1, n)
    x, y = np.meshgrid(t, t)
    positions = np.stack([x, y, 0.3 * np.exp(-(x**2 + y**2))], -1).reshape(-1, 3)
    rng = np.random.default_rng(0)
    truth = np.abs(sh.eval_sh(np.tile([0, 0, 1.0], (n * n, 1)), 4)) + 0.1 * rng.random((n * n, k))
    light = sh.project_latlong(np.ones((8, 16, 3)), 4)
    turns = [0, 90, 180, 270]
    lights = np.stack([light * (1 + 0.5 * np.cos(np.radians(a))) for a in turns])
    viewer_data.write(
        path,
        "prt",
        "a test frame",
        {
            "positions": viewer_data.b64_array(positions, "f4"),
            "indices": viewer_data.b64_array(grid_faces(n), "u4"),
            "coefficients": k,
            "transfer": {
                "ground truth": viewer_data.b64_array(truth, "f4"),
                "DeepPRT": viewer_data.b64_array(truth * 1.1, "f4"),
            },
            "probes": {
                "sky": {"turns": turns, "lights": viewer_data.b64_array(lights, "f4")},
                "dim": {"turns": turns, "lights": viewer_data.b64_array(0.3 * lights, "f4")},
            },
        },
    )


def _mesh_viewer(path: Path) -> None:
    def glb(mesh: trimesh.Trimesh) -> str:
        buffer = _io.BytesIO()
        mesh.export(buffer, file_type="glb")
        return viewer_data.b64_bytes(buffer.getvalue())

    meshes = {"reference": glb(trimesh.creation.icosphere(3)), "ours": glb(trimesh.creation.box())}
    viewer_data.write(
        path, "meshes", "meshes", {"meshes": meshes, "captions": {"ours": "12 triangles"}}
    )


def _frames_viewer(path: Path) -> None:
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 255, (16, 16, 3), dtype=np.uint8) for _ in range(3)]
    viewer_data.write(
        path,
        "frames",
        "frames",
        {
            "frames": {"a": [viewer_data.b64_png(f) for f in frames]},
            "overlay": {"a": [viewer_data.b64_png(255 - f) for f in frames]},
            "label": "frame",
            "overlay_label": "difference",
            "scale": 8,
        },
    )


def test_every_viewer_kind_draws_and_reacts_to_every_control(tmp_path):
    folder = tmp_path / "results" / "prt"
    folder.mkdir(parents=True)
    makers = {"prt.json": _prt_viewer, "meshes.json": _mesh_viewer, "frames.json": _frames_viewer}
    for name, make in makers.items():
        make(folder / name)
    report = tmp_path / "results" / "report.html"
    build.build_report([], [], report, viewers=[folder / n for n in makers])
    checks, errors = browser.check_report(report, tmp_path / "shots")
    assert errors == []
    assert {c.kind for c in checks} == {"prt", "meshes", "frames"}
    for c in checks:
        assert c.drawn, c
        assert c.controls and all(c.controls.values()), c
        assert Path(c.screenshot).stat().st_size > 1000
