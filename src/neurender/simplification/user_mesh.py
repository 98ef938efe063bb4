"""A user's mesh file with its material, as the simplification stage reads it.

Formats (read by :func:`neurender.mesh_file.read`, as every method reads a user's mesh):
OBJ with its MTL files and textures, glTF 2.0 (``.gltf`` with its buffers and images, or
``.glb``), PLY (vertex or face colours), OFF, STL. Every mesh of a file (glTF primitives,
OBJ groups with their own material, the instances of a glTF scene graph with their node
transforms) becomes one :class:`Part`; the parts together
are the detailed surface, welded where their vertices coincide (UV seams split vertices
in files, QEM and smooth normals need them joined).

What is read of a material, the base colour (albedo) only:

* glTF: ``baseColorTexture`` times ``baseColorFactor``, or the factor alone, or ``COLOR_0``
  when there is no texture;
* OBJ/MTL: ``map_Kd`` (``Kd`` is ignored when there is a texture, as Blender's importer
  does), else ``Kd``;
* PLY/OFF: vertex or face colours;
* nothing of the above: grey :data:`PLAIN_ALBEDO`.

Normal maps, metallic/roughness, emission and alpha of the file are not read; shading
normals are the area-weighted vertex normals of the welded surface (the file's own
normals are ignored). Every surface is a Lambertian reflector of that albedo.

Colour spaces: textures and 8-bit vertex colours in files are sRGB-encoded and decoded
here (:func:`neurender.display.linear_from_srgb`); glTF's ``baseColorFactor`` and
``COLOR_0`` and MTL's ``Kd`` are linear, as their specifications (and Blender) use them.
Everything this module returns is linear, as Mitsuba's reflectance is.

Texture conventions (those of :mod:`neurender.simplification.render` and
:func:`neurender.mesh_file.sample_bilinear`): arrays ``(H, W, 3)`` with row 0 the image's
top row, texture coordinates ``(u, v)`` with ``v`` pointing down the image (glTF's; OBJ and
trimesh count ``v`` up: :func:`~neurender.mesh_file.image_uv` gives ``v = 1 - v_obj``),
bilinear, repeating.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import ModuleType

import numpy as np
import trimesh

from neurender import asset_files, mesh_file, mitsuba_setup
from neurender.display import linear_from_srgb
from neurender.geometry import vertex_normals
from neurender.mesh_file import image_uv, image_values, sample_bilinear

PLAIN_ALBEDO = 0.5


@dataclasses.dataclass
class Part:
    """One mesh of the file with one material, in the file's world space.

    Attributes:
        vertices, faces: ``(n, 3)`` float64 and ``(m, 3)`` int64.
        albedo: linear ``(3,)`` colour; it multiplies ``texture`` and is the colour where
            there is neither a texture nor vertex or face colours.
        uvs, texture: ``(n, 2)`` texture coordinates and ``(H, W, 3)`` linear texture, or None.
        vertex_colours, face_colours: linear ``(n, 3)`` or ``(m, 3)``, or None.
        normal_texture: ``(H, W, 3)`` tangent-space normal map as stored (values in
            [0, 1]; glTF ``normalTexture`` or MTL ``norm``), or None; not used by the
            references, read back by :mod:`neurender.simplification.export`.
    """

    vertices: np.ndarray
    faces: np.ndarray
    albedo: np.ndarray
    uvs: np.ndarray | None = None
    texture: np.ndarray | None = None
    vertex_colours: np.ndarray | None = None
    face_colours: np.ndarray | None = None
    normal_texture: np.ndarray | None = None

    @property
    def kind(self) -> str:
        """``texture``, ``vertex``, ``face`` or ``constant``: where the albedo comes from."""
        if self.texture is not None:
            return "texture"
        if self.vertex_colours is not None:
            return "vertex"
        return "face" if self.face_colours is not None else "constant"

    def albedo_at(self, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """Linear albedo ``(K, 3)`` at barycentrics ``bary (K, 3)`` of ``faces (K,)``."""
        corners = self.faces[faces]
        if self.kind == "texture":
            uv = np.einsum("kj,kjc->kc", bary, self.uvs[corners])
            return sample_bilinear(self.texture, uv) * self.albedo
        if self.kind == "vertex":
            return np.einsum("kj,kjc->kc", bary, self.vertex_colours[corners]) * self.albedo
        if self.kind == "face":
            return self.face_colours[faces] * self.albedo
        return np.tile(self.albedo, (len(faces), 1))


@dataclasses.dataclass
class UserMesh:
    """A user's asset: its parts and the welded surface they make together.

    Attributes:
        path: the file it was read from.
        parts: the meshes of the file, each with its material.
        vertices, faces: ``(V, 3)``, ``(F, 3)`` welded surface; its faces are the parts'
            faces in order (part 0's first).
        weld: ``(sum n,)`` welded vertex of each part vertex (parts' vertices in order).
    """

    path: str
    parts: list[Part]
    vertices: np.ndarray
    faces: np.ndarray
    weld: np.ndarray

    @property
    def face_part(self) -> tuple[np.ndarray, np.ndarray]:
        """Part index and face index within its part of every welded face, ``(F,)`` each."""
        counts = [len(p.faces) for p in self.parts]
        part = np.repeat(np.arange(len(self.parts)), counts)
        local = np.arange(len(part)) - np.repeat(np.cumsum([0] + counts[:-1]), counts)
        return part, local

    def albedo_at(self, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """Linear albedo ``(K, 3)`` at barycentrics ``bary (K, 3)`` of welded ``faces (K,)``."""
        part, local = self.face_part
        out = np.zeros((len(faces), 3))
        for k, p in enumerate(self.parts):
            mine = part[faces] == k
            if mine.any():
                out[mine] = p.albedo_at(local[faces[mine]], bary[mine])
        return out

    def transformed(self, scale: float, offset: np.ndarray) -> UserMesh:
        """The mesh at ``(x - offset) * scale`` (uniform: normals and UVs are unchanged)."""
        parts = [dataclasses.replace(p, vertices=(p.vertices - offset) * scale) for p in self.parts]
        return dataclasses.replace(self, parts=parts, vertices=(self.vertices - offset) * scale)

    def normals(self) -> list[np.ndarray]:
        """Every part's ``(n, 3)`` shading normals: the welded surface's area-weighted
        vertex normals, so that the shading is smooth across UV seams and parts."""
        welded = vertex_normals(self.vertices, self.faces)[self.weld]
        splits = np.cumsum([len(p.vertices) for p in self.parts])[:-1]
        return np.split(welded, splits)

    def mitsuba_shapes(self, mi: ModuleType) -> list:
        """One Mitsuba mesh per part, Lambertian with the part's albedo: a raw (linear)
        repeating bitmap, a ``vertex_color``/``face_color`` mesh attribute, or an RGB."""
        shapes = []
        for k, (part, normals) in enumerate(zip(self.parts, self.normals(), strict=True)):
            kind = part.kind
            if kind == "texture":
                reflectance = {
                    "type": "bitmap",
                    "raw": True,
                    "data": mi.TensorXf(
                        np.ascontiguousarray(part.texture * part.albedo, dtype=np.float32)
                    ),
                    "wrap_mode": "repeat",
                }
            elif kind in ("vertex", "face"):
                reflectance = {"type": "mesh_attribute", "name": f"{kind}_color"}
            else:
                reflectance = {"type": "rgb", "value": [float(c) for c in part.albedo]}
            shape = mitsuba_setup.mesh(
                mi,
                part.vertices,
                part.faces,
                {"type": "diffuse", "reflectance": reflectance},
                part.uvs if kind == "texture" else None,
                normals,
                name=f"part{k}",
            )
            if kind in ("vertex", "face"):
                colours = part.vertex_colours if kind == "vertex" else part.face_colours
                values = np.ravel(colours * part.albedo).astype(np.float32)
                shape.add_attribute(f"{kind}_color", 3, mi.Float(values))
            shapes.append(shape)
        return shapes


def _factor(values, default: float) -> np.ndarray:
    """A uint8 RGB(A) colour trimesh stores (0..255) as a linear ``(3,)`` in [0, 1]."""
    if values is None:
        return np.full(3, default)
    return np.asarray(values, dtype=np.float64).ravel()[:3] / 255.0


def _part(mesh: trimesh.Trimesh, linear_colours: bool) -> Part:
    """The :class:`Part` of one trimesh mesh (see the module docstring for what is read)."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    part = Part(vertices, faces, np.full(3, PLAIN_ALBEDO))
    visual = mesh.visual
    if visual.kind == "texture":
        material = visual.material
        if isinstance(material, trimesh.visual.material.PBRMaterial):
            image = material.baseColorTexture
            part.albedo = _factor(material.baseColorFactor, 1.0)
            normal = material.normalTexture
        else:  # SimpleMaterial (OBJ/MTL): map_Kd, else Kd
            image = material.image
            part.albedo = np.ones(3) if image is not None else _factor(material.diffuse, 1.0)
            normal = None
        uv = visual.uv
        if uv is not None and len(uv) == len(vertices):
            part.uvs = image_uv(uv)
            if image is not None:
                part.texture = linear_from_srgb(image_values(image))
            if normal is not None:
                part.normal_texture = image_values(normal)
        colours = (
            visual.vertex_attributes.get("color") if hasattr(visual, "vertex_attributes") else None
        )
        if part.texture is None and colours is not None and len(colours) == len(vertices):
            part.vertex_colours = _colours(colours, linear_colours)
    elif visual.kind == "vertex":
        part.albedo = np.ones(3)
        part.vertex_colours = _colours(visual.vertex_colors, linear_colours)
    elif visual.kind == "face":
        part.albedo = np.ones(3)
        part.face_colours = _colours(visual.face_colors, linear_colours)
    return part


def _colours(values: np.ndarray, linear: bool) -> np.ndarray:
    """Stored RGB(A) colours (uint8 0..255 or float 0..1) as linear ``(n, 3)``."""
    values = np.asarray(values)
    rgb = values[:, :3].astype(np.float64)
    if values.dtype.kind in "ui":
        rgb /= 255.0
    return rgb if linear else linear_from_srgb(rgb)


def load(path: str | Path) -> UserMesh:
    """Read a user's asset (see the module docstring).

    Raises:
        AssetFileError: naming the file and what was found (:func:`neurender.mesh_file.read`):
            an unknown suffix, a missing file or a missing or unreadable file it names (MTL,
            texture, buffer), an unreadable file, no faces, face indices out of range,
            non-finite vertices, a degenerate bounding box.
    """
    mesh = mesh_file.read(path, asset_files.TRIMESH_SUFFIXES)
    parts = [_part(m, linear_colours=mesh.linear_colours) for m in mesh.parts]
    vertices = np.concatenate([p.vertices for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    faces = np.concatenate([p.faces + o for p, o in zip(parts, offsets, strict=True)])
    welded, weld = np.unique(vertices, axis=0, return_inverse=True)
    weld = weld.ravel()
    return UserMesh(str(mesh.path), parts, welded, weld[faces], weld)
