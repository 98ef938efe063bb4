"""One reader of a user's mesh file for every method (DeepPRT's frames, NDR's objects, the
simplification's assets), one texture sampler and one texture decoder.

Formats: what trimesh reads (:data:`neurender.asset_files.TRIMESH_SUFFIXES`: OBJ with its
MTL files and textures, glTF/GLB, PLY, OFF, STL) and VTK's formats through PyVista
(:data:`~neurender.asset_files.VTK_SUFFIXES`: the surface, triangulated; an 8-bit ``RGB``,
``RGBA`` or ``Colors`` point array becomes vertex colours).

Parts (:attr:`MeshFile.parts`): every triangle mesh of the file as written (trimesh's
merging and clean-up off), with its scene-graph node transform applied (trimesh's scene
flattening), in the file's order, each with the visual trimesh gives it: texture visuals
with the file's material (glTF ``PBRMaterial``, MTL ``SimpleMaterial``) and texture
coordinates, or colour visuals (vertex or face colours, or none). A material trimesh makes
up where the file has none (a 2 x 2 grey image for texture coordinates without a material)
is dropped: such a part has plain colour visuals.

Textures are found and read here, not by trimesh: trimesh 5 refuses files that resolve
outside the asset's folder (a ``../`` name, files that are symbolic links into another
folder), falls back to a file of the same name in the asset's folder, and puts a grey image
in place of what it cannot read, all without a word. Every texture a file names (MTL
``map_Kd`` and ``norm``, glTF images, a PLY's ``TextureFile``) is found by
:func:`neurender.asset_files.named_file` (the rule of the DAG-time check) and decoded in
full; one that cannot be (missing, not an image, truncated, over Pillow's pixel limit
``PIL.Image.MAX_IMAGE_PIXELS``) is an :class:`AssetFileError` naming the file that names
it, the texture and the reason. A part whose material has a texture must have texture
coordinates.

A glTF's extensions and the texture coordinates its textures sample (``texCoord``,
``KHR_texture_transform``) are settled by :mod:`neurender.gltf_file` before trimesh reads
it: a required extension the reader does not honour is refused, a transform is applied
once, textures of one material at different coordinates are refused.

A glTF whose meshes are Draco-compressed (``KHR_draco_mesh_compression``) is decoded by
DracoPy (in trimesh); it is refused, naming the file and the mesh and primitive, when
DracoPy is missing or cannot decode the data (trimesh would log it and read zeros).

Checked once, here: faces index existing vertices (none negative, none past the last; an
OBJ's relative, negative indices are refused rather than read wrongly), the vertices
triangles use are finite, their bounding box spans at least two axes.

Repaired once, here, with a logged warning naming the file:

* vertices no triangle uses (left behind where faces were deleted) are dropped, so every
  method places and sizes the object by its surface (a warning where they lie outside the
  surface's bounding box: they would have moved it; a glTF's primitives that share one
  vertex list leave each part unused vertices inside it, logged at info level). Vertex
  indices change only where vertices are dropped, the same way in every file with the
  same triangles (the frames of a DeepPRT sequence).
* the winding (:func:`neurender.geometry.winding_flips`; not where the caller orients
  the surface itself, ``orient=False``: DeepPRT's geometry image): a closed surface wound
  inside out (negative signed volume, every normal inward, as a mirrored export or a CAD
  tool can write it) is flipped, an open surface's triangles wound against most of their
  neighbours are flipped to match them. Flipping reverses a triangle's corners (texture
  coordinates and colours stay with their vertices). The parts carry no vertex normals
  from the file (trimesh's scene flattening drops them): the normals the methods shade
  with are computed from the triangles, so they follow the repaired winding.

Texture conventions: an image array ``(H, W, C)`` has row 0 at the image's top. trimesh
gives texture coordinates with ``v`` up, OBJ's convention, for every format (it flips
glTF's on reading); :func:`sample_bilinear` takes image coordinates, ``v`` down the image
(row 0 at ``v = 0``: glTF's and Mitsuba's convention), and :func:`image_uv` converts
trimesh's to them.
"""

