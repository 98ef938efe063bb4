"""Files of the simplification stage.

* View stacks: ``(N, H, W, 4)`` float32 RGBA images (linear radiance, alpha = coverage) as
  one EXR with channels ``v000.R`` ... ``vNNN.A``.
* Low-poly meshes: ``.npz`` with the welded ``positions``/``faces`` and the atlas
  ``vmap``/``uvs``/``uv_faces`` of :class:`neurender.simplification.mesh_ops.LowPolyMesh`, the
  asset's uniform grey ``albedo`` (NaN where its colour varies; see
  :class:`neurender.simplification.assets.Asset`) and, for a user asset, ``to_asset``, the
  ``(4, 4)`` map from the stage's frame to the file's.
* Textures: ``(T, T, 3)`` values in [0, 1] as 16-bit RGB PNG, row 0 at ``v = 0``.
* The portable result (GLB, OBJ + MTL + PNGs): :mod:`neurender.simplification.export`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from neurender import io
from neurender.simplification.mesh_ops import LowPolyMesh

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


def save_lowpoly(
    path: str | Path,
    low: LowPolyMesh,
    albedo: float | None,
    to_asset: np.ndarray | None = None,
) -> None:
    """The asset's QEM atlas mesh with its uniform ``albedo`` (None: the colour varies);
    ``to_asset`` is stored only when given (user assets)."""
    extra = {} if to_asset is None else {"to_asset": to_asset}
    io.save_npz(
        path,
        positions=low.positions,
        faces=low.faces,
        vmap=low.vmap,
        uvs=low.uvs,
        uv_faces=low.uv_faces,
        albedo=np.float64(np.nan if albedo is None else albedo),
        **extra,
    )


def load_lowpoly(path: str | Path) -> LowPolyMesh:
    d = io.load_npz(path)
    return LowPolyMesh(d["positions"], d["faces"], d["vmap"], d["uvs"], d["uv_faces"])


def load_albedo(path: str | Path) -> float | None:
    """The uniform grey albedo stored with a low-poly file, None where the colour varies."""
    d = io.load_npz(path)
    if "albedo" not in d:
        raise ValueError(
            f"{path} has no albedo entry (written by an older simplification_prepare); "
            "rerun it: snakemake --forcerun simplification_prepare ..."
        )
    albedo = float(d["albedo"])
    return None if np.isnan(albedo) else albedo


def load_to_asset(path: str | Path) -> np.ndarray:
    """The ``(4, 4)`` stage-to-file map of a low-poly file (identity when it has none)."""
    return io.load_npz(path).get("to_asset", np.eye(4))


def write_texture(path: str | Path, texture: np.ndarray) -> None:
    """A ``(T, T, 3)`` texture in [0, 1] (clipped) as a 16-bit PNG."""
    io.write_png(path, np.round(np.clip(texture, 0, 1) * 65535).astype(np.uint16))


def stored(texture: np.ndarray) -> np.ndarray:
    """A ``(T, T, 3)`` texture as :func:`write_texture` stores it and :func:`read_texture`
    reads it back (clipped to [0, 1], 16-bit), without the file."""
    return np.round(np.clip(texture, 0, 1) * 65535).astype(np.uint16).astype(np.float64) / 65535.0


def read_texture(path: str | Path) -> np.ndarray:
    """A texture written by :func:`write_texture` as ``(T, T, 3)`` float64 in [0, 1]."""
    return io.read_png(path)[..., :3].astype(np.float64) / 65535.0
