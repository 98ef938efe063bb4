import numpy as np
import pytest
import torch

from neurender.metaball import Kernel, Scene
from neurender.metaballs import evaluate, gbuffers, inputs, raymarch, scenes


def test_nearer_circles_are_drawn_over_farther_ones():
    near = Scene(
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


def test_of_balls_at_equal_depth_the_first_is_drawn_and_every_draw_is_the_same():
    # Two balls at one place, red first, then green: every pixel ties on depth.
    twins = Scene(
        torch.tensor([[0.1, -0.2, 8.0], [0.1, -0.2, 8.0]], dtype=torch.float64),
        torch.tensor([1.5, 1.5], dtype=torch.float64),
        torch.tensor([[1.0, 0, 0], [0, 1.0, 0]], dtype=torch.float64),
    )
    circles = inputs.draw_inputs(twins, 64)
    spheres = inputs.draw_spheres(twins, 64)
    ring, hit = circles[3] < 1, spheres.mask
    assert ring.any() and hit.any()
    assert (circles[0][ring] == 1).all() and (circles[1][ring] == 0).all()
    assert (spheres.colour[0][hit] == 1).all() and (spheres.colour[1][hit] == 0).all()
    for _ in range(5):
        torch.testing.assert_close(inputs.draw_inputs(twins, 64), circles, atol=0, rtol=0)


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


def test_isolated_sphere_baseline_equals_the_field_for_one_ball(make_scene):
    scene = make_scene([[1.0, -0.5, 14.0]], [1.5])
    a = inputs.draw_spheres(scene, 40).stack()
    b = raymarch.render_gbuffers(scene, 40).stack()
    sa, sb = gbuffers.silhouette_depth(a), gbuffers.silhouette_depth(b)
    inside = sa & sb
    assert evaluate.iou(sa, sb) > 0.97
    np.testing.assert_allclose(
        a[gbuffers.DEPTH][0][inside], b[gbuffers.DEPTH][0][inside], atol=1e-5
    )
    assert evaluate.normal_angles(a, b, inside).max() < 0.1


def test_inflated_radii_single_ball_and_pair(make_scene):
    one = make_scene([[0.5, 0.0, 15.0]], [1.3])
    assert torch.equal(inputs.inflated_radii(one), one.radii)  # exact for an isolated ball
    pair = make_scene([[0.0, 0.0, 14.0], [3.0, 0.0, 14.0]], [1.2, 0.9])
    # each ball sees the other's field r_j^2 / d^2 at its centre: r / sqrt(1 - G)
    expected = torch.tensor([1.2 / (1 - 0.81 / 9) ** 0.5, 0.9 / (1 - 1.44 / 9) ** 0.5])
    torch.testing.assert_close(inputs.inflated_radii(pair), expected.double())
    buried = make_scene([[0.0, 0.0, 14.0], [0.1, 0.0, 14.0]], [1.5, 1.5])  # G >> 1: capped
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


# The first, pair-list implementation of the circles and impostors (one gather per pair and
# the ray-centre products from one matrix product), kept as the reference of the blocked one.
def _reference_pairs(boxes, width):
    lo = boxes[:, :2].floor().clamp(0, width).long()
    hi = (boxes[:, 2:].ceil() + 1).clamp(0, width).long()
    size = (hi - lo).clamp(min=0)
    counts = size[:, 0] * size[:, 1]
    ball = torch.repeat_interleave(torch.arange(len(boxes)), counts)
    local = torch.arange(int(counts.sum())) - (torch.cumsum(counts, 0) - counts)[ball]
    cols = size[ball, 0]
    return ball, (lo[ball, 1] + local // cols) * width + lo[ball, 0] + local % cols


def _reference_nearest(pixel, key, width):
    nearest = torch.full((width * width,), torch.inf, dtype=key.dtype)
    nearest = nearest.scatter_reduce(0, pixel, key, "amin")
    tied = torch.isfinite(key) & (key == nearest[pixel])
    pair = torch.arange(len(key))
    first = torch.full((width * width,), len(key), dtype=pair.dtype)
    first = first.scatter_reduce(0, pixel[tied], pair[tied], "amin")
    return nearest, tied & (first[pixel] == pair)


def _reference_circles(scene, width):
    centre = scenes.project(scene.centres, width)
    radius = inputs.projected_radius(scene, width)
    depth = scenes.normalised_depth(scene.centres.norm(dim=1))
    boxes = torch.cat([centre - radius[:, None], centre + radius[:, None]], 1)
    ball, pixel = _reference_pairs(boxes, width)
    dist = torch.hypot(
        (pixel % width).to(scene.centres.dtype) + 0.5 - centre[ball, 0],
        (pixel // width).to(scene.centres.dtype) + 0.5 - centre[ball, 1],
    )
    ring = (dist > 0.9 * radius[ball]) & (dist < radius[ball])
    nearest, won = _reference_nearest(pixel, torch.where(ring, depth[ball], torch.inf), width)
    image = torch.zeros(4, width * width, dtype=scene.centres.dtype)
    image[:3, pixel[won]] = scene.colours[ball[won]].T
    image[3] = torch.where(torch.isfinite(nearest), nearest, 1.0)
    return image.reshape(4, width, width)


def _reference_spheres(scene, width, matmul=True):
    """``matmul=False``: ray . centre multiplied and added in axis order instead."""
    ball, pixel = _reference_pairs(inputs._sphere_boxes(scene.centres, scene.radii, width), width)
    rays = scenes.pixel_rays(width, scene.centres.dtype).reshape(-1, 3)
    if matmul:
        b = (rays @ scene.centres.T).reshape(-1)[pixel * len(scene) + ball]
    else:
        r, c = rays[pixel], scene.centres[ball]
        b = r[:, 0] * c[:, 0] + r[:, 1] * c[:, 1] + r[:, 2] * c[:, 2]
    disc = b.square() - (scene.centres.square().sum(1) - scene.radii.square())[ball]
    t = torch.where(disc >= 0, b - disc.clamp(min=0).sqrt(), torch.inf)
    dist, won = _reference_nearest(pixel, torch.where(t > 0, t, torch.inf), width)
    hit, ball = pixel[won], ball[won]
    colour = torch.zeros(3, width * width, dtype=scene.centres.dtype)
    normal = torch.zeros_like(colour)
    colour[:, hit] = scene.colours[ball].T
    points = rays[hit] * dist[hit, None]
    normal[:, hit] = (((points - scene.centres[ball]) / scene.radii[ball, None] + 1) / 2).T
    return gbuffers.from_hits(dist, colour, normal, width)


def _reference_examples():
    """Busy and sparse scenes, big balls over the image edges, tied twins; both dtypes."""
    gen = torch.Generator().manual_seed(11)
    cases = [(145, (0.6, 1.6), 128), (20, (0.6, 1.6), 64), (30, (1.0, 3.0), 48), (3, (1, 2), 32)]
    out = [(scenes.sample_scene(n, radius, gen), width) for n, radius, width in cases]
    twins = scenes.sample_scene(6, (1.0, 2.0), gen)
    twins = Scene(  # each ball twice, in another colour: every pixel ties
        torch.cat([twins.centres, twins.centres]),
        torch.cat([twins.radii, twins.radii]),
        torch.cat([twins.colours, 1 - twins.colours]),
    )
    return [*out, (twins, 40)]


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_blocked_circles_equal_the_first_implementation_bitwise(dtype):
    for scene, width in _reference_examples():
        scene = scene.to(dtype)
        torch.testing.assert_close(
            inputs.draw_inputs(scene, width), _reference_circles(scene, width), atol=0, rtol=0
        )


def test_blocked_impostors_equal_the_first_implementation():
    # float64: bitwise. float32: the same hits and winning balls, and bitwise once
    # ray . centre is rounded alike (the first version took it from a BLAS product, whose
    # float32 rounding depends on the kernel; the square root of b^2 - |c|^2 + r^2
    # amplifies that at the rim).
    for scene, width in _reference_examples():
        s = Scene(scene.centres, inputs.inflated_radii(scene), scene.colours)
        new, ref = inputs.draw_spheres(s, width), _reference_spheres(s, width)
        torch.testing.assert_close(new.stack(), ref.stack(), atol=0, rtol=0)
        assert torch.equal(new.mask, ref.mask)
        s = s.to(torch.float32)
        new, ref = inputs.draw_spheres(s, width), _reference_spheres(s, width)
        assert torch.equal(new.mask, ref.mask) and new.mask.any()
        assert torch.equal(new.colour, ref.colour)  # the same ball won every pixel
        same_rounding = _reference_spheres(s, width, matmul=False)
        torch.testing.assert_close(new.stack(), same_rounding.stack(), atol=0, rtol=0)


def _whole_matrix_inflated_radii(scene):
    """Reference: the first implementation, every pair in one ``B x B`` matrix."""
    d2 = torch.cdist(scene.centres, scene.centres).square()
    d2.fill_diagonal_(torch.inf)
    others = (scene.radii.square()[None, :] / d2).sum(1)
    return scene.radii / (1 - others).clamp(min=inputs.MIN_FIELD_GAP).sqrt()


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_inverse_square_radii_in_row_chunks_equal_the_whole_matrix(dtype):
    for count in (3, 30, 145):
        scene = scenes.sample_scene(count, (0.6, 1.6), torch.Generator().manual_seed(count))
        scene = scene.to(dtype)
        reference = _whole_matrix_inflated_radii(scene)
        # up to PAIR_ROWS balls: one chunk, the same numbers bit for bit
        torch.testing.assert_close(inputs.inflated_radii(scene), reference, atol=0, rtol=0)
        for chunk in (1, 7, 64):  # cdist may round a partial block's products otherwise
            torch.testing.assert_close(inputs.inflated_radii(scene, chunk=chunk), reference)


FINITE = [Kernel("wyvill", 2.0), Kernel("gaussian", 2.5, 1.0)]


@pytest.mark.parametrize("kernel", FINITE, ids=lambda k: k.name)
def test_finite_kernel_radii_solve_the_kernel_in_the_others_field(kernel, make_scene):
    one = make_scene([[0.5, 0.0, 15.0]], [1.3])
    one = Scene(one.centres, one.radii, one.colours, kernel)
    torch.testing.assert_close(inputs.inflated_radii(one), one.radii)  # exact when alone
    # a crowded scene: every ball's field from the others by brute force, then k(x) = 1 - G
    scene = scenes.sample_scene(60, (0.8, 2.0), torch.Generator().manual_seed(3))
    scene = Scene(scene.centres, scene.radii, scene.colours, kernel)
    d2 = torch.cdist(scene.centres, scene.centres).square()
    f = kernel.value(d2 / scene.radii.square()[None, :])
    others = f.sum(1) - f.diagonal()
    assert (others > 0).sum() > 20 and (others > 1 - inputs.MIN_FIELD_GAP).any()
    radii = inputs.inflated_radii(scene)
    gap = (1 - others).clamp(min=inputs.MIN_FIELD_GAP)
    torch.testing.assert_close(kernel.value((radii / scene.radii).square()), gap)
    assert (radii >= scene.radii).all()


def _dense_counts(scene, width):
    """Reference: every ray against every sphere, how many it passes through."""
    rays = scenes.pixel_rays(width, scene.centres.dtype).reshape(-1, 3)
    b = rays @ scene.centres.T
    return (b.square() - (scene.centres.square().sum(1) - scene.radii.square()) > 0).sum(1)


def test_sphere_counts_equal_every_ray_against_every_sphere():
    scene = scenes.sample_scene(40, (1.0, 3.0), torch.Generator().manual_seed(9))
    counts = inputs.sphere_counts(scene, 48)
    assert torch.equal(counts, _dense_counts(scene, 48)) and counts.max() > 2
    behind = Scene(scene.centres, scene.radii + 30, scene.colours)
    with pytest.raises(ValueError, match="not wholly in front of the camera"):
        inputs.sphere_counts(behind, 16)
