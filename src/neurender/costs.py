"""What a job costs: its work in counted units, and seconds and memory from per-unit costs
measured on a 2-core CPU machine (``costs.csv`` beside this module).

Every rule has a work measure that grows with the config's sizes (rays traced, pixels
trained on times the network's width, Mitsuba samples, ray-marched pixels, ...), stated
in :func:`work`; ``costs.csv`` holds per rule ``seconds = fixed_s + per_unit_s * work`` and
``memory = fixed_mb + per_unit_mb * memory_work`` fitted to the benchmark files of a
smoke and a default run (``python -m neurender.plan --calibrate``). The scheduler
resources of a job (``runtime`` in minutes, ``mem_mb``) are these estimates times a safety
factor; ``python -m neurender.plan`` sums them per stage.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from functools import cache
from importlib import resources
from typing import Any

import pandas as pd

from neurender import io

#: Scheduler limits are estimates times this factor (and at least the floors below).
SAFETY = 3.0
MIN_RUNTIME_MIN = 5
MIN_MEM_MB = 1000
#: The stage each rule belongs to, for the plan's summary.
STAGES = {
    "prt": "DeepPRT data",
    "prt_model": "DeepPRT models",
    "ndr": "NDR",
    "metaballs": "metaballs",
    "simplify": "simplification",
    "report": "report",
    "provenance": "report",
    "example": "examples",
}
#: Rules whose work runs on a GPU when the config asks for GPUs (training, Mitsuba).
GPU_RULES = {
    "prt_train",
    "ndr_data",
    "ndr_train",
    "metaballs_train",
    "simplify_prepare",
    "simplify_optimise",
    "simplify_evaluate",
}
_MODEL_RULES = {
    "prt_train",
    "prt_momoprt",
    "prt_evaluate",
    "prt_model_summary",
    "prt_experiment",
    "prt_relight",
    "prt_viewer",
}


def stage(rule: str) -> str:
    """The stage of the report a rule belongs to."""
    if rule in _MODEL_RULES:
        return STAGES["prt_model"]
    return STAGES.get(rule.split("_")[0], "other")


def unet_work(widths: list[int]) -> float:
    """Multiply-adds per output pixel of a U-Net with ``widths`` per level, relative:
    sum over levels of ``width^2`` times the level's share of pixels."""
    return sum(w * w / 4**level for level, w in enumerate(widths)) / 1e3


Units = tuple[float, float]


