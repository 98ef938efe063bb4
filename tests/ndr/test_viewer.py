"""The NDR viewer: one panel per renderer with one tone-mapped image per map turn, in the
turns' order, and the job on a barely trained network as the workflow calls it."""

import numpy as np
import pandas as pd
import torch

from neurender import io, viewer_data
from neurender.display import tonemap
from neurender.ndr import jobs
from neurender.ndr.buffers import BUFFERS, NOISY, channels, lighting_rows
from neurender.ndr.model import SHADING_INPUT
from neurender.ndr.viewer import PANELS, relight_view

WIDTH = 16


def test_panels_hold_each_turn_tone_mapped_in_order():
    g = torch.Generator().manual_seed(0)
    images = {key: {"I_R": 3 * torch.rand(4, 3, 8, 8, generator=g)} for key in PANELS.values()}
    data = relight_view(images, [0.0, 90.0, 180.0, 270.0])
    assert list(data["frames"]) == list(PANELS) and data["steps"][2] == "180 deg"
    for label, key in PANELS.items():
        for t in range(4):
            expected = io.to_uint8(tonemap(images[key]["I_R"][t]).permute(1, 2, 0).numpy())
            np.testing.assert_array_equal(
                viewer_data.decode_png(data["frames"][label][t]), expected
            )


def _random_split(folder, split: str, count: int, seed: int) -> dict[str, str]:
    """A split of random buffers in the format of :mod:`neurender.ndr.buffers`."""
    rng = np.random.default_rng(seed)
    manifest, lighting = [], []
    for i in range(count):
        out = {}
        for group, suffixes in {**BUFFERS, **NOISY}.items():
            shape = (WIDTH, WIDTH, len(suffixes)) if suffixes else (WIDTH, WIDTH)
            values = rng.random(shape, dtype=np.float32)
            if group == "mask":
                values = (values > 0.2).astype(np.float32)
            out.update(channels(group, values))
        io.write_exr(folder / split / f"{i:05d}.exr", out)
        manifest.append({"sample": i, "file": f"{i:05d}.exr"})
        lighting += lighting_rows(i, rng.normal(size=75).astype(np.float32))
    files = {
        "dir": str(folder / split),
        "manifest": str(folder / f"{split}_manifest.csv"),
        "lighting": str(folder / f"{split}_lighting.csv"),
    }
    io.write_csv(files["manifest"], pd.DataFrame(manifest))
    io.write_csv(files["lighting"], pd.DataFrame(lighting))
    return files


def test_the_job_relights_a_test_sample_under_every_turn(tmp_path, mitsuba):
    train = {f"train_{k}": v for k, v in _random_split(tmp_path, "train", 2, 1).items()}
    val = {f"val_{k}": v for k, v in _random_split(tmp_path, "val", 1, 2).items()}
    params = {"seed": 0, "device": "cpu", "variant": "ndr", "mask_erosion": 1, "epochs": 1}
    params |= {"batch_size": 2, "lr": 1e-3, "lr_schedule": "constant", "widths": [4, 8]}
    params |= {"sh_hidden": 8, "shading_residual": True}
    checkpoint = str(tmp_path / "ndr.pt")
    jobs.ndr_train(
        train | val, {"checkpoint": checkpoint, "loss": str(tmp_path / "l.csv")}, params, 1
    )
    cfg = {"seed": 3, "device": "cpu", "width": WIDTH, "camera_distance": 3.9, "fov": 30.0}
    cfg |= {"primitives": [2, 3], "edge_length": 0.3, "environment_height": 8}
    cfg |= {"coarse_height": 8, "coarse_samples": 4, "bright_texels": 4, "spp": 4}
    cfg |= {"coarse_shading": "importance"}
    cfg |= {"reference_spp": 8, "user_probes_dir": "", "user_probe_fraction": 0.5}
    cfg |= {"small_sun_fraction": 0.3, "mask_erosion": 1, "relight_sample": 1}
    jobs.ndr_viewer({"checkpoint": checkpoint}, {"viewer": tmp_path / "v.json"}, cfg, 1)
    viewer = viewer_data.read(tmp_path / "v.json")
    data = viewer["data"]
    assert viewer["kind"] == "frames" and "test sample 1" in viewer["title"]
    # A 16-column map offers 16 distinct turns (fewer than the viewer's 24).
    assert data["steps"] == [f"{22.5 * k:.0f} deg" for k in range(16)]
    truth = [viewer_data.decode_png(x) for x in data["frames"]["Mitsuba (reference)"]]
    assert truth[0].shape == (WIDTH, WIDTH, 3)
    assert any(not np.array_equal(truth[0], t) for t in truth[1:])  # the light turns
    assert len(data["frames"]["shading input"]) == 16 and SHADING_INPUT in PANELS.values()
