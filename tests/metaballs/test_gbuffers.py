import torch

from neurender.metaballs import gbuffers, raymarch, scenes


def test_layout_covers_every_channel_once_in_order():
    channels = [c for s in gbuffers.LAYOUT.values() for c in range(s.start, s.stop)]
    assert channels == list(range(gbuffers.CHANNELS))


def test_stack_puts_each_buffer_at_its_channels():
    w = 5
    colour, depth, normal = (
        torch.full((3, w, w), 0.1),
        torch.full((1, w, w), 0.2),
        torch.rand(3, w, w),
    )
    s = gbuffers.GBuffers(colour, depth, normal, torch.ones(w, w, dtype=torch.bool)).stack()
    assert s.shape == (7, w, w) and s.dtype == torch.float32
    for name, buffer in (("colour", colour), ("depth", depth), ("normal", normal)):
        assert torch.equal(s[gbuffers.LAYOUT[name]], buffer)


def test_from_hits_sets_background_depth_one_and_normalises_hit_depth():
    distance = torch.tensor(
        [scenes.MIN_DEPTH, torch.inf, scenes.MAX_DEPTH, 16.0], dtype=torch.float64
    )
    colour = torch.rand(3, 4, dtype=torch.float64)
    g = gbuffers.from_hits(distance, colour, torch.zeros(3, 4, dtype=torch.float64), 2)
    assert g.mask.tolist() == [[True, False], [True, True]]
    torch.testing.assert_close(
        g.depth[0], torch.tensor([[0.0, 1.0], [1.0, 0.5]], dtype=torch.float64)
    )
    assert torch.equal(g.colour.reshape(3, 4), colour)


def test_silhouettes_of_a_ray_marched_scene_are_its_hit_mask():
    scene = scenes.sample_scene(5, (1.0, 2.0), torch.Generator().manual_seed(2))
    g = raymarch.render_gbuffers(scene, 24)
    s = g.stack()
    assert g.mask.any() and (~g.mask).any()
    # the surface is nearer than 0.95 of the range: the depth test is the hit mask
    assert torch.equal(gbuffers.silhouette_depth(s), g.mask)
    assert torch.equal(gbuffers.silhouette_normal(s), g.mask)


def test_mirror_negates_the_normal_component_on_the_surface_only():
    scene = scenes.sample_scene(5, (1.0, 2.0), torch.Generator().manual_seed(2))
    s = raymarch.render_gbuffers(scene, 24).stack() * 2 - 1
    for axis, dim in ((0, -1), (1, -2)):
        m = gbuffers.mirror(s, axis)
        flipped = s.flip(dim)
        fg = gbuffers.silhouette_normal((flipped + 1) / 2)
        keep = [c for c in range(7) if c != gbuffers.NORMAL.start + axis]
        assert torch.equal(m[keep], flipped[keep])
        n = gbuffers.NORMAL.start + axis
        assert torch.equal(m[n][fg], -flipped[n][fg]) and torch.equal(m[n][~fg], flipped[n][~fg])
        assert torch.equal(gbuffers.mirror(m, axis), s)  # an involution
