import math

import pytest
import torch

from neurender.metaball import Kernel

KERNELS = [Kernel(), Kernel("wyvill", 2.0), Kernel("wyvill", 1.5), Kernel("gaussian", 2.5, 1.0)]


@pytest.mark.parametrize("kernel", KERNELS, ids=lambda k: f"{k.name}-{k.support}")
def test_kernel_inverse_round_trips(kernel):
    top = float(kernel.value(torch.tensor(0.0, dtype=torch.float64)))  # k(0); inf: 1 / x
    reach = kernel.support**2
    x = torch.linspace(0.01, min(reach, 30.0) * 0.999, 200, dtype=torch.float64)
    torch.testing.assert_close(kernel.inverse(kernel.value(x)), x, rtol=1e-9, atol=1e-9)
    y = torch.linspace(1e-3, min(top, 50.0), 200, dtype=torch.float64)
    torch.testing.assert_close(kernel.value(kernel.inverse(y)), y, rtol=1e-9, atol=1e-12)
    one = torch.tensor(1.0, dtype=torch.float64)
    torch.testing.assert_close(kernel.inverse(one), one)  # k(1) = 1


@pytest.mark.parametrize("kernel", KERNELS[1:], ids=lambda k: f"{k.name}-{k.support}")
def test_kernel_inverse_clamps_into_the_kernels_range(kernel):
    top = float(kernel.value(torch.tensor(0.0, dtype=torch.float64)))
    y = torch.tensor([-1.0, 0.0, top, 2 * top], dtype=torch.float64)
    expected = torch.tensor([kernel.support**2] * 2 + [0.0] * 2, dtype=torch.float64)
    torch.testing.assert_close(kernel.inverse(y), expected, atol=1e-12, rtol=0)


def test_inverse_square_inverse_is_the_reciprocal():
    y = torch.tensor([0.0, 0.25, 1.0, 4.0], dtype=torch.float64)
    assert Kernel().inverse(y).tolist() == [math.inf, 4.0, 1.0, 0.25]
