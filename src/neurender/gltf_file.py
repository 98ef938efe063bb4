"""What a user's glTF (``.gltf`` or ``.glb``) asks of its reader beyond what trimesh does:
the extensions it requires or uses, and the texture coordinates its materials' textures
are sampled at. :func:`neurender.mesh_file.read` calls :func:`prepare` before trimesh
loads the file.

Extensions (``extensionsRequired``, ``extensionsUsed``): one the file requires and the
reader does not honour (:data:`SUPPORTED`, :data:`NO_EFFECT`) is refused, naming the file
and the extension (a reader that ignores a required extension shows the asset wrongly);
one merely used is ignored with a logged warning (not in the files this package writes:
:data:`OWN_GENERATOR`). When the geometry alone is read, extensions of materials and
textures (:data:`MATERIAL_PREFIXES`) are neither refused nor reported.

Texture coordinates: trimesh (5.2) reads ``TEXCOORD_0`` for every texture as stored: it
ignores ``texCoord``, ``KHR_texture_transform``, sparse accessors and normalized integers.
The methods sample all textures of a part at one set of coordinates (``visual.uv``:
:data:`neurender.mesh_file.PBR_TEXTURES`), so each material's colour textures
(:data:`COLOUR_TEXTURES`) must agree on one set (``texCoord``, or the extension's
``texCoord`` that overrides it) and one transform, or the file is refused naming the
material, the textures and what they use. A ``normalTexture`` that disagrees with them is
dropped with a warning (no method shades with a user file's normal map). Where the agreed
coordinates are not ``TEXCOORD_0`` as trimesh reads it, they are computed here (decoded,
transformed) and given to trimesh as the primitive's ``TEXCOORD_0``, and the material's
``texCoord`` and ``KHR_texture_transform`` are removed from the copy trimesh reads, so the
transform is applied exactly once whatever a trimesh version does with it.

``KHR_texture_transform``, in glTF's UV convention (origin at the image's top-left, ``v``
down): ``uv' = T(offset) R(rotation) S(scale) uv`` with ``R = [[cos r, sin r], [-sin r,
cos r]]`` (row-major), "counter-clockwise" in the ``v``-down UV plane as the
specification's text and example have it (``offset [0, 1]``, ``rotation pi/2``, ``scale
[0.5, 0.5]`` maps the unit square onto the image's lower-left quadrant); the
specification's GLSL listing, read column-major, is its transpose (glTF issue 1563).
"""

from __future__ import annotations

import base64
import copy
import json
import logging
import math
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from neurender import asset_files
from neurender.asset_files import AssetFileError

log = logging.getLogger(__name__)

#: Extensions the reader honours: here (``KHR_texture_transform``) or in trimesh (DracoPy
#: decodes ``KHR_draco_mesh_compression``, ``KHR_materials_pbrSpecularGlossiness`` becomes
#: metallic-roughness, Pillow decodes ``EXT_texture_webp`` images).
SUPPORTED = frozenset(
    {
        "KHR_texture_transform",
        "KHR_draco_mesh_compression",
        "KHR_materials_pbrSpecularGlossiness",
        "EXT_texture_webp",
    }
)
#: Extensions that change nothing the methods read: metadata, material variants (the
#: default material is read), lights and animations (the methods light and place the
#: object themselves).
NO_EFFECT = frozenset(
    {
        "KHR_xmp_json_ld",
        "KHR_xmp",
        "KHR_materials_variants",
        "KHR_lights_punctual",
        "KHR_animation_pointer",
    }
)
#: Name prefixes of extensions that change materials and textures only.
MATERIAL_PREFIXES = ("KHR_materials_", "EXT_materials_", "KHR_texture_", "EXT_texture_")
#: The textureInfos the methods sample for colour (base colour, metallic-roughness),
#: as ``(path in the material, name)``.
COLOUR_TEXTURES = (
    (("pbrMetallicRoughness", "baseColorTexture"), "baseColorTexture"),
    (("pbrMetallicRoughness", "metallicRoughnessTexture"), "metallicRoughnessTexture"),
    (
        ("extensions", "KHR_materials_pbrSpecularGlossiness", "diffuseTexture"),
        "KHR_materials_pbrSpecularGlossiness.diffuseTexture",
    ),
    (
        ("extensions", "KHR_materials_pbrSpecularGlossiness", "specularGlossinessTexture"),
        "KHR_materials_pbrSpecularGlossiness.specularGlossinessTexture",
    ),
)
#: ``asset.generator`` of the files this package writes (:mod:`neurender.gltf`); read
#: back without the warning for used extensions (their ``KHR_materials_specular`` states
#: the Lambertian reflector the pipeline renders).
OWN_GENERATOR = "neurender"
TRANSFORM = "KHR_texture_transform"
DRACO = "KHR_draco_mesh_compression"
#: Two transforms closer than this (texture-coordinate units) are one.
SAME_TRANSFORM = 1e-6

