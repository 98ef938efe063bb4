"""A network against its reference renderer at equal quality: the one rule every method's
equal-quality table follows.

A method sweeps its reference renderer over settings (Mitsuba's sample counts, the ray
tracer's direction counts, the ray marcher's steps and resolutions, the classic
simplification's triangle budgets) and scores each by the metrics the method scores its
networks by (:data:`Quality`). Each setting has a cost, lower is cheaper (:class:`Cost`):
its time (:data:`TIME`, milliseconds per frame, timed on the same machine, scenes and
threads as the networks, in the same job) or its triangles (:data:`TRIANGLES`, the
appearance-driven simplification against the classic QEM + bake). A network's
equal-quality render is the **cheapest** setting whose quality reaches the network's on
**every** metric (:func:`pick`); its cost over the network's is the equal-quality ratio
(with :data:`TIME`, the speed-up).

A sweep is a grid, so the ratio is that of the grid, and two cases are bounds, stated in
the table's ``bound`` column and in every sentence that quotes the number (:data:`BOUNDS`):

- :data:`LOWER`: no setting reaches the network; the ratio is taken against the costliest
  setting (the slowest, the most triangles), and a render of the network's quality costs
  more, so it is at least that.
- :data:`UPPER`: the cheapest setting of the sweep already reaches the network; a cheaper
  setting outside the sweep might too, so the ratio is at most that.
- :data:`WITHIN`: otherwise, a setting inside the sweep.

The table (:func:`table`) holds one row per setting and metric (model: the reference
renderer, ``bound`` :data:`MEASURED`) and one per network and metric, keyed by the picked
``setting`` and its ``bound``; with :data:`TIME` the ratio is ``equal_quality_speedup`` and
the picked setting's time ``equal_quality_reference_ms``, with :data:`TRIANGLES`
``equal_quality_triangle_ratio`` and ``equal_quality_reference_triangles``. The report's
summary and every method's equal-quality targets read these rows through :func:`ratios`
(:func:`speedups`) and :func:`targets`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import pandas as pd

from neurender.tables import Target, tidy_rows

#: Metric name -> whether higher is better, for the metrics a method's quality is judged by.
Quality = Mapping[str, bool]

#: What a network's equal-quality ratio is: the sweep's pick, or a bound on it.
WITHIN, LOWER, UPPER = "within the sweep", "lower bound", "upper bound"
#: The ``bound`` of the reference renderer's own rows.
MEASURED = "measured"
BOUNDS = {
    WITHIN: "against the cheapest setting of the sweep (the fastest; for triangles, the "
    "fewest) whose quality reaches the network's",
    LOWER: "no setting of the sweep reaches the network's quality: against the costliest, "
    "so the ratio is at least this",
    UPPER: "the sweep's cheapest setting already reaches the network's quality: against it, "
    "so the ratio is at most this",
}
#: The ``split`` of every equal-quality row.
SPLIT = "equal quality"
#: The metrics of a network's row beside its quality, with :data:`TIME`.
SPEEDUP, REFERENCE_MS = "equal_quality_speedup", "equal_quality_reference_ms"
#: What names a network's ratio in :func:`ratios` and :func:`speedups`.
SPEEDUP_KEYS = ("method", "dataset", "model", "setting", "bound")
#: The columns of a sweep's scores besides its quality metrics (and :attr:`Cost.column`).
SETTING, MS = "setting", "ms_per_frame"


@dataclasses.dataclass(frozen=True)
class Cost:
    """What a setting of a sweep costs and how a table names the ratio.

    Attributes:
        column: the scores' column of each setting's cost, lower is cheaper; also the
            metric of a network's own cost in the table.
        ratio: the metric of a network's ratio, the picked setting's cost over its own.
        reference: the metric of the picked setting's cost.
        cheaper: the words after ``Nx`` in a sentence: a network ``Nx faster`` than the
            cheapest reference of its quality, a mesh ``Nx fewer triangles``.
        subject: what the report's summary calls a row's model (``network``).
    """

    column: str
    ratio: str
    reference: str
    cheaper: str
    subject: str


#: Milliseconds per frame: the networks against their reference renderers.
TIME = Cost(MS, SPEEDUP, REFERENCE_MS, "faster", "network")
#: Triangles: the appearance-driven simplification's mesh against the classic QEM + bake
#: at larger triangle budgets (the ratio: the classic pipeline needs Nx the triangles).
TRIANGLES = Cost(
    "triangles",
    "equal_quality_triangle_ratio",
    "equal_quality_reference_triangles",
    "fewer triangles",
    "model",
)
#: Every cost, in the order the report's summary lists them.
COSTS = (TIME, TRIANGLES)


@dataclasses.dataclass(frozen=True)
class Pick:
    """The setting a network is compared with (its label), that setting's cost
    (:attr:`Cost.column`: milliseconds per frame, triangles) and what the ratio to it is
    (:data:`BOUNDS`)."""

    setting: str
    cost: float
    bound: str


def _check_scores(scores: pd.DataFrame, quality: Quality, cost: Cost) -> None:
    missing = [c for c in (SETTING, cost.column, *quality) if c not in scores.columns]
    if missing:
        raise ValueError(
            f"equal-quality scores have no column {missing}; expected {SETTING!r}, "
            f"{cost.column!r} and the quality metrics {list(quality)} "
            f"(found {list(scores.columns)})"
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


def pick(
    scores: pd.DataFrame, target: Mapping[str, float], quality: Quality, cost: Cost = TIME
) -> Pick:
    """The cheapest row of ``scores`` (one per setting: ``setting``, ``cost.column`` and
    ``quality``'s metrics) whose quality :func:`reaches` ``target``, ties to the first
    listed; :data:`UPPER` when it is the cheapest row of all; where none reaches, the
    costliest row, :data:`LOWER`."""
    _check_scores(scores, quality, cost)
    column = cost.column
    reached = scores[reaches(scores, target, quality)]
    if reached.empty:
        costliest = scores.loc[scores[column].idxmax()]
        return Pick(str(costliest[SETTING]), float(costliest[column]), LOWER)
    best = reached.loc[reached[column].idxmin()]
    bound = UPPER if float(best[column]) <= float(scores[column].min()) else WITHIN
    return Pick(str(best[SETTING]), float(best[column]), bound)


@dataclasses.dataclass(frozen=True)
class Network:
    """A network's side of the comparison: its ``quality`` (metric -> mean on the sweep's
    frames), its cost (:attr:`Cost.column`: milliseconds per frame, triangles) and any
    other values its rows carry (times of its parts, its engine's)."""

    quality: Mapping[str, float]
    cost: float
    extra: Mapping[str, float] = dataclasses.field(default_factory=dict)


def table(
    method: str,
    dataset: str,
    reference: str,
    scores: pd.DataFrame,
    networks: Mapping[str, Network],
    quality: Quality,
    cost: Cost = TIME,
) -> pd.DataFrame:
    """Tidy rows (split :data:`SPLIT`, key columns ``setting`` and ``bound``) of one
    dataset: per setting of ``scores`` (model ``reference``, bound :data:`MEASURED`) every
    numeric column but ``setting``; per network (model: its name) its cost
    (``cost.column``), quality, extra values, the picked setting's cost
    (``cost.reference``) and the ratio (``cost.ratio``), keyed by its :func:`pick`."""
    _check_scores(scores, quality, cost)
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
        chosen = pick(scores, net.quality, quality, cost)
        values = {
            cost.column: net.cost,
            **{m: net.quality[m] for m in quality},
            **net.extra,
            cost.reference: chosen.cost,
            cost.ratio: chosen.cost / net.cost,
        }
        rows += tidy_rows(
            method, dataset, name, SPLIT, values, setting=chosen.setting, bound=chosen.bound
        )
    return pd.DataFrame(rows)


def ratios(frame: pd.DataFrame, cost: Cost = TIME) -> pd.DataFrame:
    """The networks' ratios in ``cost`` of an equal-quality table (:func:`table`'s rows,
    of one or more datasets or methods; none for a table of another cost): columns
    :data:`SPEEDUP_KEYS` and ``ratio``, in the table's order."""
    rows = frame[(frame["metric"] == cost.ratio) & (frame["bound"] != MEASURED)]
    out = rows[[*SPEEDUP_KEYS, "value"]]
    return out.rename(columns={"value": "ratio"}).reset_index(drop=True)


def speedups(frame: pd.DataFrame) -> pd.DataFrame:
    """The networks' speed-ups (:data:`TIME`'s :func:`ratios`): columns
    :data:`SPEEDUP_KEYS` and ``speedup``."""
    return ratios(frame, TIME).rename(columns={"ratio": "speedup"})


def stated(speedup: float, bound: str) -> str:
    """The ratio (a speed-up, a triangle ratio) as every sentence quotes it: ``12.3x``,
    ``>= 12.3x (lower bound)`` or ``<= 12.3x (upper bound)``."""
    if bound == LOWER:
        return f">= {speedup:.3g}x (lower bound)"
    if bound == UPPER:
        return f"<= {speedup:.3g}x (upper bound)"
    return f"{speedup:.3g}x"


def met(speedup: float, bound: str, least: float) -> bool:
    """Whether a ratio (a speed-up) meets a target of ``least``: at least it, and not an
    upper bound (the true ratio may be below); a lower bound that reaches it passes (the
    true one is at least it)."""
    return bool(speedup >= least and bound != UPPER)


def targets(frame: pd.DataFrame, least: float, reference: str, cost: Cost = TIME) -> list[Target]:
    """The equal-quality target of every network of an equal-quality table (subject: its
    dataset): its ratio in ``cost`` to the cheapest ``reference`` render of its quality at
    least ``least`` (:func:`met`), the check naming the setting and the bound."""
    return [
        Target(
            r.dataset,
            f"{r.model} at least {least:g}x {cost.cheaper} than the cheapest {reference} of "
            f"its quality (against {r.setting}, {r.bound})",
            r.ratio,
            met(r.ratio, r.bound, least),
        )
        for r in ratios(frame, cost).itertuples()
    ]
