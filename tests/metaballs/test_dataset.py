import torch

from neurender.metaball import Scene
from neurender.metaballs import dataset, gbuffers, model, raymarch, scenes


def test_mirrored_example_is_the_mirrored_scenes_example():
    gen = torch.Generator().manual_seed(5)
    scene = scenes.sample_scene(8, (0.8, 1.6), gen)
    width = 32

    def example(s):
        x = model.network_inputs(s, width, "sphere_residual").double()
        return x * 2 - 1, raymarch.render_gbuffers(s, width).stack().double() * 2 - 1

    for horizontal, vertical in ((True, False), (False, True), (True, True)):
        sign = torch.tensor([-1.0 if horizontal else 1.0, -1.0 if vertical else 1.0, 1.0])
        mirrored = Scene(scene.centres * sign.double(), scene.radii, scene.colours)
        x, y = dataset.flip(*example(scene), horizontal, vertical, spheres=True)
        x_ref, y_ref = example(mirrored)
        torch.testing.assert_close(x, x_ref, atol=1e-5, rtol=0)
        torch.testing.assert_close(y, y_ref, atol=1e-5, rtol=0)


def test_dataset_items_and_mirrorings(tmp_path, write_split):
    write_split("train", 2)
    args = (tmp_path / "train", tmp_path / "train_manifest.csv", tmp_path / "train_balls.csv")
    plain = dataset.ABDataset(*args, "pix2pix")
    flipped = dataset.ABDataset(*args, "sphere_residual", flips=True)
    assert len(plain) == 2 and len(flipped) == 8
    x, y = plain[1]
    assert x.shape == (4, 32, 32) and y.shape == (gbuffers.CHANNELS, 32, 32)
    assert x.min() >= -1 and x.max() <= 1
    x0, y0 = flipped[4]  # example 1, not mirrored
    torch.testing.assert_close(x0[: model.CIRCLE_CHANNELS], x)
    torch.testing.assert_close(y0, y)
    x1, y1 = flipped[5]  # example 1 mirrored left-right: same depth, mirrored image
    depth = gbuffers.DEPTH.start
    torch.testing.assert_close(y1[depth], y[depth].flip(-1))
    torch.testing.assert_close(
        x1[model.CIRCLE_CHANNELS + depth], x0[model.CIRCLE_CHANNELS + depth].flip(-1)
    )


def test_a_split_over_the_memory_limit_is_read_from_disk_with_the_same_items(tmp_path, write_split):
    write_split("train", 2)
    args = (tmp_path / "train", tmp_path / "train_manifest.csv", tmp_path / "train_balls.csv")
    in_memory = dataset.ABDataset(*args, "sphere_residual", flips=True)
    on_disk = dataset.ABDataset(*args, "sphere_residual", flips=True, max_bytes=1)
    assert in_memory.images is not None and on_disk.images is None
    assert len(on_disk) == len(in_memory) == 8
    for k in range(len(in_memory)):
        for a, b in zip(on_disk[k], in_memory[k], strict=True):
            torch.testing.assert_close(a, b, atol=0, rtol=0)
