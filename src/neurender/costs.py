"""What a job costs: its work in counted units, and seconds and memory from per-unit costs
measured on a 2-core CPU machine (``costs.csv`` beside this module).

Every rule has a work measure that grows with the config's sizes (rays traced, pixels
trained on times the network's width, Mitsuba samples, ray-marched pixels, ...), stated
by its method beside its code (the ``rules`` of its record, :mod:`neurender.methods`);
``costs.csv`` holds per rule ``seconds = fixed_s + per_unit_s * work`` and
``memory = fixed_mb + per_unit_mb * memory_work`` fitted to the benchmark files of a
smoke and a default run (``python -m neurender.plan --calibrate``), averaged over the
fits of machines of different speeds (``--average-with``, docs/cluster.md). The scheduler
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

from neurender import methods
from neurender.method import Units

#: Scheduler limits are estimates times this factor (and at least the floors below).
SAFETY = 3.0
MIN_RUNTIME_MIN = 5
MIN_MEM_MB = 1000


def stage(rule: str) -> str:
    """The plan's stage of a rule (its record's, :mod:`neurender.methods`)."""
    return methods.rule(rule).stage


def uses_gpu(rule: str) -> bool:
    """Whether a rule's job runs on a GPU when the config asks for GPUs."""
    return methods.rule(rule).gpu


def work(rule: str, cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """``(time units, memory units)`` of one job of ``rule`` under the full config ``cfg``:
    its record's work measure (0 where a rule's cost does not grow with the config)."""
    return methods.rule(rule).work(cfg, wildcards)


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
