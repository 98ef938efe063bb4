"""The report's interactive simplification view of one use case: the reference and the
three variants of :mod:`neurender.simplification.evaluate` (QEM, the classic bake, ours) as
textured glTF meshes side by side, captioned with their triangle counts and held-out PSNR.

See :mod:`neurender.viewer_data` (kind ``meshes``) and :mod:`neurender.gltf`. Every mesh
is in the stage's frame (right-handed, y up, the assets' own units), so one camera frames
them all. The reference is the detailed surface the variants were made from: the head in
its uniform grey, the metaball creature with the field's colour per vertex, a user asset
with its own materials (textures over :data:`MAX_TEXTURE` texels downscaled); one of more
than :data:`MAX_REFERENCE_TRIANGLES` triangles is shown decimated, in grey. The variants
are exactly what the evaluation renders (:func:`neurender.simplification.evaluate.variant_maps`)
through the exporter's glTF conventions (:func:`neurender.simplification.export.atlas_primitive`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from PIL import Image

from neurender import gltf, viewer_data
from neurender.display import srgb
from neurender.geometry import vertex_normals
from neurender.simplification import evaluate, export, mesh_ops
from neurender.simplification.assets import Asset
from neurender.simplification.user_mesh import PLAIN_ALBEDO, Part
from neurender.tables import lookup

#: Panel labels of the variants, left to right after the reference.
LABELS = {"qem": "QEM", "baked": "classic bake", "ours": "ours"}
REFERENCE = "reference"
#: Largest side, in texels, of a user reference's texture in the viewer.
MAX_TEXTURE = 512
#: A reference with more triangles is shown decimated to this many (grey), so that one
#: large asset cannot swell the report (about 24 bytes per triangle in the viewer file).
MAX_REFERENCE_TRIANGLES = 200_000


def vertex_corners(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``n_vertices`` vertices a face that uses it ``(V,)`` and the
    barycentric coordinates ``(V, 3)`` of the vertex in that face (a unit vector); a
    vertex no face uses gets face 0 and the first corner."""
    flat = np.asarray(faces).ravel()
    face = np.zeros(n_vertices, np.int64)
    corner = np.zeros(n_vertices, np.int64)
    used, first = np.unique(flat, return_index=True)
    face[used], corner[used] = first // 3, first % 3
    return face, np.eye(3)[corner]


def _texture_png(texture: np.ndarray) -> bytes:
    """A linear ``(H, W, 3)`` texture as an sRGB PNG, its longer side at most
    :data:`MAX_TEXTURE`."""
    image = Image.fromarray(np.round(srgb(texture) * 255).astype(np.uint8))
    if max(image.size) > MAX_TEXTURE:
        image.thumbnail((MAX_TEXTURE, MAX_TEXTURE), Image.Resampling.LANCZOS)
    return gltf.png_bytes(np.asarray(image) / 255.0)


def part_primitive(part: Part, normals: np.ndarray) -> gltf.Primitive:
    """A user asset's part with its albedo (texture, vertex or face colours, or its
    uniform colour) and its ``(n, 3)`` shading normals."""
    albedo = tuple(float(c) for c in part.albedo)
    if part.kind == "texture":
        return gltf.Primitive(
            part.vertices,
            part.faces,
            normals,
            uvs=part.uvs,
            base_colour=albedo,
            base_colour_png=_texture_png(part.texture),
            wrap=gltf.REPEAT,
        )
    if part.kind == "vertex":
        return gltf.Primitive(
            part.vertices, part.faces, normals, colours=part.vertex_colours, base_colour=albedo
        )
    if part.kind == "face":  # one vertex per corner, so that each face keeps its colour
        corners = part.faces.ravel()
        return gltf.Primitive(
            part.vertices[corners],
            np.arange(len(corners)).reshape(-1, 3),
            normals[corners],
            colours=np.repeat(part.face_colours, 3, axis=0),
            base_colour=albedo,
        )
    return gltf.Primitive(part.vertices, part.faces, normals, base_colour=albedo)


def reference_primitives(asset: Asset) -> list[gltf.Primitive]:
    """The detailed surface of a use case as glTF primitives (see the module docstring);
    above :data:`MAX_REFERENCE_TRIANGLES` its QEM decimation to that count, grey."""
    if len(asset.faces) > MAX_REFERENCE_TRIANGLES:
        v, f = mesh_ops.decimate(asset.vertices, asset.faces, MAX_REFERENCE_TRIANGLES)
        return [gltf.Primitive(v, f, vertex_normals(v, f), base_colour=(PLAIN_ALBEDO,) * 3)]
    if asset.source is not None:
        return [
            part_primitive(p, n)
            for p, n in zip(asset.source.parts, asset.source.normals(), strict=True)
        ]
    normals = vertex_normals(asset.vertices, asset.faces)
    primitive = gltf.Primitive(asset.vertices, asset.faces, normals)
    if asset.colour_fn is not None:
        face, bary = vertex_corners(asset.faces, len(asset.vertices))
        primitive.colours = np.clip(asset.colour_fn(asset.vertices, face, bary), 0, 1)
    else:
        grey = PLAIN_ALBEDO if asset.albedo is None else asset.albedo
        primitive.base_colour = (float(grey),) * 3
    return [primitive]


def simplification_view(case: str, asset: Asset, files: dict, metrics: pd.DataFrame) -> dict:
    """The ``meshes`` viewer data of one use case.

    Args:
        asset: the case's reference (:func:`neurender.simplification.assets.load`).
        files: the case's files as
            :func:`neurender.simplification.evaluate.variant_maps` reads them.
        metrics: the evaluation's mean metrics (tidy; ``psnr`` of the ``test`` split).
    """
    meshes = {REFERENCE: gltf.glb(reference_primitives(asset), case)}
    captions = {REFERENCE: f"{len(asset.faces):,} triangles"}
    if len(asset.faces) > MAX_REFERENCE_TRIANGLES:
        captions[REFERENCE] += f" (shown decimated to {MAX_REFERENCE_TRIANGLES:,}, grey)"
    eye = np.eye(4)
    for variant, label in LABELS.items():
        low, positions, albedo, normal_map = evaluate.variant_maps(variant, files)
        primitive = export.atlas_primitive(low, positions, albedo, normal_map, eye)
        meshes[label] = gltf.glb([primitive], f"{case}_{variant}")
        psnr = lookup(metrics, dataset=case, model=variant, split="test", metric="psnr")
        if np.isnan(psnr):
            raise ValueError(f"the metrics table has no held-out psnr of {case} {variant}")
        captions[label] = f"{len(low.faces):,} triangles, held-out PSNR {psnr:.1f} dB"
    return {
        "meshes": {k: viewer_data.b64_bytes(v) for k, v in meshes.items()},
        "captions": captions,
    }
