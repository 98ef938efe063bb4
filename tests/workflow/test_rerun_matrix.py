"""An edit of one config key reruns exactly the rules that read that key.

Every config key of the schema gets a representative new value (one at a time) over the
smoke config, and the rules whose jobs' params change (what ``--rerun-triggers params``
reruns) must be exactly the rules that read the key (:data:`READERS`). Jobs downstream of
them rerun because their inputs change, which is another trigger and not counted here.
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

ROOT = Path(__file__).resolve().parents[2]

#: Rules whose params change when a key changes: the rules that read the key. Empty for a
#: key no job's computation reads (``gpus`` and the ``threads`` keys are resources, except
#: where a stage's timing divides by them), and for keys that only pick inputs or shape the
#: DAG (``prt.light``, ``prt.probes``, ``prt.experiments``, ``metaballs.user_scenes``,
#: ``metaballs_model.variants``, ``metaballs_scale.user_structures``: their jobs appear,
#: disappear or get other input files, which other triggers rerun). Reviewed by hand when
#: drafted from a run: each set is what the rule's job reads.
READERS: dict[str, set[str]] = {
    "seed": {
        "example_assets",
        "metaballs_demo",
        "metaballs_examples",
        "metaballs_train",
        "metaballs_viewer",
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_summary",
        "ndr_train",
        "ndr_user_objects",
        "ndr_viewer",
        "prt_benchmark",
        "prt_equal_quality",
        "prt_evaluate",
        "prt_geometry_image",
        "prt_noise_floor",
        "prt_sequence",
        "prt_train",
        "prt_transfer",
        "prt_unseen",
        "report",
        "simplification_evaluate",
        "simplification_mesh_figure",
        "simplification_optimise",
        "simplification_prepare",
        "simplification_viewer",
    },
    "device": {
        "metaballs_demo",
        "metaballs_equal_quality",
        "metaballs_evaluate",
        "metaballs_train",
        "metaballs_user_scenes",
        "metaballs_viewer",
        "ndr_data",
        "ndr_equal_quality",
        "ndr_evaluate",
        "ndr_relight",
        "ndr_summary",
        "ndr_train",
        "ndr_user_objects",
        "ndr_viewer",
        "prt_equal_quality",
        "prt_evaluate",
        "prt_experiment",
        "prt_relight",
        "prt_train",
        "prt_unseen",
        "prt_viewer",
        "simplification_evaluate",
        "simplification_optimise",
        "simplification_prepare",
    },
    "gpus": set(),
    "prt.objects": {"prt_model_summary"},
    "prt.user_meshes": set(),
    "prt.user_sequences": {"prt_sequence"},
    "prt.resolution": {"prt_geometry_image", "prt_model_summary"},
    "prt.source_vertices": {"prt_geometry_image"},
    "prt.n_bands": {
        "prt_benchmark",
        "prt_deploy",
        "prt_equal_quality",
        "prt_evaluate",
        "prt_experiment",
        "prt_figure",
        "prt_model_summary",
        "prt_momoprt",
        "prt_noise_floor",
        "prt_probe",
        "prt_relight",
        "prt_train",
        "prt_transfer",
        "prt_unseen",
        "prt_viewer",
    },
    "prt.frames.train": {"prt_sequence"},
    "prt.frames.val": {"prt_sequence"},
    "prt.frames.test": {"prt_sequence"},
    "prt.directions": {"prt_benchmark", "prt_evaluate", "prt_noise_floor", "prt_transfer"},
    "prt.reference_directions": {"prt_equal_quality", "prt_evaluate", "prt_transfer", "prt_unseen"},
    "prt.direction_sets": {
        "prt_benchmark",
        "prt_equal_quality",
        "prt_evaluate",
        "prt_noise_floor",
        "prt_transfer",
        "prt_unseen",
    },
    "prt.ray_offset": {
        "prt_benchmark",
        "prt_equal_quality",
        "prt_evaluate",
        "prt_noise_floor",
        "prt_transfer",
        "prt_unseen",
    },
    "prt.noise_floor_frames": {"prt_equal_quality", "prt_noise_floor"},
    "prt.light": set(),
    "prt.probes": set(),
    "prt.user_probes": set(),
    "prt.probe_height": {"prt_probe"},
    "prt.experiments": set(),
    "prt.experiment_train_frames": {"prt_sequence"},
    "prt.experiment_points": {"prt_sequence"},
    "prt.linear_range": {"prt_sequence"},
    "prt.excluded_expression": {"prt_sequence"},
    "prt.benchmark_paper_scale": {"prt_benchmark"},
    "prt_model.widths": {"prt_train"},
    "prt_model.blocks": {"prt_train"},
    "prt_model.epochs": {"prt_train"},
    "prt_model.batch_size": {"prt_train"},
    "prt_model.lr": {"prt_train"},
    "prt_model.shadowing_batch_size": {"prt_train"},
    "prt_model.shadowing_lr": {"prt_train"},
    "prt_model.residual_targets": {"prt_train"},
    "prt_model.lr_schedule": {"prt_train"},
    "prt_model.threads": set(),
    "prt_model.pca_components": {"prt_momoprt"},
    "prt_model.ridges": {"prt_momoprt"},
    "prt_model.render_resolution": {
        "prt_equal_quality",
        "prt_evaluate",
        "prt_experiment",
        "prt_relight",
        "prt_unseen",
    },
    "prt_model.glossy_exponent": {"prt_evaluate", "prt_unseen"},
    "prt_model.equal_quality_directions": {"prt_equal_quality"},
    "prt_model.unseen_strengths": {"prt_unseen"},
    "prt_model.unseen_frames": {"prt_unseen"},
    # The variants trained are also jobs that appear or disappear (prt_train's).
    "prt_model.variants": {
        "prt_equal_quality",
        "prt_evaluate",
        "prt_experiment",
        "prt_model_summary",
        "prt_unseen",
    },
    "prt_model.shipped": {"prt_model_summary", "prt_ship"},
    "ndr.width": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_summary",
        "ndr_train",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.samples.train": {"ndr_data"},
    "ndr.samples.val": {"ndr_data"},
    "ndr.samples.test": {"ndr_data", "ndr_user_objects"},
    "ndr.diffuse_samples.train": {"ndr_data"},
    "ndr.diffuse_samples.val": {"ndr_data"},
    "ndr.diffuse_samples.test": {"ndr_data"},
    "ndr.primitives": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.edge_length": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.camera_distance": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.fov": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.environment_height": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.coarse_height": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_summary",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.coarse_samples": {
        "ndr_data",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_summary",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.bright_texels": {
        "ndr_data",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.coarse_shading": {
        "ndr_data",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.spp": {"ndr_data", "ndr_equal_quality", "ndr_relight", "ndr_viewer"},
    "ndr.reference_spp": {"ndr_data", "ndr_relight", "ndr_user_objects", "ndr_viewer"},
    "ndr.fixed_probe": {"ndr_data"},
    "ndr.user_probes_dir": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.user_probe_fraction": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.furnace_spp": {"ndr_summary"},
    "ndr.equal_quality_spp": {"ndr_equal_quality"},
    "ndr.equal_quality_samples": {"ndr_equal_quality"},
    "ndr.small_sun_fraction": {
        "ndr_data",
        "ndr_deploy",
        "ndr_equal_quality",
        "ndr_relight",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr.sunlit_samples": {"ndr_data", "ndr_user_objects"},
    "ndr.user_objects": {"ndr_user_objects"},
    "ndr.user_object_defaults.base_colour": {"ndr_user_objects"},
    "ndr.user_object_defaults.specular": {"ndr_user_objects"},
    "ndr.user_object_defaults.roughness": {"ndr_user_objects"},
    "ndr.user_object_maps": {"ndr_user_objects"},
    "ndr_model.variants": {"ndr_deploy", "ndr_evaluate", "ndr_summary"},
    "ndr_model.widths": {"ndr_train"},
    "ndr_model.sh_hidden": {"ndr_train"},
    "ndr_model.shading_residual": {"ndr_train"},
    "ndr_model.epochs": {"ndr_train"},
    "ndr_model.batch_size": {"ndr_train"},
    "ndr_model.lr": {"ndr_train"},
    "ndr_model.lr_schedule": {"ndr_train"},
    "ndr_model.mask_erosion": {
        "ndr_equal_quality",
        "ndr_evaluate",
        "ndr_relight",
        "ndr_train",
        "ndr_user_objects",
        "ndr_viewer",
    },
    "ndr_model.ngf": {"ndr_train"},
    "ndr_model.ndf": {"ndr_train"},
    "ndr_model.l1_weight": {"ndr_train"},
    "ndr_model.gan_weight": {"ndr_train"},
    "ndr_model.threads": set(),
    "ndr_model.relight_sample": {"ndr_relight", "ndr_viewer"},
    "ndr_model.relight_turns": {"ndr_relight"},
    "metaballs.width": {
        "metaballs_demo",
        "metaballs_equal_quality",
        "metaballs_evaluate",
        "metaballs_examples",
        "metaballs_targets",
        "metaballs_train",
        "metaballs_user_scenes",
        "metaballs_viewer",
    },
    "metaballs.examples.train": {"metaballs_examples"},
    "metaballs.examples.val": {"metaballs_examples"},
    "metaballs.examples.test": {"metaballs_examples"},
    "metaballs.balls": {"metaballs_examples"},
    "metaballs.radius": {"metaballs_demo", "metaballs_examples", "metaballs_viewer"},
    "metaballs.user_scenes": set(),
    # The field's kernel: every job that builds a scene; support and sharpness only for a
    # kernel of finite support (the smoke config's is the inverse square).
    "metaballs.kernel.name": {
        "metaballs_demo",
        "metaballs_deploy",
        "metaballs_equal_quality",
        "metaballs_evaluate",
        "metaballs_examples",
        "metaballs_user_scenes",
        "metaballs_viewer",
    },
    "metaballs.kernel.support": set(),
    "metaballs.kernel.sharpness": set(),
    "metaballs.family": {"metaballs_examples"},
    "metaballs.packing": set(),  # the cluster family's only
    # The scale study's rules are not in the smoke DAG (their lists are empty there); a
    # change that adds them adds jobs, rerunning none.
    "metaballs_scale.balls": set(),
    "metaballs_scale.widths": set(),
    "metaballs_scale.scenes": set(),
    "metaballs_scale.repeats": set(),
    "metaballs_scale.structures": set(),
    "metaballs_scale.user_structures": set(),
    "metaballs_scale.ball_scale": set(),
    "metaballs_scale.trajectory_frames": set(),
    "metaballs_model.variants": set(),
    "metaballs_model.ngf": {"metaballs_train"},
    "metaballs_model.ndf": {"metaballs_train"},
    "metaballs_model.epochs": {"metaballs_train"},
    "metaballs_model.flips": {"metaballs_train"},
    "metaballs_model.batch_size": {"metaballs_train"},
    "metaballs_model.lr": {"metaballs_train"},
    "metaballs_model.lr_schedule": {"metaballs_train"},
    "metaballs_model.gan_weight": {"metaballs_train"},
    "metaballs_model.l1_weight": {"metaballs_train"},
    "metaballs_model.threads": set(),
    "metaballs_model.demo_frames": {"metaballs_demo", "metaballs_viewer"},
    "metaballs_model.equal_quality_examples": {"metaballs_equal_quality"},
    "metaballs_model.demo_balls": {"metaballs_demo", "metaballs_viewer"},
    "metaballs_model.timing_balls": {"metaballs_demo"},
    "simplification.cases": {"simplification_evaluate"},
    "simplification.user_assets": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "simplification.resolution": {
        "simplification_evaluate",
        "simplification_optimise",
        "simplification_prepare",
    },
    "simplification.texture_size": {"simplification_optimise", "simplification_prepare"},
    "simplification.train_views": {"simplification_prepare"},
    "simplification.test_views": {"simplification_prepare"},
    "simplification.reference_spp": {"simplification_prepare"},
    "simplification.test_spp": {"simplification_prepare"},
    "simplification.eval_spp": {"simplification_evaluate"},
    "simplification.supersample": {"simplification_prepare"},
    "simplification.steps": {"simplification_optimise"},
    "simplification.batch": {"simplification_optimise"},
    "simplification.spp": {"simplification_optimise"},
    "simplification.threads": {"simplification_evaluate"},
    "simplification.lr_positions": {"simplification_optimise"},
    "simplification.lr_textures": {"simplification_optimise"},
    "simplification.lr_final_fraction": {"simplification_optimise"},
    "simplification.laplacian_scale": {"simplification_optimise"},
    "simplification.laplacian_min_fraction": {"simplification_optimise"},
    "simplification.intensity": {
        "simplification_evaluate",
        "simplification_optimise",
        "simplification_prepare",
    },
    "simplification.camera_distance": {"simplification_prepare"},
    "simplification.fov": {"simplification_prepare"},
    "simplification.light_distance": {"simplification_prepare"},
    "simplification.light_cone": {"simplification_prepare"},
    "simplification.head_vertices": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "simplification.head_triangles": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "simplification.metaball_count": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "simplification.metaball_grid": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "simplification.metaball_triangles": {
        "simplification_mesh_figure",
        "simplification_prepare",
        "simplification_viewer",
    },
    "report.title": {"report"},
}

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


def test_every_schema_key_is_in_the_matrix():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    assert set(config_keys(schema)) == set(READERS)


def test_an_edit_reruns_exactly_the_rules_that_read_the_key(matrix):
    # The provenance record holds the whole resolved config, so it reads every key.
    wrong = {
        key: {"rerun": sorted(found), "readers": sorted(READERS[key] | {PROVENANCE})}
        for key, found in matrix.items()
        if found != READERS[key] | {PROVENANCE}
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
