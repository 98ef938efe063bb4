"""Screen-space fluid rendering of metaballs: a no-learning baseline of particle fluids in
games and film (van der Laan, Green, Sainz, "Screen space fluid rendering with curvature
flow", I3D 2009; Truong and Yuksel, "A narrow-range filter for screen-space fluid
rendering", I3D 2018).

1. Splats: every ball a sphere of its radius ``r``, the nearest hit per pixel
   (:func:`neurender.metaballs.inputs.sphere_hits`, O(B + covered pixels)); the foreground
   is the pixels any sphere covers, and stays so (the filter never grows the silhouette).
2. Depth smoothing of the foreground's view-space ``z`` (the depth along the optical axis,
   constant on a plane facing the camera), background ``inf``:

   - ``narrow_range`` (Truong and Yuksel): a Gaussian whose samples are taken outward
     from the centre pixel in order of distance, tracking a range ``[lower, upper]``, at
     first ``z_i -/+ mu``; a sample inside the range is averaged and widens it to its own
     ``z -/+ mu`` (the range extension: a slanted surface stays in range); a sample behind
     it (another surface far behind, or the background) gets weight 0, and so does the
     sample mirrored through the centre (so that an edge never tilts the average); a
     sample in front of it is averaged as ``z_i - clamp r`` (a nearer surface pulls the
     pixel forward by at most that). ``mu = depth_range r``.
   - ``bilateral``: Gaussian spatial weights times ``exp(-(z_j - z_i)^2 / (2 s^2))``,
     ``s = depth_range r``, background samples left out.

   ``r`` is the radius of the pixel's (nearest) ball. The filter's radius in pixels is
   ``filter_radius`` times that ball's projected radius ``r f / z_i`` (``f`` the focal
   length in pixels; the papers scale the filter with the screen-space particle radius),
   at most ``max_radius`` pixels; the Gaussian's sigma is a third of it (the reference
   shader's). ``separable`` filters rows then columns (each direction its own range, as
   the 1D shader), else the whole disc at once (one range per pixel, as the 2D shader);
   ``iterations`` repeats it.
3. Normals (van der Laan et al.): view-space positions ``z (x/z, y/z, 1)`` along the pixel
   rays; along each image axis the central difference where the surface is continuous,
   else (a silhouette, or one-sided differences whose ``dz`` differ by more than ``mu``)
   of the forward and backward differences the one of smaller ``|dz|`` (at a silhouette
   the one inside the surface); their cross product, unit, faces the camera. A pixel
   with no foreground neighbour along an axis (a one-pixel sliver) keeps its sphere's
   own normal.
4. Colour: the nearest sphere's colour averaged with the depth filter's own weights in
   every pass (a sample clamped forward keeps its colour), so colours blend where the
   surfaces blend and not across depth discontinuities.

Buffers as :mod:`neurender.metaballs.gbuffers` (depth = distance along the ray, as the
exact renderer's; background ``inf`` before normalisation). Cost: the splats, then
``O(foreground pixels x filter area)`` per pass and ``O(W^2)`` for the normals; no array
ever spans balls times pixels.
"""

from __future__ import annotations

import dataclasses
import math

import torch

from neurender.metaball import Scene
from neurender.metaballs.gbuffers import GBuffers, from_hits
from neurender.metaballs.inputs import sphere_hits
from neurender.metaballs.scenes import FOV_DEG, pixel_rays

METHODS = ("narrow_range", "bilateral")


@dataclasses.dataclass(frozen=True)
class ScreenSpace:
    """One setting of :func:`screen_space_fluid` (its keyword arguments).

    Attributes:
        filter_radius: the filter's radius in projected radii of the pixel's ball.
        iterations: passes of the filter.
        method: one of :data:`METHODS`.
        separable: rows then columns (cheaper) instead of the full disc.
        depth_range: ``mu`` (narrow range) or the range sigma (bilateral), in ball radii.
        clamp: how far (in ball radii) a nearer sample may pull a pixel forward
            (narrow range).
        max_radius: the largest filter radius in pixels.
    """

    filter_radius: float = 3.0
    iterations: int = 1
    method: str = "narrow_range"
    separable: bool = False
    depth_range: float = 2.0
    clamp: float = 1.0
    max_radius: float = 16.0

    @property
    def label(self) -> str:
        kind = "separable" if self.separable else "2D"
        return (
            f"{self.method} {kind}, radius {self.filter_radius:g} r, "
            f"{self.iterations} iteration{'s' if self.iterations != 1 else ''}"
        )


