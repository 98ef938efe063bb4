"""An edit of one config key reruns exactly the rules that read that key.

Every config key of the schema gets a representative new value (one at a time) over the
smoke config, and the rules whose jobs' params change (what ``--rerun-triggers params``
reruns) must be exactly the rules that read the key: those with a job in the smoke DAG
whose registry entry declares the key (:meth:`neurender.method.Rule.reads`), and the
provenance. Jobs downstream of them rerun because their inputs change, which is another
trigger and not counted here.
No run is needed: the params a finished smoke run would have recorded are the smoke DAG's
own (CI's no-op rerun checks that), so each changed DAG is compared with the smoke DAG
in memory, as Snakemake compares it with ``.snakemake/metadata``; nothing is written
under ``results/``.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import yaml

import neurender.methods

ROOT = Path(__file__).resolve().parents[2]

#: Representative new values where "one more" would break a config rule or mean nothing.
NEW_VALUES = {
    "device": "cpu",
    "prt.objects": ["head", "cloth"],
    "prt.user_meshes": {"extra": "results/examples/vase.ply"},
    "prt.resolution": 32,
    "prt.n_bands": 3,
    "prt.directions": 36,
    "prt.reference_directions": 324,
    "prt.light": "sunset",
    "prt.probes": ["sky", "sunset", "studio"],
    "prt.user_probes": {"mine": "results/examples/maps/outdoor_0.exr"},
    "prt.user_sequences": {"wave": {"frames": "results/examples/wave", "test_fraction": 0.2}},
    "prt.experiment_train_frames": 5,
    "prt.linear_range": [-0.5, 1.5],
    "prt.excluded_expression": "smile",
    "prt_model.widths": [8, 24],
    "prt_model.lr_schedule": "constant",
    "prt_model.ridges": [1.0e-4, 1.0e-2],
    "prt_model.equal_quality_directions": [16, 36],
    "prt_model.unseen_strengths": [0.25, 1.0],
    "prt_model.variants": ["shadowing"],
    "prt_model.shipped": "paper",
    "ndr.width": 64,
    "ndr.primitives": [2, 6],
    "ndr.coarse_samples": 25,
    "ndr.coarse_shading": "prefiltered",
    "ndr.spp": 4,
    "ndr.equal_quality_spp": [1, 2],
    "ndr.fixed_probe": "sunset",
    "ndr.user_probes_dir": "results/examples/maps",
    "ndr.user_objects": {"vase": "results/examples/vase.ply", "rock": "results/examples/rock.glb"},
    "ndr.user_object_defaults.base_colour": [0.5, 0.5, 0.5],
    "ndr_model.variants": ["ndr", "ndr_direct"],
    "ndr_model.widths": [8, 24],
    "ndr_model.lr_schedule": "constant",
    "metaballs.width": 64,
    "metaballs.balls": [2, 5],
    "metaballs.radius": [0.5, 1.6],
    "metaballs_model.variants": ["pix2pix", "sphere_residual"],
    "metaballs_model.lr_schedule": "constant",
    "metaballs_model.timing_balls": [3, 21],
    "metaballs.user_scenes": "",
    "metaballs.kernel.name": "gaussian",
    "metaballs.family": "cluster",
    "metaballs_scale.widths": [64],
    "metaballs_scale.structures": ["1a28"],
    "metaballs_scale.user_structures": ["src/neurender/metaballs/structures/1a28.pdb.gz"],
    "metaballs_scale.balls": [10],
    "simplification.cases": ["head"],
    "simplification.equal_quality_multiples": [1, 3],
    "simplification.user_assets": {
        "crate": {"path": "results/examples/crate.obj", "triangles": 120}
    },
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


@contextmanager
def smoke_dag(change: dict, cores: int = 2) -> Iterator[Any]:
    """The Snakemake workflow of the smoke config with ``change`` applied (as ``--config``
    would) on ``cores`` cores, its DAG built for ``results/report.html`` with every job in
    it.

    In-process through Snakemake's API (a DAG in about half a second, where a ``snakemake
    -n`` process takes four); no job runs and nothing is written under ``results/``.
    """
    from snakemake.api import SnakemakeApi
    from snakemake.settings.types import (
        ConfigSettings,
        DAGSettings,
        OutputSettings,
        Quietness,
        ResourceSettings,
    )

    # forceall: every job of the DAG, whatever a run in the checkout's results/ holds.
    dag_settings = DAGSettings(targets={"results/report.html"}, forceall=True)
    with SnakemakeApi(OutputSettings(quiet={Quietness.ALL})) as api:
        dag_api = api.workflow(
            resource_settings=ResourceSettings(cores=cores),
            config_settings=ConfigSettings(configfiles=[ROOT / "config/smoke.yaml"], config=change),
            snakefile=ROOT / "Snakefile",
            workdir=ROOT,
        ).dag(dag_settings)
        workflow = dag_api.workflow_api._workflow
        workflow._prepare_dag(forceall=False, ignore_incomplete=False, lock_warn_only=True)
        workflow._build_dag()
        yield workflow


def job_params(change: dict, cores: int = 2) -> dict[str, tuple[str, frozenset]]:
    """Per output file of the smoke DAG with ``change`` applied (on ``cores`` cores): its
    job's rule and params as Snakemake records them (``persistence._params``)."""
    with smoke_dag(change, cores) as workflow:
        persistence = workflow.persistence
        return {
            str(f): (job.rule.name, frozenset(persistence._params(job)))
            for job in workflow.dag.jobs
            for f in job.output
        }


