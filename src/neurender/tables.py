"""Tidy result tables and targets: the one row shape every stage writes and the report reads.

A tidy row is one measurement: ``method, dataset, model, split[, keys...], metric, value``
(``keys`` such as ``frame`` or ``view`` sit between ``split`` and ``metric``). A target is
one check of a measured value against a threshold from the method's ``targets.csv``
(beside its code and its published numbers: :meth:`neurender.method.Method.table`),
stated as met or missed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from typing import Any

import pandas as pd

from neurender import methods

TIDY_COLUMNS = ("method", "dataset", "model", "split", "metric", "value")
TARGET_COLUMNS = ("method", "subject", "check", "measured", "met")


def tidy_rows(
    method: str, dataset: str, model: str, split: str, values: Mapping[str, Any], **keys: Any
) -> list[dict[str, Any]]:
    """One tidy row per ``metric -> value`` of ``values`` (values as floats)."""
    head = {"method": method, "dataset": dataset, "model": model, "split": split, **keys}
    return [{**head, "metric": k, "value": float(v)} for k, v in values.items()]


def lookup(frame: pd.DataFrame, **where: Any) -> float:
    """The value of the first row whose columns equal ``where`` (NaN if there is none)."""
    mask = pd.Series(True, index=frame.index)
    for column, wanted in where.items():
        mask &= frame[column] == wanted
    sel = frame.loc[mask, "value"]
    return float(sel.iloc[0]) if len(sel) else math.nan


@dataclasses.dataclass(frozen=True)
class Target:
    """``subject`` (an object, case, model or the stage) passes ``check`` (a sentence with
    its threshold) when ``met``; ``measured`` is the value checked."""

    subject: str
    check: str
    measured: float
    met: bool


def target_table(method: str, targets: Iterable[Target]) -> pd.DataFrame:
    """A method's targets as rows of :data:`TARGET_COLUMNS`."""
    rows = [{"method": method, **dataclasses.asdict(t)} for t in targets]
    frame = pd.DataFrame(rows, columns=list(TARGET_COLUMNS))
    return frame.astype({"measured": float, "met": bool})


def threshold(method: str, name: str) -> float:
    """The threshold of target ``name`` of the registered method ``method``, from its
    ``targets.csv`` (``KeyError`` naming both if absent)."""
    table = methods.by_key(method).table("targets")
    sel = table[table["name"] == name]
    if sel.empty:
        raise KeyError(f"the targets.csv of method {method!r} has no target {name!r}")
    return float(sel["value"].iloc[0])
