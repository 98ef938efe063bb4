"""An edit of one config key reruns exactly the rules that read that key.

Every config key of the schema gets a representative new value (one at a time) over the
smoke config, and the rules whose jobs' params change (what ``--rerun-triggers params``
reruns) must be exactly the rules that read the key: those with a job in the smoke DAG
whose registry entry declares the key (:meth:`neurender.method.Rule.reads`), and the
provenance. Jobs downstream of them rerun because their inputs change, which is another
trigger and not counted here.

Through Snakemake's public API only (:mod:`snakemake.api`, and a logger plugin that keeps
the jobs Snakemake reports), in a temporary working directory that links the checkout's
files and holds a finished smoke run (:func:`finish_smoke_run`): the ``touch`` executor
records every job's metadata, its params among them, as a run does, and every output is an
empty file, all of one modification time. No job runs and nothing is written under the
checkout's ``results/``. For each edit, Snakemake's summary (``--summary``) gives
every output's status against that record: ``params changed``, or ``set of input files
changed``, which it reports first, so that it hides whether the params changed too; for
those files a dry run of their rule alone (``--allowed-rules``) with params as the only
rerun trigger says it (:func:`rules_with_changed_params`). ``--list-params-changes``
(``DAGApi.list_changes``) cannot tell: Snakemake 9.27 lists there the last output of every
job it has a record of, its params changed or not.
"""

from __future__ import annotations

import contextlib
import csv
import io
import multiprocessing
import os
import shutil
import tempfile
import time
import types
from collections.abc import Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from snakemake_interface_logger_plugins.base import LogHandlerBase
from snakemake_interface_logger_plugins.common import LogEvent
from snakemake_interface_logger_plugins.registry import LoggerPluginRegistry
from snakemake_interface_logger_plugins.settings import LogHandlerSettingsBase

import neurender.methods

ROOT = Path(__file__).resolve().parents[2]

#: The smoke DAG: its target and config file (over config/config.yaml).
TARGET = "results/report.html"
CONFIGFILE = "config/smoke.yaml"

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


@dataclass
class Job:
    """A job as Snakemake reports it to logger plugins (``LogEvent.JOB_INFO``): a dry run
    reports each job it would run, the ``touch`` executor each job it touches."""

    rule: str
    wildcards: dict[str, str]
    input: list[str]
    output: list[str]
    #: Why it runs (``Params have changed since last execution``, ...).
    reason: str


@dataclass
class LogHandlerSettings(LogHandlerSettingsBase):
    """The settings of :class:`LogHandler`: the list it appends the jobs to."""

    jobs: list[Job] = field(default_factory=list)


class LogHandler(LogHandlerBase):
    """A Snakemake logger plugin (``snakemake-interface-logger-plugins``) that keeps every
    job Snakemake reports, whatever ``OutputSettings.quiet`` (its own filter)."""

    writes_to_stream = False
    writes_to_file = False
    has_filter = True
    has_formatter = True
    needs_rulegraph = False

    def emit(self, record) -> None:
        if getattr(record, "event", None) == LogEvent.JOB_INFO:
            self.settings.jobs.append(
                Job(
                    record.rule_name,
                    dict(record.wildcards),
                    list(record.input),
                    list(record.output),
                    record.reason,
                )
            )


#: :class:`LogHandler`'s name among Snakemake's logger plugins.
JOBS_PLUGIN = "neurender-jobs"


def register_jobs_plugin() -> None:
    """Register :class:`LogHandler` as the logger plugin :data:`JOBS_PLUGIN`, as an
    installed ``snakemake_logger_plugin_neurender_jobs`` package would be (nothing if it
    is already)."""
    plugin = types.ModuleType("snakemake_logger_plugin_neurender_jobs")
    plugin.LogHandler = LogHandler
    plugin.LogHandlerSettings = LogHandlerSettings
    LoggerPluginRegistry().register_plugin(plugin.__name__, plugin)


