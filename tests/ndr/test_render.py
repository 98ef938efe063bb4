import math

import numpy as np
import pytest
import torch

from neurender import lights
from neurender.ndr import data, furnace, render, split_kind
from neurender.ndr.buffers import NDRDataset

CFG = {
    "seed": 3,
    "device": "cpu",
    "width": 32,
    "camera_distance": 3.9,
    "fov": 30.0,
    "primitives": [2, 3],
    "edge_length": 0.3,
    "environment_height": 32,
    "coarse_height": 8,
    "coarse_shading": "importance",
    "coarse_samples": 16,
    "bright_texels": 16,
    "spp": 8,
    "reference_spp": 32,
    "fixed_probe": "sky",
    "user_probes_dir": "",
    "user_probe_fraction": 0.5,
    "small_sun_fraction": 0.3,
}


def test_white_furnace_checks_pass(mitsuba):
    """Each check's measured value against a tolerance stated here, not the module's."""
    mi, _ = mitsuba
    checks = furnace.furnace(mi, 32, 64, 64, 0)
    assert len(checks) == 7
    i_d, i_d_per_pixel, s_d, s_s, fast_d, fast_s, sun = (c.measured for c in checks)
    # Mitsuba's white Lambertian sphere in a unit environment: mean 1 up to its Monte
    # Carlo error, per-pixel error within 1 / sqrt(64 spp).
    assert abs(i_d - 1) <= 0.01 and i_d_per_pixel <= 64**-0.5
    # The coarse S_D of a constant map is exact; the prefiltered one up to quadrature.
    assert abs(s_d - 1) <= 1e-6 and abs(fast_d - 1) <= 1e-3
    # Both GGX albedo estimates within 2 % of Mitsuba's I_S; the sun within 25 %.
    assert s_s <= 0.02 and fast_s <= 0.02 and sun <= 0.25
    assert all(c.met for c in checks), checks


def test_the_sun_check_shows_plain_brdf_sampling_speckle(mitsuba):
    """Under a sun holding most of the map's power in one coarse texel, the estimator with
    bright texels stays near Mitsuba's unoccluded shading; the paper's plain BRDF sampling
    (stated in the check) is off by several times more; the prefiltered shading (SH and
    the sun as a light, stated too) is within the same tolerance."""
    mi, _ = mitsuba
    check = furnace.sun_check(mi, 32, 64, 64, 16, 0)
    stated = check.check.split("plain BRDF sampling: ")[1]
    plain = float(stated.split(",")[0])
    assert check.met and plain > 4 * check.measured
    assert float(stated.split("SH and lights: ")[1].split(")")[0]) < 0.25