_FLOAT = 5126
_TRIANGLES = (4, 5, 6)  # triangles, strip, fan
_DTYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", _FLOAT: "<f4"}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
#: The top-level lists a rewrite reads and appends to.
_LISTS = ("meshes", "materials", "accessors", "bufferViews", "buffers")
_IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def prepare(path: Path, materials: bool) -> bytes | None:
    """Check the extensions of the glTF at ``path`` (module docstring) and, when
    ``materials`` are read and some primitive's texture coordinates are not its
    ``TEXCOORD_0`` as trimesh reads it (or a disagreeing normal map is dropped), the file's
    bytes for trimesh to read in its place (same format, same folder for the files it
    names); else ``None`` (read the file itself).

    Raises:
        AssetFileError: naming the file: a required extension the reader does not honour;
            a material whose colour textures use different coordinates; an invalid
            ``texCoord`` or ``KHR_texture_transform``; coordinates that cannot be read.
    """
    tree = asset_files.gltf_json(path)
    if not isinstance(tree, dict) or not tree:
        return None  # unreadable: trimesh's error names it
    check_extensions(path, tree, materials)
    check_attributes(path, tree)
    if not materials:
        return None
    rewritten = _with_coordinates(path, tree)
    if rewritten is None:
        return None
    if path.suffix.lower() == ".gltf":
        return json.dumps(rewritten).encode()
    return _glb(path.read_bytes(), rewritten)


def check_extensions(path: Path, tree: dict, materials: bool = True) -> None:
    """Refuse a required extension the reader does not honour; warn of a used one that
    changes what is shown (module docstring).

    Raises:
        AssetFileError: ``{path}: requires glTF extension(s) ...``, or a malformed list.
    """
    lists = {}
    for key in ("extensionsRequired", "extensionsUsed"):
        names = tree.get(key, [])
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise AssetFileError(f"{path}: {key} = {names!r}; expected a list of extension names")
        lists[key] = [
            n
            for n in dict.fromkeys(names)
            if n not in SUPPORTED | NO_EFFECT and (materials or not n.startswith(MATERIAL_PREFIXES))
        ]
    required, used = lists["extensionsRequired"], lists["extensionsUsed"]
    if required:
        raise AssetFileError(
            f"{path}: requires glTF extension(s) {', '.join(required)} (extensionsRequired), "
            f"which this reader does not support (ignoring a required extension would show the "
            f"asset wrongly); it supports {', '.join(sorted(SUPPORTED))}: export the asset "
            f"without the others"
        )
    generator = (
        tree.get("asset", {}).get("generator") if isinstance(tree.get("asset"), dict) else None
    )
    if used and not (isinstance(generator, str) and generator.startswith(OWN_GENERATOR)):
        log.warning(
            "%s: uses glTF extension(s) %s (extensionsUsed), which this reader ignores; "
            "what they change in the asset's look is not rendered",
            path,
            ", ".join(used),
        )


#: The accessor type each vertex attribute must have (glTF 2.0, 3.7.2.1); others unchecked.
_ATTRIBUTE_TYPES = {"POSITION": "VEC3", "NORMAL": "VEC3", "TEXCOORD_": "VEC2"}


