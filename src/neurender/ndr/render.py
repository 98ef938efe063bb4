"""Ground truth and G-buffers of one NDR scene: an object under a distant environment map.

Camera: perspective, fixed at ``(0, 0, distance)`` looking at the origin with +y up, so
world space *is* view space (x right, y up, z towards the viewer) and the SH light input
needs no rotation. Objects fit the unit sphere, so linear depth along the view axis lies
in ``[distance - 1, distance + 1]``; the depth buffer maps that range to [0, 1] with
background 1.

Ground truth is Mitsuba 3's ``direct`` integrator (direct illumination with occlusion,
MIS between emitter and BSDF samples, box pixel filter):

* ``I_D``: every surface a white Lambertian (``reflectance = 1``), so ``I_D`` is the
  cosine-weighted, visibility-masked irradiance over pi;
* ``I_S``: every surface a GGX microfacet reflector with Fresnel = 1 and the per-vertex
  ``alpha = roughness^2``, so ``I_R = I_S * A_S + I_D * A_D`` exactly (paper eq. 2).

G-buffers are point-sampled at pixel centres by Embree with barycentric interpolation of
the same per-vertex data Mitsuba shades (smooth vertex normals, roughness, albedos).
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from neurender import mitsuba_setup
from neurender.camera import Camera, pixel_rays, sensor
from neurender.ndr.objects import ProceduralObject
from neurender.raytrace import embree_scene, first_hits


def camera(distance: float, fov: float) -> Camera:
    """The fixed NDR camera."""
    return Camera((0.0, 0.0, float(distance)), (0.0, 0.0, 0.0), fov)


def object_mesh(mi: ModuleType, obj: ProceduralObject, bsdf: dict):
    """The object as a Mitsuba mesh with its smooth vertex normals and the per-vertex GGX
    width ``vertex_alpha = roughness^2`` that :data:`SPECULAR_BSDF` reads."""
    mesh = mitsuba_setup.mesh(mi, obj.vertices, obj.faces, bsdf, normals=obj.normals, name="object")
    mesh.add_attribute("vertex_alpha", 1, np.ravel(obj.roughness.astype(np.float32) ** 2))
    return mesh


DIFFUSE_BSDF = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
SPECULAR_BSDF = {
    "type": "roughconductor",
    "distribution": "ggx",
    "material": "none",
    "specular_reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
    "alpha": {"type": "mesh_attribute", "name": "vertex_alpha"},
}
# One scene renders both maps: a blend whose weight is 0 (diffuse) or 1 (specular) is
# exactly one lobe, and switching it costs no scene rebuild (half the time per sample).
_SWITCH_KEY = "object.bsdf.weight.value"


def shading_scene(
    mi: ModuleType,
    obj: ProceduralObject,
    environment: np.ndarray,
    view: Camera,
    width: int,
    spp: int,
):
    """The Mitsuba scene of both shading maps of ``obj`` under ``environment`` at ``spp``
    samples per pixel, set to the diffuse lobe (see :func:`render_shading`)."""
    bsdf = {"type": "blendbsdf", "weight": 0.0, "diffuse": DIFFUSE_BSDF, "specular": SPECULAR_BSDF}
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct", "hide_emitters": True},
            "sensor": sensor(mi, view, width, spp),
            "environment": {
                "type": "envmap",
                "bitmap": mi.Bitmap(mitsuba_setup.envmap_rows(environment)),
            },
            "object": object_mesh(mi, obj, bsdf),
        }
    )


def render_shading(
    mi: ModuleType, scene, seed: int, specular: bool = True
) -> dict[str, np.ndarray]:
    """``I_D``, ``I_S`` and coverage (as :func:`shading_maps`) of a :func:`shading_scene`,
    which is left set to the diffuse lobe again, so it can be rendered any number of times."""
    image = np.array(mi.render(scene, seed=seed), dtype=np.float32)
    out = {"I_D": image[..., :3], "coverage": image[..., 3]}
    if specular:
        params = mi.traverse(scene)
        params[_SWITCH_KEY] = 1.0
        params.update()
        out["I_S"] = np.array(mi.render(scene, seed=seed + 1), dtype=np.float32)[..., :3]
        params[_SWITCH_KEY] = 0.0
        params.update()
    else:
        out["I_S"] = np.zeros_like(out["I_D"])
    return out


def shading_maps(
    mi: ModuleType,
    obj: ProceduralObject,
    environment: np.ndarray,
    view: Camera,
    width: int,
    spp: int,
    seed: int,
    specular: bool = True,
) -> dict[str, np.ndarray]:
    """Ray-traced ``I_D`` and ``I_S`` ``(W, W, 3)`` float32 linear radiance and the pixel
    coverage ``(W, W)``; ``I_S`` is zero (and not rendered) when ``specular`` is False."""
    scene = shading_scene(mi, obj, environment, view, width, spp)
    return render_shading(mi, scene, seed, specular)


def g_buffers(obj: ProceduralObject, view: Camera, width: int) -> dict[str, np.ndarray]:
    """Screen-space buffers at pixel centres, row 0 at the top.

    Returns float32 arrays: ``normal`` ``(W, W, 3)`` unit view-space shading normals (0 off
    the object), ``view_dir`` ``(W, W, 3)`` unit vectors from the surface to the eye,
    ``depth`` ``(W, W)`` in [0, 1] (1 off the object), ``roughness`` ``(W, W)``,
    ``albedo_diffuse`` and ``albedo_specular`` ``(W, W, 3)``, ``mask`` ``(W, W)`` in {0, 1}.
    """
    dirs = pixel_rays(view, width).reshape(-1, 3).astype(np.float32)
    origins = np.broadcast_to(np.asarray(view.origin, np.float32), dirs.shape)
    hits = first_hits(embree_scene(obj.vertices, obj.faces), obj.faces, origins, dirs)

    def interpolate(values: np.ndarray) -> np.ndarray:
        return hits.interpolate(values).reshape(width, width, -1)

    normal = interpolate(obj.normals)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    forward = -np.asarray(view.origin, np.float64) / np.linalg.norm(view.origin)
    z = (hits.distance * (dirs @ forward)).reshape(width, width)
    distance = float(np.linalg.norm(view.origin))
    m = hits.mask.reshape(width, width)
    return {
        "normal": normal,
        "view_dir": (-dirs).reshape(width, width, 3),
        "depth": np.where(m, np.clip((z - (distance - 1)) / 2, 0, 1), 1.0).astype(np.float32),
        "roughness": interpolate(obj.roughness)[..., 0],
        "albedo_diffuse": interpolate(obj.albedo_diffuse),
        "albedo_specular": interpolate(obj.albedo_specular),
        "mask": m.astype(np.float32),
    }
