"""A report made small enough to share (:mod:`neurender.report.publish`)."""

import base64
import io
import json
import re

import numpy as np
import pytest
from PIL import Image

from neurender import viewer_data
from neurender.report.publish import main, palette_png, publish


def _png(pixels: np.ndarray) -> bytes:
    out = io.BytesIO()
    Image.fromarray(pixels).save(out, "PNG")
    return out.getvalue()


def _pixels(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))


def _photo(seed: int, size: int = 96) -> np.ndarray:
    """A smooth colour ramp with noise: far more than 256 colours, as a rendered frame."""
    rng = np.random.default_rng(seed)
    ramp = np.linspace(0, 200, size)[:, None, None] + np.linspace(0, 50, size)[None, :, None]
    noisy = ramp + rng.normal(0, 3, (size, size, 3))
    return np.clip(noisy, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("channels", [3, 4])
def test_an_image_of_few_colours_keeps_every_pixel(channels):
    rng = np.random.default_rng(channels)
    palette = rng.integers(0, 256, (200, channels), dtype=np.uint8)
    pixels = palette[rng.integers(0, 200, (40, 50))]
    out = palette_png(_png(pixels))
    want = pixels if channels == 4 else np.concatenate([pixels, np.full((40, 50, 1), 255)], -1)
    assert np.array_equal(_pixels(out), want)


def test_a_photo_is_reduced_to_the_colours_asked_for_and_is_smaller():
    data = _png(_photo(0))
    out = palette_png(data, colours=16)
    pixels = _pixels(out)
    assert pixels.shape[:2] == (96, 96)
    assert len(np.unique(pixels.reshape(-1, 4), axis=0)) <= 16
    assert len(out) < len(data)
    # a palette, not a new picture: every pixel near its original (the ramp spans 250 levels)
    assert np.abs(pixels[..., :3].astype(int) - _photo(0)).mean() < 12


def test_a_png_that_a_palette_would_not_shrink_is_kept_byte_for_byte():
    data = palette_png(_png(_photo(1)), colours=8)
    assert palette_png(data, colours=256) == data


def test_a_resampled_image_has_the_scaled_size():
    out = palette_png(_png(_photo(2)), scale=0.5)
    assert _pixels(out).shape[:2] == (48, 48)


@pytest.mark.parametrize("colours", [1, 257])
def test_a_colour_count_outside_a_png_palette_is_refused(colours):
    with pytest.raises(ValueError, match=f"colours = {colours}: expected 2 to 256"):
        palette_png(_png(_photo(3)), colours)


def _report() -> str:
    """A page as :mod:`neurender.report.build` writes one: a figure, a GIF, a viewer."""
    figure = base64.b64encode(_png(_photo(4, 128))).decode()
    gif = io.BytesIO()
    Image.fromarray(_photo(5, 8)).save(gif, "GIF")
    frames = viewer_data.frames_data(
        {"truth": [_photo(6 + k, 64) for k in range(3)]}, "turn", 2, steps=["0", "1", "2"]
    )
    data = json.dumps(frames, separators=(",", ":"))
    return (
        f"<html><body><table><tr><td>0.123</td></tr></table>"
        f'<figure><img src="data:image/png;base64,{figure}" alt="f"></figure>'
        f'<img src="data:image/gif;base64,{base64.b64encode(gif.getvalue()).decode()}">'
        f'<script type="application/json" id="viewer-0-data">{data}</script></body></html>'
    )


def _figures(page: str) -> list[np.ndarray]:
    found = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    return [_pixels(base64.b64decode(b)) for b in found]


def _viewer(page: str) -> dict:
    found = re.search(r'id="viewer-0-data">(.*?)</script>', page, re.S)
    return json.loads(found.group(1))


def test_a_published_page_keeps_its_tables_gifs_and_viewers_and_fits_its_budget():
    page = _report()
    published = publish(page, len(page))
    assert len(published.encode()) <= len(page)
    assert "<td>0.123</td>" in published
    gif = re.search(r'data:image/gif;base64,([^"]+)"', page).group(1)
    assert f"data:image/gif;base64,{gif}" in published  # GIFs untouched
    (figure,) = _figures(published)
    assert figure.shape[:2] == (128, 128)
    viewer, before = _viewer(published), _viewer(page)
    assert viewer["steps"] == before["steps"] and viewer["scale"] == before["scale"]
    frames = [viewer_data.decode_png(b) for b in viewer["frames"]["truth"]]
    assert [f.shape[:2] for f in frames] == [(64, 64)] * 3
    colours = [len(np.unique(f.reshape(-1, f.shape[-1]), axis=0)) for f in frames]
    assert max(colours) <= 256 < len(np.unique(_photo(6, 64).reshape(-1, 3), axis=0))


def test_figures_are_resampled_and_shown_at_their_width_only_when_the_palette_is_not_enough():
    page = _report()
    palette_only = publish(page, len(page))
    tighter = publish(page, len(palette_only.encode()) - 1)
    (figure,) = _figures(tighter)
    assert figure.shape[0] < 128
    assert '<img width="128" src=' in tighter
    viewer = _viewer(tighter)  # the viewers' frames keep their pixels' size
    assert viewer_data.decode_png(viewer["frames"]["truth"][0]).shape[:2] == (64, 64)
    assert len(tighter.encode()) < len(palette_only.encode())


def test_a_budget_no_scale_reaches_names_both_sizes():
    with pytest.raises(ValueError, match=r"the budget is 0\.0 MB: raise --max-mb"):
        publish(_report(), 100)


def test_the_command_writes_the_page_and_refuses_a_missing_report(tmp_path, capsys):
    source, out = tmp_path / "report.html", tmp_path / "shared.html"
    source.write_text(_report())
    main([str(source), str(out), "--max-mb", "1"])
    assert out.read_text() == publish(_report(), 10**6)
    assert [p.name for p in tmp_path.iterdir()] == sorted(["report.html", "shared.html"])
    with pytest.raises(SystemExit):
        main([str(tmp_path / "none.html"), str(out)])
    assert "none.html: no such report" in capsys.readouterr().err
