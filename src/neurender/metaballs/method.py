"""The image-space metaballs as the rest of the project sees them
(:class:`neurender.method.Method`): their config rules, the work of each of their rules,
their report section's files and the user's files. Read at DAG time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib import resources
from typing import Any

from neurender import checks, io
from neurender.metaballs import (
    EQUAL_QUALITY_BISECTIONS,
    EQUAL_QUALITY_MIN_STEPS,
    EQUAL_QUALITY_RESOLUTIONS,
    GAN_VARIANTS,
    MIRRORINGS,
    trained_variants,
)
from neurender.metaballs import rule_keys as keys
from neurender.metaballs.scene_file import read_user_scenes
from neurender.method import Method, ReportInputs, Rule, Study, Units
from neurender.user_paths import UserPath, made_by_the_workflow

STAGE = "metaballs"


def gan_step_cost(ngf: int, ndf: int) -> float:
    """How many steps without the discriminator a step with it costs: the generator's
    passes plus the discriminator's three (real, fake, the generator's loss), which grow
    with ``(ndf / ngf)^2``. Fitted on the 2-core reference CPU (width 128, batch 4,
    ngf 16, one thread): 2.2 at ndf 16, 3.9 at ndf 32; ``benchmarks/gpu_check.py`` counts
    GPU steps alike."""
    return 1.63 + 0.57 * (ndf / ngf) ** 2


def problems(config: Mapping[str, Any]) -> Iterator[str]:
    """The config rules of the metaballs' section the schema cannot state."""
    yield from checks.ordered(config, "metaballs", "balls")
    yield from checks.ordered(config, "metaballs", "radius")
    yield from checks.power_of_two_at_least(
        config["metaballs"]["width"], 32, "metaballs.width", "the pix2pix U-Net halves it to 1"
    )
    scenes = config["metaballs"]["user_scenes"]
    if scenes and not made_by_the_workflow(scenes):
        try:
            read_user_scenes(scenes)
        except (OSError, ValueError) as err:
            yield f"metaballs.user_scenes = {scenes!r}: {err}"
    yield from _structure_problems(config["metaballs_scale"]["user_structures"])


def _structure_problems(paths: list[str]) -> Iterator[str]:
    """Each of your structure files that gemmi cannot read as the job would, named."""
    if not paths:
        return
    from neurender.metaballs import molecules  # gemmi: only when there are files to read

    for index, path in enumerate(paths):
        if made_by_the_workflow(path):
            continue
        try:
            molecules.read_frames(path)
        except (OSError, ValueError) as err:
            yield f"metaballs_scale.user_structures[{index}] = {path!r}: {err}"


