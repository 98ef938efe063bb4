"""Files the report's interactive viewers read (``src/neurender/report/viewer/viewers.js``).

A viewer file is JSON: ``{"kind": ..., "title": ..., "data": {...}}`` with binary arrays
base64-encoded (little-endian, C order), so the report can embed it in a page that opens
from disk. Kinds and their ``data``:

* ``prt``: ``positions`` float32 ``(V, 3)``, ``indices`` uint32 ``(F, 3)``,
  ``coefficients`` ``K``, ``transfer`` model -> float32 ``(V, K)`` diffuse transfer (the
  first model is the ground truth), ``probes`` name -> ``{"turns": [degrees...],
  "lights": float32 (T, K, 3)}`` SH light per turn about +y.
* ``meshes``: ``meshes`` name -> GLB bytes, ``captions`` name -> text.
* ``frames``: ``frames`` name -> list of PNG bytes (one per step), optional ``overlay``
  name -> list of PNG bytes, ``label`` of the slider, ``overlay_label``, ``scale`` (the
  on-screen magnification of the images).
"""

from __future__ import annotations

import base64
import io as _io
import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from neurender import io

KINDS = ("prt", "meshes", "frames")


def b64_array(array: np.ndarray, dtype: str) -> str:
    """An array as base64 of its little-endian bytes in C order."""
    return base64.b64encode(
        np.ascontiguousarray(array, np.dtype(dtype).newbyteorder("<")).tobytes()
    ).decode()


def b64_bytes(data: bytes) -> str:
    return base64.b64encode(data).decode()


def b64_png(image: np.ndarray) -> str:
    """A ``(H, W[, C])`` uint8 image as base64 PNG."""
    buffer = _io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG", optimize=True)
    return b64_bytes(buffer.getvalue())


def write(path: str | Path, kind: str, title: str, data: dict[str, Any]) -> None:
    """Write a viewer file atomically."""
    if kind not in KINDS:
        raise ValueError(f"viewer kind {kind!r}: expected one of {KINDS}")
    with io.atomic_path(path) as tmp:
        tmp.write_text(json.dumps({"kind": kind, "title": title, "data": data}), encoding="utf-8")


def read(path: str | Path) -> dict[str, Any]:
    """A viewer file's ``{"kind", "title", "data"}``, naming the file if it is not one."""
    p = Path(path)
    try:
        viewer = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise OSError(f"cannot read viewer file {p}: {err}") from err
    if viewer.get("kind") not in KINDS or "data" not in viewer:
        raise ValueError(f"viewer file {p}: expected a kind among {KINDS} and data")
    return viewer
