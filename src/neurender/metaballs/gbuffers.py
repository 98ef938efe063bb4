"""The G-buffers a network predicts and the ray marcher produces, and their silhouettes.

A G-buffer stack is ``(7, W, W)``, view space of :mod:`neurender.metaballs.scenes`, values
in [0, 1]: colour (channels :data:`COLOUR`, the field-weighted blend of the balls'
colours, 0 on the background), depth (:data:`DEPTH`, distance along the ray normalised by
:func:`neurender.metaballs.scenes.normalised_depth`, background 1) and the outward unit
normal (:data:`NORMAL`, encoded ``(n + 1) / 2``, background 0). Networks see it mapped to
[-1, 1] (``2 x - 1``, "signed").

Silhouettes: depth below :data:`DEPTH_FOREGROUND` of the range (networks predict the
background's depth near 0.97, not 1), or, as thesis 7.1, a non-black normal buffer
(channel sum above :data:`NORMAL_FOREGROUND`; a unit normal's encoding always sums to more).
"""

from __future__ import annotations

import dataclasses

import torch

from neurender.metaballs.scenes import MAX_DEPTH, normalised_depth

COLOUR = slice(0, 3)
DEPTH = slice(3, 4)
NORMAL = slice(4, 7)
#: Name to channels of a stack, in channel order.
LAYOUT = {"colour": COLOUR, "depth": DEPTH, "normal": NORMAL}
CHANNELS = 7

DEPTH_FOREGROUND = 0.95
NORMAL_FOREGROUND = 0.3


@dataclasses.dataclass
class GBuffers:
    """Rendered G-buffers: colour ``(3, W, W)``, depth ``(1, W, W)``, normal ``(3, W, W)``
    (encoded), all in [0, 1], and the hit mask ``(W, W)`` bool."""

    colour: torch.Tensor
    depth: torch.Tensor
    normal: torch.Tensor
    mask: torch.Tensor

    def stack(self) -> torch.Tensor:
        """The ``(7, W, W)`` float32 stack."""
        return stack(self.colour, self.depth, self.normal)


def stack(colour: torch.Tensor, depth: torch.Tensor, normal: torch.Tensor) -> torch.Tensor:
    """``(7, W, W)`` float32 stack of colour ``(3, W, W)``, depth ``(1, W, W)`` and encoded
    normal ``(3, W, W)``."""
    return torch.cat([colour, depth, normal]).float()


def from_hits(
    distance: torch.Tensor, colour: torch.Tensor, normal: torch.Tensor, width: int
) -> GBuffers:
    """G-buffers of a ``W x W`` image from per-pixel hits, pixels in row-major order.

    Args:
        distance: ``(W * W,)`` distance along each pixel's ray, ``inf`` where it missed.
        colour: ``(3, W * W)``; normal: ``(3, W * W)`` encoded; both 0 where it missed.
    """
    mask = torch.isfinite(distance)
    depth = torch.where(mask, normalised_depth(distance.nan_to_num(posinf=MAX_DEPTH)), 1.0)
    shape = (width, width)
    return GBuffers(
        colour=colour.reshape(3, *shape),
        depth=depth.reshape(1, *shape),
        normal=normal.reshape(3, *shape),
        mask=mask.reshape(shape),
    )


def decoded_normals(buffers: torch.Tensor) -> torch.Tensor:
    """The normal channels of a ``(7, ...)`` stack decoded to [-1, 1] (``(3, ...)``, not
    renormalised: a network's normals are not exactly unit)."""
    return buffers[NORMAL] * 2 - 1


def silhouette_depth(buffers: torch.Tensor) -> torch.Tensor:
    """``(W, W)`` bool foreground of a ``(7, W, W)`` stack by depth."""
    return buffers[DEPTH][0] < DEPTH_FOREGROUND


def silhouette_normal(buffers: torch.Tensor) -> torch.Tensor:
    """``(W, W)`` bool foreground of a ``(7, W, W)`` stack by a non-black normal buffer
    (thesis 7.1)."""
    return buffers[NORMAL].sum(0) > NORMAL_FOREGROUND


def mirror(signed: torch.Tensor, axis: int) -> torch.Tensor:
    """The G-buffers of the scene mirrored across the image's vertical (``axis`` 0: x
    negated) or horizontal (``axis`` 1: y negated) centre line.

    The camera is symmetric, so this is the image flipped with the normals' ``axis``
    component negated on the foreground (by :func:`silhouette_normal`); the background's
    normal stays 0 (encoded -1).

    Args:
        signed: ``(7, W, W)`` stack in [-1, 1].
    """
    flipped = signed.flip(-1 if axis == 0 else -2)
    normal = flipped[NORMAL]
    foreground = (normal + 1).sum(0) / 2 > NORMAL_FOREGROUND  # silhouette_normal, signed
    mirrored = normal.clone()
    mirrored[axis] = torch.where(foreground, -normal[axis], normal[axis])
    return torch.cat([flipped[: NORMAL.start], mirrored])
