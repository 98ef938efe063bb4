"""NDR as the rest of the project sees it (:class:`neurender.method.Method`): its config
rules, the work of each of its rules, its report section's files and the user's files.
Read at DAG time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib import resources
from typing import Any

from neurender import checks, io
from neurender.method import Method, ReportInputs, Rule, Study, Units, unet_work
from neurender.ndr import (
    CALIBRATION_SAMPLES,
    DIFFUSE_VARIANTS,
    EQUAL_QUALITY_REPEATS,
    MESH_SUFFIXES,
    user_probes_problem,
)
from neurender.ndr import rule_keys as keys
from neurender.user_paths import UserPath, made_by_the_workflow
from neurender.viewer_data import TURNS

STAGE = "NDR"
#: The largest coarse map the prefiltered shading takes (6 levels of 2048 x 2048 weights).
MAX_PREFILTERED_HEIGHT = 32


def problems(config: Mapping[str, Any]) -> Iterator[str]:
    """The config rules of NDR's sections (``ndr``, ``ndr_model``) the schema cannot state."""
    ndr, model = config["ndr"], config["ndr_model"]
    yield from checks.ordered(config, "ndr", "primitives")
    yield from checks.halvable(ndr["width"], model["widths"], "ndr.width", "ndr_model.widths")
    if "pix2pix" in model["variants"]:
        yield from checks.power_of_two_at_least(
            ndr["width"], 32, "ndr.width", "the pix2pix baseline's U-Net halves it to 1 pixel"
        )
    yield from checks.square(ndr["coarse_samples"], "ndr.coarse_samples")
    if ndr["reference_spp"] < 8 * ndr["spp"]:
        yield (
            f"ndr.reference_spp = {ndr['reference_spp']}: expected at least 8 x ndr.spp = "
            f"{8 * ndr['spp']} (a clean reference for the test samples)"
        )
    if ndr["coarse_shading"] == "prefiltered" and ndr["coarse_height"] > MAX_PREFILTERED_HEIGHT:
        yield (
            f"ndr.coarse_height = {ndr['coarse_height']}: expected at most "
            f"{MAX_PREFILTERED_HEIGHT} with ndr.coarse_shading = prefiltered (its prefilter "
            "is a dense matrix per roughness level, coarse_height^4 x 8 entries)"
        )
    if ndr["coarse_height"] > ndr["environment_height"]:
        yield (
            f"ndr.coarse_height = {ndr['coarse_height']}: expected at most "
            f"ndr.environment_height = {ndr['environment_height']}"
        )
    if ndr["equal_quality_samples"] > ndr["samples"]["test"]:
        yield (
            f"ndr.equal_quality_samples = {ndr['equal_quality_samples']}: expected at most "
            f"ndr.samples.test = {ndr['samples']['test']} (the sweep renders test samples)"
        )
    if model["relight_sample"] >= ndr["samples"]["test"]:
        yield (
            f"ndr_model.relight_sample = {model['relight_sample']}: expected below "
            f"ndr.samples.test = {ndr['samples']['test']}"
        )
    folder = ndr["user_probes_dir"]
    if folder and not made_by_the_workflow(folder):
        if (problem := user_probes_problem(folder)) is not None:
            yield problem
    for name, path in ndr["user_objects"].items():
        yield from checks.user_file(
            f"ndr.user_objects.{name}", path, MESH_SUFFIXES, "a mesh file NDR reads", named=True
        )


def _coarse_samples(ndr: Mapping[str, Any]) -> int:
    """The coarse shading's samples per pixel (1 for the prefiltered lookups)."""
    return ndr["coarse_samples"] if ndr["coarse_shading"] == "importance" else 1


