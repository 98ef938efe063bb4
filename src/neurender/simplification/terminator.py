"""Shadow-terminator fix for low-poly meshes with smooth vertex normals (Hanika 2021,
"Hacking the shadow terminator", Ray Tracing Gems II ch. 4; Blender Cycles' "shadow
terminator geometry offset").

A flat triangle whose interpolated normal still faces a light can have its geometric
plane turned away from it: its shadow ray then enters the mesh and the point goes black
along a jagged band that follows the triangles. The fix starts the shadow ray from the
point on the smooth surface the vertex normals imply: for hit ``p`` with barycentrics
``b_i`` on a triangle with vertices ``p_i`` and unit normals ``n_i``,
``p' = p - sum_i b_i min(0, (p - p_i) . n_i) n_i`` (``p`` is lifted only where it lies
below a vertex's tangent plane, so concave regions and flat shading are unchanged).

:func:`integrator` registers and configures the Mitsuba integrator ``direct_terminator``:
``direct_projective`` (same parameters, same silhouette gradients) shading every hit from
``p'``, whose alpha channel is the pixel's coverage. The shift is detached, so gradients
with respect to the vertices flow as they do through ``p``.
"""

from __future__ import annotations

import inspect
from types import ModuleType

# Mitsuba and Dr.Jit are passed in, not imported: importing Dr.Jit before
# neurender.mitsuba_setup has pointed it to LLVM leaves it without a CPU backend.

INTEGRATOR = "direct_terminator"
_registered: set[str] = set()


def terminator_offset(mi: ModuleType, dr: ModuleType, si):
    """Detached world-space shift ``p' - p`` (``Vector3f``, zero where ``si`` is not a valid
    hit) of mesh hits ``si`` (``SurfaceInteraction3f``) whose meshes have vertex normals."""
    si = dr.detach(si)
    valid = si.is_valid()
    mesh = mi.MeshPtr(si.shape)
    corners = mesh.face_indices(si.prim_index, valid)
    points = [mesh.vertex_position(corners[k], valid) for k in range(3)]
    normals = [mesh.vertex_normal(corners[k], valid) for k in range(3)]
    # Barycentrics of p in its triangle (the interaction does not keep them).
    e1, e2, ep = points[1] - points[0], points[2] - points[0], si.p - points[0]
    d11, d12, d22 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
    d1p, d2p = dr.dot(e1, ep), dr.dot(e2, ep)
    det = dr.maximum(d11 * d22 - d12 * d12, dr.epsilon(mi.Float))
    b1 = (d22 * d1p - d12 * d2p) / det
    b2 = (d11 * d2p - d12 * d1p) / det
    shift = mi.Vector3f(0.0)
    for b, p_i, n_i in zip((1.0 - b1 - b2, b1, b2), points, normals, strict=True):
        shift -= b * dr.minimum(dr.dot(si.p - p_i, n_i), 0.0) * n_i
    # The vertex buffer may carry gradients; the shift must not (see the module docstring).
    return dr.detach(dr.select(valid, shift, mi.Vector3f(0.0)))


def register(mi: ModuleType, dr: ModuleType) -> None:
    """Register ``direct_terminator`` for the current Mitsuba variant (idempotent)."""
    if mi.variant() in _registered:
        return
    from mitsuba.ad.integrators.direct_projective import DirectProjectiveIntegrator

    signature = inspect.signature(DirectProjectiveIntegrator.sample)

    class DirectTerminatorIntegrator(DirectProjectiveIntegrator):
        def sample(self, *args, **kwargs):
            # Mitsuba calls sample() with its arguments by keyword or by position.
            call = signature.bind(self, *args, **kwargs)
            si = call.arguments.get("si_shade")
            # Mitsuba runs sample() with gradients suspended; they must be resumed around
            # every operation that p's derivative flows through, as the parent does.
            with dr.resume_grad(when=call.arguments["mode"] != dr.ADMode.Primal):
                if si is None:
                    si = call.arguments["scene"].ray_intersect(
                        call.arguments["ray"],
                        ray_flags=mi.RayFlags.All,
                        coherent=True,
                        active=call.arguments["active"],
                    )
                si.p = si.p + terminator_offset(mi, dr, si)
            call.arguments["si_shade"] = si
            radiance, valid, aovs, state = super().sample(*call.args[1:], **call.kwargs)
            # The parent marks every pixel valid; a hit is what an alpha channel should show.
            return radiance, valid & si.is_valid(), aovs, state

    mi.register_integrator(INTEGRATOR, lambda props: DirectTerminatorIntegrator(props))
    _registered.add(mi.variant())


def integrator(mi: ModuleType, dr: ModuleType, spp: int = 0) -> dict:
    """Scene-dict entry of ``direct_terminator`` (registered on first use) with ``spp``
    samples per pixel for the continuous and the primary-silhouette gradients (0 for
    renders that are not differentiated); no indirect-visibility gradients, no guiding."""
    register(mi, dr)
    return {"type": INTEGRATOR, "sppc": spp, "sppp": spp, "sppi": 0, "guiding": "none"}
