"""An edit of one config key reruns exactly the rules that read that key.

On a finished smoke run, every config key of the schema gets a representative new value
(one at a time) and ``snakemake -n --rerun-triggers params`` lists the rules whose
params changed; they must be exactly the rules that read the key (:data:`READERS`).
Jobs downstream of them rerun because their inputs change, which the dry run reports
under another reason and this test does not count. Needs the smoke run in the checkout
(``snakemake results/report.html --cores 2 --configfile config/smoke.yaml``), as CI has it
before the tests; skipped otherwise.
"""

from __future__ import annotations

import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

#: Rules whose params change when a key changes. Keys of ``threads`` and ``report`` are
#: read by no job's computation; DAG-shaping keys (objects, probes, variants, cases) add or
#: drop jobs besides (reported as missing outputs, not counted here).
READERS: dict[str, set[str]] = {}

#: Representative new values where "one more" would break a config rule or mean nothing.
NEW_VALUES = {
    "device": "cpu",
    "prt.objects": ["head", "cloth"],
    "prt.user_meshes": {},
    "prt.resolution": 32,
    "prt.n_bands": 3,
    "prt.directions": 36,
    "prt.reference_directions": 324,
    "prt.light": "sunset",
    "prt.probes": ["sky", "sunset", "studio"],
    "prt.user_probes": {},
    "prt.user_sequences": {"wave": {"frames": "results/examples/wave", "test_fraction": 0.2}},
    "prt.experiment_train_frames": 5,
    "prt.linear_range": [-0.5, 1.5],
    "prt.excluded_expression": "smile",
    "prt_model.widths": [8, 24],
    "prt_model.lr_schedule": "constant",
    "prt_model.ridges": [1.0e-4, 1.0e-2],
    "prt_model.equal_quality_directions": [16, 36],
    "ndr.width": 64,
    "ndr.primitives": [2, 6],
    "ndr.coarse_samples": 25,
    "ndr.spp": 4,
    "ndr.fixed_probe": "sunset",
    "ndr.user_probes_dir": "",
    "ndr.user_objects": {"vase": "results/examples/vase.ply", "rock": "results/examples/rock.glb"},
    "ndr.user_object_defaults.base_colour": [0.5, 0.5, 0.5],
    "ndr_model.variants": ["ndr", "ndr_direct"],
    "ndr_model.widths": [8, 24],
    "ndr_model.lr_schedule": "constant",
    "metaballs.width": 64,
    "metaballs.balls": [2, 5],
    "metaballs.radius": [0.5, 1.6],
    "metaballs_model.lr_schedule": "constant",
    "metaballs_model.timing_balls": [3, 21],
    "metaballs.user_scenes": "",
    "simplify.cases": ["head"],
    "simplify.user_assets": {"crate": {"path": "results/examples/crate.obj", "triangles": 120}},
    "report.title": "another title",
}


def config_keys(schema: dict, prefix: str = "") -> dict[str, dict]:
    """Every leaf key of the schema (dotted) with its property schema."""
    keys = {}
    for name, prop in schema["properties"].items():
        if prop.get("type") == "object" and "properties" in prop:
            keys |= config_keys(prop, f"{prefix}{name}.")
        else:
            keys[f"{prefix}{name}"] = prop
    return keys


def smoke_config() -> dict:
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    from snakemake.utils import update_config, validate

    update_config(cfg, yaml.safe_load((ROOT / "config/smoke.yaml").read_text()))
    validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))
    return cfg


def changed_value(key: str, prop: dict, current):
    """A valid value other than ``current`` for ``key``."""
    if key in NEW_VALUES:
        return NEW_VALUES[key]
    if prop.get("type") == "boolean":
        return not current
    if prop.get("type") == "integer":
        return current + 1
    if prop.get("type") == "number":
        return round(current * 1.1, 6) if current else 0.1
    raise KeyError(f"no representative change for {key!r} ({prop.get('type')}); add one")


def nested(key: str, value) -> dict:
    """``{"a": {"b": value}}`` for ``key`` ``"a.b"``."""
    out = value
    for part in reversed(key.split(".")):
        out = {part: out}
    return out


def rerun_by_params(change: dict, tmp: Path) -> set[str]:
    """Rules whose jobs' params differ from the finished run's under ``change``."""
    path = tmp / f"change_{abs(hash(repr(change)))}.yaml"
    path.write_text(yaml.safe_dump(change))
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "results/report.html",
            "-n",
            "--cores",
            "2",
            "--rerun-triggers",
            "params",
            "--quiet",
            "rules",
            "--configfile",
            "config/smoke.yaml",
            str(path),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    out = result.stdout + result.stderr
    if result.returncode:
        raise AssertionError(f"dry run with {change} failed:\n{out[-2000:]}")
    match = re.search(r"params have changed since last execution:\n\s+(.+)", out)
    return set(match.group(1).split(", ")) if match else set()


def finished_smoke_run() -> bool:
    if not (ROOT / "results/report.html").is_file():
        return False
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "results/report.html",
            "-n",
            "--cores",
            "2",
            "--configfile",
            "config/smoke.yaml",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    return "Nothing to be done" in result.stdout + result.stderr


@pytest.fixture(scope="module")
def matrix(tmp_path_factory):
    if not finished_smoke_run():
        pytest.skip("needs a finished smoke run in the checkout (see the module docstring)")
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    cfg = smoke_config()
    tmp = tmp_path_factory.mktemp("changes")
    changes = {}
    for key, prop in config_keys(schema).items():
        current = cfg
        for part in key.split("."):
            current = current[part]
        changes[key] = nested(key, changed_value(key, prop, current))
    with ThreadPoolExecutor(2) as pool:
        found = pool.map(lambda change: rerun_by_params(change, tmp), changes.values())
        return dict(zip(changes, found, strict=True))


def test_every_schema_key_is_in_the_matrix():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    assert set(config_keys(schema)) == set(READERS)


def test_an_edit_reruns_exactly_the_rules_that_read_the_key(matrix):
    wrong = {
        key: {"rerun": sorted(found), "readers": sorted(READERS[key])}
        for key, found in matrix.items()
        if found != READERS[key]
    }
    assert not wrong, wrong
