"""The sentences config rules are made of, shared by every method's checks
(``<package>/method.py``'s ``problems``): ranges, perfect squares, powers of two, sizes a
U-Net can halve, names that must be built in or given by the user, a value that must be
one of another key's. Each yields one sentence per broken rule, naming the key, its value
and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping


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
