"""What a network sees of a metaball scene: circle images (thesis 4.1.1, listing 5.1) and,
for our residual model, sphere impostors.

Circles: each ball becomes the outline of a circle at its projected centre: a camera-facing
square billboard of world size ``2 r`` at the ball's centre, with the ring ``0.45 < |uv -
0.5| < 0.5`` of the quad filled, i.e. between 0.9 and 1.0 of the projected radius. RGB = the
ball's colour; A = the normalised depth of the centre. Nearer circles are drawn over farther
ones. Background: RGB 0, A 1 (far).

Sphere impostors: every ball ray-traced as a sphere, the nearest hit per pixel, as G-buffers
in the layout of :mod:`neurender.metaballs.gbuffers`. Both cost one test per ball and pixel
of the ball's screen rectangle (a billboard per ball on a GPU), never a march through the
field: the rectangles' rows go in blocks of equal padded width, so that each test is an
operation on whole arrays, and a depth test keeps per pixel the nearest fragment (of tied
ones, the lowest ball's).
"""

from __future__ import annotations

import dataclasses
import math

import torch

from neurender.metaball import THRESHOLD, Scene
from neurender.metaballs.gbuffers import GBuffers, from_hits
from neurender.metaballs.grid import BallGrid, build_grid
from neurender.metaballs.scenes import FOV_DEG, normalised_depth, pixel_rays, project

# Floor of 1 - G in ``inflated_radii``: a ball buried in its neighbours' field grows at most
# 1 / sqrt(0.3) = 1.8 times instead of without bound.
MIN_FIELD_GAP = 0.3


def projected_radius(scene: Scene, width: int) -> torch.Tensor:
    """Radius ``(B,)`` in pixels of each ball's billboard (world size ``2 r`` at depth ``z``)."""
    return scene.radii / scene.centres[:, 2] / math.tan(math.radians(FOV_DEG)) * width / 2


#: Columns of the narrowest block of :func:`_footprints` (rectangles up to 8 pixels wide),
#: and the padding (pixels) below which a block joins the next wider one.
MIN_BLOCK_COLUMNS = 8
MERGE_PADDING = 1 << 14


@dataclasses.dataclass
class _Block:
    """Screen rectangle rows of balls of similar width, each row padded to ``C`` columns
    (a rasteriser's tile): ``R`` rows of ``C`` pixels, per-row values ``(R, 1)``.

    Attributes:
        ball: ``(R, 1)`` ball of each row.
        row: ``(R, 1)`` image row.
        column: ``(R, C)`` image column (clamped into the image on the padding).
        valid: ``(R, C)`` false on the padding.
        pixel: ``(R, C)`` flat pixel index ``row * W + column``.
    """

    ball: torch.Tensor
    row: torch.Tensor
    column: torch.Tensor
    valid: torch.Tensor
    pixel: torch.Tensor


def _footprints(boxes: torch.Tensor, width: int) -> list[_Block]:
    """Every pixel whose centre can lie inside each ball's screen rectangle (a conservative
    superset), in blocks of balls whose rectangles are at most ``C`` pixels wide, ``C`` a
    power of two: every per-pixel value is then an operation on a ``(R, C)`` array with
    per-row values broadcast, not a gather per pixel.

    Args:
        boxes: ``(B, 4)`` continuous pixel bounds ``x0, y0, x1, y1`` (column, row).
    """
    device = boxes.device
    lo = boxes[:, :2].floor().clamp(0, width).long()
    hi = (boxes[:, 2:].ceil() + 1).clamp(0, width).long()
    cols, rows = (hi - lo).clamp(min=0).unbind(1)
    # Block k holds the balls 2^(k-1) < cols / MIN_BLOCK_COLUMNS <= 2^k (k = 0: the rest);
    # a block padding fewer than MERGE_PADDING pixels more in the next one's width joins
    # it (a block's fixed cost of some 30 array operations outweighs that padding).
    level = torch.log2(cols.clamp(min=1) / MIN_BLOCK_COLUMNS).ceil().clamp(min=0).long()
    levels = level.unique().tolist()
    rows_at = {k: int(rows[level == k].sum()) for k in levels}
    groups, pending, pending_rows = [], [], 0
    for k, nxt in zip(levels, [*levels[1:], None], strict=True):
        pending, pending_rows = [*pending, k], pending_rows + rows_at[k]
        extra = None if nxt is None else MIN_BLOCK_COLUMNS * ((1 << nxt) - (1 << k))
        if extra is None or pending_rows * extra >= MERGE_PADDING:
            groups.append((pending, k))
            pending, pending_rows = [], 0
    blocks = []
    for members, k in groups:
        balls = torch.nonzero(torch.isin(level, torch.tensor(members, device=device))).squeeze(1)
        ball = torch.repeat_interleave(balls, rows[balls])
        start = torch.cumsum(rows[balls], 0) - rows[balls]
        local = torch.arange(len(ball), device=device) - torch.repeat_interleave(start, rows[balls])
        row = (lo[ball, 1] + local)[:, None]
        offset = torch.arange(MIN_BLOCK_COLUMNS << k, device=device)[None, :]
        valid = offset < cols[ball, None]
        column = (lo[ball, 0, None] + offset).clamp(max=width - 1)
        blocks.append(_Block(ball[:, None], row, column, valid, row * width + column))
    return blocks


