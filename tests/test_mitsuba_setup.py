import numpy as np
import pytest

from neurender import mitsuba_setup, sh


def _envmap_radiance(mitsuba, bitmap: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Mitsuba's envmap radiance ``(N, 3)`` towards unit directions ``dirs`` ``(N, 3)``."""
    mi, dr = mitsuba
    emitter = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(bitmap)})
    si = dr.zeros(mi.SurfaceInteraction3f, len(dirs))
    si.wi = mi.Vector3f(*(-dirs.T))  # eval looks along -wi
    return np.array(emitter.eval(si)).T


def _index_map(height: int, width: int) -> np.ndarray:
    """R = row index, G = column index, B = 1."""
    image = np.ones((height, width, 3), np.float32)
    image[..., 0] = np.arange(height)[:, None]
    image[..., 1] = np.arange(width)[None, :]
    return image


def test_mitsuba_puts_raw_rows_off_our_texel_centres(mitsuba):
    """Why envmap_rows exists: a map handed over as it is has its rows shifted."""
    image = _index_map(8, 16)
    dirs, _ = sh.latlong_directions(8, 16)
    got = _envmap_radiance(mitsuba, image, dirs.reshape(-1, 3)).reshape(8, 16, 3)
    assert np.abs(got[..., 0] - image[..., 0]).max() > 0.4
    np.testing.assert_allclose(got[..., 1], image[..., 1], atol=1e-4)  # columns agree


def test_envmap_rows_gives_every_texel_its_value_at_its_centre(mitsuba):
    image = _index_map(8, 16)
    dirs, _ = sh.latlong_directions(8, 16)
    got = _envmap_radiance(mitsuba, mitsuba_setup.envmap_rows(image), dirs.reshape(-1, 3))
    np.testing.assert_allclose(got.reshape(8, 16, 3), image, atol=1e-4)


def test_envmap_rows_keeps_a_one_texel_sun_where_it_is(mitsuba):
    """A sun in one texel: the centre of Mitsuba's radiance (power-weighted mean direction
    over a fine grid) is the texel's centre, and its power the texel's (the map as it is
    puts the centre 2.3 degrees off, a fifth of a texel)."""
    height, width, row, col = 16, 32, 4, 9
    image = np.full((height, width, 3), 0.1, np.float32)
    image[row, col] = 1000.0
    fine, weights = sh.latlong_directions(8 * height, 8 * width)
    got = _envmap_radiance(mitsuba, mitsuba_setup.envmap_rows(image), fine.reshape(-1, 3))
    excess = (got[:, 0].reshape(weights.shape) - 0.1) * weights
    centroid = (excess[..., None] * fine).sum(axis=(0, 1))
    centroid /= np.linalg.norm(centroid)
    dirs, solid_angle = sh.latlong_directions(height, width)
    assert np.degrees(np.arccos(centroid @ dirs[row, col])) < 0.3
    assert excess.sum() == pytest.approx((1000.0 - 0.1) * solid_angle[row, col], rel=0.01)


def test_envmap_rows_refuses_too_few_subrows():
    with pytest.raises(ValueError, match="subrows"):
        mitsuba_setup.envmap_rows(np.ones((4, 8, 3)), subrows=1)


def test_auto_picks_the_cuda_variant_only_with_a_driver():
    assert mitsuba_setup.variant_for("auto", has_cuda=True) == "cuda_ad_rgb"
    assert mitsuba_setup.variant_for("auto", has_cuda=False) == "llvm_ad_rgb"
    with pytest.raises(RuntimeError, match="no CUDA driver"):
        mitsuba_setup.variant_for("cuda", has_cuda=False)


@pytest.mark.skipif(not mitsuba_setup.cuda_available(), reason="needs a CUDA driver Dr.Jit can use")
def test_cuda_and_llvm_variants_render_the_same_envmap():
    """The GPU variant sees a map where the CPU one does (same radiance at texel centres)."""
    image = np.random.default_rng(0).uniform(0.1, 2.0, (8, 16, 3)).astype(np.float32)
    dirs, _ = sh.latlong_directions(8, 16)
    values = []
    for device in ("cpu", "cuda"):
        values.append(
            _envmap_radiance(
                mitsuba_setup.import_mitsuba(device),
                mitsuba_setup.envmap_rows(image),
                dirs.reshape(-1, 3),
            )
        )
    np.testing.assert_allclose(values[0], values[1], rtol=1e-5)
