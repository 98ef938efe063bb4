"""Cell lists over metaballs of finite support: the field, its safe steps and the surface
attributes from the balls near a point only, and a ray marcher that visits the cells its
rays cross.

A uniform grid of cubic cells covers every ball's support (a sphere of radius ``support x
r``, :class:`neurender.metaball.Kernel`); each cell lists the balls whose support meets it
(compressed rows: :attr:`BallGrid.starts` into :attr:`BallGrid.balls`). A point's field is
then the sum over its cell's list, exact, at a cost of the balls near it rather than all of
them. A ray steps as :func:`neurender.metaball.march` with the safe step of a finite
kernel computed over its cell's list, never past the cell's far face (beyond it other balls
may reach); empty cells are crossed in one step. Building the grid costs ``O(B)`` time and
memory (at most 27 cells a ball when the cell is the largest reach); a query costs the
number of point-ball pairs it makes.
"""

from __future__ import annotations

import dataclasses
import math

import torch

from neurender.metaball import BISECTIONS, THRESHOLD, Scene, attributes, bisect, finite_step

#: The most cells a grid holds (int64 offsets, float64 bounds: 16 bytes a cell); a scene
#: whose reach would need more gets larger cells.
MAX_CELLS = 1 << 22
#: How far past a cell's far face a ray's step lands (in cells), so that it is in the next.
FACE_NUDGE = 1e-7
#: The marcher's step floor, in units of the smallest ball's radius.
MIN_STEP_SHARE = 0.02