def test_g_buffers_of_a_sphere_match_the_camera_analytically():
    sphere = furnace.white_sphere(0.5)
    width, distance, fov = 64, 3.9, 30.0
    g = render.g_buffers(sphere, render.camera(distance, fov), width)
    # Projected radius: the silhouette cone has half-angle asin(1 / d).
    radius_px = math.tan(math.asin(1 / distance)) / math.tan(math.radians(fov / 2)) * width / 2
    assert g["mask"].sum() == pytest.approx(math.pi * radius_px**2, rel=0.03)
    centre = (slice(width // 2 - 1, width // 2 + 1),) * 2
    # The nearest point (z = 1) is at depth d - 1, the start of the [d - 1, d + 1] range.
    assert g["depth"][centre].max() < 0.01
    np.testing.assert_allclose(g["normal"][centre].reshape(-1, 3), [[0, 0, 1]] * 4, atol=0.02)
    assert (g["depth"][g["mask"] == 0] == 1).all()
    assert (g["normal"][g["mask"] == 0] == 0).all()


def test_a_built_scene_renders_both_maps_again_as_a_fresh_one(mitsuba):
    """:func:`render.render_shading` leaves its scene on the diffuse lobe, so rendering it
    again (as the equal-quality sweep times it) gives the maps of :func:`render.shading_maps`."""
    mi, _ = mitsuba
    obj, env, _, _ = data.sample_scene(CFG, "test", 0)
    view = render.camera(CFG["camera_distance"], CFG["fov"])
    fresh = render.shading_maps(mi, obj, env, view, 16, 4, 11)
    scene = render.shading_scene(mi, obj, env, view, 16, 4)
    for _ in range(2):
        again = render.render_shading(mi, scene, 11)
        for key in ("I_D", "I_S", "coverage"):
            np.testing.assert_allclose(again[key], fresh[key], rtol=1e-5, atol=1e-6, err_msg=key)
    assert not np.allclose(fresh["I_D"], fresh["I_S"])


def test_split_names():
    assert split_kind("diffuse_test") == ("diffuse", "test")
    assert split_kind("train") == ("complex", "train")
    assert split_kind("sunlit_test") == ("sunlit", "test")
    with pytest.raises(ValueError, match="'glossy_train'"):
        split_kind("glossy_train")
    with pytest.raises(ValueError, match="'sunlit_train'"):
        split_kind("sunlit_train")


def test_samples_are_deterministic_and_load_as_a_dataset(mitsuba, tmp_path):
    mi, _ = mitsuba
    a, light_a, row = data.make_sample(CFG, "test", 1, mi)
    b, light_b, _ = data.make_sample(CFG, "test", 1, mi)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    np.testing.assert_array_equal(light_a, light_b)
    assert row["spp"] == CFG["reference_spp"]
    assert {"I_D_noisy.R", "S_S.B", "N.Z", "mask"} <= set(a)
    # The clean reference and the noisy render are independent estimates of one image.
    m = a["mask"] > 0
    assert abs(a["I_D.G"][m].mean() - a["I_D_noisy.G"][m].mean()) < 0.1 * a["I_D.G"][m].mean()

    data.generate_split(
        CFG, "test", 2, tmp_path / "test", tmp_path / "m.csv", tmp_path / "l.csv", 1
    )
    dataset = NDRDataset(tmp_path / "test", tmp_path / "m.csv", tmp_path / "l.csv", erosion=1)
    item = dataset[1]
    assert item["light"].shape == (75,)
    assert item["N"].shape == (3, 32, 32) and item["I_S_noisy"].shape == (3, 32, 32)
    # Eroding only removes pixels.
    assert (item["mask"] <= dataset.buffers["mask"][1]).all()
    assert item["mask"].sum() < (dataset[1]["N"].abs().sum(0) > 0).sum()
    # A split over the memory limit stays on disk and reads the same items.
    on_disk = NDRDataset(
        tmp_path / "test", tmp_path / "m.csv", tmp_path / "l.csv", erosion=1, max_bytes=1
    )
    assert on_disk.buffers is None and len(on_disk) == len(dataset)
    for i in range(len(dataset)):
        for key, value in dataset[i].items():
            torch.testing.assert_close(on_disk[i][key], value, atol=0, rtol=0)


def test_user_maps_light_samples_and_the_test_split_gets_unseen_ones(mitsuba, tmp_path):
    mi, _ = mitsuba
    for i in range(3):
        lights.write_probe(tmp_path / f"map{i}.exr", np.full((16, 32, 3), 0.5 + i, np.float32))
    cfg = {**CFG, "user_probes_dir": str(tmp_path), "user_probe_fraction": 1.0}
    assert [p.stem for p in data._user_probes(cfg, "test")] == ["map2"]
    assert [p.stem for p in data._user_probes(cfg, "train")] == ["map0", "map1"]
    _, light, row = data.make_sample(cfg, "train", 0, mi)
    assert row["environment"] in ("map0", "map1")
    # A constant map's SH is its DC term: 0.5 or 1.5 times sqrt(4 pi).
    assert light[0] / math.sqrt(4 * math.pi) == pytest.approx(
        0.5 + int(row["environment"][-1]), rel=1e-3
    )


def test_turning_the_map_relights_without_changing_the_buffers(mitsuba):
    mi, _ = mitsuba
    cfg = {**CFG, "reference_spp": 16}
    base, light, _ = data.make_sample(cfg, "test", 2, mi)
    turned, turned_light, _ = data.make_sample(cfg, "test", 2, mi, env_shift=16)
    for key in ("N.X", "D", "R", "A_D.G", "A_S.B", "mask"):
        np.testing.assert_array_equal(base[key], turned[key], err_msg=key)
    for key in ("S_D.R", "I_D.R"):
        assert not np.allclose(base[key], turned[key]), key
    # A turn about +y keeps the SH terms that are invariant under it (DC, y-dipole).
    np.testing.assert_allclose(turned_light[:6], light[:6], rtol=1e-5, atol=1e-6)
    assert not np.allclose(turned_light[9:12], light[9:12])


def test_real_world_like_samples_are_complex_objects_under_a_small_sun(mitsuba):
    mi, _ = mitsuba
    out, _, row = data.make_sample({**CFG, "reference_spp": 16}, "sunlit_test", 0, mi)
    assert row["environment"] == "sunlit"
    m = out["mask"] > 0
    assert out["I_S.G"][m].mean() > 0 and out["A_S.G"][m].mean() > 0  # SVBRDFs, rendered
    assert {"I_D_noisy.R", "I_S_noisy.B"} <= set(out)  # a test set: the noise floor too
