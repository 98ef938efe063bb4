"""User light probes: negative pixels clamped with a stated count and energy share; NaN,
infinities, wrong shapes and maps without positive radiance refused, naming the file;
warnings for maps that render black or hold all their energy in one texel."""

import logging
import math

import numpy as np
import pytest
import scipy.ndimage

from neurender import display, io, lights
from neurender.ndr import environments


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
    # The positive values: 1 everywhere but the four negative ones.
    negative = 3 * 0.5 * _texel_solid_angle(height, 3) + 2.0 * _texel_solid_angle(height, 10)
    positive = 3 * 4 * math.pi - 3 * _texel_solid_angle(height, 3) - _texel_solid_angle(height, 10)
    energy = lights.probe_energy(image)
    assert energy.negative_values == 4
    # Midpoint against exact solid angles.
    assert energy.negative_share == pytest.approx(negative / positive, rel=2e-3)
    (record,) = caplog.records
    assert str(path) in record.message and "clamped 4 negative values" in record.message
    assert f"{100 * energy.negative_share:.3g}% of the map's positive energy" in record.message


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
    energy = lights.probe_energy(coarse.astype(np.float32))
    assert energy.negative_values == int((coarse < 0).sum()) > 0
    assert 0 < energy.negative_share < 0.1
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