@contextlib.contextmanager
def smoke_dag(
    workdir: Path,
    change: dict | None = None,
    *,
    cores: int = 2,
    jobs: list[Job] | None = None,
    targets: Iterable[str] = (TARGET,),
    **dag_settings: Any,
) -> Iterator[Any]:
    """Snakemake's ``DAGApi`` of the smoke config with ``change`` applied (as ``--config``
    would) in ``workdir``, on ``cores`` cores, for ``targets``; the jobs Snakemake reports
    while it is open are appended to ``jobs`` (complete once it is closed).
    ``dag_settings``: more of ``DAGSettings`` (``forceall``, ``allowed_rules`` ...)."""
    from snakemake.api import SnakemakeApi
    from snakemake.settings.types import (
        ConfigSettings,
        DAGSettings,
        OutputSettings,
        Quietness,
        ResourceSettings,
    )

    handlers = {}
    if jobs is not None:
        register_jobs_plugin()
        handlers[JOBS_PLUGIN] = LogHandlerSettings(jobs)
    output = OutputSettings(quiet={Quietness.ALL}, log_handler_settings=handlers)
    with SnakemakeApi(output) as api:
        yield api.workflow(
            resource_settings=ResourceSettings(cores=cores),
            config_settings=ConfigSettings(configfiles=[workdir / CONFIGFILE], config=change or {}),
            snakefile=workdir / "Snakefile",
            workdir=workdir,
        ).dag(DAGSettings(targets=set(targets), **dag_settings))


#: The modification time of every output of the finished smoke run (:func:`make_outputs`):
#: one for all, so that no input is newer than the outputs of the job that reads it, and
#: later than any file of the checkout.
MTIME = time.time()


def make_outputs(workdir: Path, paths: Iterable[str]) -> list[Path]:
    """Make each of ``paths`` (relative to ``workdir``) that does not exist an empty file
    of modification time :data:`MTIME` (a folder's output too: building a DAG, Snakemake
    only asks whether an output exists and how old it is); the files made."""
    made = []
    for path in paths:
        file = workdir / path
        if not file.exists():
            file.parent.mkdir(parents=True, exist_ok=True)
            file.touch()
            os.utime(file, (MTIME, MTIME))
            made.append(file)
    return made


def finish_smoke_run(workdir: Path, copies: Iterable[str] = ()) -> list[Job]:
    """Make the empty folder ``workdir`` a checkout with a finished smoke run, without
    running a job: a link to each file and folder of the checkout (``results/`` and
    Snakemake's metadata left out; a copy of those named in ``copies``), Snakemake's
    metadata of every job of the smoke DAG (recorded by the ``touch`` executor, which
    records it as a run does, outputs missing or not) and every output an empty file
    (:func:`make_outputs`). The jobs, as Snakemake reports them."""
    for entry in ROOT.iterdir():
        if entry.name in copies:
            copy = shutil.copytree if entry.is_dir() else shutil.copy2
            copy(entry, workdir / entry.name)
        elif entry.name not in {"results", ".snakemake", ".git"}:
            (workdir / entry.name).symlink_to(entry)
    jobs: list[Job] = []
    with smoke_dag(workdir, jobs=jobs, forceall=True) as dag:
        dag.execute_workflow(executor="touch")
    make_outputs(workdir, [f for job in jobs for f in job.output])
    return jobs


def summary(
    workdir: Path, change: dict | None = None, detailed: bool = False
) -> dict[str, dict[str, str]]:
    """Per output file of the smoke DAG with ``change`` applied: its row of Snakemake's
    summary (``--summary``; ``--detailed-summary`` if ``detailed``), columns ``rule``,
    ``status`` (against the run recorded in ``workdir``), ``input-file(s)`` (detailed:
    those recorded; ``-`` without a record) ..."""
    out = io.StringIO()
    with smoke_dag(workdir, change) as dag, contextlib.redirect_stdout(out):
        dag.summary(detailed=detailed)
    lines = out.getvalue().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("output_file\t"))
    rows = csv.DictReader(lines[header:], delimiter="\t", quoting=csv.QUOTE_NONE)
    return {row["output_file"]: row for row in rows}


#: The statuses an output may have in the summary of an edit: ``missing`` for a new job's
#: output (no record, so no params change, as in a run), the others against its record;
#: never ``updated input files`` (all outputs are as old) nor a code change.
STATUSES = {"ok", "missing", "params changed", "set of input files changed"}


