"""The appearance-driven simplification as the rest of the project sees it
(:class:`neurender.method.Method`): its config rules, the work of each of its rules, its
report section's files and the user's files. Read at DAG time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib import resources
from typing import Any

from neurender import asset_files, checks
from neurender.method import Method, ReportInputs, Rule, Units
from neurender.simplification import CASES, EXPORTED, VARIANTS
from neurender.simplification import rule_keys as keys
from neurender.user_paths import UserPath

STAGE = "simplification"


def problems(config: Mapping[str, Any]) -> Iterator[str]:
    """The config rules of the simplification's section the schema cannot state."""
    section = config["simplification"]
    detail = 2 * section["head_vertices"]
    if "head" in section["cases"] and section["head_triangles"] >= detail:
        yield (
            f"simplification.head_triangles = {section['head_triangles']}: expected fewer than the "
            f"detailed head's about {detail} triangles (2 x simplification.head_vertices)"
        )
    for name, entry in section["user_assets"].items():
        key = f"simplification.user_assets.{name}"
        path = entry["path"]
        if name in CASES:
            yield f"{key}: the name of a built-in case ({', '.join(CASES)}); pick another"
        yield from checks.user_file(
            f"{key}.path", path, asset_files.TRIMESH_SUFFIXES, "a mesh file", named=True
        )


def _detail(s: Mapping[str, Any]) -> float:
    """The detailed reference's size: the head's vertices or the metaballs' grid cells / 20."""
    return max(s["head_vertices"], s["metaball_grid"] ** 3 / 20)


def _prepare(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Mitsuba samples of the training and test views, and the reference's building."""
    s = cfg["simplification"]
    pixels = s["resolution"] ** 2
    rendered = s["train_views"] * s["reference_spp"] + s["test_views"] * s["test_spp"]
    detail = _detail(s)
    return (rendered * pixels + 40 * detail) / 1e6, (detail + s["texture_size"] ** 2) / 1e4


def _reference(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The reference rebuilt."""
    detail = _detail(cfg["simplification"])
    return detail / 1e6, detail / 1e4


def _optimise(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Differentiable Mitsuba samples: steps x views per step x samples x pixels."""
    s = cfg["simplification"]
    pixels = s["resolution"] ** 2
    return s["steps"] * s["batch"] * s["spp"] * pixels / 1e6, s["texture_size"] ** 2 / 1e4


def _deploy(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The normal map re-expressed texel by texel in glTF's tangent frame, in the export
    and in each of its two read-backs."""
    texels = cfg["simplification"]["texture_size"] ** 2
    return 3 * texels / 1e4, texels / 1e4


def _evaluate(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Every case's variants and its two shipped files rendered from the test views."""
    s = cfg["simplification"]
    pixels = s["resolution"] ** 2
    cases = max(len(s["cases"]), 1)
    renders = cases * (len(VARIANTS) + len(EXPORTED)) * s["test_views"]
    return renders * s["eval_spp"] * pixels / 1e6, pixels / 1e3


def _equal_quality(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """Every case's classic pipeline at each budget swept: its bake and its renders from
    the test views; and each reference rebuilt."""
    s = cfg["simplification"]
    pixels = s["resolution"] ** 2
    cases = max(len(s["cases"]) + len(s["user_assets"]), 1)
    settings = cases * len(s["equal_quality_multiples"])
    rendered = settings * s["test_views"] * s["eval_spp"] * pixels
    baked = settings * s["texture_size"] ** 2
    return (rendered + 40 * baked + cases * 40 * _detail(s)) / 1e6, (
        _detail(s) + s["texture_size"] ** 2
    ) / 1e4


def user_paths(config: Mapping[str, Any]) -> Iterator[UserPath]:
    """The simplification's user files: each asset's mesh (naming its materials and
    textures)."""
    for name, entry in config["simplification"]["user_assets"].items():
        yield UserPath(f"simplification.user_assets.{name}.path", entry["path"], asset=True)


def report_inputs(config: Mapping[str, Any]) -> ReportInputs:
    """The tables (each case's deployment table among them), figures (one of meshes per
    case) and viewers (one per case) of the simplification's report section; nothing when
    there is no case."""
    section = config["simplification"]
    cases = tuple(section["cases"]) + tuple(section["user_assets"])
    tables = ("targets", "metrics", "equal_quality", "stats") if cases else ()
    tables += tuple(f"{case}/deployment" for case in cases)
    figures = ("comparison", "equal_quality", "loss_curves") if cases else ()
    figures += tuple(f"{case}_meshes" for case in cases)
    return ReportInputs(
        tables=[f"results/simplification/{t}.csv" for t in tables],
        figures=[f"results/simplification/figures/{name}.png" for name in figures],
        viewers=[f"results/simplification/viewers/{case}.json" for case in cases],
    )


METHOD = Method(
    key="simplification",
    title="Appearance-driven simplification",
    citation=(
        "Jon Hasselgren, Jacob Munkberg, Jaakko Lehtinen, Miika Aittala, Samuli Laine. "
        "Appearance-Driven Automatic 3D Model Simplification. Eurographics Symposium on "
        "Rendering 2021."
    ),
    link="https://doi.org/10.2312/sr.20211293",
    config_sections=("simplification",),
    problems=problems,
    report_inputs=report_inputs,
    user_paths=user_paths,
    rules={
        "simplification_prepare": Rule(STAGE, _prepare, gpu=True, params=keys.PREPARE),
        "simplification_optimise": Rule(STAGE, _optimise, gpu=True, params=keys.OPTIMISE),
        "simplification_deploy": Rule(STAGE, _deploy, params=keys.DEPLOY),
        "simplification_summary": Rule(STAGE),
        "simplification_evaluate": Rule(STAGE, _evaluate, gpu=True, params=keys.EVALUATE),
        "simplification_equal_quality": Rule(
            STAGE, _equal_quality, gpu=True, params=keys.EQUAL_QUALITY
        ),
        "simplification_targets": Rule(STAGE),
        "simplification_viewer": Rule(STAGE, _reference, params=keys.VIEWER),
        "simplification_mesh_figure": Rule(STAGE, _reference, params=keys.VIEWER),
    },
    tables_dir=resources.files(__package__),
    unread_keys=keys.UNREAD,
    stage_rules={"data": "simplification_prepare", "train": "simplification_optimise"},
)