def _examples(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Ray-marched pixels x the mean number of balls (the middle of ``metaballs.balls``)."""
    mb = cfg["metaballs"]
    w = mb["width"]
    count = mb["examples"][wildcards.get("split", "train")]
    return count * w * w * sum(mb["balls"]) / 2 / 1e6, w * w / 1e3


def _train(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Steps x pixels x the generator's width squared (a GAN step costs more)."""
    mb, mm = cfg["metaballs"], cfg["metaballs_model"]
    w = mb["width"]
    gan = wildcards.get("variant", "pix2pix") in GAN_VARIANTS
    gan = gan_step_cost(mm["ngf"], mm["ndf"]) if gan else 1.0
    flips = MIRRORINGS if mm["flips"] else 1
    steps = mm["epochs"] * flips * mb["examples"]["train"]
    data_mb = min(mb["examples"]["train"] * w * w * 12, io.IN_MEMORY_LIMIT_BYTES) / 1e6
    return steps * w * w * mm["ngf"] ** 2 * gan / 1e9, data_mb


def _deploy(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Per network: an export, and 2 x 23 timed frames."""
    w, ngf = cfg["metaballs"]["width"], cfg["metaballs_model"]["ngf"]
    networks = len(trained_variants(cfg["metaballs_model"]["variants"]))
    return networks * (1 + w * w * ngf**2 / 1e6), w * w / 1e3


def _viewer(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The demo rendered by every network and by the ray marcher."""
    w, frames = cfg["metaballs"]["width"], cfg["metaballs_model"]["demo_frames"]
    renderers = len(trained_variants(cfg["metaballs_model"]["variants"])) + 1
    return frames * w * w * renderers / 1e6, frames * w * w * renderers / 1e3


def _test(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The test examples and the demo's frames."""
    mb, mm = cfg["metaballs"], cfg["metaballs_model"]
    w = mb["width"]
    return (mb["examples"]["test"] + mm["demo_frames"]) * w * w / 1e6, w * w / 1e3


def user_paths(config: Mapping[str, Any]) -> Iterator[UserPath]:
    """The metaballs' user files: the scenes CSV and the structure files."""
    yield UserPath("metaballs.user_scenes", config["metaballs"]["user_scenes"])
    for index, path in enumerate(config["metaballs_scale"]["user_structures"]):
        yield UserPath(f"metaballs_scale.user_structures[{index}]", path)


def _equal_quality(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Ray-marched pixels of the sweep on its examples x the mean number of balls (each
    setting marches at its resolution squared), and the networks' timed frames."""
    mb, mm = cfg["metaballs"], cfg["metaballs_model"]
    w = mb["width"]
    per_resolution = len(EQUAL_QUALITY_MIN_STEPS) * len(EQUAL_QUALITY_BISECTIONS)
    pixels = per_resolution * sum(round(r * w) ** 2 for r in EQUAL_QUALITY_RESOLUTIONS)
    networks = len(trained_variants(mm["variants"]))
    work = mm["equal_quality_examples"] * (pixels * sum(mb["balls"]) / 2 + networks * w * w)
    return work / 1e6, w * w / 1e3


def _scale(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Every renderer's pixels x balls over the counts, widths and scenes measured."""
    sc = cfg["metaballs_scale"]
    pixels = sum(w * w for w in sc["widths"])
    return pixels * sum(sc["balls"]) * sc["scenes"] / 1e9, max(sc["widths"]) ** 2 / 1e3


def _real_scenes(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The real scenes' count at the trained width (each some 10^4 balls)."""
    sc, w = cfg["metaballs_scale"], cfg["metaballs"]["width"]
    scenes = len(sc["structures"]) + len(sc["user_structures"])
    return scenes * sc["trajectory_frames"] * w * w / 1e5, w * w / 1e3


def report_inputs(config: Mapping[str, Any]) -> ReportInputs:
    """The tables, figures (the demo's GIF last) and viewer (the demo) of the metaballs'
    report section; the user scenes' table and figure when there are any."""
    tables = ("targets", "metrics", "timing", "equal_quality", "deployment", "data")
    figures = (
        "comparison",
        "accuracy_by_scene",
        "demo_network_vs_raymarch",
        "temporal_stability",
        "frame_time_vs_balls",
        "equal_quality",
        "examples",
    )
    if config["metaballs"]["user_scenes"]:
        tables += ("user_scenes",)
        figures += ("your_scenes",)
    animations = ["demo"]
    if config["metaballs_scale"]["balls"]:
        tables += ("scale_equal_quality",)
        figures += ("scale",)
    scale = config["metaballs_scale"]
    if scale["structures"] or scale["user_structures"]:
        tables += ("real_scenes",)
        figures += ("real_scenes",)
    if "adk_dims" in scale["structures"]:
        animations.append("trajectory")
    return ReportInputs(
        tables=[f"results/metaballs/{t}.csv" for t in tables],
        figures=[f"results/metaballs/figures/{name}.png" for name in figures]
        + [f"results/metaballs/figures/{name}.gif" for name in animations],
        viewers=["results/metaballs/viewers/demo.json"],
    )


#: The committed run of the scale study (config/studies/metaballs_scale.yaml).
SCALE_STUDY = "benchmarks/results/metaball_scale.csv"
EQUAL_QUALITY_STUDY = "benchmarks/results/metaball_scale_equal_quality.csv"
REAL_SCENES_STUDY = "benchmarks/results/metaball_real_scenes.csv"
#: The committed run of the learning-curve study (config/studies/metaballs_learning_curve.yaml).
LEARNING_CURVE_STUDY = "benchmarks/results/metaball_learning_curve.csv"
_CURVE_METRICS = (
    "metric in ['iou_depth', 'normal_error_mean_deg', 'normal_error_median_deg', "
    "'ssim_normal', 'l1_normal']"
)


def _curve_study(title: str, description: str, runs: str, figures: tuple[str, ...] = ()) -> Study:
    """A table of the learning-curve study: the isolated spheres and the pix2pix ``runs``
    (a query over examples and epochs), the figure's metrics as columns."""
    return Study(
        csv=LEARNING_CURVE_STUDY,
        title=f"Learning curve: pix2pix (the thesis) {title}",
        description=description,
        query=f"(model == 'isolated spheres' or {runs}) and {_CURVE_METRICS}",
        index=("model", "examples", "epochs"),
        columns=("metric",),
        digits=3,
        figures=figures,
    )


STUDIES = (
    _curve_study(
        "against the training examples",
        (
            "pix2pix from the circle image (the thesis's network) trained from scratch for 2 "
            "epochs on 600, 1,200, 2,400, 4,800 and 9,600 thesis scenes (four mirrorings per "
            "example and epoch, a cosine schedule per run; every other setting the default "
            "config's: 128 px, 16-filter generator and discriminator, lr 5e-4, batch 4, one "
            "thread), scored on the 300 test scenes beside the isolated spheres (0 examples, "
            "0 epochs), which need no learning. The thesis trained on 20,000 examples."
        ),
        "epochs == 2",
    ),
    _curve_study(
        "against the epochs",
        (
            "The same network and settings on the default config's 1,200 examples for 1, "
            "2, 4, 8 and 16 epochs, each run from scratch with its own cosine schedule (the "
            "1,200 x 2 run is the table above's)."
        ),
        "examples == 1200",
    ),
    _curve_study(
        "at more examples and more epochs at once",
        (
            "The same network and settings on 4,800 examples for 8 epochs: 16 times the "
            "default run's training (examples x epochs), twice that of 9,600 x 2 and of "
            "1,200 x 16 above. The figure's bottom row sets every run against examples x "
            "epochs."
        ),
        "(examples > 1200 and epochs > 2)",
        figures=("benchmarks/results/metaball_learning_curve.png",),
    ),
    Study(
        csv=EQUAL_QUALITY_STUDY,
        title="At scale: ours against each renderer of its quality",
        description=(
            "Cluster scenes of 10^2 to 10^5 balls at a constant density (Wyvill kernel, "
            "packing 0.15, no wall), two per count, one thread: per renderer the fastest "
            "setting whose mean silhouette IoU and normal error reach ours "
            "(sphere_residual, trained 2 epochs on 600 cluster scenes of 10^2 to 10^4 balls "
            "at 128 px; at 512 px its quality at 128 px and the time of a generator of its "
            "size built for 512 px), its time over ours, and its bound (the shared rule: "
            "'lower bound', no setting reaches ours, the slowest shown; 'upper bound', the "
            "fastest already does). Above 1 the network is faster."
        ),
        query="network == 'sphere_residual'",
        index=("width", "renderer", "bound"),
        columns=("balls",),
        values="speedup",
        digits=3,
        figures=("benchmarks/results/metaball_scale.png",),
    ),
    Study(
        csv=SCALE_STUDY,
        title="At scale: milliseconds per frame",
        description=(
            "The same scenes: each renderer's time per frame (the networks' inputs and "
            "network together) against the number of balls, the mean over the scenes."
        ),
        query="metric == 'ms_per_frame' and setting in ['reference', 'trained', "
        "'timed only (untrained, same size)', '4 steps', 'spheres of radius r', "
        "'spacing 0.5 r', 'narrow_range separable, radius 1.5 r, 1 iteration', "
        "'1 width, 4 bisections']",
        index=("width", "renderer", "setting"),
        columns=("balls",),
        digits=3,
    ),
    Study(
        csv=REAL_SCENES_STUDY,
        title="Real scenes: molecules, a trajectory and a fluid frame",
        description=(
            "The shipped Protein Data Bank entries (1a28, 19hc, 6msm), three frames of the "
            "adenylate-kinase trajectory and the SPlisHSPlasH dam-break frame, framed at "
            "128 px with the Wyvill kernel, by the networks of the scale study and each "
            "no-learning renderer: milliseconds per frame, silhouette IoU and mean normal "
            "error (degrees) against the exact renderer."
        ),
        query="metric in ['ms_per_frame', 'iou_depth', 'normal_error_mean_deg'] and setting "
        "in ['reference', 'trained', '4 steps', 'spheres of radius r', 'spacing 0.5 r', "
        "'narrow_range separable, radius 1.5 r, 1 iteration']",
        index=("scene", "renderer"),
        columns=("metric",),
        digits=3,
        figures=("benchmarks/results/metaball_real_scenes.png",),
    ),
)

METHOD = Method(
    key="metaballs",
    title="Image-space metaballs (pix2pix)",
    citation=(
        "Robert Horvath. Image-Space Metaballs Using Deep Learning. Master's thesis, TU Wien, "
        "Faculty of Informatics, 2019 (advisor Ivan Viola)."
    ),
    link="https://repositum.tuwien.at",
    config_sections=("metaballs", "metaballs_model", "metaballs_scale"),
    problems=problems,
    report_inputs=report_inputs,
    user_paths=user_paths,
    rules={
        "metaballs_examples": Rule(STAGE, _examples, params=keys.EXAMPLES),
        "metaballs_summary": Rule(STAGE),
        "metaballs_train": Rule(STAGE, _train, gpu=True, params=keys.TRAIN),
        "metaballs_evaluate": Rule(STAGE, _test, params=keys.EVALUATE),
        "metaballs_equal_quality": Rule(STAGE, _equal_quality, params=keys.EQUAL_QUALITY),
        "metaballs_demo": Rule(STAGE, _test, params=keys.DEMO),
        "metaballs_deploy": Rule(STAGE, _deploy, params=keys.DEPLOY),
        "metaballs_targets": Rule(STAGE, params=keys.TARGETS),
        "metaballs_user_scenes": Rule(STAGE, params=keys.EVALUATE),
        "metaballs_viewer": Rule(STAGE, _viewer, params=keys.VIEWER),
        "metaballs_scale": Rule(STAGE, _scale, params=keys.SCALE),
        "metaballs_real_scenes": Rule(STAGE, _real_scenes, params=keys.REAL_SCENES),
    },
    tables_dir=resources.files(__package__),
    unread_keys=keys.UNREAD,
    studies=STUDIES,
    stage_rules={"data": "metaballs_examples"},
)
