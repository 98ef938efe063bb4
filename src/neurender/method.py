"""What a method tells the rest of the project: one :class:`Method` record per method
package (``<package>/method.py``), listed once in :mod:`neurender.methods`.

The config checks, the cost model, the plan, the targets' thresholds, the report and the
report rule read these records (and the tables each names, beside its code) and nothing
else of a method, so a new method is a new package with its record and tables, and no
shared module changes. A record's module is read when Snakemake builds the DAG: it
imports only plain Python, numpy and pandas (never torch or Mitsuba).
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable, Iterator, Mapping
from importlib.resources.abc import Traversable
from pathlib import Path, PurePosixPath
from typing import Any

import pandas as pd

from neurender.user_paths import UserPath

#: ``(time units, memory units)`` of one job: its work, which ``costs.csv``'s per-rule lines
#: turn into seconds and MB (:mod:`neurender.costs`).
Units = tuple[float, float]
#: ``work(config, wildcards)``: the :data:`Units` of one job of a rule under the full
#: (defaults-filled) config and the job's wildcard values.
Work = Callable[[Mapping[str, Any], Mapping[str, str]], Units]


def no_work(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> Units:
    """The work of a rule whose cost does not grow with the config: none beyond its fixed
    cost."""
    return 0.0, 0.0


def no_user_paths(cfg: Mapping[str, Any]) -> Iterator[UserPath]:
    """The user paths of a method that reads no user files: none."""
    return iter(())


def unet_work(widths: list[int]) -> float:
    """Multiply-adds per output pixel of a U-Net with ``widths`` per level, relative:
    sum over levels of ``width^2`` times the level's share of pixels."""
    return sum(w * w / 4**level for level, w in enumerate(widths)) / 1e3


#: ``applies(config, wildcards)`` or ``compute(config, wildcards)``: a function of the full
#: (defaults-filled) config and one job's wildcard values.
OfJob = Callable[[Mapping[str, Any], Mapping[str, str]], Any]


@dataclasses.dataclass(frozen=True)
class Value:
    """A value of a job's params that is not a config key as it stands: ``name`` =
    ``compute(config, wildcards)``, which reads the config keys ``reads`` (dotted; none
    for a wildcard or a constant) and no other."""

    name: str
    compute: OfJob
    reads: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class When:
    """Params entries that only some jobs of a rule read: those for which
    ``applies(config, wildcards)`` is true. The keys the condition looks at are read only
    where they are entries too (a key that picks the job's inputs reruns it by them)."""

    applies: OfJob
    entries: tuple[Entry, ...]


@dataclasses.dataclass(frozen=True)
class Group:
    """Params entries gathered in one dict of the params, named ``name``."""

    name: str
    entries: tuple[Entry, ...]


@dataclasses.dataclass(frozen=True)
class Given:
    """A value of the params that the rules file passes, ``name`` (no config key nor
    wildcard: the config files' paths); :meth:`Rule.job_params`'s ``given``."""

    name: str


#: One entry of a rule's params (:attr:`Rule.params`): a dotted config key (``"seed"``,
#: ``"prt.n_bands"``, ``"prt.frames"`` for the whole section), named in the params by its
#: last part, or a :class:`Value`, :class:`When`, :class:`Group` or :class:`Given`.
Entry = str | Value | When | Group | Given


def wildcard(name: str) -> Value:
    """The job's wildcard ``name``, under that name."""
    return Value(name, lambda cfg, wildcards: wildcards[name])


def config_value(config: Mapping[str, Any], key: str) -> Any:
    """The value of the dotted ``key`` in ``config``."""
    value = config
    for part in key.split("."):
        value = value[part]
    return value


