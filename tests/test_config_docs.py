"""config/README.md is generated from the schema and the default config, and current."""

from pathlib import Path

import yaml

from neurender import config_docs

ROOT = Path(__file__).resolve().parents[1]


def test_config_readme_is_generated_from_the_schema_and_is_current():
    """config/README.md restates the schema: it must be what the generator writes now."""
    expected = config_docs.render()
    stale = (ROOT / "config/README.md").read_text() != expected
    assert not stale, f"config/README.md is stale: run {config_docs.COMMAND}"


def test_config_readme_lists_every_schema_key_with_its_default():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    table = {r[0]: r for r in config_docs.rows(schema, {})}
    assert table["prt.frames.train"][2] == "`200`"  # a nested key, dotted
    assert table["ndr_model.lr_schedule"][1] == "one of constant, cosine"
    assert table["simplification.user_assets.<name>.ratio"][2] == "`0.02`"
    assert table["prt.n_bands"][1] == "integer >= 1, <= 5"
    for section, sub in schema["properties"].items():
        for key in sub.get("properties", {}):
            assert any(k.startswith(f"{section}.{key}") for k in table), f"{section}.{key}"


def test_a_config_key_set_to_its_default_is_shown_so():
    schema = {"properties": {"epochs": {"type": "integer", "default": 12, "description": "x"}}}
    ((_, kind, default, configured, _),) = config_docs.rows(schema, {"epochs": 14})
    assert (kind, default, configured) == ("integer", "`12`", "`14`")
    ((*_, unset, _),) = config_docs.rows(schema, {})
    assert unset == "-"