def check_attributes(path: Path, tree: dict) -> None:
    """Refuse a primitive's vertex attribute that is not an accessor's index (a JSON
    ``true``/``false`` would read as accessor 1/0 in Python) or whose accessor has the
    wrong type for it (``POSITION``/``NORMAL`` ``VEC3``, ``TEXCOORD_n`` ``VEC2``): trimesh
    would read such an attribute as it is, e.g. positions as texture coordinates. A
    malformed structure is left to trimesh, whose error names the file.

    Raises:
        AssetFileError: naming the file, the mesh, primitive and attribute, and the value.
    """
    meshes, accessors = tree.get("meshes", []), tree.get("accessors", [])
    if not isinstance(meshes, list) or not isinstance(accessors, list):
        return
    for m, mesh in enumerate(meshes):
        primitives = mesh.get("primitives") if isinstance(mesh, dict) else None
        for p, primitive in enumerate(primitives if isinstance(primitives, list) else []):
            attributes = primitive.get("attributes") if isinstance(primitive, dict) else None
            for name, index in (attributes if isinstance(attributes, dict) else {}).items():
                key = f"meshes[{m}].primitives[{p}].attributes.{name}"
                if isinstance(index, bool) or not isinstance(index, int):
                    raise AssetFileError(
                        f"{path}: {key} = {json.dumps(index)}; expected an accessor's index"
                    )
                if not 0 <= index < len(accessors) or not isinstance(accessors[index], dict):
                    continue  # a broken reference: trimesh's error names the file
                wanted = next(
                    (t for prefix, t in _ATTRIBUTE_TYPES.items() if name.startswith(prefix)), None
                )
                found = accessors[index].get("type")
                if wanted is not None and found != wanted:
                    raise AssetFileError(
                        f"{path}: {key} = {index}, an accessor of type {found!r}; expected "
                        f"{wanted} for {name}"
                    )


def uv_transform(path: Path, label: str, info: dict) -> tuple[int, np.ndarray]:
    """The texture-coordinate set and the ``(2, 3)`` affine map ``[A | t]`` (``uv' = A uv
    + t``, glTF's UV convention) a textureInfo samples with: its ``texCoord``, overridden
    by ``KHR_texture_transform``'s, and ``T(offset) R(rotation) S(scale)`` (module
    docstring); identity without the extension.

    Raises:
        AssetFileError: naming ``label`` (the material and texture) and the invalid value.
    """
    index = info.get("texCoord", 0)
    _check_set(path, f"{label}.texCoord", index)
    ext = info.get("extensions", {})
    ext = ext.get(TRANSFORM) if isinstance(ext, dict) else None
    if ext is None:
        return index, _IDENTITY
    key = f"{label}.extensions.{TRANSFORM}"
    if not isinstance(ext, dict):
        raise AssetFileError(f"{path}: {key} = {ext!r}; expected an object")
    if "texCoord" in ext:
        index = ext["texCoord"]
        _check_set(path, f"{key}.texCoord", index)
    offset = _numbers(path, f"{key}.offset", ext.get("offset", [0.0, 0.0]), 2)
    (rotation,) = _numbers(path, f"{key}.rotation", [ext.get("rotation", 0.0)], 1)
    scale = _numbers(path, f"{key}.scale", ext.get("scale", [1.0, 1.0]), 2)
    c, s = math.cos(rotation), math.sin(rotation)
    linear = np.array([[c, s], [-s, c]]) @ np.diag(scale)
    return index, np.column_stack([linear, offset])


