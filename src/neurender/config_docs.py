"""``config/README.md``, generated from the schema, the one place every default is kept.

Run as ``python -m neurender.config_docs > config/README.md`` after editing
``workflow/schemas/config.schema.yaml`` or ``config/config.yaml``; a test fails while the
file is stale. One table per config section, one row per key (nested keys dotted, the
entries of a name -> settings map as ``<name>``): its type and range, the schema's default,
the default config's value where ``config/config.yaml`` sets one, and the schema's
description.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import yaml

from neurender import io

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow/schemas/config.schema.yaml"
DEFAULT_CONFIG = ROOT / "config/config.yaml"
COMMAND = "python -m neurender.config_docs > config/README.md"

INTRO = f"""\
# Configuration keys

<!-- Generated from workflow/schemas/config.schema.yaml and config/config.yaml by
`{COMMAND}`; edit those, not this file (tests/test_config.py fails when it is stale). -->

Four configs ship: `config.yaml` (the default: a real result on a 2-core laptop),
`smoke.yaml` (CI, toy sizes), `paper.yaml` (the papers' scale) and
`examples/own_assets.yaml` (every method on assets of the kinds users bring). A config
passed with `--configfile` is merged over `config.yaml`; a key no config sets takes the
schema's default below (the schema `workflow/schemas/config.schema.yaml` is the one place
defaults are kept; each config sets only what differs, with a comment on why). Unknown
keys and values of the wrong type are errors before any job runs.

The column `config.yaml` shows the default config's value where it sets one.
"""

#: A key a config does not set, or a schema key without a default.
_NONE = object()


def _value(value: Any) -> str:
    """A value as YAML flow text in a code span (``-`` when there is none)."""
    if value is _NONE:
        return "-"
    text = yaml.safe_dump(value, default_flow_style=True, width=10_000, sort_keys=False).strip()
    text = text.removesuffix("...").strip()
    return f"`{text}`"


def _bounds(schema: Mapping[str, Any]) -> str:
    parts = []
    for key, symbol in (
        ("minimum", ">="),
        ("exclusiveMinimum", ">"),
        ("maximum", "<="),
        ("exclusiveMaximum", "<"),
    ):
        if key in schema:
            parts.append(f"{symbol} {json.dumps(schema[key])}")
    return ", ".join(parts)


def type_text(schema: Mapping[str, Any]) -> str:
    """A key's type as a reader says it: ``integer >= 8``, ``one of constant, cosine``,
    ``list of integer >= 1 (2 items)``, ``name -> path``."""
    if "enum" in schema:
        return "one of " + ", ".join(str(v) for v in schema["enum"])
    kind = schema.get("type", "any")
    kinds = kind if isinstance(kind, list) else [kind]
    if "array" in kinds:
        items = schema.get("items", {})
        text = f"list of {type_text(items)}" if items else "list"
        lo, hi = schema.get("minItems"), schema.get("maxItems")
        if lo is not None and lo == hi:
            text += f" ({lo} items)"
        elif lo:
            text += f" (at least {lo})"
        return text
    if "object" in kinds:
        extra = schema.get("additionalProperties")
        if isinstance(extra, Mapping):
            return "name -> " + ("settings" if "properties" in extra else type_text(extra))
        return "settings"
    names = [{"integer": "integer", "number": "number", "null": "null"}.get(k, k) for k in kinds]
    text = " or ".join(names)
    bounds = _bounds(schema)
    return f"{text} {bounds}" if bounds else text


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def rows(
    schema: Mapping[str, Any], configured: Any, prefix: str = ""
) -> Iterator[tuple[str, str, str, str, str]]:
    """``(key, type, default, config.yaml value, description)`` of every key below
    ``schema`` (an object schema) with the values ``configured`` sets: keys of a nested
    section whose keys all have defaults dotted (``frames.train``), the settings of a
    name -> settings map as ``<name>.key``."""
    for key, sub in schema.get("properties", {}).items():
        name = f"{prefix}{key}"
        value = configured.get(key, _NONE) if isinstance(configured, Mapping) else _NONE
        nested = sub.get("properties", {})
        if nested and all("default" in p for p in nested.values()):
            yield from rows(sub, value, f"{name}.")
            continue
        kind = type_text(sub)
        if nested:  # one default for the whole object, e.g. samples per split
            kind = ", ".join(nested) + ": " + type_text(next(iter(nested.values())))
        default = _value(sub.get("default", _NONE))
        yield (name, kind, default, _value(value), sub.get("description", ""))
        entries = sub.get("additionalProperties")
        if isinstance(entries, Mapping) and "properties" in entries:
            yield from rows(entries, _NONE, f"{name}.<name>.")


def render(schema_path: Path = SCHEMA, config_path: Path = DEFAULT_CONFIG) -> str:
    """The Markdown text of ``config/README.md``."""
    schema = io.read_yaml(schema_path)
    configured = io.read_yaml(config_path) or {}
    lines = [INTRO]
    top = {k: v for k, v in schema["properties"].items() if v.get("type") != "object"}
    sections = {k: v for k, v in schema["properties"].items() if v.get("type") == "object"}
    header = ["| key | type | default | `config.yaml` | meaning |", "|---|---|---|---|---|"]
    lines += ["## Top level", "", *header]
    lines += [_row(r) for r in rows({"properties": top}, configured)]
    for section, sub in sections.items():
        lines += ["", f"## `{section}`: {sub['description']}", "", *header]
        lines += [_row(r) for r in rows(sub, configured.get(section, {}))]
    return "\n".join(lines) + "\n"


def _row(row: tuple[str, str, str, str, str]) -> str:
    key, *cells = row
    return f"| `{key}` | " + " | ".join(_cell(c) for c in cells) + " |"


def main() -> None:
    print(render(), end="")


if __name__ == "__main__":
    main()