def _nearest(
    blocks: list[_Block], keys: list[torch.Tensor], width: int, scene: Scene
) -> tuple[torch.Tensor, torch.Tensor]:
    """Depth test of the blocks' pixels, ``keys[i]`` ``(R, C)`` of block ``i`` (``inf``:
    no fragment; a ball covers a pixel at most once), in the dtype of ``scene``.

    Returns:
        Per pixel ``(W * W,)`` the smallest key (``inf`` where none) and its ball: of
        balls at equal key the lowest (``len(scene)`` where none), so that which of
        several tied fragments lands never depends on the thread schedule.
    """
    count, device = len(scene), scene.centres.device
    pixels = [b.pixel.reshape(-1) for b in blocks]
    nearest = torch.full((width * width,), math.inf, dtype=scene.centres.dtype, device=device)
    for pixel, key in zip(pixels, keys, strict=True):
        nearest.scatter_reduce_(0, pixel, key.reshape(-1), "amin")
    first = torch.full((width * width,), count, dtype=torch.long, device=device)
    for b, pixel, key in zip(blocks, pixels, keys, strict=True):
        tied = torch.isfinite(key) & (key == nearest.index_select(0, pixel).view_as(key))
        first.scatter_reduce_(0, pixel, torch.where(tied, b.ball, count).reshape(-1), "amin")
    return nearest, first


def draw_inputs(scene: Scene, width: int) -> torch.Tensor:
    """The ``(4, W, W)`` circle image (RGB colour, A centre depth), values in [0, 1].

    Rasterised like the thesis's billboards (only the pixels of each ball's square), with a
    depth test instead of drawing far to near; the result is the same.
    """
    dtype = scene.centres.dtype
    centre = project(scene.centres, width)  # (B, 2) column, row
    radius = projected_radius(scene, width)
    depth = normalised_depth(scene.centres.norm(dim=1))
    blocks = _footprints(torch.cat([centre - radius[:, None], centre + radius[:, None]], 1), width)
    keys = []
    for b in blocks:
        dist = torch.hypot(
            b.column.to(dtype) + 0.5 - centre[b.ball, 0], b.row.to(dtype) + 0.5 - centre[b.ball, 1]
        )
        r = radius[b.ball]
        ring = (dist > 0.9 * r) & (dist < r) & b.valid
        keys.append(torch.where(ring, depth[b.ball], math.inf))
    nearest, first = _nearest(blocks, keys, width, scene)
    image = torch.zeros(4, width * width, dtype=dtype, device=scene.centres.device)
    hit = first < len(scene)
    image[:3, hit] = scene.colours[first[hit]].T
    image[3] = torch.where(hit, nearest, 1.0)
    return image.reshape(4, width, width)


def _sphere_boxes(centres: torch.Tensor, radii: torch.Tensor, width: int) -> torch.Tensor:
    """``(B, 4)`` exact pixel bounds of each sphere's image (spheres in front of the camera).

    The planes ``x = u z`` through the camera tangent to a sphere satisfy
    ``(c_x - u c_z)^2 = r^2 (1 + u^2)``, whose roots bound ``x / z`` on it; likewise ``y / z``.
    """
    cz, r2 = centres[:, 2], radii.square()
    denom = cz.square() - r2
    bounds = []
    for axis in (0, 1):
        c = centres[:, axis]
        half = radii * (c.square() + denom).sqrt()
        bounds.append(((c * cz - half) / denom, (c * cz + half) / denom))
    (u0, u1), (v0, v1) = bounds
    # Corners (u0, v1) and (u1, v0) on the plane z = 1: top-left and bottom-right in pixels.
    ones = torch.ones_like(u0)
    corners = torch.stack([torch.stack([u0, v1, ones], 1), torch.stack([u1, v0, ones], 1)], 1)
    return project(corners.reshape(-1, 3), width).reshape(-1, 4)