@dataclasses.dataclass
class BallGrid:
    """A scene's balls in uniform cells (module docstring).

    Attributes:
        scene: the balls (a kernel of finite support).
        lower: ``(3,)`` the grid's corner of least coordinates (world units).
        cell: a cell's edge (world units).
        dims: ``(3,)`` cells along x, y, z (int64); cell ``(i, j, k)`` has the index
            ``(i * dims[1] + j) * dims[2] + k``.
        starts: ``(C + 1,)`` int64, cell ``c``'s balls at ``balls[starts[c]:starts[c + 1]]``.
        balls: ``(E,)`` int64 ball indices, by cell.
    """

    scene: Scene
    lower: torch.Tensor
    cell: float
    dims: torch.Tensor
    starts: torch.Tensor
    balls: torch.Tensor

    @property
    def upper(self) -> torch.Tensor:
        """``(3,)`` the grid's corner of greatest coordinates."""
        return self.lower + self.dims.to(self.lower.dtype) * self.cell

    def cell_of(self, points: torch.Tensor) -> torch.Tensor:
        """``(R,)`` int64 index of the cell holding each point ``(R, 3)``, -1 outside."""
        ijk = ((points - self.lower) / self.cell).floor()
        outside = ((ijk < 0) | (ijk >= self.dims)).any(1)
        ijk = ijk.long().clamp(min=0)
        index = (ijk[:, 0] * self.dims[1] + ijk[:, 1]) * self.dims[2] + ijk[:, 2]
        return torch.where(outside, -1, index)

    def pairs(self, cells: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Every (query, ball) pair of query cells ``(R,)`` (-1: none): the query's
        position ``(P,)`` in ``cells`` and the ball ``(P,)``."""
        valid = cells >= 0
        safe = cells.clamp(min=0)
        first = self.starts[safe]
        counts = torch.where(valid, self.starts[safe + 1] - first, 0)
        owner = torch.repeat_interleave(torch.arange(len(cells), device=cells.device), counts)
        offset = torch.arange(len(owner), device=cells.device) - torch.repeat_interleave(
            counts.cumsum(0) - counts, counts
        )
        return owner, self.balls[first[owner] + offset]

    def _terms(self, points: torch.Tensor, cells: torch.Tensor):
        """Pairs of points ``(R, 3)`` in ``cells`` ``(R,)`` with their balls and
        :func:`neurender.metaball.attributes` of each pair."""
        owner, ball = self.pairs(cells)
        s = self.scene
        f, tinted, grad = attributes(
            points[owner], s.centres[ball], s.radii[ball], s.colours[ball], s.kernel
        )
        return owner, ball, f, tinted, grad

    def field(self, points: torch.Tensor) -> torch.Tensor:
        """Field ``F`` ``(R,)`` at points ``(R, 3)`` (0 outside the grid)."""
        owner, _, f, _, _ = self._terms(points, self.cell_of(points))
        return torch.zeros(len(points), dtype=points.dtype, device=points.device).index_add_(
            0, owner, f
        )

    def surface_attributes(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """As :func:`neurender.metaball.surface_attributes`, from the balls near each
        point: blended colour and outward unit normal, each ``(R, 3)``."""
        owner, _, f, tinted, grad = self._terms(points, self.cell_of(points))
        zeros = torch.zeros(len(points), 3, dtype=points.dtype, device=points.device)
        total = torch.zeros(len(points), dtype=points.dtype, device=points.device)
        total.index_add_(0, owner, f)
        colour = zeros.clone().index_add_(0, owner, tinted) / total[:, None]
        gradient = zeros.index_add_(0, owner, grad)
        return colour, -gradient / gradient.norm(dim=1, keepdim=True)

    def field_and_step(
        self, points: torch.Tensor, dirs: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Field ``F`` ``(R,)`` at points ``(R, 3)`` inside the grid and the step along unit
        ``dirs`` ``(R, 3)`` that cannot reach the surface: the finite kernel's safe step
        (:mod:`neurender.metaball`) over the cell's balls, at most to just past the
        cell's far face."""
        cells = self.cell_of(points)
        owner, ball, f, _, _ = self._terms(points, cells)
        s = self.scene
        n = len(points)
        total = torch.zeros(n, dtype=points.dtype, device=points.device).index_add_(0, owner, f)
        dist = (points[owner] - s.centres[ball]).norm(dim=1)
        reach = s.reach[ball]
        inside = dist < reach
        free = torch.full_like(total, math.inf).scatter_reduce_(
            0, owner, torch.where(inside, math.inf, dist - reach), "amin"
        )
        bound = s.kernel.lipschitz / s.radii[ball]
        slope = torch.zeros_like(total).index_add_(0, owner, torch.where(inside, bound, 0.0))
        return total, torch.minimum(finite_step(total, free, slope), self._to_exit(points, dirs))

    def _to_exit(self, points: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
        """``(R,)`` distance along unit ``dirs`` from ``points`` to just past the far face
        of the cell holding each point."""
        low = ((points - self.lower) / self.cell).floor() * self.cell + self.lower
        face = torch.where(dirs > 0, low + self.cell, low)
        with torch.no_grad():
            per_axis = torch.where(dirs != 0, (face - points) / dirs, math.inf)
        return per_axis.amin(1).clamp(min=0) + FACE_NUDGE * self.cell

    def march(
        self,
        origins: torch.Tensor,
        dirs: torch.Tensor,
        near: float,
        far: float,
        min_step: float | None = None,
        bisections: int = BISECTIONS,
    ) -> torch.Tensor:
        """As :func:`neurender.metaball.march` (distance ``(R,)`` to the first crossing in
        ``[near, far]``, ``inf`` if none), visiting only the cells the rays cross; the step
        floor ``min_step`` defaults to :data:`MIN_STEP_SHARE` of the smallest radius."""
        if min_step is None:
            min_step = MIN_STEP_SHARE * float(self.scene.radii.min())
        enter, leave = _slab(origins, dirs, self.lower, self.upper)
        t = enter.clamp(min=near)
        end = leave.clamp(max=far)
        prev = t.clone()
        active = t <= end
        hit = torch.zeros_like(active)
        while active.any():
            idx = active.nonzero().squeeze(1)
            f, step = self.field_and_step(origins[idx] + t[idx, None] * dirs[idx], dirs[idx])
            crossed = f >= THRESHOLD
            hit[idx[crossed]] = True
            going = idx[~crossed]
            prev[going] = t[going]
            t[going] = t[going] + step[~crossed].clamp(min=min_step)
            active[idx[crossed]] = False
            active[going[t[going] > end[going]]] = False
        return bisect(
            origins[hit], dirs[hit], prev[hit], t[hit], hit, self.scene, bisections, self.field
        )


def _slab(
    origins: torch.Tensor, dirs: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Distances ``(R,)`` at which rays ``(R, 3)`` enter and leave the box ``[lower,
    upper]`` (enter > leave: a miss)."""
    with torch.no_grad():
        inv = torch.where(dirs != 0, 1 / dirs, math.inf)
    a = (lower - origins) * inv
    b = (upper - origins) * inv
    a = torch.where(
        dirs != 0, a, torch.where((origins >= lower) & (origins <= upper), -math.inf, math.inf)
    )
    b = torch.where(
        dirs != 0, b, torch.where((origins >= lower) & (origins <= upper), math.inf, -math.inf)
    )
    return torch.minimum(a, b).amax(1), torch.maximum(a, b).amin(1)


def build_grid(scene: Scene, cell: float | None = None) -> BallGrid:
    """Cell lists of a scene whose kernel has finite support.

    Args:
        scene: the balls.
        cell: a cell's edge (world units; default the largest reach, so a ball meets at
            most 27 cells), enlarged if the grid would hold more than :data:`MAX_CELLS`.

    Raises:
        ValueError: a kernel of infinite support (every ball reaches every point).
    """
    if not scene.kernel.finite:
        raise ValueError(
            f"cell lists need a kernel of finite support; {scene.kernel.name!r} reaches every point"
        )
    reach = scene.reach
    lower = (scene.centres - reach[:, None]).amin(0)
    upper = (scene.centres + reach[:, None]).amax(0)
    extent = (upper - lower).clamp(min=1e-9)
    cell = float(reach.max()) if cell is None else float(cell)
    cells = float(torch.ceil(extent / cell).prod())
    if cells > MAX_CELLS:
        cell *= (cells / MAX_CELLS) ** (1 / 3) * 1.01
    dims = torch.ceil(extent / cell).long().clamp(min=1)
    first = ((scene.centres - reach[:, None] - lower) / cell).floor().long()
    last = ((scene.centres + reach[:, None] - lower) / cell).floor().long()
    first = torch.minimum(first.clamp(min=0), dims - 1)
    last = torch.minimum(last.clamp(min=0), dims - 1)
    span = last - first + 1  # (B, 3)
    counts = span.prod(1)
    ball = torch.repeat_interleave(torch.arange(len(scene), device=counts.device), counts)
    local = torch.arange(len(ball), device=counts.device) - torch.repeat_interleave(
        counts.cumsum(0) - counts, counts
    )
    sj, sk = span[ball, 1], span[ball, 2]
    ijk = first[ball] + torch.stack([local // (sj * sk), local // sk % sj, local % sk], 1)
    # Keep a (cell, ball) entry only where the ball's support sphere meets the cell's box.
    low = lower + ijk.to(lower.dtype) * cell
    nearest = torch.minimum(torch.maximum(scene.centres[ball], low), low + cell)
    meets = (nearest - scene.centres[ball]).square().sum(1) < reach[ball].square()
    ball, ijk = ball[meets], ijk[meets]
    index = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = torch.argsort(index, stable=True)
    per_cell = torch.bincount(index, minlength=int(dims.prod()))
    starts = torch.cat([per_cell.new_zeros(1), per_cell.cumsum(0)])
    return BallGrid(scene, lower, cell, dims, starts, ball[order])
