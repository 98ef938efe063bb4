"""Paths the user writes in the config: how they are normalised, listed and checked.

Standard library only: the Snakefile and :mod:`neurender.config` use it when the DAG is
built. Conventions:

- A path is relative to the working directory (the repository root) or absolute; a
  leading ``./`` and ``a/../b`` are spelled out the same way (:func:`normalise`), so
  ``./results/examples/crate.obj`` is the workflow's output ``results/examples/crate.obj``.
- A folder stands for its regular files, hidden ones left out (``.DS_Store``, macOS's
  ``._frame_001.obj`` resource forks, editors' ``.swp``); a glob for what it matches
  (hidden names only when the pattern names them, as :func:`glob.glob` does).
- Suffixes compare case-insensitively (``B.EXR`` is an EXR map).
"""

from __future__ import annotations

import glob
import os
import re
import stat
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

#: A ``{name}`` or ``{name,constraint}`` that Snakemake reads as a wildcard in any input
#: path (its ``WILDCARD_REGEX``, which has no escape for literal braces).
_WILDCARD = re.compile(r"\{\s*[.\w]+(\s*,\s*([^{}]+|\{\d+(,\d+)?\})*)?\s*\}")


def normalise(path: str) -> str:
    """``path`` with ``./``, doubled slashes and ``a/../b`` spelled out (POSIX style);
    ``""`` stays ``""``."""
    return os.path.normpath(path) if path else path


def made_by_the_workflow(path: str) -> bool:
    """Paths under ``results/`` (after :func:`normalise`) are outputs of the workflow
    (e.g. the example assets), checked when the job that makes them has run."""
    return bool(path) and Path(normalise(path)).parts[:1] == ("results",)


def as_input(path: str) -> str:
    """``path`` as a Snakemake input: a workflow output (:func:`made_by_the_workflow`)
    spelled as the rule that makes it spells it, any other path as written (``a/../b``
    through a symlinked ``a`` is not ``b``)."""
    return normalise(path) if made_by_the_workflow(path) else path


def file_problem(path: str | os.PathLike) -> str | None:
    """What ``path`` is when it is no regular file (symbolic links followed), as words
    that follow its name: ``does not exist``, ``is a folder, not a file``, ``is a named
    pipe (FIFO), not a file`` ...; ``None`` for a regular file. A FIFO is never opened
    (reading one waits for a writer)."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        if path.is_symlink():
            return f"is a symbolic link to {path.readlink()}, which does not exist"
        return "does not exist"
    except OSError as err:
        return f"cannot be examined ({err.strerror or err})"
    if stat.S_ISREG(mode):
        return None
    kinds = {
        stat.S_ISDIR: "a folder",
        stat.S_ISFIFO: "a named pipe (FIFO)",
        stat.S_ISSOCK: "a socket",
        stat.S_ISCHR: "a character device",
        stat.S_ISBLK: "a block device",
    }
    kind = next((word for test, word in kinds.items() if test(mode)), "not a regular file")
    return f"is {kind}, not a file"


def is_hidden(path: Path) -> bool:
    """A dot file (``.DS_Store``, ``._frame.obj``): left out of folders."""
    return path.name.startswith(".")


def files_of(path: str) -> list[Path]:
    """The regular files behind one user path, sorted: the visible files of a folder, the
    matches of a glob, or the file itself (whatever it is, for the caller to check)."""
    p = Path(path)
    if p.is_dir():
        return sorted(q for q in p.iterdir() if q.is_file() and not is_hidden(q))
    if glob.has_magic(path):
        return sorted(q for q in map(Path, glob.glob(path)) if q.is_file())
    return [p]


def with_suffix(paths: Iterable[Path], suffixes: Iterable[str]) -> list[Path]:
    """The ``paths`` whose suffix is one of ``suffixes`` (lowercase, with the dot), in any
    case, in the given order."""
    wanted = {s.lower() for s in suffixes}
    return [p for p in paths if p.suffix.lower() in wanted]


def wildcard_problem(path: str | os.PathLike) -> str | None:
    """A message when ``path`` holds ``{...}`` that Snakemake would read as a wildcard
    (``balls{v2}.csv``), else ``None``. Snakemake has no escape for literal braces in
    input files, so such a file cannot be an input; rename it (or its folder)."""
    found = _WILDCARD.search(str(path))
    if not found:
        return None
    return (
        f"{path} contains {found.group(0)!r}, which Snakemake reads as a wildcard in an "
        "input file (it has no escape for literal braces); rename the file or folder "
        "without braces"
    )


def config_paths(config: Mapping) -> Iterator[tuple[str, str]]:
    """Every path the user wrote in the (defaults-filled) ``config``, as ``(key, path)``
    (``key`` spelled as in messages, e.g. ``ndr.user_objects.rock``); empty ones left out."""
    prt, ndr = config["prt"], config["ndr"]
    for section in ("user_meshes", "user_probes"):
        for name, path in prt[section].items():
            yield f"prt.{section}.{name}", path
    for name, entry in prt["user_sequences"].items():
        for field in ("frames", "test_frames"):
            yield f"prt.user_sequences.{name}.{field}", entry[field]
    for name, path in ndr["user_objects"].items():
        yield f"ndr.user_objects.{name}", path
    yield "ndr.user_probes_dir", ndr["user_probes_dir"]
    yield "metaballs.user_scenes", config["metaballs"]["user_scenes"]
    for name, entry in config["simplification"]["user_assets"].items():
        yield f"simplification.user_assets.{name}.path", entry["path"]


#: Keys whose file is a mesh that names other files (MTL, textures, glTF buffers).
ASSET_KEYS = ("ndr.user_objects.", "simplification.user_assets.")


def _inputs(key: str, path: str) -> list[str]:
    """The files a user path brings into the DAG: its folder's or glob's files, and the
    files a mesh names (:func:`neurender.asset_files.asset_inputs`)."""
    files = [path, *map(str, files_of(path))]
    if key.startswith(ASSET_KEYS) and file_problem(path) is None:
        from neurender.asset_files import asset_inputs  # lazily: it may import this module

        try:
            files += asset_inputs(path)
        except (OSError, ValueError):  # an unreadable mesh is named by the asset check
            pass
    return files


def problems(config: Mapping) -> Iterator[str]:
    """Problems every user path shares, one sentence each naming the key and the file:
    braces Snakemake would read as a wildcard, in the path, in a file of its folder or
    glob, or in a file a mesh names (the workflow's own paths are checked as written)."""
    for key, path in config_paths(config):
        if not path:
            continue
        files = [path] if made_by_the_workflow(path) else _inputs(key, path)
        for file in dict.fromkeys(files):
            problem = wildcard_problem(file)
            if problem:
                yield f"{key} = {path!r}: {problem}"
                break