def draw_spheres(scene: Scene, width: int) -> GBuffers:
    """Every ball ray-traced as a sphere of its radius ``r`` (the nearest hit per pixel).

    For an isolated ball this is exactly its metaball surface (``r^2 / d^2 = 1`` at
    ``d = r``); colour is the ball's own, normal the sphere's (encoded ``(n + 1) / 2``).
    Rasterised per ball over its screen rectangle (a sphere impostor).
    """
    dtype = scene.centres.dtype
    rays = pixel_rays(width, dtype, scene.centres.device).reshape(-1, 3).T.contiguous()
    dist, first = sphere_hits(scene, width, rays)
    count = len(scene)
    missed = first >= count
    # Every pixel gathers a ball (the last where none is hit) and is zeroed where none is:
    # whole-image gathers cost less than indexing by a mask where many pixels are hit, and
    # in place, few image-sized temporaries (each a fresh allocation) where few are.
    ball = first.clamp(max=count - 1)
    colour = scene.colours.T.index_select(1, ball).masked_fill_(missed, 0)
    # Channels first, as the G-buffers are laid out: (hit point - centre) / r, encoded.
    normal = rays * dist.masked_fill(missed, 0)
    normal.sub_(scene.centres.T.index_select(1, ball)).div_(scene.radii[ball])
    normal.add_(1).div_(2).masked_fill_(missed, 0)
    return from_hits(dist, colour, normal, width)


