import math

import numpy as np
import pytest
import torch

from neurender.metaball import Scene, field, march
from neurender.metaballs import raymarch, scenes


def _one_ball(z=15.0, r=2.0):
    return Scene(
        torch.tensor([[0.0, 0.0, z]], dtype=torch.float64),
        torch.tensor([r], dtype=torch.float64),
        torch.tensor([[0.2, 0.4, 0.6]], dtype=torch.float64),
    )


def test_isolated_ball_is_a_sphere():
    g = raymarch.render_gbuffers(_one_ball(), 33)
    c = 16  # the central pixel looks straight down +z
    assert g.depth[0, c, c] == pytest.approx((13.0 - 7.0) / 18.0, abs=1e-6)
    np.testing.assert_allclose(g.normal[:, c, c], [0.5, 0.5, 0.0], atol=1e-3)  # facing the camera
    np.testing.assert_allclose(g.colour[:, c, c], [0.2, 0.4, 0.6], atol=1e-9)
    assert g.depth[0, 0, 0] == 1.0 and g.normal[:, 0, 0].abs().sum() == 0  # background
    # silhouette: angular radius asin(r / d)
    dirs = scenes.pixel_rays(33)
    inside = torch.acos(dirs[..., 2]) < math.asin(2.0 / 15.0)
    assert (inside == g.mask).float().mean() > 0.99


def test_safe_stepping_matches_brute_force_marching():
    gen = torch.Generator().manual_seed(0)
    scene = scenes.sample_scene(12, (0.8, 2.0), gen)
    dirs = scenes.pixel_rays(24).reshape(-1, 3)
    origins = torch.zeros_like(dirs)
    fast = march(origins, dirs, scene, scenes.MIN_DEPTH, scenes.MAX_DEPTH)
    # brute force: fixed 0.002 steps, first sample with F >= 1
    ts = torch.arange(scenes.MIN_DEPTH, scenes.MAX_DEPTH, 0.002, dtype=torch.float64)
    checked = 0
    for i in range(0, len(dirs), 97):
        f = field(dirs[i][None] * ts[:, None], scene)[0]
        above = (f >= 1).nonzero()
        if len(above) == 0:
            assert math.isinf(fast[i])
        else:
            checked += 1
            assert abs(float(fast[i]) - float(ts[above[0, 0]])) < 0.003  # < 1e-3 of the range (18)
    assert checked > 0  # some sampled rays hit the surface


def test_render_gbuffers_chunks_do_not_change_the_result():
    scene = scenes.sample_scene(6, (0.8, 2.0), torch.Generator().manual_seed(3))
    whole = raymarch.render_gbuffers(scene, 20)
    chunked = raymarch.render_gbuffers(scene, 20, chunk=37)
    assert torch.equal(whole.stack(), chunked.stack()) and torch.equal(whole.mask, chunked.mask)