def screen_space_settings() -> list[ScreenSpace]:
    """Settings for an equal-quality sweep, roughly cheap to expensive: the splats'
    depth unfiltered, separable passes, then the full disc, each at growing filter radius
    and iterations, then the bilateral filter and more iterations."""
    settings = [ScreenSpace(filter_radius=0.0)]
    settings += [
        ScreenSpace(filter_radius=radius, iterations=iterations, separable=separable)
        for separable in (True, False)
        for iterations in (1, 2)
        for radius in (1.5, 3.0, 5.0)
    ]
    return [*settings, ScreenSpace(method="bilateral"), ScreenSpace(iterations=3)]


def focal_pixels(width: int) -> float:
    """Focal length in pixels: a view-space ``x / z`` of ``tan(FOV)`` is the image edge."""
    return width / 2 / math.tan(math.radians(FOV_DEG))


@dataclasses.dataclass
class _Foreground:
    """The foreground pixels ``(F,)`` of a ``W x W`` image padded to ``padded_width``.

    Attributes:
        index: ``(F,)`` flat index into the padded image.
        radius: ``(F,)`` filter radius in pixels; ``sigma``: ``(F,)`` its Gaussian's.
        mu: ``(F,)`` the range half-width; ``clamp``: ``(F,)`` the forward clamp distance.
    """

    index: torch.Tensor
    padded_width: int
    radius: torch.Tensor
    sigma: torch.Tensor
    mu: torch.Tensor
    clamp: torch.Tensor


def _offsets(reach: float, separable: bool) -> list[list[tuple[int, int, float]]]:
    """The passes' sample offsets ``(row, column, distance)`` up to ``reach`` pixels, one
    of each mirrored pair (the other is its negation), nearest first: ``separable``: a
    pass along the rows then one along the columns; else one pass over the half disc."""
    pad = math.floor(reach)
    if separable:
        return [
            [(0, k, float(k)) for k in range(1, pad + 1)],
            [(k, 0, float(k)) for k in range(1, pad + 1)],
        ]
    half = [
        (dy, dx, math.hypot(dy, dx))
        for dy in range(0, pad + 1)
        for dx in range(-pad, pad + 1)
        if (dy > 0 or dx > 0) and math.hypot(dy, dx) <= reach
    ]
    return [sorted(half, key=lambda o: (o[2], o[0], o[1]))]


