"""A network against its reference renderer at equal quality: the one rule every method's
equal-quality table follows.

A method sweeps its reference renderer over settings (Mitsuba's sample counts, the ray
tracer's direction counts, the ray marcher's steps and resolutions), each timed on the
same machine, scenes and threads as its networks, in the same job, and scored by the
metrics the method scores its networks by (:data:`Quality`). A network's equal-quality
render is the **fastest** setting whose quality reaches the network's on **every** metric
(:func:`pick`); its time over the network's is the equal-quality speed-up.

A sweep is a grid, so the speed-up is that of the grid, and two cases are bounds, stated
in the table's ``bound`` column and in every sentence that quotes the number
(:data:`BOUNDS`):

- :data:`LOWER`: no setting reaches the network; the speed-up is taken against the slowest
  setting, and a render of the network's quality costs more, so it is at least that.
- :data:`UPPER`: the fastest setting of the sweep already reaches the network; a cheaper
  setting outside the sweep might too, so the speed-up is at most that.
- :data:`WITHIN`: otherwise, a setting inside the sweep.

The table (:func:`table`) holds one row per setting and metric (model: the reference
renderer, ``bound`` :data:`MEASURED`) and one per network and metric, keyed by the picked
``setting`` and its ``bound``; the speed-up is ``equal_quality_speedup`` and the picked
setting's time ``equal_quality_reference_ms``. The report's summary and every method's
equal-quality targets read these rows through :func:`speedups` and :func:`targets`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import pandas as pd

from neurender.tables import Target, tidy_rows

#: Metric name -> whether higher is better, for the metrics a method's quality is judged by.
Quality = Mapping[str, bool]

#: What a network's ``equal_quality_speedup`` is: the sweep's pick, or a bound on it.
WITHIN, LOWER, UPPER = "within the sweep", "lower bound", "upper bound"
#: The ``bound`` of the reference renderer's own rows.
MEASURED = "measured"
BOUNDS = {
    WITHIN: "against the fastest setting of the sweep whose quality reaches the network's",
    LOWER: "no setting of the sweep reaches the network's quality: against the slowest, "
    "so the speed-up is at least this",
    UPPER: "the sweep's fastest setting already reaches the network's quality: against it, "
    "so the speed-up is at most this",
}
#: The ``split`` of every equal-quality row.
SPLIT = "equal quality"
#: The metrics of a network's row beside its quality.
SPEEDUP, REFERENCE_MS = "equal_quality_speedup", "equal_quality_reference_ms"
#: What names a network's speed-up in :func:`speedups`.
SPEEDUP_KEYS = ("method", "dataset", "model", "setting", "bound")
#: The columns of a sweep's scores besides its quality metrics.
SETTING, MS = "setting", "ms_per_frame"


@dataclasses.dataclass(frozen=True)
class Pick:
    """The setting a network is compared with (its label), that setting's milliseconds
    per frame and what the ratio to it is (:data:`BOUNDS`)."""

    setting: str
    ms_per_frame: float
    bound: str


def _check_scores(scores: pd.DataFrame, quality: Quality) -> None:
    missing = [c for c in (SETTING, MS, *quality) if c not in scores.columns]
    if missing:
        raise ValueError(
            f"equal-quality scores have no column {missing}; expected {SETTING!r}, {MS!r} "
            f"and the quality metrics {list(quality)} (found {list(scores.columns)})"
        )
    if scores.empty:
        raise ValueError("equal-quality scores have no row; expected one per setting swept")


def reaches(scores: pd.DataFrame, target: Mapping[str, float], quality: Quality) -> pd.Series:
    """Bool per row of ``scores``: every metric of ``quality`` at least as good as
    ``target``'s (the network's means on the same frames). A NaN score reaches nothing."""
    ok = pd.Series(True, index=scores.index)
    for metric, higher in quality.items():
        ok &= scores[metric] >= target[metric] if higher else scores[metric] <= target[metric]
    return ok


def pick(scores: pd.DataFrame, target: Mapping[str, float], quality: Quality) -> Pick:
    """The fastest row of ``scores`` (one per setting: ``setting``, ``ms_per_frame`` and
    ``quality``'s metrics) whose quality :func:`reaches` ``target``, ties to the first
    listed; :data:`UPPER` when it is the fastest row of all; where none reaches, the
    slowest row, :data:`LOWER`."""
    _check_scores(scores, quality)
    reached = scores[reaches(scores, target, quality)]
    if reached.empty:
        slowest = scores.loc[scores[MS].idxmax()]
        return Pick(str(slowest[SETTING]), float(slowest[MS]), LOWER)
    best = reached.loc[reached[MS].idxmin()]
    bound = UPPER if float(best[MS]) <= float(scores[MS].min()) else WITHIN
    return Pick(str(best[SETTING]), float(best[MS]), bound)


@dataclasses.dataclass(frozen=True)
class Network:
    """A network's side of the comparison: its ``quality`` (metric -> mean on the sweep's
    frames), its milliseconds per frame and any other values its rows carry (times of its
    parts, its engine's)."""

    quality: Mapping[str, float]
    ms_per_frame: float
    extra: Mapping[str, float] = dataclasses.field(default_factory=dict)


def table(
    method: str,
    dataset: str,
    reference: str,
    scores: pd.DataFrame,
    networks: Mapping[str, Network],
    quality: Quality,
) -> pd.DataFrame:
    """Tidy rows (split :data:`SPLIT`, key columns ``setting`` and ``bound``) of one
    dataset: per setting of ``scores`` (model ``reference``, bound :data:`MEASURED`) every
    numeric column but ``setting``; per network (model: its name) its ``ms_per_frame``,
    quality, extra values, ``equal_quality_reference_ms`` and ``equal_quality_speedup``,
    keyed by its :func:`pick`."""
    _check_scores(scores, quality)
    rows = []
    numeric = [
        c for c in scores.columns if c != SETTING and pd.api.types.is_numeric_dtype(scores[c])
    ]
    for _, r in scores.iterrows():
        values = {c: r[c] for c in numeric}
        rows += tidy_rows(
            method, dataset, reference, SPLIT, values, setting=str(r[SETTING]), bound=MEASURED
        )
    for name, net in networks.items():
        chosen = pick(scores, net.quality, quality)
        values = {
            MS: net.ms_per_frame,
            **{m: net.quality[m] for m in quality},
            **net.extra,
            REFERENCE_MS: chosen.ms_per_frame,
            SPEEDUP: chosen.ms_per_frame / net.ms_per_frame,
        }
        rows += tidy_rows(
            method, dataset, name, SPLIT, values, setting=chosen.setting, bound=chosen.bound
        )
    return pd.DataFrame(rows)


def speedups(frame: pd.DataFrame) -> pd.DataFrame:
    """The networks' speed-ups of an equal-quality table (:func:`table`'s rows, of one or
    more datasets or methods): columns :data:`SPEEDUP_KEYS` and ``speedup``, in the
    table's order."""
    rows = frame[(frame["metric"] == SPEEDUP) & (frame["bound"] != MEASURED)]
    out = rows[[*SPEEDUP_KEYS, "value"]]
    return out.rename(columns={"value": "speedup"}).reset_index(drop=True)


def stated(speedup: float, bound: str) -> str:
    """The speed-up as every sentence quotes it: ``12.3x``, ``>= 12.3x (lower bound)`` or
    ``<= 12.3x (upper bound)``."""
    if bound == LOWER:
        return f">= {speedup:.3g}x (lower bound)"
    if bound == UPPER:
        return f"<= {speedup:.3g}x (upper bound)"
    return f"{speedup:.3g}x"


def met(speedup: float, bound: str, least: float) -> bool:
    """Whether a speed-up meets a target of ``least``: at least it, and not an upper bound
    (the true speed-up may be below); a lower bound that reaches it passes (the true one is
    at least it)."""
    return bool(speedup >= least and bound != UPPER)


def targets(frame: pd.DataFrame, least: float, reference: str) -> list[Target]:
    """The equal-quality target of every network of an equal-quality table (subject: its
    dataset): its speed-up over the cheapest ``reference`` render of its quality at least
    ``least`` (:func:`met`), the check naming the setting and the bound."""
    return [
        Target(
            r.dataset,
            f"{r.model} at least {least:g}x faster than the cheapest {reference} of its "
            f"quality (against {r.setting}, {r.bound})",
            r.speedup,
            met(r.speedup, r.bound, least),
        )
        for r in speedups(frame).itertuples()
    ]
