"""Mitsuba 3 for every stage: import a differentiable variant that runs here, build meshes.

``device='auto'`` picks ``cuda_ad_rgb`` when Dr.Jit finds a CUDA driver, else
``llvm_ad_rgb``. The LLVM variants need an LLVM >= 16 shared library: pip installs one
with ``karellen-llvm-core`` (``<prefix>/lib/libLLVM.so.*``), which is pointed to through
``DRJIT_LIBLLVM_PATH`` before Mitsuba loads unless the user already set it (a conda
``libllvm`` or Debian's ``libllvm19`` work the same way).
"""

from __future__ import annotations

import glob
import os
import sys
from types import ModuleType

import numpy as np

from neurender.geometry import vertex_normals

INSTALL_HINT = "pip install mitsuba karellen-llvm-core (or conda install -c conda-forge libllvm19)"


def bundled_llvm() -> str | None:
    """Path of the LLVM shared library installed into this environment, if any."""
    found = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libLLVM.so*")))
    found += sorted(glob.glob(os.path.join(sys.prefix, "lib", "libLLVM-*.so")))
    return found[-1] if found else None


def variant_for(device: str, has_cuda: bool) -> str:
    """Mitsuba variant for a config ``device`` (``auto``, ``cpu``, ``cuda``, ``cuda:N``)."""
    if device == "cpu":
        return "llvm_ad_rgb"
    if device.startswith("cuda"):
        if not has_cuda:
            raise RuntimeError(f"device {device!r} requested but Dr.Jit finds no CUDA driver")
        return "cuda_ad_rgb"
    if device != "auto":
        raise ValueError(f"device {device!r}: expected auto, cpu, cuda or cuda:N")
    return "cuda_ad_rgb" if has_cuda else "llvm_ad_rgb"


def _import() -> tuple[ModuleType, ModuleType]:
    """``(mitsuba, drjit)``, imported with the LLVM library pointed to first."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ and (llvm := bundled_llvm()):
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as err:
        raise RuntimeError(f"Mitsuba 3 is not installed ({err}); run: {INSTALL_HINT}") from err
    return mi, dr


def cuda_available() -> bool:
    """Whether Dr.Jit finds a CUDA driver (Mitsuba's ``cuda_ad_rgb`` can run)."""
    _, dr = _import()
    return bool(dr.has_backend(dr.JitBackend.CUDA))


def import_mitsuba(device: str = "auto") -> tuple[ModuleType, ModuleType]:
    """Return ``(mitsuba, drjit)`` with a differentiable RGB variant set.

    Raises:
        RuntimeError: with the install command when Mitsuba or LLVM is missing.
    """
    mi, dr = _import()
    variant = variant_for(device, dr.has_backend(dr.JitBackend.CUDA))
    if variant.startswith("llvm") and not dr.has_backend(dr.JitBackend.LLVM):
        raise RuntimeError(
            "Mitsuba's llvm_ad_rgb variant needs an LLVM >= 16 shared library and Dr.Jit "
            f"found none (DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH')!r}); "
            f"run: {INSTALL_HINT}"
        )
    mi.set_variant(variant)
    return mi, dr


def require_mitsuba(device: str = "auto") -> tuple[ModuleType, ModuleType]:
    """:func:`import_mitsuba` for job scripts: a missing install ends the job with the
    one-line message saying what to install instead of a stack trace."""
    try:
        return import_mitsuba(device)
    except RuntimeError as err:
        raise SystemExit(f"error: {err}") from None


def mesh(
    mi: ModuleType,
    positions: np.ndarray,
    faces: np.ndarray,
    bsdf: dict,
    uvs: np.ndarray | None = None,
    normals: np.ndarray | None = None,
    name: str = "mesh",
):
    """A Mitsuba triangle mesh built in memory.

    Args:
        positions: ``(V, 3)`` world positions; faces: ``(F, 3)`` vertex indices.
        bsdf: a BSDF dict for ``mi.load_dict``.
        uvs: optional ``(V, 2)`` texture coordinates.
        normals: ``(V, 3)`` unit vertex normals Mitsuba shades with (default: the
            area-weighted ones of :func:`neurender.geometry.vertex_normals`). Mitsuba does
            not recompute them when the positions change later.
    """
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    shape = mi.Mesh(
        name,
        len(positions),
        len(faces),
        has_vertex_normals=True,
        has_vertex_texcoords=uvs is not None,
        props=props,
    )
    params = mi.traverse(shape)
    params["vertex_positions"] = np.ravel(positions).astype(np.float32)
    params["faces"] = np.ravel(faces).astype(np.uint32)
    if normals is None:
        normals = vertex_normals(positions, faces)
    params["vertex_normals"] = np.ravel(normals).astype(np.float32)
    if uvs is not None:
        params["vertex_texcoords"] = np.ravel(uvs).astype(np.float32)
    params.update()
    return shape


#: Rows of Mitsuba's map per row of ours in :func:`envmap_rows` (1 of each cell's ``k``
#: rows is an edge, the rest hold the texel's value).
ENVMAP_SUBROWS = 4


def envmap_rows(latlong: np.ndarray, subrows: int = ENVMAP_SUBROWS) -> np.ndarray:
    """Our lat-long map ``(H, W, C)`` as the bitmap ``(subrows H + 1, W, C)`` to hand to
    Mitsuba's ``envmap``, so that both agree on where each texel is.

    Mitsuba's ``envmap`` interpolates its bitmap bilinearly with columns at texel centres
    (``phi = 2 pi (c + 0.5) / W``, as ours) but rows on a grid that includes both poles
    (``theta = pi r / (H - 1)``), not at centres (``theta = pi (r + 0.5) / H``, ours, see
    :mod:`neurender.sh`): handed over as it is, the map would be shifted by up to half a
    texel in elevation, and a sun in one texel would light the scene from the wrong angle.
    Here each of our rows becomes ``subrows`` Mitsuba rows: the cell's edges hold the mean of
    the two neighbouring texels (the poles the first and last row), the rows inside it the
    texel itself. Mitsuba then returns our value exactly at every texel centre and in the
    middle of each cell, blending only near the cell's edges (power is kept to first order).
    """
    if subrows < 2:
        raise ValueError(f"envmap_rows: subrows must be at least 2, got {subrows}")
    height = latlong.shape[0]
    out = np.repeat(latlong, subrows, axis=0)
    edges = np.concatenate([latlong[:1], 0.5 * (latlong[:-1] + latlong[1:]), latlong[-1:]], axis=0)
    out = np.concatenate([out, latlong[-1:]], axis=0)  # subrows H + 1 rows
    out[::subrows] = edges
    assert out.shape[0] == subrows * height + 1
    return np.ascontiguousarray(out, dtype=np.float32)
