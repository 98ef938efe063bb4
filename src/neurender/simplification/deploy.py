"""The optimised asset as the files it ships as, checked and timed: the one place a case's
result (its optimised positions and maps, :mod:`neurender.simplification.optimise`)
becomes its GLB and OBJ + MTL + PNG textures (:func:`neurender.simplification.export.
export`, in the asset file's own units).

Each file is read back as a user's tool reads it (trimesh, through
:func:`neurender.simplification.export.reimport`, into the stage's frame) and compared,
corner by corner of every triangle, with the mesh it was written from: the triangle count
exactly, positions to :data:`POSITION_TOLERANCE` of the mesh's size (its bounding box's
longest side), texture coordinates to :data:`UV_TOLERANCE`; a file beyond them is an error
naming it (:class:`ReadBackError`), so a broken export never reaches the evaluation. The
textures' 8-bit quantisation and the normal map's change of tangent frame are checked by
the evaluation, which renders both files read back beside ours.

The deployment table (``results/simplification/{case}/deployment.csv``) is tidy: ``case,
file, quantity, value``: per exported file its ``bytes``; for the GLB and the OBJ also the
``triangles`` read back and the largest read-back errors (``max_position_error``, a
fraction of the mesh's size; ``max_uv_error``); for the whole export (file ``all``) its
``export_seconds`` (the GLB and the OBJ are written from one glTF primitive) and the
seconds of the read-back checks, ``read_back_seconds``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from neurender.simplification import export
from neurender.simplification.mesh_ops import LowPolyMesh

#: Largest |read back - written| of a vertex position, as a fraction of the mesh's size:
#: float32 (the GLB's offsets from its node's translation) is good to about 1e-7 of it.
POSITION_TOLERANCE = 1e-6
#: Largest |read back - written| of a texture coordinate (float32 in the GLB, nine digits
#: in the OBJ).
UV_TOLERANCE = 1e-6
#: The files read back and compared, by their key in
#: :data:`neurender.simplification.EXPORT_FILES`.
READ_BACK = ("glb", "obj")
COLUMNS = ["case", "file", "quantity", "value"]


class ReadBackError(ValueError):
    """An exported file that does not read back as the mesh it was written from."""


def read_back_errors(
    path: str | Path, low: LowPolyMesh, positions: np.ndarray, to_asset: np.ndarray
) -> dict[str, float]:
    """The file at ``path`` (GLB or OBJ) read back into the stage's frame and compared
    with the atlas mesh ``low`` at welded ``positions (V, 3)``, corner by corner of each
    triangle (in the file's triangle order, which the export keeps): its ``triangles``,
    ``max_position_error`` (a fraction of the bounding box's longest side, infinite for
    another triangle count) and ``max_uv_error``."""
    back, _, _ = export.reimport(path, to_asset)
    triangles = len(back.uv_faces)
    if triangles != len(low.uv_faces):
        return {"triangles": triangles, "max_position_error": np.inf, "max_uv_error": np.inf}
    written = low.atlas_positions(positions)[low.uv_faces]
    read = back.atlas_positions()[back.uv_faces]
    size = float(np.ptp(positions, axis=0).max())
    uv_error = np.abs(back.uvs[back.uv_faces] - low.uvs[low.uv_faces]).max()
    return {
        "triangles": triangles,
        "max_position_error": float(np.abs(read - written).max() / size),
        "max_uv_error": float(uv_error),
    }


def check(path: str | Path, errors: Mapping[str, float], triangles: int) -> None:
    """Raise :class:`ReadBackError` naming ``path`` when its read-back ``errors``
    (:func:`read_back_errors`) exceed the tolerances or its triangle count differs from the
    ``triangles`` written."""
    if errors["triangles"] != triangles:
        raise ReadBackError(
            f"{path} reads back with {errors['triangles']} triangles; {triangles} were written"
        )
    for name, tolerance in (
        ("max_position_error", POSITION_TOLERANCE),
        ("max_uv_error", UV_TOLERANCE),
    ):
        if not errors[name] <= tolerance:
            raise ReadBackError(
                f"{path} reads back with {name} = {errors[name]:.3g}; expected at most "
                f"{tolerance:g} (positions as a fraction of the mesh's size)"
            )


def deploy(
    case: str,
    paths: Mapping[str, str | Path],
    low: LowPolyMesh,
    positions: np.ndarray,
    albedo: np.ndarray,
    normal_map: np.ndarray,
    to_asset: np.ndarray,
) -> pd.DataFrame:
    """Export the optimised asset of ``case`` to ``paths`` (the keys of
    :data:`neurender.simplification.EXPORT_FILES`; arguments as
    :func:`neurender.simplification.export.export`), read the GLB and the OBJ back and
    :func:`check` them; the deployment table's rows (module docstring)."""
    started = time.perf_counter()
    export.export(paths, low, positions, albedo, normal_map, to_asset)
    exported = time.perf_counter() - started
    rows = [(Path(path).name, "bytes", Path(path).stat().st_size) for path in paths.values()]
    started = time.perf_counter()
    for key in READ_BACK:
        errors = read_back_errors(paths[key], low, positions, to_asset)
        check(paths[key], errors, len(low.uv_faces))
        rows += [(Path(paths[key]).name, name, value) for name, value in errors.items()]
    checked = time.perf_counter() - started
    rows += [("all", "export_seconds", exported), ("all", "read_back_seconds", checked)]
    frame = pd.DataFrame(rows, columns=COLUMNS[1:]).astype({"value": float})
    frame.insert(0, "case", case)
    return frame
