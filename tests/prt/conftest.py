import numpy as np
import pytest


@pytest.fixture
def bowl_positions():
    """Factory: ``(F, n, n, 3)`` geometry images of a shallow bowl (it shadows itself),
    frame ``f`` of depth ``1 + 0.5 f`` times the first's."""

    def make(n: int = 6, frames: int = 2) -> np.ndarray:
        u = np.linspace(-1, 1, n)
        x, y = np.meshgrid(u, u, indexing="ij")
        bowl = np.stack([x, y, 0.6 * (x**2 + y**2)], -1)
        return np.stack([bowl * [1, 1, 1 + 0.5 * f] for f in range(frames)]).astype(np.float32)

    return make