def apply(matrix: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``uv (K, 2)`` mapped by a ``(2, 3)`` affine ``matrix`` (:func:`uv_transform`)."""
    return np.asarray(uv, np.float64) @ matrix[:, :2].T + matrix[:, 2]


def buffer_bytes(path: Path, tree: dict, index: int) -> bytes:
    """The bytes of buffer ``index`` of the glTF at ``path``: a GLB's binary chunk, a
    ``data:`` URI or a file found by :func:`asset_files.named_file`."""
    uri = tree["buffers"][index].get("uri")
    if uri is None:  # the GLB's BIN chunk
        data = path.read_bytes()
        offset = 12
        while offset + 8 <= len(data):
            length, kind = struct.unpack_from("<I4s", data, offset)
            if kind == b"BIN\x00":
                return data[offset + 8 : offset + 8 + length]
            offset += 8 + length
        raise ValueError("no binary chunk")
    if uri.startswith("data:"):
        return base64.b64decode(uri.split("base64,", 1)[1])
    return asset_files.named_file(path, unquote(uri)).read_bytes()


def _check_set(path: Path, key: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise AssetFileError(
            f"{path}: {key} = {value!r}; expected a texture-coordinate set 0, 1 ..."
        )


def _numbers(path: Path, key: str, value, count: int) -> list[float]:
    ok = isinstance(value, list) and len(value) == count
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    if not ok or not all(_finite(v) for v in value):
        shown = value[0] if count == 1 and isinstance(value, list) else value
        what = "a finite number" if count == 1 else f"{count} finite numbers"
        raise AssetFileError(f"{path}: {key} = {shown!r}; expected {what}")
    return [float(v) for v in value]


def _finite(value: int | float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer past float's range
        return False


def _material_label(tree: dict, index: int) -> str:
    name = tree["materials"][index].get("name")
    return f'material {index} "{name}"' if name else f"material {index}"


def _texture_info(material: dict, keys: tuple[str, ...]) -> dict | None:
    node = material
    for key in keys:
        node = node.get(key) if isinstance(node, dict) else None
    return node if isinstance(node, dict) and "index" in node else None


def _describe(index: int, matrix: np.ndarray) -> str:
    if np.allclose(matrix, _IDENTITY, rtol=0, atol=SAME_TRANSFORM):
        return f"TEXCOORD_{index} untransformed"
    return f"TEXCOORD_{index} through {TRANSFORM} [A | t] = {np.round(matrix, 6).tolist()}"


def _material_plan(
    path: Path, tree: dict, index: int, out: dict
) -> tuple[tuple[int, np.ndarray] | None, bool]:
    """The set and transform all of material ``index``'s sampled textures use (``None``
    when it has none), and whether its copy in ``out`` lost a disagreeing
    ``normalTexture``."""
    material = tree["materials"][index]
    label = _material_label(tree, index)
    plans = {}
    for keys, name in COLOUR_TEXTURES:
        info = _texture_info(material, keys)
        if info is not None:
            plans[name] = uv_transform(path, f"{label} {name}", info)
    distinct = _distinct(plans.values())
    if len(distinct) > 1:
        uses = "; ".join(f"{name} samples {_describe(*plan)}" for name, plan in plans.items())
        raise AssetFileError(
            f"{path}: {label} samples its textures at different texture coordinates ({uses}), "
            f"and the methods sample every texture of a material at one set; expected the same "
            f"texCoord and {TRANSFORM} on all of them"
        )
    normal = _texture_info(material, ("normalTexture",))
    if normal is None:
        return (distinct[0] if distinct else None), False
    plan = uv_transform(path, f"{label} normalTexture", normal)
    if not distinct:
        return plan, False
    if len(_distinct([plan, distinct[0]])) == 1:
        return distinct[0], False
    log.warning(
        "%s: %s: its normalTexture samples %s, its colour textures %s; the normal map is not "
        "read (the methods do not shade with a file's normal map)",
        path,
        label,
        _describe(*plan),
        _describe(*distinct[0]),
    )
    del out["materials"][index]["normalTexture"]
    return distinct[0], True


def _distinct(plans) -> list[tuple[int, np.ndarray]]:
    found: list[tuple[int, np.ndarray]] = []
    for k, m in plans:
        if not any(k == j and np.allclose(m, n, rtol=0, atol=SAME_TRANSFORM) for j, n in found):
            found.append((k, m))
    return found


def _strip(material: dict) -> None:
    """Remove ``texCoord`` and ``KHR_texture_transform`` from every textureInfo of a
    material (its coordinates are computed here)."""
    for value in list(material.values()):
        if isinstance(value, dict):
            if "index" in value:
                value.pop("texCoord", None)
                extensions = value.get("extensions")
                if isinstance(extensions, dict):
                    extensions.pop(TRANSFORM, None)
            _strip(value)


def _with_coordinates(path: Path, tree: dict) -> dict | None:
    """A copy of ``tree`` whose textured primitives' ``TEXCOORD_0`` are the coordinates
    their materials sample (module docstring), or ``None`` when every primitive's are its
    ``TEXCOORD_0`` as trimesh reads it and no normal map is dropped."""
    if not all(isinstance(tree.get(k, []), list) for k in _LISTS):
        return None  # malformed: trimesh's own error names the file
    out = copy.deepcopy(tree)
    materials, meshes = tree.get("materials", []), tree.get("meshes", [])
    plans: dict[int, tuple[int, np.ndarray] | None] = {}
    dropped, blobs, buffers = False, [], {}
    for m, mesh in enumerate(meshes):
        primitives = mesh.get("primitives") if isinstance(mesh, dict) else None
        if not isinstance(primitives, list):
            continue  # trimesh's own error names the file
        for p, primitive in enumerate(primitives):
            index = primitive.get("material") if isinstance(primitive, dict) else None
            if (
                not isinstance(index, int)
                or not 0 <= index < len(materials)
                or not isinstance(materials[index], dict)
                or primitive.get("mode", 4) not in _TRIANGLES
                or not isinstance(primitive.get("attributes"), dict)
            ):
                continue  # no material, or trimesh's own error names the file
            if index not in plans:
                plans[index], lost = _material_plan(path, tree, index, out)
                dropped |= lost
            if plans[index] is None:
                continue
            uv_set, matrix = plans[index]
            name = f"TEXCOORD_{uv_set}"
            accessor = primitive["attributes"].get(name)
            trivial = uv_set == 0 and np.array_equal(matrix, _IDENTITY)
            if trivial and (accessor is None or _read_as_stored(tree, accessor)):
                continue
            where = f"mesh {m} primitive {p} ({_material_label(tree, index)})"
            if accessor is None:
                raise AssetFileError(
                    f"{path}: {where}: its textures sample {name}, which the primitive does not "
                    f"have (its attributes: {', '.join(primitive['attributes']) or 'none'})"
                )
            uv = _attribute(path, tree, buffers, primitive, name, where)
            if uv.shape[1] != 2:
                raise AssetFileError(
                    f"{path}: {where}: {name} (accessor {accessor}) holds {uv.shape[1]} "
                    f"components per vertex; expected 2 (VEC2)"
                )
            vertices = len(_attribute(path, tree, buffers, primitive, "POSITION", where))
            if len(uv) != vertices:
                raise AssetFileError(
                    f"{path}: {where}: {name} (accessor {accessor}) holds {len(uv)} entries; "
                    f"expected one per vertex of its POSITION ({vertices})"
                )
            uv = apply(matrix, uv)
            target = out["meshes"][m]["primitives"][p]
            target["attributes"]["TEXCOORD_0"] = len(tree.get("accessors", [])) + len(blobs)
            draco = _draco(target)
            if draco is not None:
                draco["attributes"].pop("TEXCOORD_0", None)  # trimesh would overwrite ours
            blobs.append(np.ascontiguousarray(uv, dtype="<f4"))
            _strip(out["materials"][index])
    if blobs:
        _append_accessors(out, blobs)
    return out if blobs or dropped else None


def _draco(primitive: dict) -> dict | None:
    """The primitive's ``KHR_draco_mesh_compression`` object, if it has a well-formed one."""
    extensions = primitive.get("extensions")
    draco = extensions.get(DRACO) if isinstance(extensions, dict) else None
    ok = isinstance(draco, dict) and isinstance(draco.get("attributes"), dict)
    return draco if ok else None


