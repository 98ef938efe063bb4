import math

import numpy as np
import pytest
import torch

from neurender.metaballs import ab, inputs, raymarch, scenes


def _one_ball(z=15.0, r=2.0):
    return scenes.Scene(
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
    fast = raymarch.march(origins, dirs, scene)
    # brute force: fixed 0.002 steps, first sample with F >= 1
    ts = torch.arange(scenes.MIN_DEPTH, scenes.MAX_DEPTH, 0.002, dtype=torch.float64)
    for i in range(0, len(dirs), 97):
        f = raymarch.field(dirs[i][None] * ts[:, None], scene)[0]
        above = (f >= 1).nonzero()
        if len(above) == 0:
            assert math.isinf(fast[i])
        else:
            assert abs(float(fast[i]) - float(ts[above[0, 0]])) < 0.003  # < 1e-3 of the range (18)


def test_nearer_circles_are_drawn_over_farther_ones():
    near = scenes.Scene(
        torch.tensor([[0.0, 0.0, 10.0], [0.0, 0.0, 20.0]], dtype=torch.float64),
        torch.tensor([1.0, 2.0], dtype=torch.float64),
        torch.tensor([[1.0, 0, 0], [0, 1.0, 0]], dtype=torch.float64),
    )
    img = inputs.draw_inputs(near, 64)
    # both rings have the same projected radius (r / z equal): the near (red) one wins
    ring = img[3] < 1
    assert ring.any()
    assert (img[0][ring] == 1).all() and (img[1][ring] == 0).all()
    assert img[3][ring].unique().tolist() == [pytest.approx(3.0 / 18.0)]
    assert img[3][~ring].eq(1).all()


def test_ab_round_trip(tmp_path):
    gen = torch.Generator().manual_seed(1)
    scene = scenes.sample_scene(5, (1.0, 2.0), gen)
    g = raymarch.render_gbuffers(scene, 16)
    x = inputs.draw_inputs(scene, 16)
    packed = ab.pack(x, g.colour, g.depth, g.normal)
    assert packed.shape == (16, 48, 4) and packed.dtype == np.uint8
    ab.write_ab(tmp_path / "a.png", packed)
    back = ab.read_ab(tmp_path / "a.png")
    for key, ref in (("inputs", x), ("colour", g.colour), ("depth", g.depth), ("normal", g.normal)):
        np.testing.assert_allclose(back[key].double(), ref, atol=0.5 / 255 + 1e-6)
    with pytest.raises(ValueError, match="expected \\(W, 3W, 4\\)"):
        ab.unpack(packed[:, :40])


def _painted_circles(scene, width):
    """Reference: the thesis's billboards drawn one by one, far to near."""
    image = torch.zeros(4, width, width, dtype=torch.float64)
    image[3] = 1.0
    centre = scenes.project(scene.centres, width)
    radius = inputs.projected_radius(scene, width)
    depth = scenes.normalised_depth(scene.centres.norm(dim=1))
    coords = torch.arange(width, dtype=torch.float64) + 0.5
    for i in torch.argsort(depth, descending=True).tolist():
        dist = torch.hypot(coords[None, :] - centre[i, 0], coords[:, None] - centre[i, 1])
        ring = (dist > 0.9 * radius[i]) & (dist < radius[i])
        image[:3, ring] = scene.colours[i][:, None]
        image[3, ring] = depth[i]
    return image


def test_vectorised_circles_equal_painting_far_to_near():
    gen = torch.Generator().manual_seed(2)
    scene = scenes.sample_scene(25, (0.6, 1.6), gen)
    torch.testing.assert_close(inputs.draw_inputs(scene, 48), _painted_circles(scene, 48))


def test_mirrored_example_is_the_mirrored_scenes_example():
    from neurender.metaballs import model

    gen = torch.Generator().manual_seed(5)
    scene = scenes.sample_scene(8, (0.8, 1.6), gen)
    width = 32

    def example(s):
        x = model.network_inputs(s, width, "sphere_residual").double()
        return x * 2 - 1, raymarch.render_gbuffers(s, width).stack().double() * 2 - 1

    for horizontal, vertical in ((True, False), (False, True), (True, True)):
        sign = torch.tensor([-1.0 if horizontal else 1.0, -1.0 if vertical else 1.0, 1.0])
        mirrored = scenes.Scene(scene.centres * sign.double(), scene.radii, scene.colours)
        x, y = model.flip(*example(scene), horizontal, vertical, spheres=True)
        x_ref, y_ref = example(mirrored)
        torch.testing.assert_close(x, x_ref, atol=1e-5, rtol=0)
        torch.testing.assert_close(y, y_ref, atol=1e-5, rtol=0)


def test_generate_split_is_deterministic_and_round_trips(tmp_path):
    from neurender import io
    from neurender.metaballs import data

    cfg = {"seed": 3, "width": 16, "examples": {"test": 5}, "balls": [2, 5], "radius": [1.0, 2.0]}
    for run, workers in (("a", 1), ("b", 2)):
        data.generate_split(
            "test", cfg, workers, tmp_path / run, tmp_path / f"{run}.csv", tmp_path / f"{run}_b.csv"
        )
    m = io.read_csv(tmp_path / "a.csv", ["balls", "coverage", "min_depth_separation"])
    assert len(m) == 5 and m.balls.between(2, 5).all()
    assert m.example.tolist() == list(range(5))
    for f in m.file:
        np.testing.assert_array_equal(
            io.read_png(tmp_path / "a" / f), io.read_png(tmp_path / "b" / f)
        )
    back = ab.read_ab(tmp_path / "a" / m.file[0])
    assert back["inputs"].shape == (4, 16, 16)
    scenes_back = data.read_scenes(tmp_path / "b_b.csv")
    assert sorted(scenes_back) == list(range(5))
    for i, scene in scenes_back.items():  # the ball table gives back the exact scene
        ref = data.example_scene(cfg, "test", i)
        assert len(scene) == m.balls[i]
        for a, b in ((scene.centres, ref.centres), (scene.radii, ref.radii)):
            assert torch.equal(a, b)
        assert torch.equal(scene.colours, ref.colours)
