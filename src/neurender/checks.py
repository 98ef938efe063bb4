"""The sentences config rules are made of, shared by every method's checks
(``<package>/method.py``'s ``problems``): ranges, perfect squares, powers of two, sizes a
U-Net can halve, names that must be built in or given by the user, a value that must be
one of another key's, a file the user names. Each yields one sentence per broken rule,
naming the key, its value and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from pathlib import Path

from neurender import asset_files
from neurender.user_paths import file_problem, made_by_the_workflow


def ordered(config: Mapping, section: str, key: str) -> Iterator[str]:
    """``config[section][key]`` is a ``[min, max]`` pair with ``min <= max``."""
    low, high = config[section][key]
    if low > high:
        yield f"{section}.{key} = {[low, high]}: expected [min, max] with min <= max"


def square(value: int, name: str) -> Iterator[str]:
    """``value`` (config key ``name``) is a perfect square (a sample grid's count)."""
    if math.isqrt(value) ** 2 != value:
        yield f"{name} = {value}: expected a perfect square (e.g. 16, 64, 256)"


def power_of_two_at_least(value: int, minimum: int, name: str, why: str) -> Iterator[str]:
    """``value`` is a power of two of at least ``minimum``, for the reason ``why``."""
    if value < minimum or value & (value - 1):
        yield f"{name} = {value}: expected a power of two >= {minimum} ({why})"


def halvable(size: int, widths: list, name: str, widths_name: str) -> Iterator[str]:
    """``size`` halves through every level of a U-Net with ``widths`` per level."""
    factor = 2 ** (len(widths) - 1)
    if size % factor:
        yield (
            f"{name} = {size}: expected a multiple of {factor}, the downsampling of the "
            f"U-Net's {len(widths)} levels ({widths_name})"
        )


def known(entries: list, builtins: tuple, user: Mapping, name: str) -> Iterator[str]:
    """Each of ``entries`` (config key ``name``) is built in or a key of ``user``."""
    for entry in entries:
        if entry not in builtins and entry not in user:
            yield (
                f"{name} entry {entry!r} is neither built in ({', '.join(builtins)}) nor listed "
                f"under the user entries ({', '.join(user) or 'none'})"
            )


def member(value, options: list, name: str, options_name: str) -> Iterator[str]:
    """``value`` (config key ``name``) is one of ``options`` (config key ``options_name``)."""
    if value not in options:
        yield f"{name} = {value!r}: expected one of {options_name} {list(options)}"


def user_file(
    key: str, path: str, suffixes: tuple[str, ...], what: str, named: bool = False
) -> Iterator[str]:
    """The file ``path`` the user gives at config key ``key`` (dotted, e.g.
    ``prt.user_meshes.mine``) is ``what`` (e.g. ``a mesh file``): a regular file (not a
    folder, a FIFO ...) with one of ``suffixes`` (lowercase, with the dot; any case
    matches) and, with ``named``, every material file and texture it names is one
    (:func:`neurender.asset_files.missing`). A path the workflow makes is checked for its
    suffix only (the job that makes it has not run)."""
    expected = f"expected {what} ({', '.join(suffixes)})"
    problem = None if made_by_the_workflow(path) else file_problem(path)
    if problem:
        yield f"{key} = {path!r}: {problem}; {expected}"
    elif Path(path).suffix.lower() not in suffixes:
        yield f"{key} = {path!r}: {expected}"
    elif named and not made_by_the_workflow(path):
        yield from (f"{key} = {path!r}: {sentence}" for sentence in asset_files.missing(path))
