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
- A folder of inputs may hold notes beside them (``README``, ``LICENSE.txt``,
  :func:`is_note`); a reader of such a folder refuses any other file it does not read
  rather than leave it out unsaid.
"""

from __future__ import annotations

import glob
import os
import re
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

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


def workdir_relative(path: str | os.PathLike) -> str:
    """``path`` relative to the working directory when it lies inside it (``.``,
    ``config/smoke.yaml``), else absolute (a config file in the home folder). Job params
    hold paths in this form: Snakemake records params per output (``.snakemake/metadata``)
    and makes ``--configfile`` paths absolute, so an absolute path there would rerun the
    jobs of a checkout moved or copied elsewhere with its results."""
    absolute = os.path.abspath(path)
    relative = os.path.relpath(absolute)
    if relative == os.pardir or relative.startswith(os.pardir + os.sep):
        return absolute
    return relative


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


#: Files meant for people that a folder of inputs may hold beside them (an HDRI site's
#: licence, the user's notes): by suffix, or by name whatever the suffix.
NOTE_SUFFIXES = (".txt", ".md", ".rst", ".pdf", ".html", ".htm")
NOTE_STEMS = ("readme", "license", "licence", "copying", "credits", "notice", "authors")


def is_note(path: Path) -> bool:
    """A note or licence (:data:`NOTE_SUFFIXES`, :data:`NOTE_STEMS`; any case):
    ``README``, ``LICENSE.txt``, ``sources.md``."""
    name = path.name.lower()
    return path.suffix.lower() in NOTE_SUFFIXES or name.split(".")[0] in NOTE_STEMS


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


class UserPath(NamedTuple):
    """One path the user wrote in the (defaults-filled) config, as a method's record lists
    it (:attr:`neurender.method.Method.user_paths`).

    ``key``: spelled as in messages, e.g. ``ndr.user_objects.rock``; ``path``: as written
    (``""`` when the key is unset); ``asset``: a mesh whose material files and textures
    are inputs too (:func:`neurender.asset_files.asset_inputs`).
    """

    key: str
    path: str
    asset: bool = False
