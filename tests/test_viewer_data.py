"""Viewer files: arrays and images survive the base64 round trip, the overlay marks
exactly the pixels where two masks differ, and frame viewers refuse uneven panels."""

import numpy as np
import pytest

from neurender import viewer_data


@pytest.mark.parametrize("dtype", ["f4", "u4", "u2", "u1"])
def test_arrays_round_trip_bit_for_bit(dtype):
    rng = np.random.default_rng(0)
    array = (rng.random((7, 5)) * 200).astype(dtype)
    back = viewer_data.decode_array(viewer_data.b64_array(array, dtype), dtype, (7, 5))
    np.testing.assert_array_equal(back, array)


def test_pngs_round_trip_and_files_are_read_back(tmp_path):
    image = np.random.default_rng(1).integers(0, 256, (6, 9, 3), dtype=np.uint8)
    np.testing.assert_array_equal(viewer_data.decode_png(viewer_data.b64_png(image)), image)
    data = {"frames": {"a": [viewer_data.b64_png(image)]}, "label": "t", "scale": 2}
    viewer_data.write(tmp_path / "v.json", "frames", "title", data)
    assert viewer_data.read(tmp_path / "v.json") == {
        "kind": "frames",
        "title": "title",
        "data": data,
    }
    with pytest.raises(ValueError, match="viewer kind 'video'"):
        viewer_data.write(tmp_path / "w.json", "video", "title", data)


def test_mask_difference_marks_extra_and_missing_pixels_only():
    mask = np.array([[1, 1, 0, 0]], bool)
    reference = np.array([[1, 0, 1, 0]], bool)
    out = viewer_data.mask_difference(mask, reference)
    assert out.shape == (1, 4, 4) and out.dtype == np.uint8
    np.testing.assert_array_equal(out[0, :, 3], [0, 255, 255, 0])
    assert tuple(out[0, 1, :3]) == viewer_data.EXTRA_COLOUR
    assert tuple(out[0, 2, :3]) == viewer_data.MISSING_COLOUR


def test_frames_data_keeps_panel_order_and_counts():
    images = [np.full((4, 4, 3), v, np.uint8) for v in (10, 20, 30)]
    data = viewer_data.frames_data(
        {"b": images, "a": images[::-1]}, "turn", 3, steps=["0 deg", "120 deg", "240 deg"]
    )
    assert list(data["frames"]) == ["b", "a"] and data["steps"][1] == "120 deg"
    decoded = [viewer_data.decode_png(x)[0, 0, 0] for x in data["frames"]["a"]]
    assert decoded == [30, 20, 10] and data["scale"] == 3 and "overlay" not in data
    with pytest.raises(ValueError, match="same number of images"):
        viewer_data.frames_data({"a": images, "b": images[:2]}, "turn", 1)
    with pytest.raises(ValueError, match="overlays"):
        viewer_data.frames_data({"a": images}, "turn", 1, overlay={"c": images})
    with pytest.raises(ValueError, match="step labels"):
        viewer_data.frames_data({"a": images}, "turn", 1, steps=["x"])


@pytest.mark.parametrize(("width", "scale"), [(16, 16), (32, 8), (64, 4), (128, 2), (512, 1)])
def test_display_scale_shows_images_at_about_256_pixels(width, scale):
    assert viewer_data.display_scale(width) == scale
