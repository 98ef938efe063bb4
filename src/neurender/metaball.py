"""The metaball implicit surface and an exact ray marcher for it (torch).

Field: ``F(X) = sum_i k(|X - P_i|^2 / r_i^2)``, surface at ``F = THRESHOLD``. Every kernel
``k`` is normalised to ``k(1) = 1``, so that an isolated ball is a sphere of radius ``r``
whatever the kernel (:class:`Kernel`):

- ``inverse_square`` (Blinn 1982; the image-space metaballs thesis, eq. 5.1): ``k(x) =
  1 / x``; it never falls to zero, so every ball reaches every point and, at a constant
  density of balls, the surface swells with the size of the scene.
- ``wyvill``: the compact polynomial of Wyvill, McPheeters and Wyvill's soft objects
  (1986), ``(1 - x / s^2)^3`` for ``x < s^2``, else 0: a ball reaches ``s r``.
- ``gaussian``: Blinn's blobby molecules as QuickSurf uses them (Krone, Stone, Ertl,
  Schulten, EuroVis 2012), ``exp(-a x)`` truncated at ``x = s^2`` (shifted to reach 0 there).

Rays advance by the largest step that provably cannot cross the surface. For the inverse
square, with ``d`` the distance to the nearest centre, any point within ``s`` has ``F <= F
(d / (d - s))^2``, so ``s = d (1 - sqrt(F))`` keeps ``F < 1``. For a kernel of finite
support (a Lipschitz bound, Hart's sphere tracing): only balls whose support holds the point
can raise ``F`` before the ray reaches another ball's support, each by at most its slope
bound ``L_i`` per unit of distance, so ``s = min(distance to the nearest support not holding
the point, (THRESHOLD - F) / sum L_i)``. A floor ``min_step`` keeps rays moving near
tangencies; the bracketed crossing is then refined by bisection. Positions are in world
units of whatever space the balls live in.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import torch

THRESHOLD = 1.0
#: :func:`march`'s step floor (world units) and bisections of the bracketed crossing.
MIN_STEP = 0.02
BISECTIONS = 24

KERNELS = ("inverse_square", "wyvill", "gaussian")


@dataclasses.dataclass(frozen=True)
class Kernel:
    """A ball's field ``k(x)`` of ``x = d^2 / r^2``, ``k(1) = 1`` (module docstring).

    Attributes:
        name: one of :data:`KERNELS`.
        support: where ``k`` reaches 0, in units of the ball's ``r`` (``inf`` for the
            inverse square; above 1 for the others).
        sharpness: ``a`` of the Gaussian's ``exp(-a x)`` (unused by the others).
    """

    name: str = "inverse_square"
    support: float = math.inf
    sharpness: float = 1.0

    def __post_init__(self):
        if self.name not in KERNELS:
            raise ValueError(f"metaball kernel {self.name!r}: expected one of {KERNELS}")
        finite = self.name != "inverse_square"
        if finite and not (1 < self.support < math.inf):
            raise ValueError(
                f"metaball kernel {self.name!r}: support {self.support} must be finite and "
                "above 1 (in units of a ball's radius)"
            )
        if not finite and self.support != math.inf:
            raise ValueError("the inverse_square kernel has no finite support")
        if self.sharpness <= 0:
            raise ValueError(f"metaball kernel sharpness {self.sharpness} must be positive")

    @property
    def finite(self) -> bool:
        """Whether a ball's field reaches 0 at ``support`` times its radius."""
        return math.isfinite(self.support)

    def _scale(self) -> float:
        """The divisor that makes ``k(1) = 1``."""
        s2 = self.support**2
        if self.name == "wyvill":
            return (1 - 1 / s2) ** 3
        if self.name == "gaussian":
            return math.exp(-self.sharpness) - math.exp(-self.sharpness * s2)
        return 1.0

    def value(self, x: torch.Tensor) -> torch.Tensor:
        """``k(x)`` at ``x = d^2 / r^2`` (any shape), 0 at and beyond the support."""
        if self.name == "inverse_square":
            return 1 / x
        s2 = self.support**2
        if self.name == "wyvill":
            raw = (1 - x / s2).clamp(min=0) ** 3
        else:
            raw = (torch.exp(-self.sharpness * x) - math.exp(-self.sharpness * s2)).clamp(min=0)
        return raw / self._scale()

    def slope(self, x: torch.Tensor) -> torch.Tensor:
        """``dk/dx`` at ``x`` (any shape; 0 beyond the support)."""
        if self.name == "inverse_square":
            return -1 / x.square()
        s2 = self.support**2
        inside = x < s2
        if self.name == "wyvill":
            raw = -3 / s2 * (1 - x / s2).clamp(min=0).square()
        else:
            raw = -self.sharpness * torch.exp(-self.sharpness * x)
        return torch.where(inside, raw, torch.zeros_like(raw)) / self._scale()

    def inverse(self, y: torch.Tensor) -> torch.Tensor:
        """The ``x`` ``>= 0`` with ``k(x) = y`` (any shape), ``y`` clamped into ``[0,
        k(0)]``: ``1 / y`` for the inverse square (``inf`` at 0), ``s^2 (1 - (c y)^(1/3))``
        for Wyvill's and ``-ln(c y + e^(-a s^2)) / a`` for the Gaussian, ``c`` the
        normalisation of ``k(1) = 1``; ``y = 0`` gives the support ``s^2``, ``k(0)`` gives
        0."""
        if self.name == "inverse_square":
            return 1 / y.clamp(min=0)
        s2, scale = self.support**2, self._scale()
        if self.name == "wyvill":
            scaled = y.clamp(0, 1 / scale) * scale
            x = s2 * (1 - scaled.pow(1 / 3))
        else:
            floor = math.exp(-self.sharpness * s2)
            scaled = y.clamp(0, (1 - floor) / scale) * scale
            x = -torch.log(scaled + floor) / self.sharpness
        return x.clamp(0, s2)

    @property
    def lipschitz(self) -> float:
        """``max |dk/dd|`` for a ball of radius 1 (the bound ``L_i`` of the module docstring
        is this over ``r_i``); ``inf`` for the inverse square. With ``d = sqrt(x)``,
        ``|dk/dd| = 2 sqrt(x) |dk/dx|``, whose maximum is at ``x = s^2 / 5`` (Wyvill) or
        ``x = 1 / (2 a)`` (Gaussian, if inside the support)."""
        if not self.finite:
            return math.inf
        if self.name == "wyvill":
            x = self.support**2 / 5
        else:
            x = min(1 / (2 * self.sharpness), self.support**2)
        return float(2 * math.sqrt(x) * -self.slope(torch.tensor(x, dtype=torch.float64)))