@dataclasses.dataclass(frozen=True)
class Rule:
    """One rule of the workflow as the plan, the scheduler and its jobs see it.

    ``stage``: the line of ``python -m neurender.plan``'s summary it is counted under;
    ``work``: its work measure (:data:`Work`); ``gpu``: its job runs on a GPU when the
    config asks for GPUs (config key ``gpus``); ``params``: what its jobs read of the
    config, in the order of their params (:meth:`job_params`), which Snakemake compares
    with a finished job's: an edit of a key reruns exactly the jobs that read it.
    """

    stage: str
    work: Work = no_work
    gpu: bool = False
    params: tuple[Entry, ...] = ()

    def job_params(
        self,
        config: Mapping[str, Any],
        wildcards: Mapping[str, str],
        given: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """The params of the job with ``wildcards``: each entry's value by its name, in
        order (the entries of a :class:`When` whose condition holds in place of it).
        ``ValueError`` for a name given twice."""
        return _params(self.params, config, wildcards, given or {})

    def reads(self, config: Mapping[str, Any], wildcards: Mapping[str, str]) -> set[str]:
        """The dotted config keys the job with ``wildcards`` reads."""
        return set(_keys(self.params, lambda when: when.applies(config, wildcards)))

    @property
    def keys(self) -> set[str]:
        """The dotted config keys some job of the rule may read."""
        return set(_keys(self.params, lambda when: True))


def _params(
    entries: tuple[Entry, ...],
    config: Mapping[str, Any],
    wildcards: Mapping[str, str],
    given: Mapping[str, Any],
) -> dict[str, Any]:
    """The params of ``entries`` (:meth:`Rule.job_params`)."""
    found: dict[str, Any] = {}
    for entry in entries:
        if isinstance(entry, When):
            part = (
                _params(entry.entries, config, wildcards, given)
                if entry.applies(config, wildcards)
                else {}
            )
        elif isinstance(entry, Group):
            part = {entry.name: _params(entry.entries, config, wildcards, given)}
        elif isinstance(entry, Value):
            part = {entry.name: entry.compute(config, wildcards)}
        elif isinstance(entry, Given):
            part = {entry.name: given[entry.name]}
        else:
            part = {entry.rpartition(".")[2]: config_value(config, entry)}
        twice = sorted(set(part) & set(found))
        if twice:
            raise ValueError(f"params {twice} given twice; expected each name once")
        found.update(part)
    return found


def _keys(entries: tuple[Entry, ...], applies: Callable[[When], bool]) -> Iterator[str]:
    """The config keys of ``entries``, those of each :class:`When` where ``applies``."""
    for entry in entries:
        if isinstance(entry, When):
            if applies(entry):
                yield from _keys(entry.entries, applies)
        elif isinstance(entry, Group):
            yield from _keys(entry.entries, applies)
        elif isinstance(entry, Value):
            yield from entry.reads
        elif isinstance(entry, str):
            yield entry


@dataclasses.dataclass(frozen=True)
class ReportInputs:
    """The files a method's report section shows, all under ``results/<key>/``: CSV
    tables, PNG/GIF figures and viewer files (:mod:`neurender.viewer_data`), in the order
    the section shows them."""

    tables: list[str]
    figures: list[str]
    viewers: list[str]


#: The tables a method keeps beside its code (``<tables_dir>/<kind>.csv``), by kind: their
#: columns, each a string but ``value`` (a float). ``paper_numbers``: its published
#: numbers, each row citing its table or section (``source``); ``headlines``: its report
#: summary's rows, which of our numbers (``table``: its path under ``results/<key>/``
#: without ``.csv``; ``dataset``, ``model``, ``split``, ``metric``) stands beside which
#: published one (``paper_*``, empty when the paper reports none); ``targets``: its
#: targets' thresholds (``name``, ``value``), read by :func:`neurender.tables.threshold`.
TABLE_COLUMNS = {
    "paper_numbers": ("method", "source", "setting", "model", "metric", "value", "note"),
    "headlines": (
        "method",
        "label",
        "table",
        "dataset",
        "model",
        "split",
        "metric",
        "paper_source",
        "paper_setting",
        "paper_model",
        "paper_metric",
    ),
    "targets": ("method", "name", "value", "description"),
}


@dataclasses.dataclass(frozen=True)
class Study:
    """A committed study of a method (hours of compute, outside CI): its tidy CSV under
    ``benchmarks/results/`` with a sidecar ``.json`` beside it (:attr:`sidecar`: the
    command and commit of each run that made it), and the compact table the report shows.

    Attributes:
        csv: the CSV's path relative to the repository root.
        title: the report's heading of the study.
        description: what was measured, at which budget (a sentence or two).
        query: a :meth:`pandas.DataFrame.query` string selecting the rows shown ("" for all).
        index: the columns whose values name the table's rows (at least one).
        columns: the columns whose values name the table's columns (none: one column,
            ``values``).
        values: the numeric column shown in the cells; rows that share ``index`` and
            ``columns`` values (seeds, frames, strengths) are averaged.
        digits: significant digits of the cells.
        figures: committed figures of the study (PNG paths relative to the repository
            root), shown under its table.
    """

    csv: str
    title: str
    description: str
    query: str = ""
    index: tuple[str, ...] = ()
    columns: tuple[str, ...] = ()
    values: str = "value"
    digits: int = 4
    figures: tuple[str, ...] = ()

    def __post_init__(self):
        bad = [f for f in self.figures if not f.endswith(".png")]
        if bad:
            raise ValueError(f"study {self.csv}: figures {bad} must be PNG files")
        if not self.index:
            raise ValueError(f"study {self.csv}: index is empty; expected at least one column")
        if not self.csv.endswith(".csv"):
            raise ValueError(f"study {self.csv}: expected a path ending in .csv")

    @property
    def sidecar(self) -> str:
        """The sidecar's path relative to the repository root: the CSV's, ``.json``."""
        return str(PurePosixPath(self.csv).with_suffix(".json"))

    def view(self, root: str | Path) -> pd.DataFrame:
        """The table of the CSV under ``root``: the rows of :attr:`query`, one row per
        :attr:`index` values (in order of appearance) and one column per :attr:`columns`
        values (the first column's varying slowest, each in order of appearance), each cell
        the mean of :attr:`values` over the rows that share them. The index columns come
        first; the others are named by their values joined with
        ``", "``, a number prefixed with its column's name (``rel_l1_diffuse, epochs 3``).
        ``ValueError`` naming the file for an unreadable CSV, a missing column, a
        non-numeric ``values``, a query that fails or selects nothing."""
        path = Path(root) / self.csv
        try:
            frame = pd.read_csv(path)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
            raise ValueError(f"{path}: not a CSV table ({err}); expected a study's CSV") from err
        needed = list(dict.fromkeys((*self.index, *self.columns, self.values)))
        missing = [c for c in needed if c not in frame.columns]
        if missing:
            raise ValueError(
                f"{path}: no column {missing}; the study {self.title!r} needs columns "
                f"{needed} (found {list(frame.columns)})"
            )
        if not pd.api.types.is_numeric_dtype(frame[self.values]):
            raise ValueError(f"{path}: column {self.values!r} is not numeric; expected numbers")
        if self.query:
            try:
                frame = frame.query(self.query)
            except Exception as err:  # pandas raises many kinds for a bad query
                raise ValueError(f"{path}: query {self.query!r} failed: {err}") from err
        if frame.empty:
            raise ValueError(f"{path}: no rows match query {self.query!r}; expected some")
        wide = frame.pivot_table(
            index=list(self.index),
            columns=list(self.columns) or None,
            values=self.values,
            aggfunc="mean",
            sort=False,
        )
        if self.columns:
            # the first of ``columns`` varies slowest, each level in order of appearance
            rank = [{v: i for i, v in enumerate(pd.unique(frame[c]))} for c in self.columns]
            keys = [k if isinstance(k, tuple) else (k,) for k in wide.columns]
            order = sorted(
                range(len(keys)), key=lambda j: [r[v] for r, v in zip(rank, keys[j], strict=True)]
            )
            wide = wide.iloc[:, order]
            wide.columns = [_label(wide.columns.names, key) for key in wide.columns]
        return wide.reset_index()

    def runs(self, root: str | Path) -> tuple[str, list[dict[str, Any]]]:
        """The sidecar under ``root``: its ``note`` ("" without one) and its runs, each
        with ``command`` and ``commit`` (strings), ``dirty`` (``True``, ``False`` or
        ``None`` when not recorded) and ``note`` (""). A sidecar is either one run's
        record or ``{"note": ..., "runs": [...]}``. ``ValueError`` naming the file and key
        for anything else."""
        path = Path(root) / self.sidecar
        try:
            record = json.loads(path.read_text())
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not JSON ({err}); expected a study's sidecar") from err
        if not isinstance(record, dict):
            raise ValueError(f"{path}: expected a JSON object")
        runs = record.get("runs", [record])
        if not isinstance(runs, list) or not runs:
            raise ValueError(f"{path}: 'runs' must be a non-empty list of run records")
        found = []
        for i, run in enumerate(runs):
            where = f"{path}: run {i}" if "runs" in record else str(path)
            if not isinstance(run, dict):
                raise ValueError(f"{where}: expected a JSON object")
            command, commit = run.get("command"), run.get("commit")
            if not isinstance(command, str) or not command:
                raise ValueError(f"{where}: 'command' = {command!r}; expected a command line")
            if not isinstance(commit, str) or not re.fullmatch(r"[0-9a-f]{7,40}", commit):
                raise ValueError(f"{where}: 'commit' = {commit!r}; expected a git commit hash")
            dirty = run.get("dirty")
            if dirty not in (True, False, None):
                raise ValueError(f"{where}: 'dirty' = {dirty!r}; expected true or false")
            note = run.get("note", "") if "runs" in record else ""
            found.append({"command": command, "commit": commit, "dirty": dirty, "note": note})
        return record.get("note", ""), found


def _label(names: list[str], key: object) -> str:
    """A pivoted column's name: its values joined, a number after its column's name."""
    values = key if isinstance(key, tuple) else (key,)
    return ", ".join(
        str(v) if isinstance(v, str) else f"{n} {v}" for n, v in zip(names, values, strict=True)
    )


#: The stages every method has, in order, each one rule of its rules file
#: (:attr:`Method.stages`): its data; the data's summary; training; deployment (the one
#: place a result becomes its shipped files, checked and timed: a change to the export
#: reruns it, not training); the evaluation on held-out data; the equal-quality comparison
#: with its reference renderer (:mod:`neurender.equal_quality`); its targets (from its
#: results only: ``results/<key>/targets.csv``).
STAGES = ("data", "summary", "train", "deploy", "evaluate", "equal_quality", "targets")


@dataclasses.dataclass(frozen=True)
class Method:
    """One method of the project.

    Attributes:
        key: its results folder (``results/<key>/``), its report section and the value of
            the ``method`` column of its rows in every table.
        title: the report section's heading; the part before a colon is its short name.
        citation: the publication the method and its published numbers come from.
        link: the publication's DOI (or URL).
        config_sections: the top-level config sections it reads (schema
            ``workflow/schemas/config.schema.yaml``).
        problems: ``problems(config)``: every config rule the (defaults-filled) config
            breaks that the schema cannot state, one sentence each naming keys and values.
        report_inputs: ``report_inputs(config)``: the files of its report section.
        rules: every rule of its rules file, by name.
        stage_rules: the rule of each of :data:`STAGES` that is not named
            ``<key>_<stage>`` (:attr:`stages`), by stage.
        tables_dir: the folder of its published numbers, headline rows and target
            thresholds (:data:`TABLE_COLUMNS`, read by :meth:`table`): its package's,
            ``importlib.resources.files(__package__)``, so that they ship with its code.
        user_paths: ``user_paths(config)``: every path the user wrote in its config
            sections (:class:`neurender.user_paths.UserPath`, empty ones included), which
            :func:`neurender.config.wildcard_problems` checks for braces; none by default.
        studies: its committed studies (:class:`Study`), shown in its report section
            after the run's tables as results of their own commits, not of the run.
        unread_keys: the dotted keys of its config sections no job's params hold (no
            rule's :attr:`Rule.params`): those that only pick input files or add and
            remove jobs (which other rerun triggers rerun) and resources (threads).
    """

    key: str
    title: str
    citation: str
    link: str
    config_sections: tuple[str, ...]
    problems: Callable[[Mapping[str, Any]], Iterator[str]]
    report_inputs: Callable[[Mapping[str, Any]], ReportInputs]
    rules: Mapping[str, Rule]
    tables_dir: Traversable
    user_paths: Callable[[Mapping[str, Any]], Iterator[UserPath]] = no_user_paths
    studies: tuple[Study, ...] = ()
    unread_keys: tuple[str, ...] = ()
    stage_rules: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        other = sorted(set(self.stage_rules) - set(STAGES))
        if other:
            raise ValueError(
                f"method {self.key!r}: stage_rules {other}; expected stages of {STAGES}"
            )
        unknown = {s: r for s, r in self.stages.items() if r not in self.rules}
        if unknown:
            raise ValueError(f"method {self.key!r}: stages {unknown} name no rule of its rules")

    @property
    def stages(self) -> dict[str, str]:
        """Its rule of each of :data:`STAGES`, in their order: ``<key>_<stage>`` unless
        :attr:`stage_rules` names another."""
        return {stage: self.stage_rules.get(stage, f"{self.key}_{stage}") for stage in STAGES}

    @property
    def short_title(self) -> str:
        """The name the report's summary tables give the method."""
        return self.title.split(":")[0]

    def table(self, kind: str) -> pd.DataFrame:
        """Its table ``kind`` of :data:`TABLE_COLUMNS` (``<tables_dir>/<kind>.csv``):
        those columns, strings (empty cells are empty strings) but ``value`` (floats).
        ``ValueError`` naming the file for other columns or a row of another method."""
        columns = TABLE_COLUMNS[kind]
        path = self.tables_dir.joinpath(f"{kind}.csv")
        dtypes = {c: float if c == "value" else str for c in columns}
        with path.open() as f:
            frame = pd.read_csv(f, keep_default_na=False, dtype=dtypes)
        if tuple(frame.columns) != columns:
            raise ValueError(f"{path}: columns {list(frame.columns)}; expected {list(columns)}")
        others = sorted(set(frame.method) - {self.key})
        if others:
            raise ValueError(f"{path}: rows of method {others}; expected only {self.key!r}")
        return frame
