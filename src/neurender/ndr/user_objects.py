"""Your objects through NDR: meshes with their materials from the files users bring, and
their renders under the test maps, the real-world-like maps and the user's maps.

Loading (:func:`load_user_object`, through :func:`neurender.mesh_file.read` as every
method reads a user's mesh): whatever trimesh loads (OBJ + MTL + textures, glTF/GLB, PLY,
OFF, STL) and the VTK formats through PyVista (``.vtk``, ``.vtp``, ``.vtu``). One
object is every triangle mesh of the file (a glTF scene's nodes with their transforms),
normalised to the unit sphere like the procedural objects (:mod:`neurender.ndr.objects`:
bounding-box centre at the origin, farthest vertex at distance 1), in the file's own axes
(the camera looks along -z with +y up, glTF's convention). Shading normals are the smooth
vertex normals of the mesh welded by position, so a seam of split UVs does not show.

Per-vertex materials, in the conventions of :mod:`neurender.ndr.objects` (linear RGB):

* base colour ``b``: the base-colour texture (glTF ``baseColorTexture``, MTL ``map_Kd``;
  8-bit sRGB, decoded) sampled bilinearly at the vertex's UV (wrapping), times the glTF
  ``baseColorFactor``; without a texture, the vertex colours (PLY and VTK ``RGB`` arrays:
  8-bit sRGB, decoded; glTF ``COLOR_0`` of a mesh without material: linear, as glTF
  specifies), else the material's factor (glTF base colour, MTL ``Kd``, linear), else
  ``defaults["base_colour"]``. An MTL's ``Kd`` does not tint its
  ``map_Kd`` (exporters disagree on it; trimesh writes 0.4 beside every texture).
* glTF metallic-roughness, where the material has a metallic or roughness factor or a
  metallic-roughness texture (its B and G channels scale the factors; a missing factor is
  glTF's 1): metallic ``m``, roughness ``rho``, mapped as the glTF specification's BRDF
  (Appendix B) to the two lobes of NDR's ``I_R = I_S A_S + I_D A_D``: ``A_D = b (1 - m)
  (1 - 0.04)``, ``A_S = 0.04 (1 - m) + b m`` (the normal-incidence Fresnel ``F0``: our GGX
  lobe has Fresnel = 1, so the specular albedo is ``F0``), ``roughness = rho`` (glTF's
  ``alpha = rho^2`` is ours), clamped to [0.05, 1] as the training objects are.
* otherwise (PLY, VTK, MTL, a glTF material without metallic-roughness values):
  ``A_D = b``, ``A_S = defaults["specular"]`` (grey), ``roughness = defaults["roughness"]``.
  An MTL's ``Ks`` and ``Ns`` are not read (exporters write placeholders).

Rendering (:func:`render_object`): the fixed NDR camera, Mitsuba's reference at
``reference_spp`` and the coarse shading, exactly as a test sample
(:mod:`neurender.ndr.data`).
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import trimesh

from neurender import mesh_file, rng
from neurender.display import linear_from_srgb
from neurender.geometry import vertex_normals
from neurender.ndr import MESH_SUFFIXES, data, environments, render
from neurender.ndr.buffers import light_features, stack_samples
from neurender.ndr.evaluate import predict, score
from neurender.ndr.model import SHADING_INPUT, NDRModel, compose, shading_input
from neurender.ndr.objects import ProceduralObject

#: The dielectric normal-incidence reflectance of the glTF metallic-roughness model.
DIELECTRIC_F0 = 0.04
#: The roughness range of the training objects (:mod:`neurender.ndr.objects`).
ROUGHNESS_RANGE = (0.05, 1.0)
#: The map sets a user object is rendered under, in the order of the tables.
MAP_SETS = ("test maps", "real-world-like maps", "your maps")
#: The ``dataset`` label of the rows.
DATASET = "your objects"


@dataclasses.dataclass
class UserObject(ProceduralObject):
    """A user's mesh with per-vertex materials (fields of :class:`ProceduralObject`;
    ``n_primitives`` is the number of meshes in the file)."""

    @functools.cached_property
    def normals(self) -> np.ndarray:
        """Smooth unit vertex normals ``(V, 3)`` float64 of the mesh welded by position."""
        _, first, inverse = np.unique(
            self.vertices.round(6), axis=0, return_index=True, return_inverse=True
        )
        welded = np.asarray(self.vertices[first], np.float64)
        return vertex_normals(welded, inverse.reshape(-1)[self.faces])[inverse.reshape(-1)]


@dataclasses.dataclass
class Material:
    """Per-vertex ``base`` ``(V, 3)`` linear colour, and ``metallic``, ``roughness``
    ``(V,)`` where the mesh has glTF metallic-roughness values (else ``None``)."""

    base: np.ndarray
    metallic: np.ndarray | None = None
    roughness: np.ndarray | None = None


def _sample(picture, uv: np.ndarray) -> np.ndarray:
    """A PIL image's stored values ``(V, 3)`` (not decoded) sampled bilinearly at trimesh's
    texture coordinates ``uv`` ``(V, 2)``, wrapping (glTF's default sampler)."""
    return mesh_file.sample_bilinear(
        mesh_file.image_values(picture, np.float64), mesh_file.image_uv(uv)
    )


def _factor(colour, default: np.ndarray) -> np.ndarray:
    if colour is None:
        return default
    return np.asarray(colour, np.float64)[:3] / 255.0


def piece_material(mesh: trimesh.Trimesh, defaults: dict, srgb_colours: bool = True) -> Material:
    """The per-vertex material of one trimesh mesh (rules in the module docstring);
    ``srgb_colours``: its 8-bit vertex colours are sRGB-encoded (PLY, VTK), not linear
    (glTF's ``COLOR_0``)."""
    count = len(mesh.vertices)
    default = np.asarray(defaults["base_colour"], np.float64)
    visual = mesh.visual
    if visual.kind in ("vertex", "face"):
        colours = np.asarray(visual.vertex_colors, np.float64)[:, :3] / 255.0
        return Material(linear_from_srgb(colours) if srgb_colours else colours)
    if not isinstance(visual, trimesh.visual.TextureVisuals) or visual.material is None:
        return Material(np.broadcast_to(default, (count, 3)).copy())
    material, uv = visual.material, visual.uv
    has_uv = uv is not None and len(uv) == count
    if isinstance(material, trimesh.visual.material.PBRMaterial):
        base = np.broadcast_to(_factor(material.baseColorFactor, np.ones(3)), (count, 3)).copy()
        if material.baseColorTexture is not None and has_uv:
            base *= linear_from_srgb(_sample(material.baseColorTexture, uv))
        elif material.baseColorFactor is None:
            base[:] = default
        mr_texture = material.metallicRoughnessTexture if has_uv else None
        if (
            material.metallicFactor is None
            and material.roughnessFactor is None
            and (mr_texture is None)
        ):
            return Material(base)
        metallic = np.full(
            count, 1.0 if material.metallicFactor is None else material.metallicFactor
        )
        rough = np.full(
            count, 1.0 if material.roughnessFactor is None else material.roughnessFactor
        )
        if mr_texture is not None:
            texel = _sample(mr_texture, uv)
            metallic, rough = metallic * texel[:, 2], rough * texel[:, 1]
        return Material(base, metallic, rough)
    image = getattr(material, "image", None)
    if image is not None and has_uv:
        return Material(linear_from_srgb(_sample(image, uv)))
    return Material(
        np.broadcast_to(_factor(getattr(material, "diffuse", None), default), (count, 3)).copy()
    )


def lobes(material: Material, defaults: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``albedo_diffuse`` ``(V, 3)``, ``albedo_specular`` ``(V, 3)`` and ``roughness``
    ``(V,)``, float32, of a material (the glTF mapping of the module docstring, or the
    ``defaults``' specular albedo and roughness)."""
    base = np.clip(material.base, 0, 1)
    count = len(base)
    if material.metallic is None:
        specular = np.full((count, 3), defaults["specular"])
        rough = np.full(count, defaults["roughness"])
        diffuse = base
    else:
        m = np.clip(material.metallic, 0, 1)[:, None]
        diffuse = base * (1 - m) * (1 - DIELECTRIC_F0)
        specular = DIELECTRIC_F0 * (1 - m) + base * m
        rough = material.roughness
    return (
        diffuse.astype(np.float32),
        np.clip(specular, 0, 1).astype(np.float32),
        np.clip(rough, *ROUGHNESS_RANGE).astype(np.float32),
    )


def load_user_object(path: str | Path, defaults: dict) -> UserObject:
    """A user's mesh file as an object with per-vertex materials, normalised to the unit
    sphere (module docstring).

    Args:
        defaults: ``base_colour`` (3 linear values), ``specular`` and ``roughness`` for
            what the file does not say (``ndr.user_object_defaults``).

    Raises:
        AssetFileError: naming the file and what was found (:func:`neurender.mesh_file.read`).
    """
    mesh = mesh_file.read(path, MESH_SUFFIXES)
    srgb = not mesh.linear_colours
    materials = [lobes(piece_material(p, defaults, srgb), defaults) for p in mesh.parts]
    v, faces = mesh.merged()
    v = v - (v.min(0) + v.max(0)) / 2
    v /= np.linalg.norm(v, axis=1).max()
    ad, as_, rough = (np.concatenate(lobe) for lobe in zip(*materials, strict=True))
    return UserObject(
        vertices=v.astype(np.float32),
        faces=faces.astype(np.int32),
        albedo_diffuse=ad,
        albedo_specular=as_,
        roughness=rough,
        n_primitives=len(mesh.parts),
    )


@dataclasses.dataclass(frozen=True)
class MapEntry:
    """One map a user object is rendered under: its set (:data:`MAP_SETS`), name and
    image ``(H, 2H, 3)``."""

    map_set: str
    name: str
    image: np.ndarray


def object_maps(cfg: dict) -> list[MapEntry]:
    """The maps every user object is rendered under: those of the first
    ``user_object_maps`` test samples and as many real-world-like test samples (replayed
    from their seeds, :func:`neurender.ndr.data.sample_scene`), then every user map
    (resized to ``environment_height`` rows, as loaded; checked first)."""
    count = cfg["user_object_maps"]
    entries = []
    for split, map_set, total in (
        ("test", MAP_SETS[0], cfg["test_samples"]),
        ("sunlit_test", MAP_SETS[1], cfg["sunlit_samples"]),
    ):
        for i in range(min(count, total)):
            _, image, name, _ = data.sample_scene(cfg, split, i)
            entries.append(MapEntry(map_set, f"{split} {i} ({name})", image))
    if cfg["user_probes_dir"]:
        for path in environments.check_user_probes(
            cfg["user_probes_dir"], cfg["environment_height"]
        ):
            entries.append(
                MapEntry(
                    MAP_SETS[2], path.stem, environments.user_map(path, cfg["environment_height"])
                )
            )
    return entries


def render_object(
    mi, cfg: dict, name: str, obj: ProceduralObject, entry: MapEntry
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """One user object under one map, as a test sample: its EXR channels (format of
    :mod:`neurender.ndr.buffers`, without the noisy render) and SH vector ``(75,)``."""
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    g = render.g_buffers(obj, view, cfg["width"])
    key = rng.stable_seed(cfg["seed"], "ndr-user", name, entry.map_set, entry.name)
    seed = int(np.random.default_rng(key).integers(2**30))
    maps = render.shading_maps(mi, obj, entry.image, view, cfg["width"], cfg["reference_spp"], seed)
    s_d, s_s = data.coarse_maps(cfg, g, entry.image, "user", name, entry.map_set, entry.name)
    return data.sample_channels(g, s_d, s_s, maps), environments.sh_features(entry.image)


def description(obj: ProceduralObject) -> dict[str, float]:
    """What the loader made of a mesh, for the log: counts and mean material values."""
    return {
        "meshes": obj.n_primitives,
        "vertices": len(obj.vertices),
        "triangles": len(obj.faces),
        "mean_albedo_diffuse": float(obj.albedo_diffuse.mean()),
        "mean_albedo_specular": float(obj.albedo_specular.mean()),
        "mean_roughness": float(obj.roughness.mean()),
        "mean_edge": float(
            np.linalg.norm(
                obj.vertices[obj.faces[:, 0]] - obj.vertices[obj.faces[:, 1]], axis=1
            ).mean()
        ),
    }


@dataclasses.dataclass
class ObjectScores:
    """Scored renders of user objects: tidy ``rows`` per map (keys ``object``, ``map``),
    the ``truth`` and every method's HDR images ``(N, 3, H, W)`` and the ``buffers``."""

    rows: list[dict]
    truth: dict[str, torch.Tensor]
    methods: dict[str, dict[str, torch.Tensor]]
    buffers: dict[str, torch.Tensor]


def score_objects(
    renders: list[tuple[dict[str, np.ndarray], np.ndarray]],
    labels: list[tuple[str, MapEntry]],
    model: NDRModel,
    erosion: int,
    device: torch.device,
) -> ObjectScores:
    """NDR and the shading input against Mitsuba on every render (``renders`` of
    :func:`render_object`, ``labels`` their ``(object, map)``), as the test sets are scored
    (:func:`neurender.ndr.evaluate.score`)."""
    b = stack_samples([r[0] for r in renders], erosion)
    light = light_features(np.stack([r[1] for r in renders]))
    items = [{"light": light[i], **{g: v[i] for g, v in b.items()}} for i in range(len(light))]
    truth = compose(b["I_D"], b["I_S"], b)
    methods = {"ndr": predict(model, items, device), SHADING_INPUT: shading_input(b)}
    rows = []
    for method, images in methods.items():
        for metric, values in score(images, truth, b["mask"]).items():
            rows += [
                {
                    "method": "ndr",
                    "dataset": DATASET,
                    "model": method,
                    "split": entry.map_set,
                    "object": name,
                    "map": entry.name,
                    "metric": metric,
                    "value": float(value),
                }
                for (name, entry), value in zip(labels, values, strict=True)
            ]
    return ObjectScores(rows, truth, methods, b)


def mean_rows(per_map: pd.DataFrame) -> pd.DataFrame:
    """Per object and map set, the mean of each metric over the maps (tidy)."""
    keys = ["method", "dataset", "model", "split", "object", "metric"]
    return per_map.groupby(keys, as_index=False, sort=False)["value"].mean()