#: The thesis's field (eq. 5.1), the default.
INVERSE_SQUARE = Kernel()


def kernel_from_config(cfg: Mapping[str, Any]) -> Kernel:
    """The kernel of a config's ``metaballs.kernel``: ``name``, and for a finite kernel its
    ``support`` and ``sharpness`` (the inverse square takes neither)."""
    if cfg["name"] == "inverse_square":
        return INVERSE_SQUARE
    return Kernel(cfg["name"], float(cfg["support"]), float(cfg["sharpness"]))


@dataclasses.dataclass
class Scene:
    """Metaballs.

    Attributes:
        centres: ``(B, 3)`` float positions.
        radii: ``(B,)`` size parameters ``r``.
        colours: ``(B, 3)`` linear RGB in [0, 1].
        kernel: every ball's field (:class:`Kernel`).
    """

    centres: torch.Tensor
    radii: torch.Tensor
    colours: torch.Tensor
    kernel: Kernel = INVERSE_SQUARE

    def __len__(self) -> int:
        return len(self.radii)

    def to(self, dtype: torch.dtype) -> Scene:
        return Scene(
            self.centres.to(dtype), self.radii.to(dtype), self.colours.to(dtype), self.kernel
        )

    @property
    def reach(self) -> torch.Tensor:
        """``(B,)`` distance at which each ball's field reaches 0 (``inf`` for the inverse
        square)."""
        return self.radii * self.kernel.support


def field(points: torch.Tensor, scene: Scene) -> tuple[torch.Tensor, torch.Tensor]:
    """Field ``F`` ``(R,)`` at points ``(R, 3)`` and a step ``(R,)`` along any direction
    that cannot reach ``F = THRESHOLD`` from a point outside the surface (module
    docstring; meaningless inside it)."""
    d2 = torch.cdist(points, scene.centres).square()
    f = scene.kernel.value(d2 / scene.radii.square())
    total = f.sum(1)
    if not scene.kernel.finite:
        return total, d2.min(1).values.sqrt() * (1 - total.clamp(max=THRESHOLD).sqrt())
    dist, reach = d2.sqrt(), scene.reach
    inside = dist < reach
    free = torch.where(inside, math.inf, dist - reach).amin(1)
    slope = torch.where(inside, scene.kernel.lipschitz / scene.radii, 0.0).sum(1)
    return total, finite_step(total, free, slope)