def _prt_work(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units | None:
    """:func:`work` of DeepPRT's rules (None for another rule)."""
    prt, pm = cfg["prt"], cfg["prt_model"]
    n = prt["resolution"]
    frames = prt["frames"]
    split = wildcards.get("split", "train")
    if rule == "prt_transfer":
        count = frames.get(split, frames["test"])
        dirs = prt["reference_directions"] if split == "test" else prt["directions"]
        return count * n * n * dirs / 2 / 1e6, n * n * dirs / 1e6
    if rule == "prt_noise_floor":
        return prt["noise_floor_frames"] * n * n * prt["directions"] / 1e6, n * n / 1e3
    if rule == "prt_benchmark":
        paper = 2 * 256 * 256 * 1024 / 2 if prt["benchmark_paper_scale"] else 0
        return (6 * n * n * prt["directions"] / 2 + paper) / 1e6, (paper > 0) * 65.536
    if rule in ("prt_sequence", "prt_geometry_image"):
        return (sum(frames.values()) * n * n + prt["source_vertices"]) / 1e6, n * n / 1e3
    if rule == "prt_train":
        k = prt["n_bands"] ** 2 * (3 if wildcards.get("material") == "glossy" else 1)
        pixels = (frames["train"] + frames["val"]) * n * n
        return pm["epochs"] * pixels * unet_work(pm["widths"]) / 1e6, pixels * (6 + k) / 1e6
    if rule == "prt_evaluate":
        rays = frames["test"] * n * n * prt["directions"] / 2
        rays += (
            prt["noise_floor_frames"]
            * n
            * n
            / 2
            * (sum(pm["equal_quality_directions"]) + prt["reference_directions"])
        )
        renders = (frames["val"] + frames["test"]) * pm["render_resolution"] ** 2 * 8
        return (rays + renders) / 1e6, (frames["val"] + frames["test"]) * n * n * 60 / 1e6
    if rule == "prt_viewer":  # the test split read, one frame predicted
        return frames["test"] * n * n / 1e6, frames["test"] * n * n * 60 / 1e6
    if rule == "prt_mesh_figure":
        return sum(frames.values()) * n * n / 1e6, n * n / 1e3
    if rule == "prt_momoprt":
        pixels = (frames["train"] + frames["val"]) * n * n
        return pixels * prt["n_bands"] ** 2 / 1e6, pixels * prt["n_bands"] ** 2 * 3 / 1e6
    return None


def _ndr_work(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units | None:
    """:func:`work` of NDR's rules (None for another rule)."""
    ndr, nm = cfg["ndr"], cfg["ndr_model"]
    w = ndr["width"]
    split = wildcards.get("split", "train")
    if rule == "ndr_data":
        kind, _, part = split.rpartition("_")
        if kind == "sunlit":
            count = ndr["sunlit_samples"]
        else:
            count = (ndr["diffuse_samples"] if kind else ndr["samples"])[part]
        spp = ndr["spp"] + (ndr["reference_spp"] if part == "test" else 0)
        return count * w * w * (spp + ndr["coarse_samples"]) / 1e6, w * w / 1e3
    if rule == "ndr_train":
        variant = wildcards.get("variant", "ndr")
        diffuse = variant in ("ndr_diffuse", "real_shading")
        count = (ndr["diffuse_samples"] if diffuse else ndr["samples"])["train"]
        pixels = count * w * w
        # Splits over the in-memory limit are read from disk sample by sample.
        data_mb = min(pixels * 30 * 4, io.IN_MEMORY_LIMIT_BYTES) / 1e6
        return nm["epochs"] * pixels * unet_work(nm["widths"]) / 1e6, data_mb
    if rule in ("ndr_evaluate", "ndr_relight"):
        tests = ndr["samples"]["test"] + ndr["diffuse_samples"]["test"]
        return tests * w * w * len(nm["variants"]) / 1e6, tests * w * w * 40 / 1e6
    if rule == "ndr_viewer":  # one test sample per turn (neurender.viewer_data.TURNS: 24)
        spp = ndr["spp"] + ndr["reference_spp"] + ndr["coarse_samples"]
        return 24 * w * w * spp / 1e6, 24 * w * w * 40 / 1e6
    if rule == "ndr_summary":
        return ndr["furnace_spp"] * w * w / 1e6, 0.0
    if rule == "ndr_deploy":  # per network: an export, and 2 x 23 timed frames
        networks = len({"ndr", *nm["variants"]})
        return networks * (1 + w * w * unet_work(nm["widths"]) / 1e3), w * w / 1e3
    return None


def _metaballs_work(
    rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]
) -> Units | None:
    """:func:`work` of the metaballs's rules (None for another rule)."""
    mb, mm = cfg["metaballs"], cfg["metaballs_model"]
    w = mb["width"]
    split = wildcards.get("split", "train")
    if rule == "metaballs_examples":
        count = mb["examples"][split]
        return count * w * w * sum(mb["balls"]) / 2 / 1e6, w * w / 1e3
    if rule == "metaballs_train":
        variant = wildcards.get("variant", "pix2pix")
        gan = 3.7 if variant == "pix2pix" else 1.0
        flips = 4 if mm["flips"] else 1
        steps = mm["epochs"] * flips * mb["examples"]["train"]
        data_mb = min(mb["examples"]["train"] * w * w * 12, io.IN_MEMORY_LIMIT_BYTES) / 1e6
        return steps * w * w * mm["ngf"] ** 2 * gan / 1e9, data_mb
    if rule == "metaballs_deploy":  # per network (metaballs.VARIANTS: 3): an export, 2 x 23 frames
        return 3 * (1 + w * w * mm["ngf"] ** 2 / 1e6), w * w / 1e3
    if rule == "metaballs_viewer":  # the demo by every network (3) and the ray marcher
        return mm["demo_frames"] * w * w * 4 / 1e6, mm["demo_frames"] * w * w * 4 / 1e3
    if rule in ("metaballs_evaluate", "metaballs_demo"):
        return (mb["examples"]["test"] + mm["demo_frames"]) * w * w / 1e6, w * w / 1e3
    return None


def _simplify_work(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units | None:
    """:func:`work` of the simplification's rules (None for another rule)."""
    s = cfg["simplify"]
    pixels = s["resolution"] ** 2
    if rule == "simplify_prepare":
        rendered = s["train_views"] * s["reference_spp"] + s["test_views"] * s["test_spp"]
        detail = max(s["head_vertices"], s["metaball_grid"] ** 3 / 20)
        return (rendered * pixels + 40 * detail) / 1e6, (detail + s["texture_size"] ** 2) / 1e4
    if rule in ("simplify_viewer", "simplify_mesh_figure"):  # the reference rebuilt
        detail = max(s["head_vertices"], s["metaball_grid"] ** 3 / 20)
        return detail / 1e6, detail / 1e4
    if rule == "simplify_optimise":
        return s["steps"] * s["batch"] * s["spp"] * pixels / 1e6, s["texture_size"] ** 2 / 1e4
    if rule == "simplify_evaluate":
        cases = max(len(s["cases"]), 1)
        return cases * 3 * s["test_views"] * s["eval_spp"] * pixels / 1e6, pixels / 1e3
    return None


def work(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """``(time units, memory units)`` of one job of ``rule`` under the full config ``cfg``
    (0 where a rule's cost does not grow with the config)."""
    for stage_work in (_prt_work, _ndr_work, _metaballs_work, _simplify_work):
        units = stage_work(rule, cfg, wildcards)
        if units is not None:
            return units
    return 0.0, 0.0


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A job's estimated wall seconds (on the reference 2-core CPU, with the rule's
    threads) and peak memory in MB."""

    seconds: float
    mem_mb: float

    @property
    def runtime_min(self) -> int:
        """The scheduler's time limit in minutes: the estimate times :data:`SAFETY`."""
        return max(MIN_RUNTIME_MIN, math.ceil(SAFETY * self.seconds / 60))

    @property
    def mem_limit_mb(self) -> int:
        """The scheduler's memory request: the estimate times 1.5, at least the floor."""
        return max(MIN_MEM_MB, math.ceil(1.5 * self.mem_mb))


@cache
def coefficients() -> pd.DataFrame:
    """Per rule ``fixed_s, per_unit_s, fixed_mb, per_unit_mb`` (``costs.csv``)."""
    with resources.files("neurender").joinpath("costs.csv").open() as f:
        return pd.read_csv(f).set_index("rule")


def estimate(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Estimate:
    """The cost of one job from :func:`work` and the measured coefficients (a rule that
    has none yet is given a minute and a gigabyte)."""
    table = coefficients()
    if rule not in table.index:
        return Estimate(60.0, 1000.0)
    c = table.loc[rule]
    units, mem_units = work(rule, cfg, wildcards)
    return Estimate(
        float(c.fixed_s + c.per_unit_s * units), float(c.fixed_mb + c.per_unit_mb * mem_units)
    )
