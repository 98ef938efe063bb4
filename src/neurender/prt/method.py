"""DeepPRT as the rest of the project sees it (:class:`neurender.method.Method`): its
config rules, the work of each of its rules, its report section's files and the user's
files. Read at DAG time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib import resources
from typing import Any

from neurender import checks
from neurender.lights import BUILTIN_PROBES
from neurender.method import Method, ReportInputs, Rule, Study, Units, unet_work
from neurender.prt import (
    CALIBRATION_FRAMES,
    CHECK_FRAMES,
    DISK_EXPECTED,
    EXPERIMENTS,
    MESH_SUFFIXES,
    OBJECTS,
    RESERVED,
    VTK_SUFFIXES,
    too_small,
    user_sequence_problems,
)
from neurender.prt import rule_keys as keys
from neurender.user_paths import UserPath, made_by_the_workflow

#: The plan's stages: the ground truth (data, transfer, figures) and the learned models.
DATA, MODELS = "DeepPRT data", "DeepPRT models"
#: Transfer coefficients per SH coefficient: 1 (diffuse) or 3 (glossy, per colour).
GLOSSY_CHANNELS = 3
#: Unseen-deformation families of an object with blendshapes, the most
#: (:data:`neurender.prt.unseen.FAMILIES`; not imported: it is heavy).
UNSEEN_FAMILIES = 6


def problems(config: Mapping[str, Any]) -> Iterator[str]:
    """The config rules of DeepPRT's sections (``prt``, ``prt_model``) the schema cannot state."""
    prt, model = config["prt"], config["prt_model"]
    meshes, sequences = prt["user_meshes"], prt["user_sequences"]
    yield from checks.known(prt["objects"], OBJECTS, {**meshes, **sequences}, "prt.objects")
    for name in sorted(set(meshes) & set(sequences)):
        yield (
            f"prt.user_meshes.{name} and prt.user_sequences.{name}: one name for two user "
            "objects; expected each name in one of them"
        )
    for section, entries in (("user_meshes", meshes), ("user_sequences", sequences)):
        for name in sorted(set(entries) & set(RESERVED)):
            yield (
                f"prt.{section}.{name}: the name of a built-in dataset; expected another "
                f"name (reserved: {', '.join(RESERVED)})"
            )
    for name, entry in sequences.items():
        yield from user_sequence_problems(name, entry, made_by_the_workflow)
    yield from checks.known(prt["probes"], BUILTIN_PROBES, prt["user_probes"], "prt.probes")
    yield from checks.member(prt["light"], prt["probes"], "prt.light", "prt.probes")
    yield from checks.member(
        model["shipped"], model["variants"], "prt_model.shipped", "prt_model.variants"
    )
    yield from checks.square(prt["directions"], "prt.directions")
    yield from checks.square(prt["reference_directions"], "prt.reference_directions")
    for count in model["equal_quality_directions"]:
        yield from checks.square(count, "prt_model.equal_quality_directions entry")
    if prt["reference_directions"] < 4 * prt["directions"]:
        yield (
            f"prt.reference_directions = {prt['reference_directions']}: expected at least 4 x "
            f"prt.directions = {4 * prt['directions']} (a clean reference for the test frames)"
        )
    if prt["experiments"] and prt["experiment_train_frames"] > prt["frames"]["train"]:
        yield (
            f"prt.experiment_train_frames = {prt['experiment_train_frames']}: expected at most "
            f"prt.frames.train = {prt['frames']['train']}"
        )
    yield from checks.ordered(config, "prt", "linear_range")
    yield from checks.halvable(
        prt["resolution"], model["widths"], "prt.resolution", "prt_model.widths"
    )
    for name, path in meshes.items():
        key = f"prt.user_meshes.{name}"
        found = list(checks.user_file(key, path, MESH_SUFFIXES + VTK_SUFFIXES, "a mesh file"))
        yield from found
        count = None if found or made_by_the_workflow(path) else too_small(path)
        if count is not None:
            yield f"{key} = {path!r}: {count} vertices; {DISK_EXPECTED}"
    for name, path in prt["user_probes"].items():
        yield from checks.user_file(
            f"prt.user_probes.{name}", path, (".exr",), "a lat-long EXR light probe"
        )