def finite_step(total: torch.Tensor, free: torch.Tensor, slope: torch.Tensor) -> torch.Tensor:
    """The safe step ``(R,)`` of a kernel of finite support (module docstring) from the
    field ``total``, the distance ``free`` to the nearest support not holding the point
    and the summed slope bound ``slope`` of the supports holding it (each ``(R,)``)."""
    gap = (THRESHOLD - total).clamp(min=0)
    return torch.minimum(free, torch.where(slope > 0, gap / slope.clamp(min=1e-30), math.inf))


def march(
    origins: torch.Tensor,
    dirs: torch.Tensor,
    scene: Scene,
    near: float,
    far: float,
    min_step: float = MIN_STEP,
    bisections: int = BISECTIONS,
) -> torch.Tensor:
    """Distance ``(R,)`` to the first ``F = THRESHOLD`` crossing along each ray in
    ``[near, far]`` (``inf`` if none); rays ``(R, 3)``, directions of unit length."""
    t = torch.full(origins.shape[:1], near, dtype=origins.dtype, device=origins.device)
    prev = t.clone()
    active = torch.ones_like(t, dtype=torch.bool)
    hit = torch.zeros_like(active)
    while active.any():
        idx = active.nonzero().squeeze(1)
        f, safe = field(origins[idx] + t[idx, None] * dirs[idx], scene)
        crossed = f >= THRESHOLD
        hit[idx[crossed]] = True
        going = idx[~crossed]
        step = safe[~crossed].clamp(min=min_step)
        prev[going] = t[going]
        t[going] = t[going] + step
        active[idx[crossed]] = False
        active[going[t[going] > far]] = False
    return bisect(origins[hit], dirs[hit], prev[hit], t[hit], hit, scene, bisections)


def bisect(
    origins: torch.Tensor,
    dirs: torch.Tensor,
    lo: torch.Tensor,
    hi: torch.Tensor,
    hit: torch.Tensor,
    scene: Scene,
    bisections: int,
    field_of=None,
) -> torch.Tensor:
    """Distances ``(len(hit),)``: the crossing bracketed in ``[lo, hi]`` (``(H,)``, field
    below the threshold at ``lo``, at or above it at ``hi``) on the rays ``(H, 3)`` where
    ``hit`` ``(R,)`` is true, after ``bisections`` halvings; ``inf`` elsewhere.
    ``field_of(points)`` gives ``F`` (default :func:`field`'s over every ball)."""
    field_of = field_of or (lambda p: field(p, scene)[0])
    for _ in range(bisections):
        mid = (lo + hi) / 2
        inside = field_of(origins + mid[:, None] * dirs) >= THRESHOLD
        hi = torch.where(inside, mid, hi)
        lo = torch.where(inside, lo, mid)
    out = torch.full(hit.shape, float("inf"), dtype=lo.dtype, device=lo.device)
    out[hit] = hi
    return out


def attributes(
    points: torch.Tensor,
    centres: torch.Tensor,
    radii: torch.Tensor,
    colours: torch.Tensor,
    kernel: Kernel,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per point-ball pair ``(P,)`` of points ``(P, 3)`` and balls (``centres (P, 3)``,
    ``radii (P,)``, ``colours (P, 3)``): the field ``f (P,)``, ``f`` times the colour
    ``(P, 3)`` and the field's gradient ``(P, 3)``, to be summed per point."""
    diff = points - centres
    x = diff.square().sum(-1) / radii.square()
    f = kernel.value(x)
    grad = (2 * kernel.slope(x) / radii.square())[:, None] * diff
    return f, f[:, None] * colours, grad


def surface_attributes(points: torch.Tensor, scene: Scene) -> tuple[torch.Tensor, torch.Tensor]:
    """Blended colour ``sum c_i f_i / F`` and outward unit normal ``-grad F / |grad F|``
    (each ``(R, 3)``) at points ``(R, 3)`` on (or near) the surface."""
    diff = points[:, None, :] - scene.centres[None]  # (R, B, 3)
    x = diff.square().sum(-1) / scene.radii.square()
    f = scene.kernel.value(x)  # (R, B)
    colour = (f @ scene.colours) / f.sum(1, keepdim=True)
    slope = 2 * scene.kernel.slope(x) / scene.radii.square()  # (R, B)
    grad = (slope[..., None] * diff).sum(1)
    return colour, -grad / grad.norm(dim=1, keepdim=True)