from __future__ import annotations

import base64
import dataclasses
import logging
import re
import struct
import warnings
from io import BytesIO
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import trimesh
from PIL import Image

from neurender import asset_files, gltf_file, user_paths
from neurender.asset_files import AssetFileError
from neurender.geometry import winding_flips

log = logging.getLogger(__name__)

#: A bounding box counts as degenerate when its second-largest extent is below this
#: fraction of its largest (a point or a line segment: no surface to render).
FLAT_TOLERANCE = 1e-6
#: Point arrays of a VTK file read as 8-bit vertex colours, in order of preference.
VTK_COLOURS = ("RGB", "RGBA", "Colors")
#: glTF material textures a part needs texture coordinates for.
PBR_TEXTURES = ("baseColorTexture", "metallicRoughnessTexture", "normalTexture")

_OBJ_VERTEX = re.compile(rb"^[ \t]*v[ \t]", re.M)
_OBJ_UV = re.compile(rb"^[ \t]*vt[ \t]", re.M)
_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]+([^\r\n#]*)", re.M)
_CORNER_VERTEX = re.compile(rb"(?:^|[ \t])([-+]?\d+)", re.M)
_CORNER_UV = re.compile(rb"(?:^|[ \t])[-+]?\d+/([-+]?\d+)", re.M)
_MAP_KD = re.compile(rb"^[ \t]*map_kd[ \t].*$", re.M | re.I)


@dataclasses.dataclass
class MeshFile:
    """A user's mesh file as read (module docstring).

    Attributes:
        path: the file.
        parts: its triangle meshes, node transforms applied, each with ``(n, 3)`` float64
            vertices, ``(m, 3)`` int64 faces indexing them, and its visual.
    """

    path: Path
    parts: list[trimesh.Trimesh]

    @property
    def linear_colours(self) -> bool:
        """Whether 8-bit vertex colours are linear (glTF's ``COLOR_0``, as its specification
        says) rather than sRGB-encoded (PLY, OFF, VTK, OBJ)."""
        return self.path.suffix.lower() in (".glb", ".gltf")

    def merged(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertices ``(V, 3)`` float64 and triangles ``(F, 3)`` int64 of all parts together
        (the parts' vertices in order, their faces offset to match)."""
        offsets = np.cumsum([0] + [len(p.vertices) for p in self.parts[:-1]])
        vertices = np.concatenate([np.asarray(p.vertices, np.float64) for p in self.parts])
        faces = [
            np.asarray(p.faces, np.int64) + o for p, o in zip(self.parts, offsets, strict=True)
        ]
        return vertices, np.concatenate(faces)


def read(
    path: str | Path,
    suffixes: tuple[str, ...] = asset_files.TRIMESH_SUFFIXES + asset_files.VTK_SUFFIXES,
    materials: bool = True,
    orient: bool = True,
) -> MeshFile:
    """Read a user's mesh file (module docstring).

    Args:
        suffixes: the formats the caller reads.
        materials: read the materials and textures (and require the files the mesh names);
            ``False`` reads the geometry only (the parts' visuals are then undefined).
        orient: repair the winding (module docstring); ``False`` keeps the file's, for a
            caller that orients the surface itself once for several files (DeepPRT's
            sequences: one orientation for every frame).

    Raises:
        AssetFileError: naming the file and what was found: an unknown suffix, no such file
            (or a folder, a FIFO ...), a missing or unreadable file it names, an unreadable
            file, Draco data that cannot be decoded, no faces, face indices out of range,
            non-finite vertices, a degenerate bounding box, a texture without texture
            coordinates.
    """
    path = asset_files.check(path, suffixes, named=materials)
    if path.suffix.lower() in asset_files.VTK_SUFFIXES:
        parts = [_vtk_part(path)]
    else:
        parts = _trimesh_parts(path, materials)
    _check_surface(path, parts)
    _drop_unused(path, parts)
    if orient:
        _orient(path, parts)
    return MeshFile(path, parts)


def image_values(image: Image.Image, dtype=np.float32) -> np.ndarray:
    """A PIL image as ``(H, W, 3)`` values in [0, 1] of ``dtype``, still encoded as stored
    (8 or 16 bit; grey is repeated in three channels, alpha is dropped); row 0 is the
    image's top row."""
    if image.mode in ("I;16", "I;16L", "I;16B", "I"):
        grey = np.asarray(image, dtype=dtype) / dtype(65535.0)
        return np.repeat(grey[..., None], 3, axis=-1)
    return np.asarray(image.convert("RGB"), dtype=dtype) / dtype(255.0)


def image_uv(uv: np.ndarray) -> np.ndarray:
    """trimesh's texture coordinates ``(K, 2)`` (``v`` up, OBJ's convention) as image
    coordinates (``v`` down: :func:`sample_bilinear`'s), float64: ``(u, 1 - v)``."""
    uv = np.asarray(uv, np.float64)
    return np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])


def sample_bilinear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup with repeat wrapping (glTF's default sampler; Mitsuba's ``bitmap``
    texture with ``wrap_mode: repeat``).

    Args:
        texture: ``(H, W, C)``, row 0 at ``v = 0``; texel ``(r, c)`` is centred at
            ``((c + 0.5) / W, (r + 0.5) / H)``.
        uv: ``(K, 2)`` image coordinates (``v`` down the image; :func:`image_uv` converts
            trimesh's).

    Returns:
        ``(K, C)`` float64 values.
    """
    h, w = texture.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    c0, r0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    top = texture[r0, c0] * (1 - fx) + texture[r0, c1] * fx
    bottom = texture[r1, c0] * (1 - fx) + texture[r1, c1] * fx
    return top * (1 - fy) + bottom * fy


def load_image(source: Path | bytes, mesh: Path, what: str) -> Image.Image:
    """The image in file or bytes ``source``, decoded in full.

    Args:
        mesh, what: for the message: the mesh file, and the texture as its file names it
            (``/a/box.mtl names wood.png (/a/../textures/wood.png)``).

    Raises:
        AssetFileError: ``{mesh}: {what}, which ...``: no file there, or the reason it
            cannot be decoded (not an image, truncated, over Pillow's pixel limit).
    """
    if isinstance(source, Path):
        problem = user_paths.file_problem(source)
        if problem:
            raise AssetFileError(f"{mesh}: {what}, which {problem}")
    try:
        with warnings.catch_warnings():
            # Pillow only warns between its limit and twice it; a texture too large to
            # trust is refused either way.
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            image = Image.open(source if isinstance(source, Path) else BytesIO(source))
            image.load()
        return image
    except (Image.DecompressionBombWarning, Image.DecompressionBombError) as err:
        reason = (
            f"it is over Pillow's pixel limit, PIL.Image.MAX_IMAGE_PIXELS = "
            f"{Image.MAX_IMAGE_PIXELS} ({err})"
        )
    except Exception as err:  # Pillow raises many kinds for a broken image
        reason = f"it cannot be decoded ({type(err).__name__}: {err})"
    raise AssetFileError(f"{mesh}: {what}, which could not be read: {reason}")


class _Files(trimesh.resolvers.Resolver):
    """What trimesh asks for while loading ``referrer``: files found by
    :func:`asset_files.named_file`, or (an OBJ) the ``mtl`` text for any MTL it asks for."""

    def __init__(self, referrer: Path, mtl: bytes | None = None):
        self.referrer, self.mtl = referrer, mtl
        self.file_name = referrer.name  # trimesh names an OBJ's parts after it

    def get(self, name: str) -> bytes:
        if self.mtl is not None:
            return self.mtl
        return asset_files.named_file(self.referrer, unquote(name)).read_bytes()

    def keys(self):
        return iter(())

    def namespaced(self, namespace: str):
        raise NotImplementedError("the formats read here name files, not folders")

    def write(self, name: str, data) -> None:
        raise NotImplementedError("reading only")


def _trimesh_parts(path: Path, materials: bool) -> list[trimesh.Trimesh]:
    """The parts of a file trimesh reads, indices checked, textures read and checked."""
    suffix = path.suffix.lower()
    kwargs, textures, source = {}, {}, path
    if suffix == ".obj":
        _check_obj_indices(path)
        if materials:
            mtls = asset_files.obj_mtl_files(path)
            textures = _obj_textures(path, mtls)
            # trimesh reads the first MTL only, and its textures its own way: give it every
            # MTL without texture statements; the textures are attached below.
            text = b"\n".join(_MAP_KD.sub(b"", m.read_bytes()) for m in mtls)
            kwargs["resolver"] = _Files(path, text)
        else:
            kwargs["skip_materials"] = True
    elif suffix in (".gltf", ".glb"):
        _check_draco(path)
        # Extensions first: an image only a required extension decodes is named as such.
        rewritten = gltf_file.prepare(path, materials)
        if materials:
            _check_gltf_images(path)
        if rewritten is not None:
            source, kwargs["file_type"] = BytesIO(rewritten), suffix[1:]
    elif materials and suffix == ".ply" and asset_files.ply_texture(path):
        texture = asset_files.ply_texture(path)
        textures[None] = {"map_kd": load_image(texture, path, _names(path, texture))}
    kwargs.setdefault("resolver", _Files(path))
    try:
        scene = trimesh.load(source, force="scene", process=False, **kwargs)
        for geometry in scene.geometry.values():
            if isinstance(geometry, trimesh.Trimesh):
                _check_arrays(path, geometry.vertices, geometry.faces)
        geometries = scene.dump(concatenate=False) if len(scene.geometry) else []
    except AssetFileError:
        raise
    except Exception as err:  # trimesh raises many kinds for an unreadable file
        raise AssetFileError(
            f"{path}: could not be read as {suffix[1:].upper()} ({type(err).__name__}: {err})"
        ) from err
    meshes = [g for g in geometries if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    if not meshes:
        found = ", ".join(f"{type(g).__name__} of {len(g.vertices)} vertices" for g in geometries)
        raise AssetFileError(f"{path}: no faces; found {found or 'no geometry'}")
    for mesh in meshes:
        if materials:
            _file_material(path, mesh, textures)
        uv = getattr(mesh.visual, "uv", None)
        if uv is not None and len(uv) != len(mesh.vertices):
            # No texture reads them (a textured material's were checked above): drop them
            # rather than keep coordinates that are not one per vertex.
            mesh.visual = trimesh.visual.ColorVisuals(mesh)
    return meshes


def _names(referrer: Path, target: Path) -> str:
    return f"{referrer} names {target.name} ({target})"


def _obj_textures(path: Path, mtls: list[Path]) -> dict[str, dict[str, Image.Image]]:
    """Every texture of the OBJ's materials, by material name and MTL statement (a later
    definition of a name wins, as in trimesh)."""
    found = {}
    for mtl in mtls:
        for name, maps in asset_files.mtl_materials(mtl).items():
            found[name] = {k: load_image(p, path, _names(mtl, p)) for k, p in maps.items()}
    return found


def _file_material(path: Path, mesh: trimesh.Trimesh, textures: dict) -> None:
    """Give ``mesh`` the textures read here and drop a material trimesh made up (module
    docstring); refuse a texture without texture coordinates."""
    visual = mesh.visual
    if not isinstance(visual, trimesh.visual.TextureVisuals):
        return
    material = visual.material
    suffix = path.suffix.lower()
    if isinstance(material, trimesh.visual.material.PBRMaterial):
        images = [getattr(material, k) for k in PBR_TEXTURES]
    elif suffix == ".obj" and getattr(material, "name", None) in textures:
        material.image = textures[material.name].get("map_kd")
        images = [material.image]
    elif suffix == ".ply" and None in textures:
        material.image = textures[None]["map_kd"]
        images = [material.image]
    else:  # trimesh's stand-in where the file has no material
        colours = getattr(visual, "vertex_attributes", {}).get("color")
        if colours is not None and len(colours) != len(mesh.vertices):
            colours = None
        mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=colours)
        return
    if any(image is not None for image in images):
        uv = visual.uv
        if uv is None or len(uv) != len(mesh.vertices):
            raise AssetFileError(
                f"{path}: a mesh with a textured material "
                f"({getattr(material, 'name', None) or 'unnamed'}) has no texture coordinates "
                f"for its {len(mesh.vertices)} vertices"
            )


def _check_gltf_images(path: Path) -> None:
    """Decode every image a glTF names (external file, ``data:`` URI or buffer view)."""
    tree = asset_files.gltf_json(path)
    images = tree.get("images", []) if isinstance(tree, dict) else []
    for k, image in enumerate(images if isinstance(images, list) else []):
        uri = image.get("uri") if isinstance(image, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:"):
            target = asset_files.named_file(path, unquote(uri))
            load_image(target, path, _names(path, target))
            continue
        try:
            if isinstance(uri, str):
                blob = base64.b64decode(uri.split("base64,", 1)[1])
            else:
                view = tree["bufferViews"][image["bufferView"]]
                start = view.get("byteOffset", 0)
                blob = gltf_file.buffer_bytes(path, tree, view["buffer"])
                blob = blob[start : start + view["byteLength"]]
        except (KeyError, IndexError, TypeError, ValueError, OSError, struct.error) as err:
            raise AssetFileError(
                f"{path}: image {k} is embedded, but its bytes cannot be found "
                f"({type(err).__name__}: {err})"
            ) from err
        load_image(blob, path, f"its image {k} (embedded)")


def _check_draco(path: Path) -> None:
    """Refuse a glTF with Draco-compressed primitives when DracoPy is missing or cannot
    decode one (trimesh logs either and reads the primitive as zeros)."""
    tree = asset_files.gltf_json(path)
    try:
        compressed = [
            (m, k, mesh.get("name"), primitive["extensions"][gltf_file.DRACO])
            for m, mesh in enumerate(tree.get("meshes", []))
            for k, primitive in enumerate(mesh.get("primitives", []))
            if gltf_file.DRACO in (primitive.get("extensions") or {})
        ]
    except (AttributeError, TypeError):
        return  # a malformed file: trimesh's error names it
    if not compressed:
        return
    try:
        import DracoPy
    except ImportError as err:
        raise AssetFileError(
            f"{path}: its meshes are Draco-compressed (glTF extension {gltf_file.DRACO}), "
            f"which needs the Python package DracoPy: pip install DracoPy "
            f"({type(err).__name__}: {err})"
        ) from err
    for m, k, name, draco in compressed:
        where = f"mesh {m}{f' ({name})' if isinstance(name, str) else ''} primitive {k}"
        try:
            index = draco["bufferView"]
            view = tree["bufferViews"][index]
            start = view.get("byteOffset", 0)
            blob = gltf_file.buffer_bytes(path, tree, view["buffer"])
            blob = blob[start : start + view["byteLength"]]
            if len(blob) != view["byteLength"]:
                raise ValueError(f"the buffer ends {len(blob)} bytes into the view")
        except (KeyError, IndexError, TypeError, ValueError, OSError, struct.error) as err:
            raise AssetFileError(
                f"{path}: {where}: its Draco-compressed data ({gltf_file.DRACO}) cannot be "
                f"found ({type(err).__name__}: {err})"
            ) from err
        try:
            DracoPy.decode(blob)
        except Exception as err:  # DracoPy raises its own kinds for data it cannot read
            raise AssetFileError(
                f"{path}: {where}: its Draco-compressed data ({gltf_file.DRACO}, bufferView "
                f"{index}, {len(blob)} bytes) cannot be decoded by DracoPy "
                f"({type(err).__name__}: {err}); the file may be truncated (copy or download "
                f"it again) or written by a Draco encoder DracoPy cannot read (export it "
                f"again, or without compression)"
            ) from err


def _check_obj_indices(path: Path) -> None:
    """Refuse an OBJ whose faces name vertices or texture coordinates that do not exist,
    or use relative (negative) indices; trimesh would wrap those to the file's last
    vertices, right only when every vertex precedes every face."""
    data = path.read_bytes().replace(b"\\\r\n", b"").replace(b"\\\n", b"")
    corners = b"\n".join(_OBJ_FACE.findall(data))
    for kind, noun, pattern, count in (
        ("vertex", "vertices", _CORNER_VERTEX, len(_OBJ_VERTEX.findall(data))),
        ("texture-coordinate", "texture coordinates", _CORNER_UV, len(_OBJ_UV.findall(data))),
    ):
        indices = [int(i) for i in pattern.findall(corners)]
        negative = sum(i < 0 for i in indices)
        past = [i for i in indices if i == 0 or i > count]
        if negative or past:
            example = f" (e.g. {past[0]})" if past else ""
            raise AssetFileError(
                f"{path}: {negative + len(past)} face {kind} indices out of range for its "
                f"{count} {noun}: {negative} negative (OBJ's relative indices are not read; "
                f"write absolute ones), {len(past)} outside 1..{count}{example}"
            )


def _check_arrays(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Refuse vertices that are not ``(n, 3)`` and faces ``(m, 3)`` with an index outside
    ``0 .. n - 1``."""
    vertices, faces = np.asarray(vertices), np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise AssetFileError(
            f"{path}: vertices of shape {vertices.shape}; expected 3 coordinates each"
        )
    count = len(vertices)
    if faces.size == 0:
        return
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu":
        raise AssetFileError(
            f"{path}: faces of shape {faces.shape} ({faces.dtype}); expected triangles"
        )
    negative, past = int((faces < 0).sum()), int((faces >= count).sum())
    if negative or past:
        example = f" (e.g. {int(faces.max())})" if past else ""
        raise AssetFileError(
            f"{path}: {negative + past} face indices out of range for its {count} vertices: "
            f"{negative} negative, {past} at or past {count}{example}"
        )


def _vtk_part(path: Path) -> trimesh.Trimesh:
    """A VTK file read by PyVista, its surface triangulated; an 8-bit :data:`VTK_COLOURS`
    point array becomes vertex colours."""
    import pyvista as pv

    try:
        data = pv.read(str(path))
        surface = data if isinstance(data, pv.PolyData) else data.extract_surface()
        surface = surface.triangulate()
    except Exception as err:  # VTK's readers raise many kinds
        raise AssetFileError(
            f"{path}: could not be read by PyVista ({type(err).__name__}: {err})"
        ) from err
    faces = surface.faces.reshape(-1, 4)[:, 1:] if surface.n_cells else np.zeros((0, 3), int)
    if not len(faces):
        raise AssetFileError(f"{path}: no faces; found {surface.n_points} points")
    _check_arrays(path, surface.points, faces)
    colours = next(
        (
            np.asarray(surface.point_data[k])
            for k in VTK_COLOURS
            if k in surface.point_data and np.asarray(surface.point_data[k]).dtype == np.uint8
        ),
        None,
    )
    return trimesh.Trimesh(surface.points, faces, vertex_colors=colours, process=False)


def _check_surface(path: Path, parts: list[trimesh.Trimesh]) -> None:
    """Refuse non-finite vertices that triangles use and a degenerate bounding box of the
    used vertices."""
    for part in parts:
        vertices = np.asarray(part.vertices, np.float64)
        bad = ~np.isfinite(vertices).all(1) & _used(part)
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise AssetFileError(
                f"{path}: {int(bad.sum())} of {len(vertices)} vertices are not finite (NaN "
                f"or inf), e.g. vertex {first} = {vertices[first].tolist()}"
            )
    used = np.concatenate([np.asarray(p.vertices)[np.unique(p.faces)] for p in parts])
    extents = np.sort(used.max(0) - used.min(0))[::-1]
    if not extents[0] > 0 or extents[1] < FLAT_TOLERANCE * extents[0]:
        raise AssetFileError(
            f"{path}: degenerate bounding box, extents {[float(e) for e in extents]} "
            f"(sorted); expected a surface that spans at least two axes"
        )


def _used(part: trimesh.Trimesh) -> np.ndarray:
    """``(n,)`` bool: the part's vertices that a triangle uses."""
    used = np.zeros(len(part.vertices), bool)
    used[np.asarray(part.faces).ravel()] = True
    return used


def _drop_unused(path: Path, parts: list[trimesh.Trimesh]) -> None:
    """Drop the vertices no triangle uses from every part (trimesh keeps the visuals'
    texture coordinates and colours with their vertices); log how many, a warning where
    some lie outside the used vertices' bounding box (module docstring)."""
    masks = [_used(p) for p in parts]
    unused = np.concatenate([np.asarray(p.vertices)[~m] for p, m in zip(parts, masks, strict=True)])
    if not len(unused):
        return
    used = np.concatenate([np.asarray(p.vertices)[m] for p, m in zip(parts, masks, strict=True)])
    low, high = used.min(0), used.max(0)
    margin = FLAT_TOLERANCE * float(np.max(high - low))
    # Non-finite vertices are outside any box (comparisons with NaN are false).
    outside = ~((unused >= low - margin) & (unused <= high + margin)).all(1)
    total = sum(len(p.vertices) for p in parts)
    for part in parts:
        part.remove_unreferenced_vertices()
    if outside.any():
        log.warning(
            "%s: %d of its %d vertices belong to no triangle, %d of them outside the "
            "surface's bounding box (e.g. at %s; the surface spans %s to %s); they are "
            "left out, so the object is placed and sized by its triangles (delete loose "
            "vertices in your modelling tool to silence this)",
            path,
            len(unused),
            total,
            int(outside.sum()),
            unused[outside][0].tolist(),
            low.tolist(),
            high.tolist(),
        )
    else:
        log.info(
            "%s: %d of its %d vertices belong to no triangle; left out", path, len(unused), total
        )


def _orient(path: Path, parts: list[trimesh.Trimesh]) -> None:
    """Flip the triangles :func:`neurender.geometry.winding_flips` finds across all parts
    (a surface may span several); log a warning naming the file and the counts."""
    sizes = [len(p.faces) for p in parts]
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    vertices = np.concatenate([np.asarray(p.vertices, np.float64) for p in parts])
    faces = np.concatenate(
        [np.asarray(p.faces, np.int64) + o for p, o in zip(parts, offsets, strict=True)]
    )
    flip, closed = winding_flips(vertices, faces)
    if not flip.any():
        return
    for part, part_flip in zip(parts, np.split(flip, np.cumsum(sizes)[:-1]), strict=True):
        if not part_flip.any():
            continue
        old = np.asarray(part.faces)
        part.faces = np.where(part_flip[:, None], old[:, ::-1], old)
    for kind, mask, what in (
        (
            "closed",
            closed,
            "wound inside out (clockwise seen from outside: their normals point inward, as a "
            "mirrored export or a CAD tool can write them); they are flipped so that the "
            "normals point outward",
        ),
        (
            "open",
            ~closed,
            "wound against most of their surface's triangles; they are flipped to match them "
            "(an open surface has no inside: its front is the side most triangles face)",
        ),
    ):
        if flip[mask].any():
            log.warning(
                "%s: %d of the %d triangles of its %s surfaces are %s",
                path,
                int(flip[mask].sum()),
                int(mask.sum()),
                kind,
                what,
            )
