"""YAML and JSON text read as ``yaml.safe_load`` and ``json.loads`` read it, except that a
mapping which sets one key twice is refused.

Both libraries (and so Snakemake's ``--configfile``) keep the last of two equal keys
without a word: ``ndr: {width: 32}`` and, further down, ``ndr: {width: 64}`` drop the first
section whole. :class:`DuplicateKeyError` names the source, every repeated key by its
dotted path from the top (``ndr.width``; a list item as ``[i]``, e.g.
``images[0].uri``) and, for YAML, the lines (1-based) that set it. Keys are compared as
read, so YAML's ``1`` and ``1.0``, or ``a`` and ``'a'``, are the same key. A YAML merge
(``<<: *base``) may still override the keys it brings in.

Standard library and PyYAML (which Snakemake itself needs) only: :mod:`neurender.asset_files`
uses it when the DAG is built. Files are read by :func:`neurender.io.read_yaml`.
"""

from __future__ import annotations

import json
from typing import Any

import yaml

_MERGE = "tag:yaml.org,2002:merge"


class DuplicateKeyError(ValueError):
    """A mapping that sets one key twice; the message names the source, the key's dotted
    path and (YAML) the lines."""


def _times(count: int) -> str:
    return "twice" if count == 2 else f"{count} times"


def _lines(lines: list[int]) -> str:
    return ", ".join(map(str, lines[:-1])) + f" and {lines[-1]}"


def _refused(source: str, found: list[str]) -> DuplicateKeyError:
    return DuplicateKeyError(
        f"{source}: " + "; ".join(found) + "; only the last would count: keep one"
    )


def _child(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


class _UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that checks the composed document for repeated keys first."""

    def construct_document(self, node: yaml.Node) -> Any:
        repeated: dict[str, list[int]] = {}
        self._find_repeated(node, "", repeated, set())
        if repeated:
            raise _refused(
                self.name,
                [
                    f"key '{key}' is set {_times(len(lines))}, on lines {_lines(lines)}"
                    for key, lines in repeated.items()
                ],
            )
        return super().construct_document(node)

    def _find_repeated(
        self, node: yaml.Node, path: str, repeated: dict[str, list[int]], seen: set[int]
    ) -> None:
        """Add ``path.key -> lines`` to ``repeated`` for each key set twice at or below
        ``node``; an anchored node (``&a``, met again as ``*a``) is walked once."""
        if id(node) in seen:
            return
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            for k, item in enumerate(node.value):
                self._find_repeated(item, f"{path}[{k}]", repeated, seen)
        if not isinstance(node, yaml.MappingNode):
            return
        first: dict[Any, tuple[str, int]] = {}  # key as read -> (its path, its line)
        for key_node, value_node in node.value:
            if key_node.tag == _MERGE or not isinstance(key_node, yaml.ScalarNode):
                self._find_repeated(value_node, path, repeated, seen)
                continue
            key = self.construct_object(key_node)
            key_path = _child(path, key_node.value)
            line = key_node.start_mark.line + 1
            try:
                earlier = first.get(key)
            except TypeError:  # unhashable: the constructor refuses it with its own message
                continue
            if earlier:
                repeated.setdefault(earlier[0], [earlier[1]]).append(line)
            else:
                first[key] = (key_path, line)
            self._find_repeated(value_node, key_path, repeated, seen)


def load_yaml(text: str, source: str) -> Any:
    """``yaml.safe_load(text)``, refusing a repeated key (:class:`DuplicateKeyError`);
    ``source`` (a file name) names the text in every error, syntax errors included."""
    loader = _UniqueKeyLoader(text)
    loader.name = source  # the marks of yaml's own errors name the source too
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


class _Pairs(list):
    """A JSON object's ``(key, value)`` pairs in file order, repeats kept."""


def _to_dicts(value: Any, path: str, repeated: dict[str, int]) -> Any:
    """``value`` with every :class:`_Pairs` made a dict (the last of equal keys wins, as
    ``json.loads``); each repeated key's path -> how often it is set, in ``repeated``."""
    if isinstance(value, list) and not isinstance(value, _Pairs):
        return [_to_dicts(item, f"{path}[{k}]", repeated) for k, item in enumerate(value)]
    if not isinstance(value, _Pairs):
        return value
    out: dict[str, Any] = {}
    for key, item in value:
        if key in out:
            repeated[_child(path, key)] = repeated.get(_child(path, key), 1) + 1
        out[key] = _to_dicts(item, _child(path, key), repeated)
    return out


def load_json(text: str | bytes, source: str) -> Any:
    """``json.loads(text)``, refusing a repeated key (:class:`DuplicateKeyError`, naming
    ``source`` and the key's path; json reports no lines for it)."""
    repeated: dict[str, int] = {}
    data = _to_dicts(json.loads(text, object_pairs_hook=_Pairs), "", repeated)
    if repeated:
        raise _refused(
            source,
            [
                f"key '{key}' is set {_times(count)} in one JSON object"
                for key, count in repeated.items()
            ],
        )
    return data
