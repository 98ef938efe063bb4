"""glTF 2.0 binary (GLB) files of triangle meshes, written without a dependency.

One node and one mesh per file; each :class:`Primitive` is one primitive with its own
material. The node's ``translation`` is :func:`origin` of all positions, a round point
near their bounding-box centre (float64 numbers in the JSON), and ``POSITION`` holds the
float32 offsets from it: a mesh far from the origin (a georeferenced scan at 5e6 m) keeps
float32's relative precision of its own size, where absolute float32 coordinates would
round to 0.5 m steps. A mesh about the origin gets no translation (offsets = positions).

Materials are the pipeline's Lambertian reflector in glTF's terms:
``metallicFactor`` 0, ``roughnessFactor`` 1 and ``KHR_materials_specular`` with
``specularFactor`` 0 (a viewer without the extension shows a rough dielectric with a
faint sheen). Conventions (glTF's): right-handed, y up; ``TEXCOORD_0`` with ``v`` pointing
down the image (row 0 of a texture is the image's top row); ``baseColorFactor`` and
``COLOR_0`` linear, base-colour textures sRGB-encoded PNG, normal textures linear
``(n + 1) / 2`` in the frame of ``TANGENT`` (``(T, w)``, bitangent ``cross(N, T) w``).
"""

from __future__ import annotations

import dataclasses
import io as _io
import json
import struct

import numpy as np
from PIL import Image

from neurender import io

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125  # component types
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
LINEAR, LINEAR_MIPMAP_LINEAR = 9729, 9987
CLAMP_TO_EDGE, REPEAT = 33071, 10497


@dataclasses.dataclass
class Primitive:
    """One triangle mesh with one material.

    Attributes:
        positions: ``(N, 3)`` vertex positions; faces: ``(F, 3)`` vertex indices.
        normals: ``(N, 3)`` unit shading normals, or None (viewers then shade flat).
        tangents: ``(N, 4)`` glTF tangents (needed with ``normal_png``), or None.
        uvs: ``(N, 2)`` texture coordinates (``v`` down the image), or None.
        colours: ``(N, 3)`` linear vertex colours (``COLOR_0``), or None.
        base_colour: linear ``(3,)`` factor (it multiplies the texture and the colours).
        base_colour_png, normal_png: PNG bytes of the textures (need ``uvs``), or None.
        wrap: the textures' sampler wrap mode, :data:`CLAMP_TO_EDGE` or :data:`REPEAT`.
    """

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    tangents: np.ndarray | None = None
    uvs: np.ndarray | None = None
    colours: np.ndarray | None = None
    base_colour: tuple[float, float, float] = (1.0, 1.0, 1.0)
    base_colour_png: bytes | None = None
    normal_png: bytes | None = None
    wrap: int = CLAMP_TO_EDGE


def png_bytes(values: np.ndarray) -> bytes:
    """An ``(H, W, 3)`` array of values in [0, 1] as 8-bit RGB PNG bytes."""
    buffer = _io.BytesIO()
    Image.fromarray(io.to_uint8(values)).save(buffer, format="PNG")
    return buffer.getvalue()


def origin(positions: np.ndarray) -> np.ndarray:
    """The node translation ``(3,)`` for ``positions (N, 3)``: their bounding-box centre
    rounded to a multiple of ``2^floor(log2(longest side))``, so every offset from it is
    within one longest side (float32 keeps it to about 6e-8 of the side) and a mesh whose
    centre is within half that step of the origin gets exactly 0."""
    lo, hi = positions.min(0), positions.max(0)
    side = float((hi - lo).max())
    if not side > 0:  # one point (or none): any origin is exact
        return np.zeros(3)
    step = 2.0 ** np.floor(np.log2(side))
    return np.round((lo + hi) / 2 / step) * step + 0.0  # + 0.0: no -0.0 in the JSON


