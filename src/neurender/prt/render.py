"""Rendering PRT surfaces from a fixed camera (Embree primary rays, barycentric interpolation).

Exit radiance per grid vertex (linear RGB, albedo 1):

* diffuse: ``L = 1/pi sum_j l_j t_j`` (Sloan et al. 2002);
* glossy: convolution of the transferred radiance ``R`` with a normalised Phong lobe of
  exponent ``s`` evaluated at the reflected view direction ``r`` (Kautz et al. 2002):
  ``L = sum_k alpha_l g_l R_k y_k(r)`` with ``g_l`` the lobe's zonal coefficients and
  ``alpha_l = sqrt(4 pi / (2 l + 1))``.

Camera: pinhole, looking at the object's centre from ``direction`` (world, y up), image
rows top to bottom.
"""

from __future__ import annotations

import math

import numpy as np

from neurender import sh
from neurender.geometry import grid_faces, grid_normals
from neurender.raytrace import embree_scene


def phong_zonal(exponent: float, n_bands: int) -> np.ndarray:
    """Zonal coefficients ``g_l`` of the normalised lobe ``(s + 1) / (2 pi) max(cos, 0)^s``."""
    t = np.linspace(0.0, 1.0, 20001)  # cos(theta) over the upper hemisphere
    lobe = (exponent + 1) / (2 * math.pi) * t**exponent
    dirs = np.stack([np.sqrt(1 - t**2), np.zeros_like(t), t], -1)
    y = sh.eval_sh(dirs, n_bands)
    zonal = [y[:, sh.sh_index(b, 0)] for b in range(n_bands)]
    return np.array([2 * math.pi * np.trapezoid(lobe * z, t) for z in zonal])


def look_at_camera(
    positions: np.ndarray, resolution: int, direction=(0.35, 0.45, 1.0), fov_deg: float = 35.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Primary rays of a camera framing ``positions`` ``(..., 3)``.

    Returns:
        eye ``(3,)``, ray origins ``(R, 3)`` and unit directions ``(R, 3)`` float32 for an
        ``R = resolution^2`` image, row-major from the top-left pixel.
    """
    p = positions.reshape(-1, 3)
    centre = (p.min(0) + p.max(0)) / 2
    radius = np.linalg.norm(p - centre, axis=1).max()
    forward = -np.asarray(direction, np.float64) / np.linalg.norm(direction)
    eye = centre - forward * radius / math.sin(math.radians(fov_deg) / 2) * 1.05
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(fov_deg) / 2)
    s = (np.arange(resolution) + 0.5) / resolution * 2 - 1
    yy, xx = np.meshgrid(-s, s, indexing="ij")
    dirs = forward + half * (xx[..., None] * right + yy[..., None] * up)
    dirs = dirs.reshape(-1, 3) / np.linalg.norm(dirs.reshape(-1, 3), axis=1, keepdims=True)
    return eye, np.repeat(eye[None], len(dirs), 0).astype(np.float32), dirs.astype(np.float32)


class Raster:
    """Visible surface of one frame: which triangle and barycentrics each pixel sees."""

    def __init__(
        self, positions: np.ndarray, resolution: int, camera_positions: np.ndarray | None = None
    ):
        n = positions.shape[0]
        self.faces = grid_faces(n)
        self.resolution = resolution
        self.eye, origins, dirs = look_at_camera(
            positions if camera_positions is None else camera_positions, resolution
        )
        scene = embree_scene(positions.reshape(-1, 3), self.faces)
        hit = scene.run(origins, dirs, output=1)
        self.prim = hit["primID"]
        self.mask = self.prim >= 0
        u, v = hit["u"], hit["v"]
        self.bary = np.stack([1 - u - v, u, v], -1)[self.mask]
        self.corners = self.faces[self.prim[self.mask]]

    def shade(self, vertex_values: np.ndarray) -> np.ndarray:
        """Interpolate vertex values ``(n*n, C)`` to an image ``(C, res, res)``, 0 off-object."""
        c = vertex_values.shape[-1]
        img = np.zeros((self.resolution * self.resolution, c), np.float32)
        img[self.mask] = np.einsum("pk,pkc->pc", self.bary, vertex_values[self.corners])
        return np.moveaxis(img.reshape(self.resolution, self.resolution, c), -1, 0)

    def mask_image(self) -> np.ndarray:
        """``(1, res, res)`` float32 coverage."""
        return self.mask.reshape(1, self.resolution, self.resolution).astype(np.float32)


def diffuse_radiance(transfer: np.ndarray, light: np.ndarray) -> np.ndarray:
    """``(..., 3)`` radiance from diffuse transfer ``(..., K)`` and SH light ``(K, 3)``."""
    return transfer @ light / math.pi


def glossy_radiance(
    glossy: np.ndarray, positions: np.ndarray, eye: np.ndarray, exponent: float
) -> np.ndarray:
    """Exit radiance ``(n*n, 3)`` of transferred radiance ``(n, n, 3, K)`` toward ``eye``."""
    n_bands = math.isqrt(glossy.shape[-1])
    normals = grid_normals(positions).reshape(-1, 3)
    view = eye - positions.reshape(-1, 3)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    reflected = 2 * (normals * view).sum(1, keepdims=True) * normals - view
    g = phong_zonal(exponent, n_bands)
    conv = np.concatenate(
        [np.full(2 * b + 1, math.sqrt(4 * math.pi / (2 * b + 1)) * g[b]) for b in range(n_bands)]
    )
    y = sh.eval_sh(reflected, n_bands) * conv  # (N, K)
    return np.einsum("nck,nk->nc", glossy.reshape(-1, 3, glossy.shape[-1]), y)
