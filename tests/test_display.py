import numpy as np
import pytest
import torch

from neurender import display


def test_srgb_matches_the_standard_curve():
    assert np.isclose(display.srgb(np.array(1.0)), 1.0)
    assert np.isclose(display.srgb(np.array(0.001)), 0.01292)  # the linear toe
    # 0.5 linear is 0.7354 in sRGB (IEC 61966-2-1).
    assert np.isclose(display.srgb(np.array(0.5)), 0.7354, atol=1e-4)
    assert np.allclose(display.srgb(np.array([-1.0, 2.0])), [0.0, 1.0])  # clipped


@pytest.mark.parametrize("lib", [np.asarray, torch.as_tensor])
def test_tonemap_is_monotone_and_bounded_for_numpy_and_torch(lib):
    x = lib(np.array([0.0, 0.1, 1.0, 10.0, 1e6]))
    y = np.asarray(display.tonemap(x))
    assert y[0] == 0 and (np.diff(y) > 0).all() and y[-1] < 1
    assert np.isclose(y[2], 0.5 ** (1 / 2.2))  # Reinhard maps 1 to 1/2


def test_linear_from_srgb_inverts_srgb_on_both_sides_of_the_toe():
    linear = np.array([0.0, 0.001, 0.0031308, 0.01, 0.2, 0.5, 1.0])
    np.testing.assert_allclose(display.linear_from_srgb(display.srgb(linear)), linear, atol=1e-12)
    assert np.isclose(display.linear_from_srgb(np.array(0.5)), 0.21404114)  # published value