def _read_as_stored(tree: dict, index: int) -> bool:
    """Whether trimesh reads accessor ``index`` right: float, not sparse."""
    try:
        accessor = tree["accessors"][index]
        return accessor.get("componentType") == _FLOAT and "sparse" not in accessor
    except (IndexError, KeyError, TypeError, AttributeError):
        return True  # a broken reference: trimesh's error names the file


def _append_accessors(tree: dict, blobs: list[np.ndarray]) -> None:
    """Append one ``VEC2`` float accessor per array of ``blobs``, in one new buffer (a
    ``data:`` URI), to ``tree``."""
    data, views = b"", []
    for blob in blobs:
        views.append({"buffer": len(tree.get("buffers", [])), "byteOffset": len(data)})
        views[-1]["byteLength"] = blob.nbytes
        data += blob.tobytes()
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    tree.setdefault("buffers", []).append({"byteLength": len(data), "uri": uri})
    for view, blob in zip(views, blobs, strict=True):
        tree.setdefault("bufferViews", []).append(view)
        accessor = {"bufferView": len(tree["bufferViews"]) - 1, "componentType": _FLOAT}
        accessor |= {"count": len(blob), "type": "VEC2"}
        tree.setdefault("accessors", []).append(accessor)


def _glb(data: bytes, tree: dict) -> bytes:
    """GLB ``data`` with its JSON chunk replaced by ``tree`` (its other chunks as they are)."""
    (length,) = struct.unpack_from("<I", data, 12)
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + length :]
    head = struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(rest))
    return head + struct.pack("<I4s", len(text), b"JSON") + text + rest


