"""Files of the simplification stage.

* View stacks: ``(N, H, W, 4)`` float32 RGBA images (linear radiance, alpha = coverage) as
  one EXR with channels ``v000.R`` ... ``vNNN.A``.
* Low-poly meshes: ``.npz`` with the welded ``positions``/``faces`` and the atlas
  ``vmap``/``uvs``/``uv_faces`` of :class:`neurender.simplify.mesh_ops.LowPolyMesh`.
* Textures: ``(T, T, 3)`` values in [0, 1] as 16-bit RGB PNG, row 0 at ``v = 0``.
* The portable result: OBJ + MTL + albedo PNG of the atlas mesh, written by trimesh.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from neurender import io
from neurender.simplify.mesh_ops import LowPolyMesh

CHANNELS = ("R", "G", "B", "A")


def write_images(path: str | Path, images: np.ndarray) -> None:
    """``(N, H, W, 4)`` RGBA stack -> one EXR with channels ``v000.R`` ... ``vNNN.A``."""
    io.write_exr(
        path,
        {
            f"v{i:03d}.{c}": img[..., k]
            for i, img in enumerate(images)
            for k, c in enumerate(CHANNELS)
        },
    )


def read_images(path: str | Path) -> np.ndarray:
    """Inverse of :func:`write_images`: ``(N, H, W, 4)`` float32."""
    data = io.read_exr(path)
    n = len(data) // 4
    return np.stack([np.stack([data[f"v{i:03d}.{c}"] for c in CHANNELS], -1) for i in range(n)])


def save_lowpoly(path: str | Path, low: LowPolyMesh) -> None:
    io.save_npz(
        path,
        positions=low.positions,
        faces=low.faces,
        vmap=low.vmap,
        uvs=low.uvs,
        uv_faces=low.uv_faces,
    )


def load_lowpoly(path: str | Path) -> LowPolyMesh:
    d = io.load_npz(path)
    return LowPolyMesh(d["positions"], d["faces"], d["vmap"], d["uvs"], d["uv_faces"])


def write_texture(path: str | Path, texture: np.ndarray) -> None:
    """A ``(T, T, 3)`` texture in [0, 1] (clipped) as a 16-bit PNG."""
    io.write_png(path, np.round(np.clip(texture, 0, 1) * 65535).astype(np.uint16))


def read_texture(path: str | Path) -> np.ndarray:
    """A texture written by :func:`write_texture` as ``(T, T, 3)`` float64 in [0, 1]."""
    return io.read_png(path)[..., :3].astype(np.float64) / 65535.0


def write_obj(
    paths: dict[str, str | Path], low: LowPolyMesh, positions: np.ndarray, albedo: np.ndarray
) -> None:
    """The atlas mesh at welded ``positions (V, 3)`` as a textured OBJ: ``paths["obj"]``
    refers to the material file ``paths["mtl"]``, which refers to the albedo texture
    ``paths["texture"]`` (8-bit PNG), all three in one folder and each written atomically
    (trimesh's exporter returns the files instead of writing them beside the OBJ)."""
    mtl, texture = Path(paths["mtl"]), Path(paths["texture"])
    if len({Path(p).parent for p in paths.values()}) != 1:
        raise ValueError(f"OBJ, MTL and texture must share a folder; got {paths}")
    material = trimesh.visual.material.SimpleMaterial(
        image=Image.fromarray(io.to_uint8(albedo)), name=texture.stem
    )
    textured = trimesh.Trimesh(
        positions[low.vmap],
        low.uv_faces,
        process=False,
        visual=trimesh.visual.TextureVisuals(uv=low.uvs, material=material),
    )
    text, files = trimesh.exchange.obj.export_obj(
        textured, include_texture=True, mtl_name=mtl.name, return_texture=True
    )
    expected = {mtl.name, texture.name}
    if set(files) != expected:
        raise RuntimeError(f"trimesh wrote {sorted(files)}, expected {sorted(expected)}")
    for path, data in ((paths["obj"], text.encode()), (mtl, files[mtl.name])):
        with io.atomic_path(path) as tmp:
            tmp.write_bytes(data)
    with io.atomic_path(texture) as tmp:
        tmp.write_bytes(files[texture.name])
