"""Config rules the JSON schema cannot state: ranges between keys, shapes a network needs,
files that must exist. :func:`check` runs in ``workflow/rules/common.smk`` right after the
schema has filled the defaults, so a dry run refuses a bad config before any job starts,
naming the keys and values and what was expected. :func:`check_files` runs first of all:
Snakemake reads a ``--configfile`` keeping the last of two equal keys, so it rereads each
file refusing a key set twice. Each method states its own rules (its
record's ``problems``, :mod:`neurender.methods`); this module asks every registered one,
and checks every user path the records list (``user_paths``) for braces.
:func:`check_renamed` runs before the schema, so that a key an older release named
differently fails with its new name rather than as an unknown key, and so does
:func:`check_names_are_text`: YAML reads an unquoted name such as ``null``, ``001`` or
``yes`` as None, 1 or True, which the schema's name patterns do not see.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from neurender import asset_files, io, methods, unique_keys
from neurender.user_paths import made_by_the_workflow, wildcard_problem

#: Top-level config keys renamed since they were introduced: old key -> (new key, the
#: release that renamed it).
RENAMED: dict[str, tuple[str, str]] = {"simplify": ("simplification", "0.2")}


class ConfigError(ValueError):
    """A config value that breaks one of the methods' rules."""


def problems(config: Mapping[str, Any]) -> list[str]:
    """Every rule the (defaults-filled) ``config`` breaks, one sentence each, in the
    order of :data:`neurender.methods.METHODS`."""
    found = [problem for method in methods.METHODS for problem in method.problems(config)]
    return found + list(wildcard_problems(config))


def wildcard_problems(config: Mapping[str, Any]) -> Iterator[str]:
    """Braces Snakemake would read as a wildcard in a user path of any method (its record's
    ``user_paths``), in a file of its folder or glob, or in a file a mesh names, one
    sentence per path naming the key and the file; the workflow's own paths (under
    ``results/``) are checked as written."""
    for method in methods.METHODS:
        for entry in method.user_paths(config):
            if not entry.path:
                continue
            if made_by_the_workflow(entry.path):
                files = [entry.path]
            else:
                files = asset_files.user_path_inputs(entry)
            problem = next(filter(None, map(wildcard_problem, dict.fromkeys(files))), None)
            if problem:
                yield f"{entry.key} = {entry.path!r}: {problem}"


def check(config: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` listing every broken rule (nothing if there is none)."""
    found = problems(config)
    if found:
        raise ConfigError("config: " + "; ".join(found))


def check_files(configfiles: Iterable[str | Path]) -> None:
    """Raise :class:`ConfigError` naming, in each of ``configfiles`` (YAML or JSON, as
    Snakemake's ``--configfile``), every key set twice in one mapping, with its dotted
    path and lines (:func:`neurender.io.read_yaml`); nothing if there is none."""
    found = []
    for path in configfiles:
        try:
            io.read_yaml(path)
        except unique_keys.DuplicateKeyError as err:
            found.append(str(err))
    if found:
        raise ConfigError("; ".join(found))


def check_renamed(config: Mapping[str, Any], configfiles: Iterable[str | Path] = ()) -> None:
    """Raise :class:`ConfigError` for each top-level key of ``config`` that
    :data:`RENAMED` lists, naming its new key and those of ``configfiles`` (YAML, as
    Snakemake's ``--configfile``) that set it; nothing if ``config`` has none."""
    found = []
    for old, (new, release) in RENAMED.items():
        if old not in config:
            continue
        files = [str(path) for path in configfiles if old in _top_level_keys(path)]
        where = ", ".join(files) if files else "the --config arguments"
        found.append(
            f"config key '{old}' was renamed to '{new}' (neurender {release}); "
            f"rename the section in {where}"
        )
    if found:
        raise ConfigError("; ".join(found))


def _top_level_keys(path: str | Path) -> set[str]:
    """The top-level keys of a YAML config file (none for a file that is not a mapping)."""
    data = io.read_yaml(path)
    return set(data) if isinstance(data, dict) else set()


def _non_text_keys(node: Any, prefix: str = "") -> Iterator[str]:
    """Dotted paths of the mapping keys under ``node`` that are not strings."""
    if isinstance(node, Mapping):
        for key, value in node.items():
            if not isinstance(key, str):
                yield f"{prefix}{key!r} (read as {type(key).__name__})"
            else:
                yield from _non_text_keys(value, f"{prefix}{key}.")
    elif isinstance(node, list):
        for item in node:
            yield from _non_text_keys(item, prefix)


def check_names_are_text(config: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` naming every key of ``config`` that YAML did not read as
    text (an unquoted ``null``, ``001``, ``1.0`` or ``yes`` becomes None, 1, 1.0 or True,
    so two names may merge or a name come back as a missing value); nothing if every key
    is a string."""
    found = list(_non_text_keys(config))
    if found:
        raise ConfigError(
            "config: names must be text; quote each as you typed it (e.g. '001: ...' -> "
            "\"'001': ...\"): " + ", ".join(found)
        )
