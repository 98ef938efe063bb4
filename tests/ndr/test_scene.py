import math

import numpy as np
import pytest

from neurender import sh
from neurender.ndr import environments, objects


def test_random_object_is_deterministic_normalised_and_in_range():
    a = objects.random_object(np.random.default_rng(5), (2, 4), 0.3)
    b = objects.random_object(np.random.default_rng(5), (2, 4), 0.3)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.albedo_diffuse, b.albedo_diffuse)
    assert 2 <= a.n_primitives <= 4
    assert np.linalg.norm(a.vertices, axis=1).max() == pytest.approx(1.0, abs=1e-6)
    assert a.faces.max() < len(a.vertices)
    for values in (a.albedo_diffuse, a.albedo_specular):
        assert values.shape == a.vertices.shape and values.min() >= 0 and values.max() <= 1
    assert a.roughness.min() >= 0.05 and a.roughness.max() <= 1


def test_diffuse_only_objects_have_no_specular_albedo():
    obj = objects.random_object(np.random.default_rng(1), (1, 2), 0.3, diffuse_only=True)
    assert not obj.albedo_specular.any()


@pytest.mark.parametrize("kind", objects.PRIMITIVES)
def test_primitives_are_watertight_and_finely_tessellated(kind):
    mesh = objects.primitive_mesh(kind, 0.3)
    assert mesh.is_watertight
    assert mesh.edges_unique_length.max() <= 0.3 + 1e-9


def test_unknown_primitive_and_bad_range_are_refused():
    with pytest.raises(ValueError, match="unknown primitive 'torus'"):
        objects.primitive_mesh("torus", 0.3)
    with pytest.raises(ValueError, match="primitives=\\(3, 2\\)"):
        objects.random_object(np.random.default_rng(0), (3, 2), 0.3)


def test_resize_keeps_the_irradiance_integral():
    env = environments.random_environment(np.random.default_rng(2), 64)
    small = environments.resize_latlong(env, 16)
    _, big_sa = sh.latlong_directions(64, 128)
    _, small_sa = sh.latlong_directions(16, 32)
    np.testing.assert_allclose(
        (small * small_sa[..., None]).sum((0, 1)), (env * big_sa[..., None]).sum((0, 1)), rtol=5e-3
    )


def test_random_maps_have_high_dynamic_range():
    env = environments.random_environment(np.random.default_rng(3), 64)
    assert env.min() >= 0
    assert env.max() > 50 * np.median(env)


def test_rotation_about_up_keeps_the_rotation_invariant_sh():
    """Rotating about +y leaves the DC term and the y-aligned dipole y_1^-1 unchanged."""
    env = environments.random_environment(np.random.default_rng(4), 32)
    a = sh.project_latlong(env, 2)
    b = sh.project_latlong(environments.rotate_about_up(env, 17), 2)
    np.testing.assert_allclose(b[[0, 1]], a[[0, 1]], rtol=1e-6, atol=1e-9)
    assert not np.allclose(b[3], a[3], rtol=1e-3)  # x-dipole moves


def test_sh_features_of_a_constant_map():
    feats = environments.sh_features(np.full((32, 64, 3), 2.0, np.float32))
    assert feats.shape == (environments.SH_FEATURES,)
    # c_0 = integral 2 y_0 dw = 2 * sqrt(4 pi); everything else vanishes.
    np.testing.assert_allclose(feats[:3], 2 * math.sqrt(4 * math.pi), rtol=1e-3)  # quadrature
    np.testing.assert_allclose(feats[3:], 0, atol=0.01)


def test_user_probe_folder_errors_name_the_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="holds no"):
        environments.user_probes(tmp_path)
    with pytest.raises(FileNotFoundError, match="is not a folder"):
        environments.user_probes(tmp_path / "missing")
