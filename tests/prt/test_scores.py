"""Rendered-appearance scores: the relative L1 of radiance against analytic values."""

import numpy as np
import pytest

from neurender.prt.scores import relative_l1


def test_relative_l1_of_a_uniform_scaling_is_the_scale_error():
    gt = np.random.default_rng(0).uniform(0.1, 2.0, (3, 5, 7))
    assert relative_l1(1.2 * gt, gt) == pytest.approx(0.2)
    assert relative_l1(gt, gt) == 0.0


def test_relative_l1_counts_only_the_pixels_inside_the_mask():
    gt = np.ones((3, 2, 2))
    pred = gt.copy()
    pred[:, 0, 0] = 3.0  # |error| 2 on one pixel of three channels
    pred[:, 1, 1] = 100.0  # outside the mask: ignored
    mask = np.array([[[1.0, 1.0], [1.0, 0.0]]])
    # inside: 3 pixels x 3 channels of |gt| = 1, error 2 on 3 entries: 6 / 9
    assert relative_l1(pred, gt, mask) == pytest.approx(6 / 9)


def test_relative_l1_of_a_zero_reference_is_refused():
    with pytest.raises(ValueError, match="zero everywhere inside the mask"):
        relative_l1(np.ones((3, 2, 2)), np.zeros((3, 2, 2)))
