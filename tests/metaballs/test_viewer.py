"""The metaballs viewer: every frame of the demo in order, each network's panel cut from
its picture, overlays that mark exactly where its silhouette differs from the ray
marcher's, and the job as the workflow calls it."""

import numpy as np
import pytest
import torch

from neurender import viewer_data
from neurender.metaballs import GAN_VARIANTS, VARIANTS, jobs
from neurender.metaballs.demo import RAY_MARCHING, Sequence
from neurender.metaballs.viewer import demo_view

from .keys import KERNEL

W = 8


def _sequence(frames: int, names: int) -> Sequence:
    g = torch.Generator().manual_seed(0)
    pictures = [torch.rand(3, W, (names + 1) * W, generator=g) for _ in range(frames)]
    masks = [[torch.rand(W, W, generator=g) > 0.5 for _ in range(names + 1)] for _ in range(frames)]
    return Sequence(None, pictures, masks)


def test_frames_are_the_pictures_cut_into_panels_in_order():
    sequence = _sequence(4, 2)
    data = demo_view(sequence, ["a", "b"], W)
    assert list(data["frames"]) == ["a", "b", RAY_MARCHING] and list(data["overlay"]) == ["a", "b"]
    assert data["scale"] == viewer_data.display_scale(W)
    for f, picture in enumerate(sequence.pictures):
        image = np.round(picture.permute(1, 2, 0).numpy() * 255).astype(np.uint8)
        for k, panel in enumerate(data["frames"]):
            decoded = viewer_data.decode_png(data["frames"][panel][f])
            np.testing.assert_array_equal(decoded, image[:, k * W : (k + 1) * W])


def test_overlays_mark_where_each_silhouette_differs_from_the_ray_marcher():
    sequence = _sequence(3, 2)
    data = demo_view(sequence, ["a", "b"], W)
    for f, masks in enumerate(sequence.silhouettes):
        truth = masks[-1].numpy()
        for k, name in enumerate(["a", "b"]):
            overlay = viewer_data.decode_png(data["overlay"][name][f])
            differs = masks[k].numpy() != truth
            np.testing.assert_array_equal(overlay[..., 3] > 0, differs)


def test_a_picture_of_the_wrong_width_is_refused():
    with pytest.raises(ValueError, match="expected 3 panels of width 8"):
        demo_view(_sequence(1, 1), ["a", "b"], W)


def test_the_job_renders_every_variant_and_the_ray_marcher(tmp_path, write_split, split_files):
    write_split("train", 2)
    write_split("val", 1)
    files = split_files
    checkpoints = []
    for variant in VARIANTS:
        params = {"seed": 1, "device": "cpu", "width": 32, "variant": variant, "ngf": 4}
        params |= {"l1_weight": 100.0, "flips": False, "epochs": 1, "batch_size": 2, "lr": 1e-3}
        params |= {"lr_schedule": "constant"}
        params |= {"ndf": 4, "gan_weight": 1.0} if variant in GAN_VARIANTS else {"gan_weight": 0.0}
        out = {
            "checkpoint": str(tmp_path / f"{variant}.pt"),
            "loss": str(tmp_path / f"{variant}.csv"),
        }
        jobs.metaballs_train(files, out, params, 1)
        checkpoints.append(out["checkpoint"])
    params = {"seed": 0, "device": "cpu", "width": 32, "radius": [1.0, 2.0], **KERNEL}
    params |= {"demo_frames": 3, "demo_balls": 4}
    jobs.metaballs_viewer({"checkpoints": checkpoints}, {"viewer": tmp_path / "v.json"}, params, 1)
    viewer = viewer_data.read(tmp_path / "v.json")
    assert viewer["kind"] == "frames"
    assert list(viewer["data"]["frames"]) == [*VARIANTS, RAY_MARCHING]
    assert all(len(v) == 3 for v in viewer["data"]["frames"].values())
    truth = viewer_data.decode_png(viewer["data"]["frames"][RAY_MARCHING][0])
    assert truth.shape == (32, 32, 3) and truth.max() > 0  # the ray marcher drew the balls
