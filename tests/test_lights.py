"""User light probes: negative pixels clamped with a stated count and energy; NaN,
infinities and wrong shapes refused, naming the file."""

import logging
import math

import numpy as np
import pytest
import scipy.ndimage

from neurender import io, lights


def _write(path, image):
    io.write_exr(path, {c: image[..., i] for i, c in enumerate("RGB")})
    return path


def _texel_solid_angle(height: int, row: int) -> float:
    """Exact solid angle of one texel of row ``row`` in a ``(height, 2 height)`` map."""
    t0, t1 = math.pi * row / height, math.pi * (row + 1) / height
    return (math.cos(t0) - math.cos(t1)) * math.pi / height


def test_negative_pixels_are_clamped_with_their_count_and_energy(tmp_path, caplog):
    height = 16
    image = np.ones((height, 2 * height, 3), np.float32)
    image[3, 5] = -0.5  # three negative values in row 3
    image[10, 20, 1] = -2.0  # one in row 10
    path = _write(tmp_path / "ringing.exr", image)
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        loaded = lights.load_probe(path)
    assert loaded.min() == 0
    assert (loaded[image >= 0] == image[image >= 0]).all()
    # The clamped map: 1 everywhere but the four values set to 0.
    added = 3 * 0.5 * _texel_solid_angle(height, 3) + 2.0 * _texel_solid_angle(height, 10)
    total = 3 * 4 * math.pi - 3 * _texel_solid_angle(height, 3) - _texel_solid_angle(height, 10)
    _, count, fraction = lights.clamp_negative(image)
    assert count == 4
    assert fraction == pytest.approx(added / total, rel=2e-3)  # midpoint vs exact solid angle
    (record,) = caplog.records
    assert str(path) in record.message and "clamped 4 negative values" in record.message
    assert f"{100 * fraction:.3g}%" in record.message


def test_a_map_resampled_with_a_cubic_filter_loads(tmp_path, caplog):
    """A sun resampled with scipy's cubic spline rings negative around it, as downloaded
    maps do; the map loads, the clamp adds little energy."""
    fine = np.full((64, 128, 3), 0.5)
    fine[20:22, 40:42] = 5e4
    coarse = np.stack(
        [scipy.ndimage.zoom(fine[..., c], 0.25, order=3, mode="grid-wrap") for c in range(3)], -1
    )
    assert coarse.min() < 0
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        loaded = lights.load_probe(_write(tmp_path / "sun.exr", coarse.astype(np.float32)))
    assert loaded.shape == (16, 32, 3) and loaded.min() >= 0
    _, count, fraction = lights.clamp_negative(coarse.astype(np.float32))
    assert count == int((coarse < 0).sum()) > 0
    assert 0 < fraction < 0.1
    assert "negative values" in caplog.text


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_radiance_is_refused_naming_the_file(tmp_path, bad):
    image = np.ones((8, 16, 3), np.float32)
    image[2, 3, 0] = bad
    path = _write(tmp_path / "broken.exr", image)
    with pytest.raises(ValueError, match=r"broken\.exr has 1 NaN or infinite values.*\(2, 3\)"):
        lights.load_probe(path)


def test_wrong_shapes_and_channels_are_refused_naming_the_file(tmp_path):
    path = _write(tmp_path / "square.exr", np.ones((8, 8, 3), np.float32))
    with pytest.raises(ValueError, match=r"square\.exr is 8x8; a lat-long map is 2:1"):
        lights.load_probe(path)
    grey = tmp_path / "grey.exr"
    io.write_exr(grey, {"Y": np.ones((8, 16), np.float32)})
    with pytest.raises(ValueError, match=r"grey\.exr needs R, G and B channels"):
        lights.load_probe(grey)


def test_a_clean_map_loads_unchanged_and_silently(tmp_path, caplog):
    image = np.random.default_rng(0).uniform(0, 3, (8, 16, 3)).astype(np.float32)
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        loaded = lights.load_probe(_write(tmp_path / "clean.exr", image))
    np.testing.assert_array_equal(loaded, image)
    assert not caplog.records
