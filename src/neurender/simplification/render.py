"""Forward rendering with Mitsuba 3: triangle meshes under one point light, no ambient.

Images are linear RGB radiance with a box pixel filter and a black background; with
``alpha=True`` a fourth channel holds pixel coverage. Materials are Lambertian
(``albedo / pi``), optionally with a tangent-space normal map in Mitsuba's convention:
components along ``(s, t, n)`` with ``n`` the interpolated vertex normal,
``s = normalize(dp/du - n (n . dp/du))`` and ``t = n x s``, stored as ``(m + 1) / 2``.
Texture row ``r`` covers ``v`` in ``[r, r + 1] / H`` (row 0 is ``v = 0``).
"""

from __future__ import annotations

from types import ModuleType

import numpy as np
from tqdm import tqdm

from neurender import camera, mitsuba_setup
from neurender.simplification.mesh_ops import LowPolyMesh
from neurender.simplification.views import View


def bitmap(mi: ModuleType, data: np.ndarray) -> dict:
    """A raw (linear, unconverted) bilinear texture ``(H, W, 3)``."""
    return {
        "type": "bitmap",
        "raw": True,
        "data": mi.TensorXf(np.ascontiguousarray(data, dtype=np.float32)),
        "wrap_mode": "clamp",
    }


def material(
    mi: ModuleType, albedo: float | np.ndarray, normal_map: np.ndarray | None = None
) -> dict:
    """Lambertian BSDF dict: constant grey ``albedo`` or an ``(H, W, 3)`` texture, and an
    optional ``(H, W, 3)`` tangent-space normal map (values in [0, 1])."""
    reflectance = (
        {"type": "rgb", "value": [float(albedo)] * 3} if np.isscalar(albedo) else bitmap(mi, albedo)
    )
    bsdf = {"type": "diffuse", "reflectance": reflectance}
    if normal_map is None:
        return bsdf
    return {"type": "normalmap", "normalmap": bitmap(mi, normal_map), "bsdf": bsdf}


def atlas_shape(mi: ModuleType, low: LowPolyMesh, bsdf: dict, positions: np.ndarray | None = None):
    """The atlas mesh of ``low`` (welded ``positions (V, 3)``, default its own) with smooth
    normals across UV seams (:meth:`LowPolyMesh.atlas_normals`)."""
    return mitsuba_setup.mesh(
        mi,
        low.atlas_positions(positions),
        low.uv_faces,
        bsdf,
        low.uvs,
        low.atlas_normals(positions),
    )


def scene_dict(
    mi: ModuleType,
    shape,
    view: View,
    width: int,
    spp: int,
    intensity: float,
    integrator: dict | None = None,
    alpha: bool = True,
    sample_border: bool = False,
) -> dict:
    """Scene of one shape (or a list of shapes: keys ``shape``, ``shape_1``, ...), a
    perspective sensor and a point light of radiant ``intensity``; ``integrator`` defaults
    to Mitsuba's ``direct``, and ``sample_border`` lets samples fall just outside the film
    (the projective integrator needs them for silhouettes)."""
    scene = {
        "type": "scene",
        "integrator": integrator or {"type": "direct"},
        "sensor": camera.sensor(mi, view, width, spp, alpha, sample_border),
        "light": {"type": "point", "position": list(view.light), "intensity": intensity},
    }
    for k, one in enumerate(shape if isinstance(shape, list) else [shape]):
        scene["shape" if k == 0 else f"shape_{k}"] = one
    return scene


def set_view(mi: ModuleType, params, view: View) -> None:
    """Move the sensor and the light of a loaded scene to ``view`` (no update call)."""
    params["sensor.to_world"] = mi.Transform4f(camera.look_at(mi, view).matrix)
    params["light.position"] = mi.Point3f(*view.light)


def render_views(
    mi: ModuleType,
    shape,
    views: list[View],
    width: int,
    spp: int,
    intensity: float,
    seed: int,
    desc: str = "render",
    integrator: dict | None = None,
) -> np.ndarray:
    """Render ``shape`` (one or a list) from every view: ``(N, W, W, 4)`` float32 RGBA
    (alpha = coverage)."""
    scene = mi.load_dict(scene_dict(mi, shape, views[0], width, spp, intensity, integrator))
    params = mi.traverse(scene)
    images = []
    for i, view in enumerate(tqdm(views, desc=desc, mininterval=5)):
        set_view(mi, params, view)
        params.update()
        images.append(np.array(mi.render(scene, seed=seed + i), dtype=np.float32))
    return np.stack(images)
