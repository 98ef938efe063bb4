"""Framing balls from any world space (a molecule in angstroms, a fluid in metres) in the
view space of :mod:`neurender.metaballs.scenes`.

A similarity transform (a rotation, one uniform scale, a translation) takes world-space
balls to view space so that their bounding sphere sits on the view axis at depth
``(MIN_DEPTH + MAX_DEPTH) / 2``, its nearest point deeper than ``MIN_DEPTH +``
:data:`NEAR_MARGIN` and its silhouette inside the image with :data:`IMAGE_MARGIN` to
spare. The bounding sphere is that of the balls (centre plus radius), computed in world
space before the rotation, so every view of one set of balls gets the same scale: depth
errors in view units convert to world units by the same factor, :attr:`Framing.world_per_view`.

With the inverse-square kernel the metaball surface of many overlapping balls swells
beyond the balls themselves (:mod:`neurender.metaball`); the framing bounds the balls only.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch

from neurender.metaball import Scene
from neurender.metaballs.scenes import FOV_DEG, MAX_DEPTH, MIN_DEPTH

#: View units between the bounding sphere's nearest point and the ``MIN_DEPTH`` plane.
NEAR_MARGIN = 1.0
#: Share of the image's half-width left free around the bounding sphere's silhouette.
IMAGE_MARGIN = 0.05
#: Depth of the bounding sphere's centre (view units).
CENTRE_DEPTH = (MIN_DEPTH + MAX_DEPTH) / 2


@dataclasses.dataclass(frozen=True, eq=False)
class Framing:
    """A world-to-view similarity: ``view = rotation @ (world - centre) / world_per_view +
    (0, 0, CENTRE_DEPTH)``; radii divide by ``world_per_view``.

    Attributes:
        centre: ``(3,)`` float64 world position of the bounding sphere's centre.
        rotation: ``(3, 3)`` float64 proper rotation (world axes to view axes).
        world_per_view: world units per view unit (e.g. angstroms per view unit).
        ball_scale: the factor the world radii were multiplied by before framing.
    """

    centre: np.ndarray
    rotation: np.ndarray
    world_per_view: float
    ball_scale: float = 1.0

    def points(self, positions: np.ndarray) -> np.ndarray:
        """View-space positions ``(N, 3)`` float64 of world positions ``(N, 3)``."""
        local = (np.asarray(positions, np.float64) - self.centre) @ self.rotation.T
        return local / self.world_per_view + np.array([0.0, 0.0, CENTRE_DEPTH])

    def scene(self, positions: np.ndarray, radii: np.ndarray, colours: np.ndarray) -> Scene:
        """The framed :class:`~neurender.metaball.Scene` (float64 tensors) of world balls:
        positions ``(N, 3)`` and radii ``(N,)`` in world units (radii before
        :attr:`ball_scale`), colours ``(N, 3)`` linear RGB in [0, 1]."""
        positions, radii, colours = _checked(positions, radii, colours)
        view_radii = radii * self.ball_scale / self.world_per_view
        return Scene(
            torch.from_numpy(self.points(positions)),
            torch.from_numpy(view_radii),
            torch.from_numpy(colours.copy()),
        )


def view_radius() -> float:
    """Radius (view units) of the bounding sphere at :data:`CENTRE_DEPTH`: the largest
    that keeps its nearest point ``NEAR_MARGIN`` beyond ``MIN_DEPTH`` and its silhouette's
    half-angle ``a`` at ``tan(a) <= (1 - IMAGE_MARGIN) tan(FOV_DEG)``."""
    cone = math.atan((1 - IMAGE_MARGIN) * math.tan(math.radians(FOV_DEG)))
    return min(CENTRE_DEPTH - MIN_DEPTH - NEAR_MARGIN, CENTRE_DEPTH * math.sin(cone))


def bounding_sphere(positions: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, float]:
    """A sphere holding every ball: centre ``(3,)`` the middle of the balls' axis-aligned
    bounding box, radius ``max |p - c| + r`` (world units; not the smallest such sphere,
    at most ``sqrt(3)`` times its radius)."""
    low = (positions - radii[:, None]).min(0)
    high = (positions + radii[:, None]).max(0)
    centre = (low + high) / 2
    return centre, float((np.linalg.norm(positions - centre, axis=1) + radii).max())


def fit_framing(
    positions: np.ndarray,
    radii: np.ndarray,
    scale: float = 1.0,
    rotation: np.ndarray | None = None,
) -> Framing:
    """The :class:`Framing` of world balls: positions ``(N, 3)``, radii ``(N,)`` (world
    units), radii multiplied by ``scale`` (> 0) first; ``rotation`` ``(3, 3)`` a proper
    rotation (default identity) turning the balls about their bounding sphere's centre.

    For a trajectory, fit once on every frame's positions stacked together and frame each
    frame with :meth:`Framing.scene`, so that the camera stays still.
    """
    positions, radii = _checked_geometry(positions, radii)
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"ball scale must be a positive number; got {scale}")
    rotation = _checked_rotation(rotation)
    centre, world_radius = bounding_sphere(positions, radii * scale)
    if world_radius <= 0:
        raise ValueError("the balls' bounding sphere has radius 0: nothing to frame")
    return Framing(centre, rotation, world_radius / view_radius(), float(scale))


def frame_balls(
    positions: np.ndarray,
    radii: np.ndarray,
    colours: np.ndarray,
    scale: float = 1.0,
    rotation: np.ndarray | None = None,
) -> tuple[Scene, Framing]:
    """World balls framed in view space (module docstring): the float64
    :class:`~neurender.metaball.Scene` and its :class:`Framing` (whose ``world_per_view``
    turns view-space distances back into world units).

    Args:
        positions: ``(N, 3)`` ball centres, world units.
        radii: ``(N,)`` ball radii (> 0), world units, multiplied by ``scale``.
        colours: ``(N, 3)`` linear RGB in [0, 1].
        scale: factor on every radius (e.g. van-der-Waals radii times 0.5).
        rotation: ``(3, 3)`` proper rotation from world to view axes; identity if ``None``.
    """
    framing = fit_framing(positions, radii, scale, rotation)
    return framing.scene(positions, radii, colours), framing


def _checked_geometry(positions, radii) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(N, 3)`` and radii ``(N,)`` as float64 arrays; ``ValueError`` saying what
    is wrong otherwise (shapes, no balls, non-finite values, radii not positive)."""
    positions = np.asarray(positions, np.float64)
    radii = np.asarray(radii, np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3 or radii.shape != positions.shape[:1]:
        raise ValueError(
            f"expected positions (N, 3) and radii (N,); got {positions.shape} and {radii.shape}"
        )
    if len(radii) == 0:
        raise ValueError("no balls to frame")
    if not (np.isfinite(positions).all() and np.isfinite(radii).all()):
        raise ValueError("ball positions and radii must be finite")
    if (radii <= 0).any():
        raise ValueError(f"{int((radii <= 0).sum())} ball radii are not positive")
    return positions, radii


def _checked(positions, radii, colours) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_checked_geometry` plus colours ``(N, 3)`` float64 in [0, 1]."""
    positions, radii = _checked_geometry(positions, radii)
    colours = np.asarray(colours, np.float64)
    if colours.shape != positions.shape:
        raise ValueError(f"expected colours {positions.shape}; got {colours.shape}")
    if not ((colours >= 0) & (colours <= 1)).all():
        raise ValueError("ball colours must be linear RGB in [0, 1]")
    return positions, radii, colours


def _checked_rotation(rotation) -> np.ndarray:
    """``rotation`` as a float64 ``(3, 3)`` proper rotation (identity for ``None``)."""
    if rotation is None:
        return np.eye(3)
    rotation = np.asarray(rotation, np.float64)
    if rotation.shape != (3, 3):
        raise ValueError(f"rotation must be a 3x3 matrix; got shape {rotation.shape}")
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) < 0:
        raise ValueError("rotation must be orthonormal with determinant +1 (no reflection)")
    return rotation
