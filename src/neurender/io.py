"""File formats: OpenEXR (named float channels), PNG (8/16-bit), tidy CSV, NPZ, and the
YAML (or JSON) of config files.

Every writer is atomic: it writes a temporary file next to the target and renames it,
so a crash never leaves a half-written output that Snakemake or a reader would trust.
Every reader names the file in its error when the file is missing or unreadable.

Conventions: EXR holds linear float data, one 2-D ``(H, W)`` array per named channel
(e.g. ``P.x``, ``T.00``); PNG holds display-referred data as ``(H, W)`` or ``(H, W, C)``
unsigned integers (C = 1..4: grey, grey+alpha, RGB, RGBA).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import OpenEXR
import pandas as pd
import png
import yaml

from neurender import unique_keys, user_paths

#: Columns read as text exactly as written, whatever they hold (``NA``, ``None``, ``001``
#: and a blank are labels, not missing values or numbers): the tidy tables' and targets'
#: labels (:mod:`neurender.tables`) and the keys that hold the users' names: assets
#: (``case``, ``object``), maps (their file stems), metaball scenes; manifests' files.
TEXT_COLUMNS = (
    "method",
    "dataset",
    "model",
    "split",
    "metric",
    "subject",
    "check",
    "case",
    "object",
    "map",
    "scene",
    "file",
)

#: A training split whose arrays would take more memory than this (bytes) stays on disk
#: and is read one sample at a time (the papers' scale: NDR's 60 000 samples of 256^2
#: buffers are 470 GB as float32); smaller splits are read once into memory.
IN_MEMORY_LIMIT_BYTES = 8 * 2**30

PathLike = str | os.PathLike

# The process umask, read once at import (reading it means setting it, which would race
# with files other threads create later).
_UMASK = os.umask(0o022)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The temporary name keeps the suffix so libraries that pick a format from the
    extension still work. On any exception the temporary file is removed.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=target.suffix, dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates the file owner-only; give it the mode a plain open() would.
        os.chmod(tmp_path, 0o666 & ~_UMASK)
        os.replace(tmp_path, target)
    finally:
        tmp_path.unlink(missing_ok=True)


def write_json(path: PathLike, data: Any, indent: int | None = 2, **dumps: Any) -> None:
    """``data`` as JSON at ``path`` (``indent`` spaces, a final newline), atomically;
    ``dumps`` go to :func:`json.dumps` (``sort_keys``, ``default``). Serialised before
    the file is opened, so data that cannot be written leaves no file."""
    text = json.dumps(data, indent=indent, **dumps) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def _require_file(path: PathLike, what: str) -> Path:
    """``path`` as a Path; ``FileNotFoundError`` naming it and why when it is not a
    regular file (missing, a directory, a FIFO...)."""
    p = Path(path)
    problem = user_paths.file_problem(p)
    if problem:
        raise FileNotFoundError(f"{what} file {p} {problem}")
    return p


def write_exr(path: PathLike, channels: Mapping[str, np.ndarray], half: bool = False) -> None:
    """Write named channels to a scanline, ZIP-compressed OpenEXR file.

    Args:
        path: output ``.exr`` path.
        channels: name -> ``(H, W)`` array; all the same shape. float16 arrays are stored
            as half, everything else as float32 (or all as half with ``half=True``).
    """
    if not channels:
        raise ValueError(f"write_exr({path}): no channels given")
    shape = None
    data = {}
    for name, arr in channels.items():
        a = np.asarray(arr)
        if a.ndim != 2:
            raise ValueError(
                f"write_exr({path}): channel {name!r} has shape {a.shape}, expected (H, W)"
            )
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise ValueError(
                f"write_exr({path}): channel {name!r} has shape {a.shape}, others {shape}"
            )
        dtype = np.float16 if half or a.dtype == np.float16 else np.float32
        data[name] = np.ascontiguousarray(a, dtype=dtype)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, data) as f:
            f.write(str(tmp))


def read_exr(path: PathLike, names: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Read channels of an OpenEXR file.

    Args:
        path: ``.exr`` file.
        names: channels to read (all if ``None``); a missing one raises ``KeyError``
            naming the file and the channels it has.

    Returns:
        name -> ``(H, W)`` array (float32 or float16 as stored), in file order.
    """
    p = _require_file(path, "EXR")
    try:
        with OpenEXR.File(str(p), separate_channels=True) as f:
            # Copy inside the block: the pixel buffers are released when the file closes.
            stored = {k: np.array(v.pixels) for k, v in f.channels().items()}
    except Exception as err:  # OpenEXR raises plain RuntimeError/ValueError for corrupt data
        raise OSError(f"cannot read EXR file {p}: {err}") from err
    if names is None:
        return stored
    missing = [n for n in names if n not in stored]
    if missing:
        raise KeyError(f"EXR file {p} lacks channels {missing}; it has {sorted(stored)}")
    return {n: stored[n] for n in names}


def write_png(path: PathLike, image: np.ndarray) -> None:
    """Write a uint8 or uint16 image, ``(H, W)`` or ``(H, W, C)`` with C in 1..4, as PNG."""
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"write_png({path}): dtype {img.dtype}, expected uint8 or uint16")
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3 or not 1 <= img.shape[2] <= 4:
        raise ValueError(f"write_png({path}): shape {image.shape}, expected (H, W) or (H, W, 1..4)")
    h, w, c = img.shape
    writer = png.Writer(
        width=w, height=h, greyscale=c <= 2, alpha=c in (2, 4), bitdepth=8 * img.dtype.itemsize
    )
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        writer.write(f, img.reshape(h, w * c))


