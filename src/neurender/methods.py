"""The registered methods, in report order: the one list :mod:`neurender.config`,
:mod:`neurender.costs` (and through it :mod:`neurender.plan` and the rules' scheduler
resources), :mod:`neurender.report.build`, :func:`neurender.tables.threshold` and
``workflow/rules/report.smk`` loop over.

A method registers by adding its package's record (``<package>/method.py``,
:class:`neurender.method.Method`) to :data:`METHODS`. Imports nothing heavy: the
Snakefile reads it when it builds the DAG.
"""

from __future__ import annotations

import pandas as pd

from neurender.metaballs.method import METHOD as METABALLS
from neurender.method import Given, Method, Rule
from neurender.ndr.method import METHOD as NDR
from neurender.prt.method import METHOD as PRT
from neurender.simplification.method import METHOD as SIMPLIFICATION

METHODS: tuple[Method, ...] = (PRT, NDR, METABALLS, SIMPLIFICATION)

#: The rules of no method: the example assets the own-assets config reads, the report and
#: the provenance record it shows. The provenance's params are the whole resolved config
#: (``workflow/rules/provenance.smk``): it reads every key.
WORKFLOW_RULES = {
    "example_assets": Rule("examples", params=("seed",)),
    "report": Rule("report", params=("report.title", Given("configfiles"), "seed")),
    "provenance": Rule("report"),
}
#: The top-level keys no job's params hold: ``gpus``, a resource.
UNREAD_KEYS = ("gpus",)
#: The plan's stage of a rule that is registered nowhere.
OTHER_STAGE = "other"


def rules() -> dict[str, Rule]:
    """Every registered rule by name: each method's and :data:`WORKFLOW_RULES`."""
    found = dict(WORKFLOW_RULES)
    for method in METHODS:
        found.update(method.rules)
    return found


def unread_keys() -> set[str]:
    """Every config key no job's params hold (:attr:`neurender.method.Method.unread_keys`
    and :data:`UNREAD_KEYS`)."""
    return {key for method in METHODS for key in method.unread_keys} | set(UNREAD_KEYS)


def rule(name: str) -> Rule:
    """The record of the rule ``name`` (stage :data:`OTHER_STAGE`, no work and no GPU
    for a rule that is registered nowhere)."""
    return rules().get(name, Rule(OTHER_STAGE))


def by_key(key: str) -> Method:
    """The method whose results folder and report section is ``key``."""
    for method in METHODS:
        if method.key == key:
            return method
    raise KeyError(f"no registered method {key!r} (registered: {[m.key for m in METHODS]})")


def table(kind: str) -> pd.DataFrame:
    """Every method's table ``kind`` (:meth:`neurender.method.Method.table`: its published
    numbers, headline rows or target thresholds), in report order."""
    return pd.concat([method.table(kind) for method in METHODS], ignore_index=True)
