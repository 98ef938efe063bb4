import math
import os
import subprocess
import sys

import numpy as np
import pytest
import torch
import trimesh

from neurender.geometry import vertex_normals
from neurender.metaball import Scene, field
from neurender.mitsuba_setup import variant_for
from neurender.simplification import assets, bake, mesh_ops, views


def test_variant_for_devices():
    assert variant_for("auto", has_cuda=False) == "llvm_ad_rgb"
    assert variant_for("auto", has_cuda=True) == "cuda_ad_rgb"
    assert variant_for("cpu", has_cuda=True) == "llvm_ad_rgb"
    with pytest.raises(RuntimeError, match="cuda"):
        variant_for("cuda:0", has_cuda=False)
    with pytest.raises(ValueError, match="tpu"):
        variant_for("tpu", has_cuda=False)


def test_views_round_trip_through_csv_frame():
    sampled = views.sample_views(5, 3, "test", 7.0, 30.0, (-80, 80), (-30, 30), 6.0, 40.0)
    back = views.views_from_frame(views.views_frame(sampled))
    assert back == sampled
    for v in sampled:  # the light lies within the cone around the camera direction
        cos = np.dot(v.origin, v.light) / (np.linalg.norm(v.origin) * np.linalg.norm(v.light))
        assert cos >= math.cos(math.radians(40)) - 1e-9
        assert -80 <= v.azimuth <= 80


def test_decimate_keeps_shape_and_budget():
    head = assets.detailed_head(3000, 0)
    v, f = mesh_ops.decimate(head.vertices, head.faces, 300)
    assert 280 <= len(f) <= 300
    low = trimesh.Trimesh(v, f, process=False)
    assert abs(low.area - head.area) / head.area < 0.05
    with pytest.raises(ValueError, match="not below"):
        mesh_ops.decimate(v, f, len(f) + 1)


def test_implicit_mesh_of_one_ball_is_its_sphere():
    ball = Scene(
        torch.zeros(1, 3, dtype=torch.float64),
        torch.tensor([1.0], dtype=torch.float64),
        torch.ones(1, 3, dtype=torch.float64),
    )
    v, f = mesh_ops.implicit_mesh(
        lambda p: field(torch.from_numpy(p), ball)[0].numpy(),
        (np.full(3, -1.5), np.full(3, 1.5)),
        40,
        1.0,
    )
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - 1).max() < 3.0 / 39  # within one grid cell
    n = vertex_normals(v, f)
    assert ((n * v).sum(1) / r > 0.95).all()  # outward


def test_rasterised_texels_lie_in_their_triangles():
    head = assets.detailed_head(2000, 1)
    v, f = mesh_ops.decimate(head.vertices, head.faces, 200)
    low = mesh_ops.uv_atlas(v, f, 64)
    s = bake.rasterise_uvs(low.uvs, low.uv_faces, 64)
    assert np.allclose(s.bary.sum(1), 1) and (s.bary >= -1e-9).all()
    centre = np.einsum("kj,kjc->kc", s.bary, low.uvs[low.uv_faces[s.face]])
    assert np.allclose(centre * 64 - 0.5, np.column_stack([s.cols, s.rows]), atol=1e-6)
    # Charts do not overlap: each texel belongs to one triangle.
    assert len(np.unique(s.rows * 64 + s.cols)) >= 0.97 * len(s.rows)


def test_missing_llvm_is_a_one_line_error_naming_the_install(tmp_path):
    code = "from neurender.mitsuba_setup import require_mitsuba; require_mitsuba('cpu')"
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": str(tmp_path / "missing.so")}
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert run.returncode == 1
    assert "karellen-llvm-core" in run.stderr and "Traceback" not in run.stderr