def _hemispheres(upper, lower, height=8):
    """A map ``(height, 2 height, 3)``: RGB ``upper`` above the horizon, ``lower`` below.
    The two halves' (midpoint) solid angles are equal, so energy shares are exact ratios."""
    image = np.empty((height, 2 * height, 3), np.float32)
    image[: height // 2], image[height // 2 :] = upper, lower
    return image


@pytest.mark.parametrize(
    ("upper", "lower", "share"),
    [
        ([1, 1, 1], [-0.3, 0, 0], 0.3 / 3),
        ([1, 1, 1], [-0.3, 0.5, 0], 0.3 / 3.5),
        ([2, 0, 1], [0, -0.75, -0.15], 0.9 / 3),
    ],
)
def test_the_warning_states_the_negatives_share_of_the_positive_energy(
    tmp_path, caplog, upper, lower, share
):
    path = _write(tmp_path / "ringing.exr", _hemispheres(upper, lower))
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        loaded = lights.load_probe(path, "prt.user_probes.mine")
    assert loaded.min() == 0
    assert lights.probe_energy(_hemispheres(upper, lower)).negative_share == pytest.approx(share)
    (record,) = caplog.records
    negatives = 64 * sum(v < 0 for v in lower)
    assert f"{path} (prt.user_probes.mine): clamped {negatives} negative values" in record.message
    assert f"their energy was {100 * share:.3g}% of the map's positive energy" in record.message


@pytest.mark.parametrize(
    ("image", "found"),
    [
        (np.zeros((8, 16, 3), np.float32), "all 384 values are 0"),
        (np.full((8, 16, 3), -0.5, np.float32), "384 of 384 values are negative"),
        (_hemispheres([-1, -1, -1], [0, 0, 0]), "192 of 384 values are negative and the rest 0"),
    ],
)
def test_a_map_without_positive_radiance_is_refused_naming_the_file(tmp_path, image, found):
    path = _write(tmp_path / "black.exr", image)
    with pytest.raises(ValueError) as caught:
        lights.load_probe(path, "prt.user_probes.night")
    message = str(caught.value)
    assert f"light probe {path} (prt.user_probes.night) has no positive radiance" in message
    assert found in message and "expected a map with positive radiance" in message


def test_a_map_with_more_negative_than_positive_energy_is_refused(tmp_path):
    """Signed data (a difference or log image) is no ringing: clamping it leaves a map
    that has nothing to do with the file."""
    path = _write(tmp_path / "signed.exr", _hemispheres([1, 1, 1], [-2, -1, -0.5]))
    with pytest.raises(ValueError) as caught:
        lights.load_probe(path)
    message = str(caught.value)
    assert f"light probe {path}: its 192 negative values (of 384) hold 117% of" in message
    assert "expected a map with positive radiance" in message


def test_a_map_too_dim_to_show_warns(tmp_path, caplog):
    dim = np.full((8, 16, 3), 0.5 * lights.DISPLAY_BLACK, np.float32)
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        lights.load_probe(_write(tmp_path / "dim.exr", dim))
        lights.load_probe(_write(tmp_path / "night.exr", 4 * dim))
    (record,) = caplog.records
    assert "dim.exr: its brightest value is" in record.message
    assert "every render under it is black" in record.message
    # The threshold is what Reinhard and gamma 2.2 show as 0 of 255: half an 8-bit step.
    assert display.tonemap(np.float64(lights.DISPLAY_BLACK)) * 255 == pytest.approx(0.5)


def test_a_point_light_in_the_dark_warns_and_real_suns_do_not(tmp_path, caplog):
    point = np.zeros((16, 32, 3), np.float32)
    point[3, 7] = 100.0
    point[8:, :] = 1e-6  # a ground that holds 0.01 % of the energy
    with caplog.at_level(logging.WARNING, logger="neurender.lights"):
        loaded = lights.load_probe(_write(tmp_path / "point.exr", point))
    np.testing.assert_array_equal(loaded, point)  # loaded as it is
    (record,) = caplog.records
    assert "point.exr: one texel (row 3, column 7) holds" in record.message
    caplog.clear()
    # Real-world-like maps put up to about 90 % of the coarse map's power in one texel.
    for seed in range(8):
        sunlit = environments.sunlit_environment(np.random.default_rng(seed), 16)
        assert lights.probe_energy(sunlit).peak_share < lights.SINGLE_TEXEL_SHARE
        with caplog.at_level(logging.WARNING, logger="neurender.lights"):
            lights.load_probe(_write(tmp_path / f"sunlit{seed}.exr", sunlit))
    for name in lights.BUILTIN_PROBES:
        with caplog.at_level(logging.WARNING, logger="neurender.lights"):
            lights.load_probe(_write(tmp_path / f"{name}.exr", lights.procedural_probe(name, 16)))
    assert not caplog.records


def _layers(path, layers, value=None):
    """An EXR whose layer ``name`` holds ``channels``, each filled with its own radiance
    (``value[name]``, else 1): ``{"sky": "RGB", "": "RGB"}`` writes sky.R ... and R ..."""
    value = value or {}
    io.write_exr(
        path,
        {
            f"{name}.{c}" if name else c: np.full((8, 16), value.get(name, 1.0), np.float32)
            for name, channels in layers.items()
            for c in channels
        },
    )
    return path


@pytest.mark.parametrize(
    ("layers", "used"),
    [
        ({"sky": "RGB"}, "sky"),  # one prefixed layer
        ({"ViewLayer.Env": "RGB"}, "ViewLayer.Env"),  # Blender's nested layer names
        ({"matte": "R", "sky": "RGB"}, "sky"),  # a mask pass beside the only RGB layer
        ({"albedo": "RGB", "": "RGBA"}, ""),  # the unprefixed main image wins
    ],
)
def test_a_multi_layer_map_is_read_from_one_layer(tmp_path, layers, used):
    value = {name: 0.25 + i for i, name in enumerate(layers)}  # exact in float32
    path = _layers(tmp_path / "layers.exr", layers, value)
    np.testing.assert_array_equal(lights.load_probe(path), value[used])


def test_several_rgb_layers_are_refused_naming_file_key_and_layers(tmp_path):
    path = _layers(tmp_path / "layers.exr", {"albedo": "RGB", "sky": "RGB"}, {"sky": 5.0})
    with pytest.raises(ValueError) as err:
        lights.load_probe(path, "prt.user_probes.studio")
    message = str(err.value)
    assert f"{path} (prt.user_probes.studio)" in message
    assert "2 layers with R, G and B channels: 'albedo', 'sky'" in message
    assert "expected one RGB layer, or unprefixed R, G, B" in message


def test_layers_are_never_mixed_and_each_incomplete_one_is_named(tmp_path):
    path = _layers(tmp_path / "split.exr", {"sky": "RG", "matte": "B"})
    with pytest.raises(ValueError) as err:
        lights.load_probe(path, "ndr.user_probes_dir")
    message = str(err.value)
    assert f"{path} (ndr.user_probes_dir) needs R, G and B channels of one layer" in message
    assert "layer 'matte' lacks R, G" in message and "layer 'sky' lacks B" in message