def rules_with_changed_params(changes: list[dict]) -> list[set[str]]:
    """For each config change, the rules whose jobs' params differ from the smoke DAG's
    for an output both DAGs have: ``persistence.params_changed`` against the records a
    finished smoke run holds (a job new to the DAG has no record and counts as unchanged,
    as there)."""
    base = job_params({})
    found = []
    for change in changes:
        found.append(
            {
                rule
                for f, (rule, params) in job_params(change).items()
                if f in base and base[f][1] != params
            }
        )
    return found


@pytest.fixture(scope="module")
def matrix():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    cfg = smoke_config()
    changes = {}
    for key, prop in config_keys(schema).items():
        current = cfg
        for part in key.split("."):
            current = current[part]
        changes[key] = nested(key, changed_value(key, prop, current))
    items = list(changes.values())
    halves = [items[: len(items) // 2], items[len(items) // 2 :]]
    # Two worker processes: Snakemake changes the working directory and holds global state.
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        found = [rules for half in pool.map(rules_with_changed_params, halves) for rules in half]
    return dict(zip(changes, found, strict=True))


#: The rule that records the resolved config (results/provenance.json).
PROVENANCE = "provenance"


def covers(declared: str, key: str) -> bool:
    """Whether the declared key (a leaf or a section) holds the schema's leaf ``key``."""
    return key == declared or key.startswith(declared + ".")


def declared_readers(keys: list[str]) -> dict[str, set[str]]:
    """For each of ``keys``, the rules of the smoke DAG of which some job reads it by its
    registry entry (:meth:`neurender.method.Rule.reads` under the job's wildcards)."""
    with smoke_dag({}) as workflow:
        reads = [
            (
                job.rule.name,
                neurender.methods.rule(job.rule.name).reads(
                    workflow.config, dict(job.wildcards_dict)
                ),
            )
            for job in workflow.dag.jobs
        ]
    return {
        key: {rule for rule, read in reads if any(covers(d, key) for d in read)} for key in keys
    }


def schema_keys() -> list[str]:
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    return list(config_keys(schema))


def test_every_schema_key_is_declared_read_or_unread_and_every_declared_key_is_one():
    """Each schema key is some rule's (:attr:`neurender.method.Rule.keys`) or stated as
    read by no job (:func:`neurender.methods.unread_keys`), not both; every declared key
    names a schema key or a section of them."""
    keys = schema_keys()
    declared = {k: r for r, rule in neurender.methods.rules().items() for k in rule.keys}
    unread = neurender.methods.unread_keys()
    read = {key for key in keys if any(covers(d, key) for d in declared)}
    assert not read & unread, sorted(read & unread)
    assert set(keys) == read | unread, sorted(set(keys) - read - unread)
    unknown = {d: r for d, r in declared.items() if not any(covers(d, k) for k in keys)}
    assert not unknown, unknown


def test_an_edit_reruns_exactly_the_rules_that_read_the_key(matrix):
    # The provenance record holds the whole resolved config, so it reads every key.
    readers = declared_readers(list(matrix))
    wrong = {
        key: {"rerun": sorted(found), "readers": sorted(readers[key] | {PROVENANCE})}
        for key, found in matrix.items()
        if found != readers[key] | {PROVENANCE}
    }
    assert not wrong, wrong


def test_the_core_count_reruns_nothing_and_no_job_reads_a_benchmark_file():
    """``--cores`` sets jobs' threads (a resource), never their params, so a run on other
    cores reruns no job (targets included); and no job reads Snakemake's timing files
    (``results/benchmarks/``), so a job's result never depends on how long others took."""
    assert job_params({}, cores=1) == job_params({}, cores=2)
    with smoke_dag({}) as workflow:
        read = {str(f) for job in workflow.dag.jobs for f in job.input}
    assert not {f for f in read if f.startswith("results/benchmarks/")}


#: Rules that publish a deploy rule's graphs under a second name: a copy, never an export.
COPIES = {"prt_ship"}


def test_every_shipped_graph_is_written_by_a_deploy_rule():
    """A network becomes the graph a renderer ships (ONNX) in its method's deploy rule
    (``<method>_deploy``), never in the rule that trains, evaluates or times it, so that a
    change to the export reruns the deploy job and what reads the graphs, not the training
    or the renders beside them; a rule of :data:`COPIES` only copies a deploy rule's
    graphs (its job is :func:`neurender.jobs.copy_files`)."""
    with smoke_dag({}) as workflow:
        jobs = [
            (job.rule.name, [str(f) for f in job.input], [str(f) for f in job.output])
            for job in workflow.dag.jobs
        ]
    made_by = {f: rule for rule, _, outputs in jobs for f in outputs if f.endswith(".onnx")}
    assert {"prt_deploy", "ndr_deploy", "metaballs_deploy"} <= set(made_by.values())
    assert made_by["results/ndr/onnx/ndr_shipped.onnx"] == "ndr_deploy"
    assert made_by["results/ndr/onnx/ndr_shipped_int8.onnx"] == "ndr_deploy"
    elsewhere = {f: r for f, r in made_by.items() if not r.endswith("_deploy") and r not in COPIES}
    assert not elsewhere, elsewhere
    for rule, inputs, outputs in jobs:
        if rule in COPIES:
            assert "copy_files" in (ROOT / f"workflow/scripts/{rule}.py").read_text()
            graphs = [f for f in inputs if f.endswith(".onnx")]
            assert len(graphs) == len([f for f in outputs if f.endswith(".onnx")]) > 0
            assert all(made_by[f].endswith("_deploy") for f in graphs), (rule, graphs)


#: Rules that write the example assets the configs run on (a user's kind of input files, made
#: by third-party tools), not an export of a result.
EXAMPLES = {"example_assets"}


def test_every_exported_mesh_is_written_by_a_deploy_rule():
    """A simplified asset becomes the files it ships as (GLB, OBJ) in its method's deploy
    rule, as a network becomes its ONNX graph: a change to the export reruns the deploy job
    and what reads the files (the evaluation renders them), not the optimisation; only the
    example assets (:data:`EXAMPLES`, inputs) are meshes written elsewhere."""
    with smoke_dag({}) as workflow:
        made_by = {
            str(f): job.rule.name
            for job in workflow.dag.jobs
            for f in job.output
            if str(f).endswith((".glb", ".obj"))
        }
        cases = workflow.globals["SIMPLIFICATION_CASES"]
    for case in cases:
        for name in ("optimised.glb", "optimised.obj"):
            assert made_by[f"results/simplification/{case}/{name}"] == "simplification_deploy"
    elsewhere = {f: r for f, r in made_by.items() if not r.endswith("_deploy")}
    assert set(elsewhere.values()) <= EXAMPLES, elsewhere