def rules_with_changed_params(workdir: Path, change: dict) -> set[str]:
    """The rules of which some job's params, with ``change`` applied, differ from those
    recorded by the finished smoke run in ``workdir``: from the summary's status of each
    output, and where it says only ``set of input files changed``, from dry runs
    (:func:`rerun_for_params`), with the new jobs' outputs made meanwhile (there they are
    inputs, taken as they are)."""
    rows = summary(workdir, change)
    odd = {f: row["status"] for f, row in rows.items() if row["status"] not in STATUSES}
    assert not odd, f"{change}: {odd}"
    changed = {row["rule"] for row in rows.values() if row["status"] == "params changed"}
    hidden = {
        f: row["rule"]
        for f, row in rows.items()
        if row["status"] == "set of input files changed" and row["rule"] not in changed
    }
    if hidden:
        made = make_outputs(workdir, [f for f, row in rows.items() if row["status"] == "missing"])
        try:
            changed |= rerun_for_params(workdir, change, hidden)
        finally:
            for file in made:
                file.unlink()
    return changed


def rerun_for_params(workdir: Path, change: dict, files: dict[str, str]) -> set[str]:
    """The rules of ``files`` (output file: its rule) with a job, making one of them, that
    reruns because its params changed, with ``change`` applied: a dry run for ``files`` of
    their rules alone (``--allowed-rules``: no job of another rule runs, so none reruns
    theirs in turn) with params the only rerun trigger (``--rerun-triggers params``). A job
    that reruns because one of them reruns before it (its input is that job's output) is
    asked again in a dry run without the rules found."""
    from snakemake.settings.enums import RerunTrigger

    found: set[str] = set()
    rules = set(files.values())
    while rules:
        jobs: list[Job] = []
        with smoke_dag(
            workdir,
            change,
            jobs=jobs,
            targets=[f for f, rule in files.items() if rule in rules],
            allowed_rules=rules,
            rerun_triggers={RerunTrigger.PARAMS},
        ) as dag:
            dag.execute_workflow(executor="dryrun")
        now = {job.rule for job in jobs if "Params have changed" in job.reason}
        after = {job.rule for job in jobs} - now
        assert now or not after, f"{change}: rerun for another reason: {jobs}"
        found |= now
        rules = after
    return found


def changed_rules_of_a_finished_run(changes: list[dict]) -> list[set[str]]:
    """For each config change, :func:`rules_with_changed_params` against a finished smoke
    run of this process's own (a temporary folder)."""
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        finish_smoke_run(workdir)
        return [rules_with_changed_params(workdir, change) for change in changes]


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory) -> tuple[Path, list[Job]]:
    """A checkout with a finished smoke run (:func:`finish_smoke_run`) and its jobs."""
    workdir = tmp_path_factory.mktemp("checkout")
    return workdir, finish_smoke_run(workdir)


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
    # Two worker processes, each with a finished run of its own (an edit may make files in
    # it): Snakemake changes the working directory and holds global state.
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        found = [
            rules for half in pool.map(changed_rules_of_a_finished_run, halves) for rules in half
        ]
    return dict(zip(changes, found, strict=True))


#: The rule that records the resolved config (results/provenance.json).
PROVENANCE = "provenance"


def covers(declared: str, key: str) -> bool:
    """Whether the declared key (a leaf or a section) holds the schema's leaf ``key``."""
    return key == declared or key.startswith(declared + ".")


def declared_readers(jobs: list[Job], keys: list[str]) -> dict[str, set[str]]:
    """For each of ``keys``, the rules of the smoke DAG's ``jobs`` of which some job reads
    it by its registry entry (:meth:`neurender.method.Rule.reads` under the job's
    wildcards)."""
    cfg = smoke_config()
    reads = [(job.rule, neurender.methods.rule(job.rule).reads(cfg, job.wildcards)) for job in jobs]
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


def test_an_edit_reruns_exactly_the_rules_that_read_the_key(smoke_run, matrix):
    # The provenance record holds the whole resolved config, so it reads every key.
    readers = declared_readers(smoke_run[1], list(matrix))
    wrong = [
        f"{key}: rerun, not declaring it: {sorted(found - expected)}; declaring it, not rerun:"
        f" {sorted(expected - found)}"
        for key, found in matrix.items()
        if found != (expected := readers[key] | {PROVENANCE})
    ]
    assert not wrong, (
        "an edit of a key reruns (changes the params of) other rules than those declaring it:\n"
        + "\n".join(wrong)
    )


