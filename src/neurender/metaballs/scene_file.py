"""A user's metaball scenes CSV (``metaballs.user_scenes``), read and checked.

Plain numpy and pandas (no torch): the config check reads the file when the DAG is built.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from neurender import io

COLUMNS = ("scene", "x", "y", "z", "radius", "r", "g", "b")
NUMBERS = COLUMNS[1:]
#: The field's value on the surface: :data:`neurender.metaball.THRESHOLD` (that module
#: imports torch, which the DAG-time check does not).
SURFACE_FIELD = 1.0


def _rows(mask: pd.Series | np.ndarray) -> str:
    """The file's line numbers (the header is line 1) of the rows in ``mask``, a few."""
    lines = [str(i + 2) for i in np.flatnonzero(np.asarray(mask))]
    return ", ".join(lines[:5]) + (f" and {len(lines) - 5} more" if len(lines) > 5 else "")


def read_user_scenes(path: str | Path) -> pd.DataFrame:
    """The balls of a scenes CSV, checked: columns :data:`COLUMNS` (``scene`` the label
    as written, text; the rest float64), in file order. Line numbers in messages count
    the header as line 1 (a spreadsheet's row numbers).

    Raises:
        ValueError: naming the file and the lines: a missing column, no rows, a value
            that is not a finite number, a radius <= 0, a colour outside [0, 1], a centre
            not in front of the camera (z <= 0), a blank scene label, a scene whose surface
            holds the camera (:func:`camera_inside`).
        OSError: a path that is not a regular file (missing, a directory, a FIFO) or
            does not parse as CSV (a row longer than the header, an unclosed quote).
    """
    frame = io.read_csv(path, COLUMNS)
    if frame.empty:
        raise ValueError(f"metaball scenes {path} has no rows (one row per ball)")
    # Labels are text exactly as written (io.read_csv): 001, 1 and 1.0 are three scenes,
    # NA and null are labels; a ball without one would silently join no scene.
    blank = frame["scene"].str.strip() == ""
    if blank.any():
        raise ValueError(
            f"metaball scenes {path}: a ball without a scene label on line(s) {_rows(blank)} "
            "(the header is line 1); give every row its scene's label"
        )
    out = pd.DataFrame({"scene": frame["scene"]})
    for column in NUMBERS:
        values = pd.to_numeric(frame[column], errors="coerce").astype(float)
        bad = ~np.isfinite(values)
        if bad.any():
            raise ValueError(
                f"metaball scenes {path}: column {column} is not a finite number on line(s) "
                f"{_rows(bad)}"
            )
        out[column] = values
    checks = (
        (out["radius"] <= 0, "radius must be > 0"),
        (
            ~out[["r", "g", "b"]].apply(lambda c: c.between(0, 1)).all(axis=1),
            "r, g, b must lie in [0, 1]",
        ),
        (out["z"] <= 0, "z must be > 0 (in front of the camera, which looks along +z)"),
    )
    for bad, rule in checks:
        if bad.any():
            raise ValueError(f"metaball scenes {path}: {rule}; not so on line(s) {_rows(bad)}")
    inside = camera_inside(out)
    if inside:
        more = f" (and {len(inside) - 1} more scene(s) alike)" if len(inside) > 1 else ""
        raise ValueError(f"metaball scenes {path}: {inside[0]}{more}")
    return out


def camera_inside(balls: pd.DataFrame) -> list[str]:
    """One problem per scene of ``balls`` (columns :data:`COLUMNS`, rows in file order)
    whose surface holds the camera (the origin): field ``sum r^2 / |c|^2`` there at least
    :data:`SURFACE_FIELD`. Every pixel would then show the inside of the surface, a flat wall
    at the near plane, and no score means anything. Each names the scene and the lines of
    the balls whose sphere holds the camera (else of all the scene's balls, which do together).
    """
    distance = np.sqrt(balls["x"] ** 2 + balls["y"] ** 2 + balls["z"] ** 2).to_numpy()
    share = balls["radius"].to_numpy() ** 2 / distance**2
    labels = balls["scene"].to_numpy()
    notes = []
    for scene in dict.fromkeys(labels):
        rows = labels == scene
        field = float(share[rows].sum())
        if field < SURFACE_FIELD:
            continue
        own = rows & (share >= SURFACE_FIELD)  # balls whose own sphere holds the camera
        culprits = own if own.any() else rows
        first = int(np.flatnonzero(culprits)[0])
        where = "it lies inside the ball(s)" if own.any() else "the balls together reach it,"
        notes.append(
            f"scene {scene!r}: the camera (at the origin) is inside the metaball surface (field "
            f"{field:.3g} there, the surface at {SURFACE_FIELD:g}), so every pixel would show a "
            f"flat wall at the near plane; {where} on line(s) {_rows(culprits)} "
            f"(line {first + 2}: radius {balls['radius'].iloc[first]:g} at distance "
            f"{distance[first]:.3g}). "
            f"Expected a field below {SURFACE_FIELD:g} at the camera: radii well below the "
            "balls' distances from it"
        )
    return notes
