import math

import numpy as np

from neurender.camera import Camera, pixel_rays


def test_pixel_rays_centre_and_orientation():
    view = Camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), 60.0)
    d = pixel_rays(view, 4)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1)
    # Looking down -z from +z with y up: image left is world -x, image top is +y.
    assert d[0, 0, 0] < 0 and d[0, 0, 1] > 0 and d[-1, -1, 0] > 0 and d[-1, -1, 1] < 0
    half = math.tan(math.radians(30)) * (1 - 1 / 4)
    assert np.isclose(d[0, 0, 0] / -d[0, 0, 2], -half)