def test_the_core_count_reruns_nothing_and_no_job_reads_a_benchmark_file(smoke_run):
    """``--cores`` sets jobs' threads (a resource), never their params, so a run on other
    cores reruns no job (targets included); and no job reads Snakemake's timing files
    (``results/benchmarks/``), so a job's result never depends on how long others took.
    The smoke run was recorded on 2 cores, with a record of every output."""
    workdir, jobs = smoke_run
    rows = summary(workdir, detailed=True)
    assert {row["status"] for row in rows.values()} == {"ok"}
    assert not [f for f, row in rows.items() if row["input-file(s)"] == "-"], "no record"
    assert set(rows) == {f for job in jobs for f in job.output}
    rerun: list[Job] = []
    with smoke_dag(workdir, cores=1, jobs=rerun) as dag:
        dag.execute_workflow(executor="dryrun")
    assert not rerun, "on 1 core, jobs of the run on 2 rerun: " + "\n".join(
        f"{job.rule} {job.output}: {job.reason}" for job in rerun
    )
    read = {f for job in jobs for f in job.input}
    assert not {f for f in read if f.startswith("results/benchmarks/")}


#: Rules that publish a deploy rule's graphs under a second name: a copy, never an export.
COPIES = {"prt_ship"}


def test_every_shipped_graph_is_written_by_a_deploy_rule(smoke_run):
    """A network becomes the graph a renderer ships (ONNX) in its method's deploy rule
    (``<method>_deploy``), never in the rule that trains, evaluates or times it, so that a
    change to the export reruns the deploy job and what reads the graphs, not the training
    or the renders beside them; a rule of :data:`COPIES` only copies a deploy rule's
    graphs (its job is :func:`neurender.jobs.copy_files`)."""
    jobs = smoke_run[1]
    made_by = {f: job.rule for job in jobs for f in job.output if f.endswith(".onnx")}
    assert {"prt_deploy", "ndr_deploy", "metaballs_deploy"} <= set(made_by.values())
    assert made_by["results/ndr/onnx/ndr_shipped.onnx"] == "ndr_deploy"
    assert made_by["results/ndr/onnx/ndr_shipped_int8.onnx"] == "ndr_deploy"
    elsewhere = {f: r for f, r in made_by.items() if not r.endswith("_deploy") and r not in COPIES}
    assert not elsewhere, elsewhere
    for job in jobs:
        if job.rule in COPIES:
            assert "copy_files" in (ROOT / f"workflow/scripts/{job.rule}.py").read_text()
            graphs = [f for f in job.input if f.endswith(".onnx")]
            assert len(graphs) == len([f for f in job.output if f.endswith(".onnx")]) > 0
            assert all(made_by[f].endswith("_deploy") for f in graphs), (job.rule, graphs)


#: Rules that write the example assets the configs run on (a user's kind of input files, made
#: by third-party tools), not an export of a result.
EXAMPLES = {"example_assets"}


def test_every_exported_mesh_is_written_by_a_deploy_rule(smoke_run):
    """A simplified asset becomes the files it ships as (GLB, OBJ) in its method's deploy
    rule, as a network becomes its ONNX graph: a change to the export reruns the deploy job
    and what reads the files (the evaluation renders them), not the optimisation; only the
    example assets (:data:`EXAMPLES`, inputs) are meshes written elsewhere."""
    jobs = smoke_run[1]
    made_by = {f: job.rule for job in jobs for f in job.output if f.endswith((".glb", ".obj"))}
    cases = {job.wildcards["case"] for job in jobs if job.rule == "simplification_optimise"}
    assert cases
    for case in cases:
        for name in ("optimised.glb", "optimised.obj"):
            assert made_by[f"results/simplification/{case}/{name}"] == "simplification_deploy"
    elsewhere = {f: r for f, r in made_by.items() if not r.endswith("_deploy")}
    assert set(elsewhere.values()) <= EXAMPLES, elsewhere