def _attribute(
    path: Path, tree: dict, buffers: dict, primitive: dict, name: str, where: str
) -> np.ndarray:
    """Attribute ``name`` of ``primitive`` as float64 ``(count, width)``: decoded from
    Draco where the primitive's ``KHR_draco_mesh_compression`` holds it, else read from
    its accessor (strides, sparse values, normalized integers as glTF defines them)."""
    index = primitive["attributes"][name]
    try:
        draco = _draco(primitive)
        if draco is not None and name in draco["attributes"]:
            import DracoPy

            view = tree["bufferViews"][draco["bufferView"]]
            decoded = DracoPy.decode(_view_bytes(path, tree, buffers, view))
            ident = draco["attributes"][name]
            found = [a["data"] for a in decoded.attributes if a["unique_id"] == ident]
            return np.asarray(found[0], np.float64).reshape(len(found[0]), -1)
        return _accessor(path, tree, buffers, tree["accessors"][index])
    except AssetFileError:
        raise
    except Exception as err:  # a malformed file fails in many ways
        raise AssetFileError(
            f"{path}: {where}: {name} (accessor {index}) cannot be read "
            f"({type(err).__name__}: {err})"
        ) from err


def _view_bytes(path: Path, tree: dict, buffers: dict, view: dict) -> bytes:
    index = view["buffer"]
    if index not in buffers:
        buffers[index] = buffer_bytes(path, tree, index)
    start = view.get("byteOffset", 0)
    data = buffers[index][start : start + view["byteLength"]]
    if len(data) != view["byteLength"]:
        raise ValueError(f"buffer {index} ends before its view's byteLength {view['byteLength']}")
    return data


def _accessor(path: Path, tree: dict, buffers: dict, accessor: dict) -> np.ndarray:
    dtype, width = np.dtype(_DTYPES[accessor["componentType"]]), _WIDTHS[accessor["type"]]
    count = accessor["count"]
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count {count!r}: expected an integer of at least 1")
    values = np.zeros((count, width), dtype)
    if "bufferView" in accessor:
        view = tree["bufferViews"][accessor["bufferView"]]
        values = _strided(
            _view_bytes(path, tree, buffers, view),
            accessor.get("byteOffset", 0),
            view.get("byteStride", 0),
            dtype,
            count,
            width,
        )
    sparse = accessor.get("sparse")
    if sparse:
        values = values.copy()
        n, where, what = sparse["count"], sparse["indices"], sparse["values"]
        kind = np.dtype(_DTYPES[where["componentType"]])
        view = tree["bufferViews"][where["bufferView"]]
        rows = _strided(
            _view_bytes(path, tree, buffers, view), where.get("byteOffset", 0), 0, kind, n, 1
        )
        view = tree["bufferViews"][what["bufferView"]]
        data = _view_bytes(path, tree, buffers, view)
        values[rows[:, 0]] = _strided(data, what.get("byteOffset", 0), 0, dtype, n, width)
    out = values.astype(np.float64)
    if accessor.get("normalized") and dtype.kind in "iu":
        top = float(np.iinfo(dtype).max)
        out = np.maximum(out / top, -1.0)
    return out


def _strided(data: bytes, offset: int, stride: int, dtype, count: int, width: int) -> np.ndarray:
    """``count`` elements of ``width`` components from ``offset``, ``stride`` bytes apart
    (0: packed)."""
    size = dtype.itemsize * width
    stride = stride or size
    if count and offset + (count - 1) * stride + size > len(data):
        raise ValueError(f"{count} elements of {size} bytes, {stride} apart, overrun the view")
    rows = np.frombuffer(data, np.uint8, count=len(data) - offset, offset=offset)
    if count == 0:
        return np.zeros((0, width), dtype)
    picked = np.lib.stride_tricks.as_strided(rows, (count, size), (stride, 1))
    return np.ascontiguousarray(picked).view(dtype).reshape(count, width)
