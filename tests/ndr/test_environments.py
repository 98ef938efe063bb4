"""Maps of real-world dynamic range: the small sun, the real-world-like maps, and user maps
checked before any sample is rendered."""

import math

import numpy as np
import pytest

from neurender import io, sh
from neurender.ndr import data, environments


def _power(image: np.ndarray) -> np.ndarray:
    _, solid = sh.latlong_directions(*image.shape[:2])
    return (image * solid[..., None]).sum((0, 1))


@pytest.mark.parametrize("height", [16, 32, 128])
def test_the_small_sun_adds_its_power_in_one_texel(height):
    sky = np.full((height, 2 * height, 3), 0.5, np.float32)
    direction = np.array([0.3, 0.8, -0.52])
    direction /= np.linalg.norm(direction)
    radiance = np.array([1e5, 9e4, 8e4])
    out = environments.add_small_sun(sky, direction, radiance)
    changed = np.argwhere((out != sky).any(-1))
    assert len(changed) == 1
    # The texel holds the sun's direction (the lat-long convention of neurender.sh).
    dirs, _ = sh.latlong_directions(height, 2 * height)
    row, col = changed[0]
    assert dirs[row, col] @ direction > math.cos(math.pi / height * 1.5)
    radius = math.radians(environments.SMALL_SUN_DIAMETER_DEG / 2)
    expected = radiance * 2 * math.pi * (1 - math.cos(radius))
    # Exact solid angle in the deposit; the check's midpoint rule differs by < 1e-3 (rows
    # away from the poles).
    np.testing.assert_allclose(_power(out) - _power(sky), expected, rtol=2e-3)


def test_real_world_like_maps_put_most_power_in_one_coarse_texel():
    shares = [
        environments.sun_share(environments.sunlit_environment(np.random.default_rng(i), 64))
        for i in range(40)
    ]
    assert min(shares) > 0.2 and np.median(shares) > 0.5
    # The broad emitters of the other procedural maps stay below that.
    broad = [
        environments.sun_share(environments.random_environment(np.random.default_rng(i), 64))
        for i in range(40)
    ]
    assert np.median(broad) < 0.2


def test_a_share_of_procedural_maps_has_the_small_sun():
    names = [
        environments.procedural_environment(np.random.default_rng(i), 16, 0.3)[1]
        for i in range(200)
    ]
    assert set(names) == {"procedural", "procedural sun"}
    assert names.count("procedural sun") / len(names) == pytest.approx(0.3, abs=0.08)
    # Without the fraction, the maps are drawn exactly as before it existed.
    for i in range(5):
        np.testing.assert_array_equal(
            environments.random_environment(np.random.default_rng(i), 16),
            environments.procedural_environment(np.random.default_rng(i), 16, 0.0)[0],
        )


def _nan_texel(image):
    image[4, 4] = np.nan
    return image


@pytest.mark.parametrize(
    ("spoil", "problem"),
    [
        (_nan_texel, "has 3 NaN or infinite values"),
        (lambda image: -image, "has no positive radiance"),
        (np.zeros_like, "has no positive radiance"),
    ],
    ids=["nan", "negative", "zeros"],
)
def test_every_user_map_is_checked_before_any_sample_is_rendered(tmp_path, spoil, problem):
    maps = tmp_path / "maps"
    maps.mkdir()
    good = np.ones((16, 32, 3), np.float32)
    bad = spoil(good.copy())
    for name, image in (("a_good", good), ("b_broken", bad), ("c_good", good)):
        io.write_exr(maps / f"{name}.exr", {c: image[..., i] for i, c in enumerate("RGB")})
    cfg = {
        "seed": 0,
        "device": "cpu",
        "user_probes_dir": str(maps),
        "environment_height": 16,
    }
    out = tmp_path / "train"
    with pytest.raises(ValueError, match=r"b_broken\.exr \(ndr\.user_probes_dir\) " + problem):
        data.generate_split(cfg, "train", 4, out, tmp_path / "m.csv", tmp_path / "l.csv", 1)
    assert not out.exists()  # stopped before the first sample


def test_a_map_in_another_format_stops_the_job_naming_it(tmp_path):
    """A folder the workflow makes (under results/) is checked when the job runs: a map in
    another format is refused there too, not left out."""
    maps = tmp_path / "maps"
    maps.mkdir()
    io.write_exr(maps / "studio.exr", {c: np.ones((4, 8), np.float32) for c in "RGB"})
    (maps / "sunset.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n")
    with pytest.raises(ValueError, match=r"ndr\.user_probes_dir = .*\(sunset\.hdr\)"):
        environments.user_probes(maps)
    (maps / "sunset.hdr").unlink()
    assert environments.user_probes(maps) == [maps / "studio.exr"]