def read_png(path: PathLike) -> np.ndarray:
    """Read a PNG as ``(H, W, C)`` uint8 or uint16 (palette images are expanded)."""
    p = _require_file(path, "PNG")
    try:
        w, h, rows, info = png.Reader(filename=str(p)).asDirect()
        data = np.vstack([np.asarray(r) for r in rows])
    except png.Error as err:
        raise OSError(f"cannot read PNG file {p}: {err}") from err
    dtype = np.uint16 if info["bitdepth"] > 8 else np.uint8
    return data.astype(dtype).reshape(h, w, info["planes"])


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Quantise values in [0, 1] (clipped) to uint8 with rounding."""
    return np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)


def write_csv(path: PathLike, frame: pd.DataFrame) -> None:
    """Write a data frame as CSV without the index."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False)


def read_csv(
    path: PathLike, required: Sequence[str] = (), text: Sequence[str] = TEXT_COLUMNS
) -> pd.DataFrame:
    """Read a CSV and check it has the ``required`` columns.

    The columns named in ``text`` are strings exactly as written (a blank cell is ``""``);
    the others are parsed as pandas does (numbers, booleans, blanks and ``NA``-like cells
    as NaN), so a tidy table written by :func:`write_csv` reads back equal.

    Raises:
        OSError: naming the file: missing or not a regular file, not UTF-8, a row longer
            than the header, or separated by semicolons or tabs rather than commas.
        ValueError: naming the file, the missing ``required`` columns and those it has.
    """
    p = _require_file(path, "CSV")
    _check_separator(p)
    try:
        # index_col=False: a row longer than the header is an error, not an index column
        # that shifts every value one column to the right.
        with warnings.catch_warnings():
            warnings.simplefilter("error", pd.errors.ParserWarning)
            frame = pd.read_csv(p, index_col=False)
            labels = [c for c in frame.columns if c in set(text)]
            if labels:
                raw = pd.read_csv(
                    p, index_col=False, usecols=labels, dtype=str, keep_default_na=False
                )
                frame[labels] = raw[labels].fillna("")  # "" also for a short row's cells
    except pd.errors.ParserWarning as err:
        raise OSError(f"cannot parse CSV file {p}: a row has more cells than the header") from err
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise OSError(f"cannot parse CSV file {p}: {err}") from err
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise ValueError(f"CSV file {p} lacks columns {missing}; it has {list(frame.columns)}")
    return frame


def _check_separator(p: Path) -> None:
    """Refuse a CSV whose header has no comma but another separator: a spreadsheet set to
    a locale with decimal commas saves ``;``-separated files, which would otherwise read as
    one column named by the whole header, or fail on the rows' decimal commas."""
    with open(p, encoding="utf-8", errors="replace") as f:
        header = f.readline().strip()
    if "," in header:
        return
    for separator, name in ((";", "semicolons"), ("\t", "tabs")):
        if separator in header:
            raise OSError(
                f"cannot parse CSV file {p}: it is separated by {name}, not commas "
                f"(header {header!r}); "
                "expected comma-separated columns with '.' as the decimal point (in a "
                "spreadsheet: save as 'CSV (comma delimited)' with an English locale)"
            )


def read_yaml(path: PathLike) -> Any:
    """The data of a YAML config or other user YAML file, read as Snakemake reads a
    ``--configfile``: as JSON when the text is JSON, else as ``yaml.safe_load`` reads it,
    except that a mapping setting one key twice is refused (:mod:`neurender.unique_keys`).

    Raises:
        FileNotFoundError: naming the file when it is missing (or not a regular file).
        neurender.unique_keys.DuplicateKeyError: naming the file, each repeated key's dotted
            path (``ndr.width``) and (YAML) the lines that set it.
        yaml.YAMLError: naming the file, line and column of a syntax error.
        OSError: naming the file when it is not UTF-8 text.
    """
    p = _require_file(path, "YAML")
    try:
        text = p.read_text(encoding="utf-8")  # Snakemake's encoding for config files
    except UnicodeDecodeError as err:
        raise OSError(f"cannot read YAML file {p}: not UTF-8 text ({err})") from err
    try:
        return unique_keys.load_json(text, str(p))
    except json.JSONDecodeError:
        return unique_keys.load_yaml(text, str(p))
    except unique_keys.DuplicateKeyError as err:
        try:  # JSON is YAML (but for tabs), whose reader also knows the lines
            unique_keys.load_yaml(text, str(p))
        except unique_keys.DuplicateKeyError as located:
            raise located from None
        except yaml.YAMLError:
            pass
        raise err


def save_npz(path: PathLike, **arrays: np.ndarray) -> None:
    """Save arrays to an uncompressed ``.npz`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)


def load_npz(path: PathLike) -> dict[str, np.ndarray]:
    p = _require_file(path, "NPZ")
    try:
        with np.load(p) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise OSError(f"cannot read NPZ file {p}: {err}") from err


def copy_file(source: PathLike, target: PathLike) -> None:
    """Copy ``source``'s bytes to ``target`` atomically (``target`` appears whole or not
    at all)."""
    source = _require_file(source, "source")
    with atomic_path(target) as tmp:
        shutil.copyfile(source, tmp)


def checksum(paths: Sequence[PathLike]) -> str:
    """SHA-256 over the contents of files (a folder: every file below it, in sorted order)
    and their names relative to the given path: a fingerprint of a job's inputs."""
    digest = hashlib.sha256()
    for path in map(Path, paths):
        files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
        for file in files:
            _require_file(file, "input")
            digest.update(str(file.relative_to(path) if path.is_dir() else file.name).encode())
            with open(file, "rb") as f:
                for block in iter(lambda f=f: f.read(1 << 20), b""):
                    digest.update(block)
    return digest.hexdigest()
