"""Config rules the JSON schema cannot state: ranges between keys, shapes a network needs,
files that must exist. :func:`check` runs in ``workflow/rules/common.smk`` right after the
schema has filled the defaults, so a dry run refuses a bad config before any job starts,
naming the keys and values and what was expected. Each method states its own rules (its
record's ``problems``, :mod:`neurender.methods`); this module asks every registered one.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from neurender import methods, user_paths


class ConfigError(ValueError):
    """A config value that breaks one of the methods' rules."""


def problems(config: Mapping[str, Any]) -> list[str]:
    """Every rule the (defaults-filled) ``config`` breaks, one sentence each, in the
    order of :data:`neurender.methods.METHODS`."""
    found = [problem for method in methods.METHODS for problem in method.problems(config)]
    return found + list(user_paths.problems(config))


def check(config: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` listing every broken rule (nothing if there is none)."""
    found = problems(config)
    if found:
        raise ConfigError("config: " + "; ".join(found))