def _data(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Mitsuba samples: a split's samples x pixels x (samples per pixel + coarse ones)."""
    ndr = cfg["ndr"]
    w = ndr["width"]
    kind, _, part = wildcards.get("split", "train").rpartition("_")
    if kind == "sunlit":
        count = ndr["sunlit_samples"]
    else:
        count = (ndr["diffuse_samples"] if kind else ndr["samples"])[part]
    spp = ndr["spp"] + (ndr["reference_spp"] if part == "test" else 0)
    return count * w * w * (spp + _coarse_samples(ndr)) / 1e6, w * w / 1e3


def _train(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Epochs x training pixels x the U-Net's multiply-adds per pixel."""
    ndr, nm = cfg["ndr"], cfg["ndr_model"]
    w = ndr["width"]
    diffuse = wildcards.get("variant", "ndr") in DIFFUSE_VARIANTS
    count = (ndr["diffuse_samples"] if diffuse else ndr["samples"])["train"]
    pixels = count * w * w
    # Splits over the in-memory limit are read from disk sample by sample.
    data_mb = min(pixels * 30 * 4, io.IN_MEMORY_LIMIT_BYTES) / 1e6
    return nm["epochs"] * pixels * unet_work(nm["widths"]) / 1e6, data_mb


def _test(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Every test sample through every variant."""
    ndr, nm = cfg["ndr"], cfg["ndr_model"]
    w = ndr["width"]
    tests = ndr["samples"]["test"] + ndr["diffuse_samples"]["test"]
    return tests * w * w * len(nm["variants"]) / 1e6, tests * w * w * 40 / 1e6


def _viewer(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """One test sample rendered per turn of the light."""
    ndr = cfg["ndr"]
    w = ndr["width"]
    spp = ndr["spp"] + ndr["reference_spp"] + _coarse_samples(ndr)
    return TURNS * w * w * spp / 1e6, TURNS * w * w * 40 / 1e6


def _equal_quality(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Mitsuba samples of the sweep (each render timed, after one uncounted call) and the
    coarse shading's per timed NDR frame, on its test samples; the two shipped graphs on
    the whole test splits."""
    ndr = cfg["ndr"]
    w = ndr["width"]
    spp = sum({*ndr["equal_quality_spp"], ndr["spp"]}) + _coarse_samples(ndr)
    calls = EQUAL_QUALITY_REPEATS + 1
    sweep = ndr["equal_quality_samples"] * calls * w * w * spp
    graphs = ndr["samples"]["test"] + ndr["sunlit_samples"]
    scored = 2 * graphs * w * w * unet_work(cfg["ndr_model"]["widths"])
    return (sweep + scored) / 1e6, w * w / 1e3


def _summary(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The furnace test's samples."""
    w = cfg["ndr"]["width"]
    return cfg["ndr"]["furnace_spp"] * w * w / 1e6, 0.0


def _deploy(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Per network: an export, and 2 x 23 timed frames (``frame``: the 46 of them); NDR's
    shipped graph: two more exports (float32, int8) and the frames its int8 calibration
    runs."""
    nm, w = cfg["ndr_model"], cfg["ndr"]["width"]
    networks = len({"ndr", *nm["variants"]})
    frame = w * w * unet_work(nm["widths"]) / 1e3
    calibration = CALIBRATION_SAMPLES / (2 * 23) * frame
    return networks * (1 + frame) + 2 + calibration, w * w / 1e3


def user_paths(config: Mapping[str, Any]) -> Iterator[UserPath]:
    """NDR's user files: each object (a mesh naming its materials and textures) and the
    folder of lat-long maps."""
    ndr = config["ndr"]
    for name, path in ndr["user_objects"].items():
        yield UserPath(f"ndr.user_objects.{name}", path, asset=True)
    yield UserPath("ndr.user_probes_dir", ndr["user_probes_dir"])


def report_inputs(config: Mapping[str, Any]) -> ReportInputs:
    """The tables, figures and viewer (the relit test sample) of NDR's report section;
    the user objects' table and figure when there are any."""
    tables = ("targets", "metrics", "timing", "equal_quality", "deployment", "relighting")
    tables += ("furnace", "data")
    figures = ("buffers", "comparison", "equal_quality", "relighting", "training_curves")
    if config["ndr"]["user_objects"]:
        tables += ("user_objects",)
        figures += ("your_objects",)
    return ReportInputs(
        tables=[f"results/ndr/{t}.csv" for t in tables],
        figures=[f"results/ndr/figures/{name}.png" for name in figures],
        viewers=["results/ndr/viewers/relight.json"],
    )


#: The diffuse and coarse-shading studies (``benchmarks/ndr_diffuse_study.py``,
#: ``benchmarks/ndr_coarse_shading_runs.py``) and the deployment and coarse shading timings
#: (``benchmarks/ndr_graph.py``, ``benchmarks/coarse_shading.py``).
STUDIES = (
    Study(
        csv="benchmarks/results/ndr_coarse_shading_runs.csv",
        title="Coarse shading the networks train on: importance-sampled against prefiltered",
        description=(
            "DSSIM of the tone-mapped I_R on the test samples of five NDR stages on the "
            "default config that differ only in the coarse shading: importance-sampled, "
            "prefiltered with its SH and prefiltered maps only (both at 1d43cd2; the "
            "importance run trained ndr and ndr_direct only), prefiltered with the "
            "bright texels as 16 lights (583960f), and the same with 8 lights and a "
            "smaller U-Net (widths 12 24 48 96 instead of 16 32 64 128; 113e762), the "
            "attempt at a faster shipped graph: 11.8 ms a frame, 14.6x Mitsuba at 64 spp "
            "on that day's machine, on which Mitsuba took 172 ms, not 370 (30x missed), "
            "and worse under the real-world-like maps (not the default), and the default "
            "with its shading computed channels first (same values, faster graph; "
            "d696811, another machine: 7.5 ms a frame, 19.0x Mitsuba's 142 ms at 64 spp, "
            "30x missed); every network "
            "trained for 8 epochs, the best validation epoch kept. Rows shading_input "
            "and noise floor are untrained."
        ),
        query="metric == 'dssim_I_R'",
        index=("dataset", "model"),
        columns=("coarse_shading",),
    ),
    Study(
        csv="benchmarks/results/ndr_diffuse_study.csv",
        title="Diffuse-data study: NDR against Real Shading",
        description=(
            "DSSIM of the tone-mapped I_R on the diffuse data's val (24) and test (60) "
            "samples at 64 x 64, per variant and coarse shading, the mean over its seeds "
            "(1 to 3); every variant trained for 8 epochs (batch 16, cosine schedule), the "
            "best validation epoch kept. Rows shading_input and noise floor are untrained."
        ),
        query="metric == 'dssim_I_R'",
        index=("variant", "coarse_shading"),
        columns=("split",),
    ),
    Study(
        csv="benchmarks/results/ndr_graph.csv",
        title="Shipped graph: milliseconds per part",
        description=(
            "Median ONNX Runtime milliseconds of one 64 x 64 frame of the default network, "
            "the prefiltered coarse shading and the two in one graph, per thread count, "
            "each also with its convolutions int8 (ONNX Runtime's static QDQ quantizer; "
            "speed only: weights at initialisation; the trained network's int8 graph is "
            "scored and timed by the pipeline, in the equal-quality table). The CSV also "
            "holds PyTorch's times and the export check."
        ),
        index=("part",),
        columns=("threads",),
        values="onnxruntime_ms",
    ),
    Study(
        csv="benchmarks/results/coarse_shading_accuracy.csv",
        title="Coarse shading: agreement with the exact shading",
        description=(
            "Mean |estimate - reference| / mean reference of S_D and S_S over one 64 x 64 "
            "object's pixels under built-in, procedural and real-world-like maps, for the "
            "importance-sampled estimator (64 samples per lobe) and the prefiltered one "
            "(bright texels as lights), against the importance estimator at 1024 samples "
            "on the 16-row coarse map both read and on the full 128-row map (where a "
            "sun keeps its place and size)."
        ),
        index=("map", "shading"),
        columns=("estimator", "reference"),
        values="rel_diff",
        digits=3,
    ),
    Study(
        csv="benchmarks/results/coarse_shading.csv",
        title="Coarse shading: milliseconds per image",
        description=(
            "Median milliseconds of the coarse shading of one 64 x 64 object's pixels by "
            "the importance-sampled estimator (64 samples per lobe) and the prefiltered "
            "one, and of the prefiltered lighting's once-per-map preparation, per thread "
            "count."
        ),
        index=("estimator",),
        columns=("threads",),
        values="ms",
    ),
)

METHOD = Method(
    key="ndr",
    title="NDR: neural direct-illumination renderer",
    citation=(
        "Christian Suppan, Andrew Chalmers, Junhong Zhao, Alex Doronin, Taehyun Rhee. Neural "
        "Screen Space Rendering of Direct Illumination. Pacific Graphics 2021 Short Papers, "
        "The Eurographics Association, 2021."
    ),
    link="https://doi.org/10.2312/pg.20211385",
    config_sections=("ndr", "ndr_model"),
    problems=problems,
    report_inputs=report_inputs,
    user_paths=user_paths,
    studies=STUDIES,
    rules={
        "ndr_data": Rule(STAGE, _data, gpu=True, params=keys.DATA),
        "ndr_summary": Rule(STAGE, _summary, params=keys.SUMMARY),
        "ndr_train": Rule(STAGE, _train, gpu=True, params=keys.TRAIN),
        "ndr_evaluate": Rule(STAGE, _test, params=keys.EVALUATE),
        "ndr_deploy": Rule(STAGE, _deploy, params=keys.DEPLOY),
        "ndr_equal_quality": Rule(STAGE, _equal_quality, params=keys.EQUAL_QUALITY),
        "ndr_targets": Rule(STAGE),
        "ndr_relight": Rule(STAGE, _test, params=keys.RELIGHT),
        "ndr_user_objects": Rule(STAGE, params=keys.USER_OBJECTS),
        "ndr_viewer": Rule(STAGE, _viewer, params=keys.VIEWER),
    },
    tables_dir=resources.files(__package__),
    unread_keys=keys.UNREAD,
)
