import numpy as np
import pytest
import torch

from neurender.metaballs import demo, evaluate, inputs, raymarch, scenes


def _scene(centres, radii):
    c = torch.tensor(centres, dtype=torch.float64)
    return scenes.Scene(
        c, torch.tensor(radii, dtype=torch.float64), torch.rand(len(c), 3, dtype=torch.float64)
    )


def test_isolated_sphere_baseline_equals_the_field_for_one_ball():
    scene = _scene([[1.0, -0.5, 14.0]], [1.5])
    a = inputs.draw_spheres(scene, 40).stack()
    b = raymarch.render_gbuffers(scene, 40).stack()
    inside = evaluate.silhouette_depth(b) & evaluate.silhouette_depth(a)
    assert evaluate.iou(evaluate.silhouette_depth(a), evaluate.silhouette_depth(b)) > 0.97
    np.testing.assert_allclose(a[3][inside], b[3][inside], atol=1e-5)
    assert evaluate.normal_angles(a, b, inside).max() < 0.1


def test_blended_balls_differ_from_isolated_spheres():
    scene = _scene([[0.0, 0.0, 14.0], [1.6, 0.0, 14.0]], [1.2, 1.2])
    a = inputs.draw_spheres(scene, 48).stack()
    b = raymarch.render_gbuffers(scene, 48).stack()
    m = evaluate.example_metrics(a, b)
    assert m["iou_depth"] < 0.98 and m["normal_error_mean_deg"] > 1.0  # blending is missing


def test_inflated_radii_single_ball_and_pair():
    one = _scene([[0.5, 0.0, 15.0]], [1.3])
    assert torch.equal(inputs.inflated_radii(one), one.radii)  # exact for an isolated ball
    pair = _scene([[0.0, 0.0, 14.0], [3.0, 0.0, 14.0]], [1.2, 0.9])
    # each ball sees the other's field r_j^2 / d^2 at its centre: r / sqrt(1 - G)
    expected = torch.tensor([1.2 / (1 - 0.81 / 9) ** 0.5, 0.9 / (1 - 1.44 / 9) ** 0.5])
    torch.testing.assert_close(inputs.inflated_radii(pair), expected.double())
    buried = _scene([[0.0, 0.0, 14.0], [0.1, 0.0, 14.0]], [1.5, 1.5])  # G >> 1: capped
    torch.testing.assert_close(
        inputs.inflated_radii(buried), buried.radii / inputs.MIN_FIELD_GAP**0.5
    )


def test_inflated_spheres_are_closer_to_the_blend_than_isolated_ones():
    gen = torch.Generator().manual_seed(4)
    scene = scenes.sample_scene(15, (0.8, 1.6), gen)
    truth = raymarch.render_gbuffers(scene, 48).stack()
    isolated = evaluate.example_metrics(inputs.draw_spheres(scene, 48).stack(), truth)
    inflated = evaluate.example_metrics(inputs.inflated_spheres(scene, 48).stack(), truth)
    assert inflated["iou_depth"] > isolated["iou_depth"]
    assert inflated["normal_error_mean_deg"] < isolated["normal_error_mean_deg"]


def test_perfect_prediction_scores_perfectly():
    scene = _scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    g = raymarch.render_gbuffers(scene, 32).stack()
    m = evaluate.example_metrics(g, g)
    assert m["iou_depth"] == 1.0 and m["iou_normal"] == 1.0
    assert m["l1_colour"] == 0.0 and m["depth_error_world"] == 0.0
    assert m["normal_error_mean_deg"] == pytest.approx(0.0, abs=0.05)
    assert m["ssim_normal"] == pytest.approx(1.0, abs=1e-4)


def test_binned_means():
    import pandas as pd

    frame = pd.DataFrame(
        {
            "model": ["a"] * 4,
            "balls": [1, 2, 8, 9],
            "metric": ["x"] * 4,
            "value": [1.0, 3.0, 5.0, 7.0],
        }
    )
    out = evaluate.binned(frame, "balls", [0, 5, 10])
    assert out.value.tolist() == [2.0, 6.0]


def test_shading_lambert_and_background():
    scene = _scene([[0.0, 0.0, 12.0]], [2.0])
    g = raymarch.render_gbuffers(scene, 32).stack()
    lit = demo.shade(g)
    bg = ~evaluate.silhouette_depth(g)
    assert (lit[:, bg] == 0).all()
    # a surface point facing the light is brighter than one facing away
    light = torch.tensor(demo.LIGHT_DIR) / torch.tensor(demo.LIGHT_DIR).norm()
    n = g[4:7] * 2 - 1
    facing = (n * light[:, None, None]).sum(0)
    fg = ~bg
    assert lit.mean(0)[fg & (facing > 0.8)].mean() > lit.mean(0)[fg & (facing < 0.0)].mean()


def test_animated_scene_keeps_radii_and_moves_balls():
    scene = _scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    a, b = demo.animated_scene(scene, 0, 10), demo.animated_scene(scene, 3, 10)
    assert torch.equal(a.radii, scene.radii)
    assert (a.centres - b.centres).norm(dim=1).min() > 0.05


def _dense_spheres(scene, width):
    """Reference: every ray against every sphere, nearest hit."""
    d = scenes.pixel_rays(width, scene.centres.dtype).reshape(-1, 3)
    b = d @ scene.centres.T
    disc = b.square() - (scene.centres.square().sum(1) - scene.radii.square())
    t = torch.where(disc >= 0, b - disc.clamp(min=0).sqrt(), torch.inf)
    dist, ball = torch.where(t > 0, t, torch.inf).min(1)
    hit = torch.isfinite(dist)
    normal = (d[hit] * dist[hit, None] - scene.centres[ball[hit]]) / scene.radii[ball[hit], None]
    return hit.reshape(width, width), scenes.normalised_depth(dist[hit]), (normal + 1) / 2


def test_rasterised_spheres_equal_every_ray_against_every_sphere():
    # big balls near the image edges: their exact screen bounds matter
    scene = scenes.sample_scene(30, (1.0, 3.0), torch.Generator().manual_seed(7))
    g = inputs.draw_spheres(scene, 64)
    hit, depth, normal = _dense_spheres(scene, 64)
    assert torch.equal(g.mask, hit) and hit.any() and (~hit).any()
    torch.testing.assert_close(g.depth[0][hit], depth)
    torch.testing.assert_close(g.normal[:, hit].T, normal)
