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
  on-screen magnification of the images), optional ``steps`` (one label per slider step,
  shown beside the slider).
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
#: Turns of a light or map about +y that relighting viewers offer (360 / TURNS apart).
TURNS = 24


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


def decode_array(text: str, dtype: str, shape: tuple[int, ...] = (-1,)) -> np.ndarray:
    """The inverse of :func:`b64_array`: a ``dtype`` array of ``shape`` (native order)."""
    little = np.dtype(dtype).newbyteorder("<")
    return np.frombuffer(base64.b64decode(text), little).astype(np.dtype(dtype)).reshape(shape)


def decode_png(text: str) -> np.ndarray:
    """The inverse of :func:`b64_png`: a ``(H, W[, C])`` uint8 image."""
    return np.asarray(Image.open(_io.BytesIO(base64.b64decode(text))))


#: Colours of :func:`mask_difference`: covered only by the candidate, only by the reference.
EXTRA_COLOUR = (255, 40, 40)
MISSING_COLOUR = (40, 160, 255)


def mask_difference(mask: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """An ``(H, W, 4)`` uint8 RGBA overlay of two ``(H, W)`` bool masks: opaque
    :data:`EXTRA_COLOUR` where only ``mask`` covers, :data:`MISSING_COLOUR` where only
    ``reference`` does, transparent where they agree."""
    mask, reference = np.asarray(mask, bool), np.asarray(reference, bool)
    if mask.shape != reference.shape:
        raise ValueError(f"mask {mask.shape} and reference {reference.shape} differ in shape")
    out = np.zeros((*mask.shape, 4), np.uint8)
    out[mask & ~reference] = (*EXTRA_COLOUR, 255)
    out[reference & ~mask] = (*MISSING_COLOUR, 255)
    return out


def frames_data(
    frames: dict[str, list[np.ndarray]],
    label: str,
    scale: int,
    overlay: dict[str, list[np.ndarray]] | None = None,
    overlay_label: str = "",
    steps: list[str] | None = None,
) -> dict[str, Any]:
    """The ``data`` of a ``frames`` viewer: per panel name, one uint8 image ``(H, W[, C])``
    per slider step (every panel the same count); ``overlay`` panels (a subset, RGBA)
    drawn on top when the reader ticks ``overlay_label``; ``steps`` labels the steps."""
    counts = {name: len(images) for name, images in frames.items()}
    if not counts or len(set(counts.values())) != 1 or 0 in counts.values():
        raise ValueError(f"frames viewer: every panel needs the same number of images: {counts}")
    extra = set(overlay or {}) - set(frames)
    if extra or any(len(v) != len(frames[k]) for k, v in (overlay or {}).items()):
        raise ValueError(f"frames viewer: overlays {sorted(overlay or {})} must match panels")
    data: dict[str, Any] = {
        "frames": {name: [b64_png(im) for im in images] for name, images in frames.items()},
        "label": label,
        "scale": int(scale),
    }
    if steps is not None:
        if len(steps) != next(iter(counts.values())):
            raise ValueError(f"frames viewer: {len(steps)} step labels for {counts} images")
        data["steps"] = list(steps)
    if overlay:
        data["overlay"] = {name: [b64_png(im) for im in ims] for name, ims in overlay.items()}
        data["overlay_label"] = overlay_label
    return data


def display_scale(width: int, target: int = 256) -> int:
    """The whole-number on-screen magnification that shows ``width``-pixel images at about
    ``target`` pixels (at least 1)."""
    return max(1, round(target / width))


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
