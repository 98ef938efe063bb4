"""Display encodings for figures: linear radiance to values in [0, 1] for an 8-bit screen.

Each works on numpy arrays and torch tensors alike. Radiance is linear RGB; HDR values are
compressed by Reinhard's ``x / (1 + x)`` before a gamma or sRGB curve.
"""

from __future__ import annotations

import numpy as np


def reinhard(x):
    """HDR ``x >= 0`` to [0, 1): ``x / (1 + x)``."""
    return x / (1 + x)


def gamma(x, exponent: float = 2.2):
    """``clip(x, 0, 1) ** (1 / exponent)``."""
    return x.clip(0, 1) ** (1 / exponent)


def tonemap(x):
    """HDR radiance to display: Reinhard, then gamma 2.2."""
    return gamma(reinhard(x.clip(0, None)))


def srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function of ``clip(x, 0, 1)``."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def linear_from_srgb(x: np.ndarray) -> np.ndarray:
    """The inverse of :func:`srgb`: encoded values in [0, 1] to linear."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