def _transfer(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Rays traced: a split's frames x pixels x directions (half the hemisphere hit)."""
    prt, n, frames = cfg["prt"], cfg["prt"]["resolution"], cfg["prt"]["frames"]
    split = wildcards.get("split", "train")
    count = frames.get(split, frames["test"])
    dirs = prt["reference_directions"] if split == "test" else prt["directions"]
    return count * n * n * dirs / 2 / 1e6, n * n * dirs / 1e6


def _noise_floor(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    prt, n = cfg["prt"], cfg["prt"]["resolution"]
    return prt["noise_floor_frames"] * n * n * prt["directions"] / 1e6, n * n / 1e3


def _benchmark(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Rays of 6 frames, and of the paper's 256^2 x 1024-direction scale if asked for."""
    prt, n = cfg["prt"], cfg["prt"]["resolution"]
    paper = 2 * 256 * 256 * 1024 / 2 if prt["benchmark_paper_scale"] else 0
    return (6 * n * n * prt["directions"] / 2 + paper) / 1e6, (paper > 0) * 65.536


def _frames(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Every frame's geometry-image pixels, and the source mesh's vertices."""
    prt, n = cfg["prt"], cfg["prt"]["resolution"]
    return (sum(prt["frames"].values()) * n * n + prt["source_vertices"]) / 1e6, n * n / 1e3


def _train(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Epochs x training pixels x the U-Net's multiply-adds per pixel."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n, frames = prt["resolution"], prt["frames"]
    k = prt["n_bands"] ** 2 * (GLOSSY_CHANNELS if wildcards.get("material") == "glossy" else 1)
    pixels = (frames["train"] + frames["val"]) * n * n
    return pm["epochs"] * pixels * unet_work(pm["widths"]) / 1e6, pixels * (6 + k) / 1e6


def _deploy(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The network run on the int8 graph's calibration frames and the export's check
    frames (pixels times the U-Net's multiply-adds per pixel), and those frames."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n, frames = prt["resolution"], prt["frames"]
    count = min(CALIBRATION_FRAMES, frames["train"]) + min(CHECK_FRAMES, frames["val"])
    k = prt["n_bands"] ** 2 * (GLOSSY_CHANNELS if wildcards.get("material") == "glossy" else 1)
    return count * n * n * unet_work(pm["widths"]) / 1e6, count * n * n * (6 + k) / 1e6


def _evaluate(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The noise floor's rays (every test frame at both direction counts) and the
    validation and test renders."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n, frames = prt["resolution"], prt["frames"]
    rays = frames["test"] * n * n * (prt["directions"] + prt["reference_directions"]) / 2
    renders = (frames["val"] + frames["test"]) * pm["render_resolution"] ** 2 * 8
    return (rays + renders) / 1e6, (frames["val"] + frames["test"]) * n * n * 60 / 1e6


def _equal_quality(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The ray-traced estimates on the first test frames, at every direction count of the
    sweep and the reference's."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n, frames = prt["resolution"], prt["frames"]
    directions = sum(pm["equal_quality_directions"]) + prt["reference_directions"]
    rays = min(prt["noise_floor_frames"], frames["test"]) * n * n / 2 * directions
    return rays / 1e6, frames["test"] * n * n * 60 / 1e6


def _unseen(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The unseen frames' reference rays (every family, strength and frame, and the mean
    shape) and their renders (each of up to 5 models and 2 materials, and the truth)."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n = prt["resolution"]
    frames = UNSEEN_FAMILIES * len(pm["unseen_strengths"]) * pm["unseen_frames"]
    rays = (frames + 1) * n * n * prt["reference_directions"] / 2
    renders = frames * 12 * pm["render_resolution"] ** 2
    return (rays + renders) / 1e6, pm["unseen_frames"] * n * n * 60 / 1e6


def _viewer(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The test split read, one frame predicted."""
    n, frames = cfg["prt"]["resolution"], cfg["prt"]["frames"]
    return frames["test"] * n * n / 1e6, frames["test"] * n * n * 60 / 1e6


def _mesh_figure(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    n, frames = cfg["prt"]["resolution"], cfg["prt"]["frames"]
    return sum(frames.values()) * n * n / 1e6, n * n / 1e3


def _momoprt(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """A least-squares fit per SH coefficient over the training pixels."""
    prt, n, frames = cfg["prt"], cfg["prt"]["resolution"], cfg["prt"]["frames"]
    pixels = (frames["train"] + frames["val"]) * n * n
    return pixels * prt["n_bands"] ** 2 / 1e6, pixels * prt["n_bands"] ** 2 * 3 / 1e6


def user_paths(config: Mapping[str, Any]) -> Iterator[UserPath]:
    """DeepPRT's user files: each mesh and probe, each sequence's frames and test frames."""
    prt = config["prt"]
    for section in ("user_meshes", "user_probes"):
        for name, path in prt[section].items():
            yield UserPath(f"prt.{section}.{name}", path)
    for name, entry in prt["user_sequences"].items():
        for field in ("frames", "test_frames"):
            yield UserPath(f"prt.user_sequences.{name}.{field}", entry[field])


def report_inputs(config: Mapping[str, Any]) -> ReportInputs:
    """The tables, figures (four per object, one per experiment) and viewers (one per
    object) of DeepPRT's report section."""
    objects = list(config["prt"]["objects"])
    experiments = EXPERIMENTS if config["prt"]["experiments"] else ()
    tables = ("targets", "metrics", "equal_quality", "compression", "deployment", "data")
    tables += ("noise_floor",)
    tables += ("benchmark", "unseen")
    kinds = ("prediction", "unseen", "frames", "meshes")
    fixed = ["loss_curves", "equal_quality", "light_probes"]
    if len(config["prt"]["probes"]) >= 2:
        fixed.append(f"{objects[0]}_relight")
    figures = [f"{o}_{kind}" for o in objects for kind in kinds] + list(experiments) + fixed
    return ReportInputs(
        tables=[f"results/prt/{t}.csv" for t in tables]
        + [f"results/prt/{x}/experiment.csv" for x in experiments],
        figures=[f"results/prt/figures/{name}.png" for name in figures],
        viewers=[f"results/prt/viewers/{o}.json" for o in objects],
    )


#: The generalisation study, ``benchmarks/prt_generalisation.py``: the shipped model against the
#: shadowing variant and the two baselines at 3, 8 and 14 epochs.
GENERALISATION = "benchmarks/results/prt_generalisation.csv"
#: The learning curves, ``benchmarks/prt_generalisation.py --study
#: config/studies/deepprt.yaml``: budgets in epochs and in distinct training shapes.
LEARNING_CURVE = "benchmarks/results/prt_learning_curve.csv"
#: The gated correction, ``benchmarks/prt_correction_runs.py``: the shadowing
#: variant with and without its gate, retrained on the same data.
CORRECTION = "benchmarks/results/prt_correction_runs.csv"
#: The shadowing variant's own batch size, the same script: batch 5 (the paper form's)
#: against 2 (``prt_model.shadowing_batch_size``), retrained on the same data.
BATCH = "benchmarks/results/prt_batch_runs.csv"


def _run_views(
    csv: str, column: str, last: str | int, title: str, description: str, material: str
) -> tuple[Study, Study]:
    """The two views of a study of ``benchmarks/prt_correction_runs.py`` (runs of the model
    stage on the same data, named in ``column``): the shipped variant's test scores per
    run, and its relative L1 of ``material`` radiance on each unseen family per run beside
    every other model of the run ``last``."""
    return (
        Study(
            csv=csv,
            title=f"{title}: the test frames",
            description=description,
            query="split == 'test' and model == 'DeepPRT shadowing'",
            index=("dataset", "metric"),
            columns=(column,),
        ),
        Study(
            csv=csv,
            title=f"{title}: unseen deformations, {material}",
            description=(
                f"The same networks' relative L1 of {material} radiance on each unseen "
                "deformation family (mean over strengths 0.25 to 1), beside the paper's "
                "form, MoMoPRT and the baselines that need no learning (disks, unshadowed, "
                f"static) of the run {last}."
            ),
            query=(
                f"split == 'unseen' and metric == 'rel_l1_radiance_{material}' and "
                f"(model == 'DeepPRT shadowing' or {column} == {last!r})"
            ),
            index=("dataset", "family"),
            columns=("model", column),
        ),
    )


#: The rows both curves show. Their budgets: the study config's ``equal_steps`` (8 epochs
#: over 240 frames: 1920 frame passes, at each model's batch size the same optimiser steps
#: for every number of frames); baselines, untrained, have 0 epochs.
_CURVE_METRIC = "metric == 'rel_l1_diffuse' and family != 'timing'"
STUDIES = (
    Study(
        csv=LEARNING_CURVE,
        title="Learning curve: epochs",
        description=(
            "Relative L1 of the diffuse radiance on the test frames and on each unseen "
            "deformation family (mean over strengths 0.25, 0.5 and 1) of the paper's model "
            "and the shadowing variant trained for 2, 4 and 8 epochs over the same 240 "
            "frames (evenly spaced over a training sequence of 480; 64 x 64, 256 "
            "directions, references at 4096), beside the unshadowed and static baselines "
            "(0 epochs). Each model at its own batch size and learning rate (the paper's "
            "form batch 5, the shadowing variant 2, both lr 2e-3); the shadowing variant as "
            "shipped at 8512885 (disks, occlusion input, gated correction)."
        ),
        query=f"{_CURVE_METRIC} and (train_frames == 240 or epochs == 0)",
        index=("object", "model", "epochs"),
        columns=("family",),
    ),
    Study(
        csv=LEARNING_CURVE,
        title="Learning curve: distinct training shapes at equal steps",
        description=(
            "The same error for 30 to 480 training frames, evenly spaced over one "
            "sequence of 480, each model trained for the same optimiser steps at every "
            "count (64 epochs over 30 frames, 4 over 480; 384 steps at the paper form's "
            "batch of 5, 960 at the shadowing variant's 2): does variety of shapes help "
            "where more epochs do not? Baselines at 0 frames. Same models as above."
        ),
        query=f"{_CURVE_METRIC} and (epochs * train_frames == 1920 or epochs == 0)",
        index=("object", "model", "train_frames"),
        columns=("family",),
    ),
    Study(
        csv=GENERALISATION,
        title="Generalisation study: the test frames",
        description=(
            "Relative L1 of the diffuse radiance and SSIM of the diffuse images on the 40 "
            "test frames of head and cloth (64 x 64, 256 directions, references at 1024), "
            "for the paper's model and the shadowing variant, each trained for 3, 8 and 14 "
            "epochs over the same 240 frames, beside the unshadowed and static baselines."
        ),
        query="family == 'test'",
        index=("object", "model"),
        columns=("metric", "epochs"),
    ),
    Study(
        csv=GENERALISATION,
        title="Generalisation study: unseen deformations",
        description=(
            "Relative L1 of the diffuse radiance on deformations outside the training "
            "animation (each family's mean over strengths 0.25, 0.5 and 1), same models "
            "and budgets as the test frames above."
        ),
        query="family != 'test' and metric == 'rel_l1_diffuse'",
        index=("object", "family"),
        columns=("model", "epochs"),
    ),
    *_run_views(
        CORRECTION,
        "correction",
        "gated",
        "Gated correction",
        (
            "The shadowing variant as shipped before dea4ca1 (its correction added "
            "everywhere) and gated by the disks' occlusion (the correction scaled per pixel "
            "by their occluded solid angle), retrained on the same data of a default run "
            "(8 epochs each, 64 x 64, 256 directions, references at 4096): relative L1 of "
            "radiance and SSIM on the test frames. Its glossy SSIMs predate 05f4431 (only "
            "the prediction clamped at 0, not the reference: lower than today's scores)."
        ),
        "diffuse",
    ),
    *_run_views(
        BATCH,
        "batch",
        2,
        "Batch size of the shadowing variant",
        (
            "The shadowing variant (gated) trained with the paper form's batch of 5 and "
            "with its own batch of 2 (config key prt_model.shadowing_batch_size), both at "
            "learning rate 2e-3 for 8 epochs on the same data of a default run (64 x 64, "
            "256 directions, references at 4096): relative L1 of radiance and SSIM on the "
            "test frames."
        ),
        "glossy",
    ),
    Study(
        csv="benchmarks/results/prt_graph.csv",
        title="Shipped shadowing graph: milliseconds per part",
        description=(
            "Median ONNX Runtime milliseconds of one 64 x 64 frame of the default config's "
            "shadowing variant (weights at initialisation: the time does not depend on "
            "them) per material, part and thread count: the unshadowed transfer, the "
            "disks' occlusion (16 x 16 blocks, 65,536 pairs), the local features, the core "
            "network (5 dilated 3x3 layers of 48 channels) and the whole graph as shipped. "
            "The CSV also holds PyTorch's times and the export check."
        ),
        index=("material", "part"),
        columns=("threads",),
        values="onnxruntime_ms",
    ),
    Study(
        csv="benchmarks/results/prt_width.csv",
        title="Width of the shadowing network",
        description=(
            "The shadowing variant at widths 16, 24 and 32 (48 is the study above), 14 "
            "epochs on head and cloth: relative L1 of the diffuse radiance on the test "
            "frames, and the network's milliseconds per 64 x 64 frame in ONNX Runtime "
            "(1 thread; untrained networks of each width; measured at 1b41e83, before the "
            "inputs' local mean became two 1D means)."
        ),
        # The trained networks' own timing rows were taken under load: the untrained
        # networks' sweep (interleaved rounds, the median) gives the milliseconds.
        query=(
            "(family == 'test' and metric == 'rel_l1_diffuse' and model == 'shadowing')"
            " or (object == 'untrained' and metric == 'onnx_ms_per_frame')"
        ),
        index=("object", "model", "shadowing_width"),
        columns=("metric",),
    ),
)

METHOD = Method(
    key="prt",
    title="DeepPRT: deep precomputed radiance transfer for deformable objects",
    citation=(
        "Yue Li, Pablo Wiedemann, Kenny Mitchell. Deep Precomputed Radiance Transfer for "
        "Deformable Objects. Proceedings of the ACM on Computer Graphics and Interactive "
        "Techniques 2(1), 2019 (I3D 2019)."
    ),
    link="https://doi.org/10.1145/3320284",
    config_sections=("prt", "prt_model"),
    problems=problems,
    report_inputs=report_inputs,
    user_paths=user_paths,
    studies=STUDIES,
    rules={
        "prt_probe": Rule(DATA, params=keys.PROBE),
        "prt_geometry_image": Rule(DATA, _frames, params=keys.GEOMETRY_IMAGE),
        "prt_sequence": Rule(DATA, _frames, params=keys.SEQUENCE),
        "prt_transfer": Rule(DATA, _transfer, params=keys.TRANSFER_JOB),
        "prt_noise_floor": Rule(DATA, _noise_floor, params=keys.NOISE_FLOOR),
        "prt_figure": Rule(DATA, params=keys.FIGURE),
        "prt_summary": Rule(DATA),
        "prt_benchmark": Rule(DATA, _benchmark, params=keys.BENCHMARK),
        "prt_probes_figure": Rule(DATA),
        "prt_mesh_figure": Rule(DATA, _mesh_figure, params=keys.MESH_FIGURE),
        "prt_train": Rule(MODELS, _train, gpu=True, params=keys.TRAIN),
        "prt_deploy": Rule(MODELS, _deploy, params=keys.DEPLOY),
        "prt_ship": Rule(MODELS, params=keys.SHIP),
        "prt_momoprt": Rule(MODELS, _momoprt, params=keys.MOMOPRT),
        "prt_evaluate": Rule(MODELS, _evaluate, params=keys.EVALUATE),
        "prt_equal_quality": Rule(MODELS, _equal_quality, params=keys.EQUAL_QUALITY),
        "prt_model_summary": Rule(MODELS, params=keys.MODEL_SUMMARY),
        "prt_targets": Rule(MODELS, params=keys.TARGETS),
        "prt_experiment": Rule(MODELS, params=keys.EXPERIMENT),
        "prt_unseen": Rule(MODELS, _unseen, params=keys.UNSEEN),
        "prt_unseen_summary": Rule(MODELS),
        "prt_relight": Rule(MODELS, params=keys.TEST_FRAME),
        "prt_viewer": Rule(MODELS, _viewer, params=keys.VIEWER),
    },
    tables_dir=resources.files(__package__),
    unread_keys=keys.UNREAD,
    stage_rules={"data": "prt_transfer"},
)