class _Buffer:
    """The binary chunk of a GLB and the JSON arrays that point into it."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.views: list[dict] = []
        self.accessors: list[dict] = []
        self.images: list[dict] = []
        self.textures: list[dict] = []
        self.samplers: list[dict] = []

    def view(self, data: bytes, target: int | None = None) -> int:
        """A buffer view of ``data`` (padded to 4 bytes); its index."""
        entry = {"buffer": 0, "byteOffset": len(self.binary()), "byteLength": len(data)}
        if target is not None:
            entry["target"] = target
        self.chunks.append(data + b"\0" * (-len(data) % 4))
        self.views.append(entry)
        return len(self.views) - 1

    def accessor(self, array: np.ndarray, kind: str, component: int, target: int, bounds=False):
        """An accessor of ``array`` (little-endian ``component``s of glTF type ``kind``,
        with its ``min``/``max`` where ``bounds``); its index."""
        dtype = {FLOAT: np.float32, UNSIGNED_SHORT: np.uint16, UNSIGNED_INT: np.uint32}[component]
        data = np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
        entry = {
            "bufferView": self.view(data.tobytes(), target),
            "componentType": component,
            "count": len(data) if data.ndim > 1 else data.size,
            "type": kind,
        }
        if bounds:
            entry["min"] = data.min(0).tolist()
            entry["max"] = data.max(0).tolist()
        self.accessors.append(entry)
        return len(self.accessors) - 1

    def texture(self, png: bytes, wrap: int) -> dict:
        """A texture of PNG bytes with a linear, mipmapped sampler; its texture info."""
        sampler = {
            "magFilter": LINEAR,
            "minFilter": LINEAR_MIPMAP_LINEAR,
            "wrapS": wrap,
            "wrapT": wrap,
        }
        if sampler not in self.samplers:
            self.samplers.append(sampler)
        self.images.append({"bufferView": self.view(png), "mimeType": "image/png"})
        self.textures.append(
            {"sampler": self.samplers.index(sampler), "source": len(self.images) - 1}
        )
        return {"index": len(self.textures) - 1}

    def binary(self) -> bytes:
        return b"".join(self.chunks)


def _check(p: Primitive, where: str) -> None:
    """Refuse a primitive whose attributes do not match its positions or its textures."""
    for key in ("normals", "tangents", "uvs", "colours"):
        value = getattr(p, key)
        if value is not None and len(value) != len(p.positions):
            raise ValueError(f"{where}: {len(value)} {key} for {len(p.positions)} positions")
    if (p.base_colour_png or p.normal_png) and p.uvs is None:
        raise ValueError(f"{where}: textures need texture coordinates")
    if p.normal_png and p.tangents is None:
        raise ValueError(f"{where}: a normal texture needs tangents")


def _primitive(p: Primitive, k: int, buffer: _Buffer, centre: np.ndarray) -> dict:
    """The glTF primitive of ``p`` (material ``k``) with positions relative to the node's
    translation ``centre``, its arrays written to ``buffer``."""
    offsets = np.asarray(p.positions, np.float64) - centre
    attributes = {"POSITION": buffer.accessor(offsets, "VEC3", FLOAT, ARRAY_BUFFER, bounds=True)}
    for semantic, key, kind in (
        ("NORMAL", "normals", "VEC3"),
        ("TANGENT", "tangents", "VEC4"),
        ("TEXCOORD_0", "uvs", "VEC2"),
        ("COLOR_0", "colours", "VEC3"),
    ):
        if getattr(p, key) is not None:
            attributes[semantic] = buffer.accessor(getattr(p, key), kind, FLOAT, ARRAY_BUFFER)
    short = len(p.positions) < 65536
    indices = buffer.accessor(
        np.asarray(p.faces).ravel(),
        "SCALAR",
        UNSIGNED_SHORT if short else UNSIGNED_INT,
        ELEMENT_ARRAY_BUFFER,
    )
    return {"attributes": attributes, "indices": indices, "material": k, "mode": 4}


def _material(p: Primitive, name: str, buffer: _Buffer) -> dict:
    """The Lambertian glTF material of ``p`` (see the module docstring), its textures
    written to ``buffer``."""
    pbr: dict = {
        "baseColorFactor": [float(c) for c in p.base_colour] + [1.0],
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    }
    if p.base_colour_png:
        pbr["baseColorTexture"] = buffer.texture(p.base_colour_png, p.wrap)
    material: dict = {
        "name": name,
        "pbrMetallicRoughness": pbr,
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
    }
    if p.normal_png:
        material["normalTexture"] = buffer.texture(p.normal_png, p.wrap)
    return material


def glb(primitives: list[Primitive], name: str, generator: str = "neurender") -> bytes:
    """The GLB bytes of one mesh made of ``primitives``, placed by its node's translation
    (module docstring); indices are 16-bit where a primitive has fewer than 65536
    vertices, else 32-bit."""
    buffer = _Buffer()
    gl_primitives, materials = [], []
    for k, p in enumerate(primitives):
        _check(p, f"glTF primitive {k} of {name}")
    centre = origin(np.concatenate([np.asarray(p.positions, np.float64) for p in primitives]))
    node: dict = {"mesh": 0, "name": name}
    if centre.any():
        node["translation"] = centre.tolist()
    for k, p in enumerate(primitives):
        gl_primitives.append(_primitive(p, k, buffer, centre))
        materials.append(_material(p, f"{name}_{k}" if len(primitives) > 1 else name, buffer))
    binary = buffer.binary()
    tree: dict = {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": ["KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{"name": name, "primitives": gl_primitives}],
        "materials": materials,
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(binary)}],
    }
    if buffer.textures:
        tree |= {"samplers": buffer.samplers, "textures": buffer.textures, "images": buffer.images}
    text = json.dumps(tree, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return b"".join(
        [
            struct.pack("<4sII", b"glTF", 2, total),
            struct.pack("<I4s", len(text), b"JSON"),
            text,
            struct.pack("<I4s", len(binary), b"BIN\0"),
            binary,
        ]
    )