def sphere_hits(
    scene: Scene,
    width: int,
    rays: torch.Tensor | None = None,
    beyond: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per pixel ``(W * W,)`` (row-major) the distance along its ray to the nearest sphere
    of the scene's radii (``inf`` where none) and that sphere's ball (of tied ones the
    lowest; ``len(scene)`` where none), rasterised per ball over its screen rectangle.
    ``rays``: the :func:`pixel_rays` channels first, ``(3, W * W)``, when the caller has
    them already. ``beyond``: ``(W * W,)`` distances at or before which a pixel keeps no
    sphere (depth peeling: the previous layer's distances give the next layer; ``inf``
    skips a pixel)."""
    if rays is None:
        rays = pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3).T
    ray_axes = rays.contiguous()
    offset = scene.centres.square().sum(1) - scene.radii.square()  # |c|^2 - r^2
    blocks = _footprints(_sphere_boxes(scene.centres, scene.radii, width), width)
    keys = []
    for blk in blocks:
        c = scene.centres[blk.ball[:, 0]]
        pixel = blk.pixel.reshape(-1)
        # ray . centre, multiplied and added in axis order (the first version took it from
        # a matrix product, whose float32 rounding depends on the BLAS kernel it picks)
        ray = [ray_axes[k].index_select(0, pixel).view_as(blk.pixel) for k in range(3)]
        b = ray[0] * c[:, 0, None] + ray[1] * c[:, 1, None] + ray[2] * c[:, 2, None]
        disc = b.square() - offset[blk.ball]
        t = torch.where((disc >= 0) & blk.valid, b - disc.clamp(min=0).sqrt(), math.inf)
        floor = 0 if beyond is None else beyond.index_select(0, pixel).view_as(t)
        keys.append(torch.where(t > floor, t, math.inf))
    return _nearest(blocks, keys, width, scene)


def sphere_counts(scene: Scene, width: int, rays: torch.Tensor | None = None) -> torch.Tensor:
    """Per pixel ``(W * W,)`` int64 (row-major) how many spheres of the scene's radii its ray
    passes through (a tangent ray does not), rasterised as :func:`sphere_hits`: one test
    per ball and pixel of its screen rectangle. ``rays`` as :func:`sphere_hits`.

    Raises:
        ValueError: a sphere not wholly in front of the camera (centre ``z`` at most ``r``).
    """
    behind = torch.nonzero(scene.centres[:, 2] <= scene.radii).squeeze(1)
    if len(behind):
        i = int(behind[0])
        raise ValueError(
            f"sphere {i} (centre z {float(scene.centres[i, 2])}, radius "
            f"{float(scene.radii[i])}) is not wholly in front of the camera"
        )
    if rays is None:
        rays = pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3).T
    ray_axes = rays.contiguous()
    offset = scene.centres.square().sum(1) - scene.radii.square()
    counts = torch.zeros(width * width, dtype=torch.long, device=scene.centres.device)
    for blk in _footprints(_sphere_boxes(scene.centres, scene.radii, width), width):
        c = scene.centres[blk.ball[:, 0]]
        pixel = blk.pixel.reshape(-1)
        ray = [ray_axes[k].index_select(0, pixel).view_as(blk.pixel) for k in range(3)]
        b = ray[0] * c[:, 0, None] + ray[1] * c[:, 1, None] + ray[2] * c[:, 2, None]
        # the camera is outside every sphere and they lie ahead: a real root is a hit
        meets = (b.square() > offset[blk.ball]) & blk.valid
        counts.index_add_(0, pixel, meets.reshape(-1).long())
    return counts


#: Rows of the inverse square's all-pairs sum in :func:`inflated_radii` at a time: its
#: memory is this many times the number of balls.
PAIR_ROWS = 4096


def inflated_radii(
    scene: Scene, chunk: int = PAIR_ROWS, grid: BallGrid | None = None
) -> torch.Tensor:
    """Radius ``(B,)`` of each ball's surface in the field of all the others.

    Near ball ``i`` the other balls add about their field at its centre, ``G_i = sum_{j != i}
    k(|P_i - P_j|^2 / r_j^2)``, so ``k(d^2 / r_i^2) + G_i = THRESHOLD`` gives a sphere of
    radius ``r_i sqrt(k^-1(THRESHOLD - G_i))`` (:meth:`neurender.metaball.Kernel.inverse`;
    ``THRESHOLD - G_i`` floored at ``MIN_FIELD_GAP``): ``r_i / sqrt(THRESHOLD - G_i)`` for
    the inverse square. Exact for one ball; a first-order model of the blend otherwise.

    The inverse square sums every pair, ``chunk`` rows at a time (``O(B chunk)`` memory);
    a kernel of finite support only the balls listed in the cell of each centre
    (:func:`neurender.metaballs.grid.build_grid`, or ``grid`` if given): ``O(B x
    neighbours)`` time and memory.
    """
    if scene.kernel.finite:
        gap = (THRESHOLD - _neighbour_field(scene, grid)).clamp(min=MIN_FIELD_GAP)
        return scene.radii * scene.kernel.inverse(gap).sqrt()
    others = [_inverse_square_rows(scene, start, chunk) for start in range(0, len(scene), chunk)]
    others = torch.cat(others) if others else torch.zeros_like(scene.radii)
    return scene.radii / (THRESHOLD - others).clamp(min=MIN_FIELD_GAP).sqrt()


def _inverse_square_rows(scene: Scene, start: int, chunk: int) -> torch.Tensor:
    """``G_i`` ``(n,)`` of the inverse square for the balls ``start .. start + n`` (at most
    ``chunk``): ``sum_{j != i} r_j^2 / |P_i - P_j|^2``."""
    d2 = torch.cdist(scene.centres[start : start + chunk], scene.centres).square()
    rows = torch.arange(len(d2), device=d2.device)
    d2[rows, start + rows] = math.inf
    return (scene.radii.square()[None, :] / d2).sum(1)


def _neighbour_field(scene: Scene, grid: BallGrid | None) -> torch.Tensor:
    """``G_i`` ``(B,)`` of a kernel of finite support: the field of every other ball at
    each ball's centre, over the balls listed in the centre's cell."""
    grid = build_grid(scene) if grid is None else grid
    owner, ball = grid.pairs(grid.cell_of(scene.centres))
    other = ball != owner
    owner, ball = owner[other], ball[other]
    d2 = (scene.centres[owner] - scene.centres[ball]).square().sum(1)
    f = scene.kernel.value(d2 / scene.radii[ball].square())
    return torch.zeros_like(scene.radii).index_add_(0, owner, f)


def inflated_spheres(scene: Scene, width: int) -> GBuffers:
    """:func:`draw_spheres` with :func:`inflated_radii`: the prior our residual model corrects."""
    return draw_spheres(Scene(scene.centres, inflated_radii(scene), scene.colours), width)
