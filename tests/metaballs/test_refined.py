import numpy as np
import torch

from neurender.metaballs import evaluate, gbuffers, inputs, raymarch, scenes
from neurender.metaballs.refined import refined_spheres


def test_one_ball_is_its_exact_sphere(make_scene):
    scene = make_scene([[1.0, -0.5, 14.0]], [1.5])
    refined = refined_spheres(scene, 40)
    exact = inputs.draw_spheres(scene, 40)  # the isolated ball's surface: r^2 / d^2 = 1
    assert torch.equal(refined.mask, exact.mask) and exact.mask.any()
    np.testing.assert_allclose(refined.depth[0][exact.mask], exact.depth[0][exact.mask], atol=1e-6)
    np.testing.assert_allclose(
        refined.normal[:, exact.mask], exact.normal[:, exact.mask], atol=1e-6
    )
    np.testing.assert_allclose(refined.colour, exact.colour, atol=1e-12)


def test_refined_impostors_drop_what_the_inflated_ones_overestimate_and_add_nothing():
    gen = torch.Generator().manual_seed(4)
    for count in (6, 12, 15, 20):
        scene = scenes.sample_scene(count, (0.8, 1.6), gen)
        truth = gbuffers.silhouette_depth(raymarch.render_gbuffers(scene, 64).stack())
        prior = inputs.inflated_spheres(scene, 64)
        refined = refined_spheres(scene, 64)
        stack, prior_stack = refined.stack(), prior.stack()
        truth_stack = raymarch.render_gbuffers(scene, 64).stack()
        ours = evaluate.example_metrics(stack, truth_stack)
        theirs = evaluate.example_metrics(prior_stack, truth_stack)
        assert ours["iou_depth"] > theirs["iou_depth"]
        assert ours["normal_error_mean_deg"] < 0.7 * theirs["normal_error_mean_deg"]
        assert ours["l1_colour"] < theirs["l1_colour"]
        # the field is never below the threshold where the refined surface is drawn, so
        # no pixel is foreground that the ray marcher leaves empty; none the impostors miss
        assert (refined.mask & ~truth).sum() <= 0.1 * max(1, int((prior.mask & ~truth).sum()))
        assert not (refined.mask & ~prior.mask).any()