def _narrow_range_pass(
    depth: torch.Tensor,
    colour: torch.Tensor,
    fg: _Foreground,
    offsets: list[tuple[int, int, float]],
    shared: bool,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One narrow-range pass (module docstring) over padded ``depth`` ``(P,)`` (``inf``
    off the foreground) and ``colour`` ``(3, P)``; the foreground's new ``(F,)`` and
    ``(3, F)``. ``shared``: one range per pixel for all samples (2D), else one per side."""
    centre = depth[fg.index]
    lower_clamp = centre - fg.clamp
    upper = [centre + fg.mu] * 2
    lower = [centre - fg.mu] * 2
    total, weights = centre.clone(), torch.ones_like(centre)
    paint = colour[:, fg.index].clone()
    for dy, dx, dist in offsets:
        shift = dy * fg.padded_width + dx
        w = torch.exp(-(dist**2) / (2 * fg.sigma.square())) * (dist <= fg.radius)
        samples, behind = [], []
        for side, index in enumerate((fg.index + shift, fg.index - shift)):
            state = 0 if shared else side
            z = depth[index]
            far = z > upper[state]
            near = z < lower[state]
            inside = ~(far | near)
            upper[state] = torch.where(inside, torch.maximum(upper[state], z + fg.mu), upper[state])
            lower[state] = torch.where(inside, torch.minimum(lower[state], z - fg.mu), lower[state])
            samples.append((torch.where(near, lower_clamp, z), index))
            behind.append(far)
        w = w.masked_fill(behind[0] | behind[1], 0)
        for z, index in samples:
            total += w * z.masked_fill(w == 0, 0)
            paint += w * colour[:, index]
        weights += 2 * w
    return total / weights, paint / weights


def _bilateral_pass(
    depth: torch.Tensor,
    colour: torch.Tensor,
    fg: _Foreground,
    offsets: list[tuple[int, int, float]],
) -> tuple[torch.Tensor, torch.Tensor]:
    """One bilateral pass (module docstring), arguments and results as
    :func:`_narrow_range_pass`."""
    centre = depth[fg.index]
    total, weights = centre.clone(), torch.ones_like(centre)
    paint = colour[:, fg.index].clone()
    for dy, dx, dist in offsets:
        shift = dy * fg.padded_width + dx
        spatial = torch.exp(-(dist**2) / (2 * fg.sigma.square())) * (dist <= fg.radius)
        for index in (fg.index + shift, fg.index - shift):
            z = depth[index]
            hit = torch.isfinite(z)
            gap = torch.where(hit, z - centre, 0.0)
            w = torch.where(hit, spatial * torch.exp(-gap.square() / (2 * fg.mu.square())), 0.0)
            total += w * torch.where(hit, z, 0.0)
            paint += w * colour[:, index]
            weights += w
    return total / weights, paint / weights


def smooth_depth(
    z: torch.Tensor,
    colour: torch.Tensor,
    radius_px: torch.Tensor,
    ball_radius: torch.Tensor,
    method: str = "narrow_range",
    separable: bool = False,
    iterations: int = 1,
    depth_range: float = 2.0,
    clamp: float = 1.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Filter a view-space depth image on its foreground (module docstring, step 2).

    Args:
        z: ``(W, W)`` view-space ``z`` (world units), ``inf`` on the background.
        colour: ``(3, W, W)`` colours, filtered with the depth's weights.
        radius_px: ``(W, W)`` filter radius in pixels (used on the foreground).
        ball_radius: ``(W, W)`` radius ``r`` of each pixel's ball (world units).

    Returns:
        The filtered ``z`` ``(W, W)`` (background still ``inf``) and colour ``(3, W, W)``.
    """
    if method not in METHODS:
        raise ValueError(f"screen-space filter method {method!r}: expected one of {METHODS}")
    if iterations < 0:
        raise ValueError(f"screen-space filter iterations {iterations}: expected >= 0")
    width = z.shape[-1]
    mask = torch.isfinite(z)
    flat = mask.reshape(-1).nonzero().squeeze(1)
    if iterations == 0 or len(flat) == 0:
        return z, colour
    reach = float(radius_px.reshape(-1)[flat].max())
    pad = math.floor(reach)
    if pad <= 0:
        return z, colour
    padded_width = width + 2 * pad
    row, column = flat // width, flat % width
    r = ball_radius.reshape(-1)[flat]
    radius = radius_px.reshape(-1)[flat]
    fg = _Foreground(
        index=(row + pad) * padded_width + column + pad,
        padded_width=padded_width,
        radius=radius,
        sigma=(radius / 3).clamp(min=1e-6),
        mu=depth_range * r,
        clamp=clamp * r,
    )
    depth = torch.nn.functional.pad(z, (pad,) * 4, value=math.inf).reshape(-1)
    paint = torch.nn.functional.pad(colour, (pad,) * 4).reshape(3, -1)
    passes = _offsets(reach, separable)
    for _ in range(iterations):
        for offsets in passes:
            if method == "narrow_range":
                new_z, new_c = _narrow_range_pass(depth, paint, fg, offsets, shared=not separable)
            else:
                new_z, new_c = _bilateral_pass(depth, paint, fg, offsets)
            depth, paint = depth.clone(), paint.clone()
            depth[fg.index], paint[:, fg.index] = new_z, new_c
    inner = (slice(pad, pad + width),) * 2
    return depth.reshape(padded_width, padded_width)[inner], paint.reshape(
        3, padded_width, padded_width
    )[(slice(None), *inner)]


def _difference(
    p: torch.Tensor, axis: int, jump: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The derivative of positions ``p`` ``(3, W, W)`` (non-finite off the surface) along
    image ``axis`` (1: rows, 2: columns) per pixel ``(3, W, W)``, and whether it has one
    ``(W, W)``: the central difference where both neighbours are on the surface and their
    one-sided differences' ``z`` differ by at most ``jump`` ``(W, W)``; else (a silhouette
    or a depth discontinuity) the one-sided difference of smaller ``|dz|``."""
    diff = p.diff(dim=axis)
    after, before = [0, 0, 0, 0], [0, 0, 0, 0]
    after[(2 - axis) * 2 + 1] = 1
    before[(2 - axis) * 2] = 1
    forward = torch.nn.functional.pad(diff, after, value=math.inf)
    backward = torch.nn.functional.pad(diff, before, value=math.inf)
    size_f = forward[2].abs().nan_to_num(nan=math.inf)
    size_b = backward[2].abs().nan_to_num(nan=math.inf)
    smaller = torch.where(size_f <= size_b, forward, backward)
    smooth = (forward[2] - backward[2]).abs() <= jump  # false where either is not finite
    return torch.where(smooth, (forward + backward) / 2, smaller), torch.isfinite(
        torch.minimum(size_f, size_b)
    )


def depth_normals(
    z: torch.Tensor, rays: torch.Tensor, jump: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Outward unit normals ``(3, W, W)`` (view space, facing the camera) of a view-space
    depth image ``z`` ``(W, W)`` (``inf`` on the background) along unit pixel ``rays``
    ``(3, W, W)``, from the derivatives of :func:`_difference` (module docstring, step 3;
    ``jump`` ``(W, W)`` world units); and ``(W, W)`` where both image axes had one."""
    p = rays / rays[2] * z  # (3, W, W); inf (or nan) on the background
    d_col, ok_col = _difference(p, 2, jump)
    d_row, ok_row = _difference(p, 1, jump)
    # Columns run along +x, rows along -y: (+x) x (-y) = -z, towards the camera.
    n = torch.linalg.cross(d_col, d_row, dim=0)
    ok = ok_col & ok_row & torch.isfinite(z)
    n = torch.where(ok, n, 0.0)
    size = n.norm(dim=0)
    return n / size.clamp(min=1e-30), ok & (size > 0)


def screen_space_fluid(
    scene: Scene,
    width: int,
    filter_radius: float = ScreenSpace.filter_radius,
    iterations: int = ScreenSpace.iterations,
    method: str = ScreenSpace.method,
    separable: bool = ScreenSpace.separable,
    depth_range: float = ScreenSpace.depth_range,
    clamp: float = ScreenSpace.clamp,
    max_radius: float = ScreenSpace.max_radius,
) -> GBuffers:
    """The scene's G-buffers by screen-space fluid rendering (module docstring), in the
    scene's dtype and device; the arguments as :class:`ScreenSpace`'s attributes."""
    if filter_radius < 0 or max_radius < 0:
        raise ValueError(
            f"screen-space filter radius {filter_radius} (max {max_radius}): expected >= 0"
        )
    dtype, device = scene.centres.dtype, scene.centres.device
    rays = pixel_rays(width, dtype, device).permute(2, 0, 1).contiguous()  # (3, W, W)
    count = len(scene)
    dist, first = sphere_hits(scene, width, rays.reshape(3, -1))
    missed = first >= count
    ball = first.clamp(max=count - 1)
    z = (dist * rays[2].reshape(-1)).reshape(width, width)  # inf where missed
    radius = scene.radii.index_select(0, ball).reshape(width, width)
    colour = scene.colours.T.index_select(1, ball).masked_fill(missed, 0).reshape(3, width, width)
    radius_px = (filter_radius * radius * focal_pixels(width) / z).nan_to_num(posinf=0.0)
    radius_px = radius_px.clamp(max=max_radius).masked_fill(missed.reshape(width, width), 0)
    z, colour = smooth_depth(
        z, colour, radius_px, radius, method, separable, iterations, depth_range, clamp
    )
    normal, ok = depth_normals(z, rays, depth_range * radius)
    # A sliver without neighbours keeps its sphere's own normal.
    hit_point = rays.reshape(3, -1) * dist.masked_fill(missed, 0)
    sphere = (hit_point - scene.centres.T.index_select(1, ball)) / scene.radii[ball]
    normal = torch.where(ok, normal, sphere.reshape(3, width, width)).reshape(3, -1)
    normal = ((normal + 1) / 2).masked_fill(missed, 0)
    distance = (z / rays[2]).reshape(-1)
    return from_hits(distance, colour.reshape(3, -1), normal, width)
