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


def import_mitsuba(device: str = "auto") -> tuple[ModuleType, ModuleType]:
    """Return ``(mitsuba, drjit)`` with a differentiable RGB variant set.

    Raises:
        RuntimeError: with the install command when Mitsuba or LLVM is missing.
    """
    if "DRJIT_LIBLLVM_PATH" not in os.environ and (llvm := bundled_llvm()):
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as err:
        raise RuntimeError(f"Mitsuba 3 is not installed ({err}); run: {INSTALL_HINT}") from err
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
