import torch

from neurender.metaballs import demo, gbuffers, raymarch


def test_shading_lambert_and_background(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0]], [2.0])
    g = raymarch.render_gbuffers(scene, 32).stack()
    lit = demo.shade(g)
    bg = ~gbuffers.silhouette_depth(g)
    assert (lit[:, bg] == 0).all()
    # a surface point facing the light is brighter than one facing away
    light = torch.tensor(demo.LIGHT_DIR) / torch.tensor(demo.LIGHT_DIR).norm()
    facing = (gbuffers.decoded_normals(g) * light[:, None, None]).sum(0)
    fg = ~bg
    assert lit.mean(0)[fg & (facing > 0.8)].mean() > lit.mean(0)[fg & (facing < 0.0)].mean()


def test_animated_scene_keeps_radii_and_moves_balls(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    a, b = demo.animated_scene(scene, 0, 10), demo.animated_scene(scene, 3, 10)
    assert torch.equal(a.radii, scene.radii) and torch.equal(a.colours, scene.colours)
    assert (a.centres - b.centres).norm(dim=1).min() > 0.05


def test_silhouette_flips_count_changed_pixels_per_frame():
    empty = torch.zeros(2, 2, dtype=torch.bool)
    one = empty.clone()
    one[0, 0] = True
    flips = demo.silhouette_flips([[empty, empty], [one, empty], [one, one]], ["net", "truth"])
    assert flips.frame.tolist() == [1, 2]
    assert flips["net"].tolist() == [0.25, 0.0] and flips["truth"].tolist() == [0.0, 0.25]
