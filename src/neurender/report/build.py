"""Self-contained HTML report: a summary first, then one section per method with its
interactive viewers, figures, our tables (collapsed) and the papers' numbers.

The report only shows what the pipeline measured (tidy CSV tables, PNG/GIF figures and
viewer files that stages wrote under ``results/<method>/``) and each method's published
numbers (its ``paper_numbers`` table, :meth:`neurender.method.Method.table`: each row
cites its table or section). The summary takes each method's headline rows (its
``headlines`` table: our value beside the paper's) and its targets (the ``targets.csv``
its stage wrote, met or missed), and one deployment table: every trained network of every
method (its ``deployment.csv``, :mod:`neurender.deployment`) beside the papers' network
times (``paper_numbers`` rows of metric :data:`PAPER_TIME`, whose note names the
hardware) and our hardware. The sections are the registered methods'
(:data:`neurender.methods.METHODS`: ``key``, ``title``, ``citation``, ``link`` and their
tables), in that order; a method whose stage has not produced anything says so. Figures,
viewer data and the viewers' code (three.js, bundled in ``static/viewers.min.js``) are
embedded, so the file opens from disk with no server. After a section's tables come its
method's committed studies (:attr:`neurender.method.Method.studies`: CSVs under
``benchmarks/results/`` with their sidecars), each with the commands and commits that made
it, shown as results of those commits, never of this run.
"""

from __future__ import annotations

import base64
import datetime
import html
import json
import math
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import jinja2
import pandas as pd

from neurender import equal_quality, io, methods, viewer_data
from neurender.deployment import ENGINE_COLUMNS, ENGINE_NAMES, read_deployment
from neurender.method import Method, Study
from neurender.tables import TIDY_COLUMNS, lookup

#: Tables longer than this many rows are shown collapsed.
LONG_TABLE_ROWS = 12
#: The metric of the papers' network times per frame in the ``paper_numbers`` tables.
PAPER_TIME = "network_ms_per_frame"


def paper_numbers() -> pd.DataFrame:
    """Every registered method's published numbers: columns ``method, source, setting,
    model, metric, value, note``."""
    return methods.table("paper_numbers")


def _method_of(path: Path) -> str | None:
    keys = {m.key for m in methods.METHODS}
    return next((part for part in path.parts if part in keys), None)


def _format_value(v: object) -> str:
    if isinstance(v, bool):
        return "met" if v else "<strong>missed</strong>"
    if isinstance(v, float):
        if v != v:  # NaN
            return "&ndash;"
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:,.0f}"
    return html.escape(str(v))  # cells are inserted unescaped so that NaN can be a dash


def _table_html(frame: pd.DataFrame) -> str:
    """A table whose cells are already HTML (:func:`_format_value`); its headers, plain
    text such as metric names from the CSV, are escaped here."""
    frame = frame.rename(columns=lambda c: html.escape(str(c)))
    table = frame.to_html(
        index=False, border=0, classes="table", na_rep="&ndash;", escape=False, justify="left"
    )
    return '<div class="scroll">' + table.replace("<td>nan</td>", "<td>&ndash;</td>") + "</div>"


def _render_table(frame: pd.DataFrame) -> tuple[str, int]:
    """HTML of a table and its number of displayed rows. A tidy metric table becomes one
    pivoted table per split (one column per metric); anything else is shown as is."""
    if not set(TIDY_COLUMNS) <= set(frame.columns):
        return _table_html(frame.map(_format_value)), len(frame)
    parts, rows = [], 0
    for split, part in frame.groupby("split", sort=False):
        index = [c for c in part.columns if c not in ("method", "split", "metric", "value")]
        # Metrics with one value per frame are averaged; the CSV keeps every row.
        wide = part.pivot_table(
            index=index, columns="metric", values="value", aggfunc="mean", sort=False
        )
        wide = wide.dropna(axis=1, how="all").reset_index()
        wide.columns.name = None
        parts.append(f"<h4>{html.escape(str(split))}</h4>" + _table_html(wide.map(_format_value)))
        rows += len(wide)
    return "\n".join(parts), rows


def training_budget(frame: pd.DataFrame) -> str:
    """The training budget of a tidy table's learned models, from its ``epochs`` rows
    (metric ``epochs`` or ``epochs_<material>``): one sentence, saying whether every
    learned model had the same budget; empty for a table without such rows."""
    if not set(TIDY_COLUMNS) <= set(frame.columns):
        return ""
    rows = frame[frame.metric.astype(str).str.match(r"^epochs(_|$)")]
    if rows.empty:
        return ""
    per_model = rows.groupby("model", sort=False)["value"].agg(["min", "max"])
    if (
        per_model["min"].nunique() == 1
        and per_model["max"].nunique() == 1
        and (per_model["min"] == per_model["max"]).all()
    ):
        epochs = int(per_model["min"].iloc[0])
        models = ", ".join(per_model.index)
        unit = "epoch" if epochs == 1 else "epochs"
        return f"Training budget: equal, {epochs} {unit} for every learned model ({models})."
    spread = "; ".join(
        f"{m} {int(r['min'])}" + (f"-{int(r['max'])}" if r["max"] != r["min"] else "")
        for m, r in per_model.iterrows()
    )
    return f"Training budget: unequal, epochs per learned model: {spread}."


def commit_label(git: Mapping[str, Any]) -> str:
    """``<12 hex digits>``, with ``+ uncommitted changes`` when dirty; ``not a git
    checkout`` without a commit."""
    if git.get("commit") is None:
        return "not a git checkout"
    return git["commit"][:12] + (" + uncommitted changes" if git.get("dirty") else "")


def _study(study: Study, root: Path) -> dict:
    """A committed study as its section shows it: title, description, the sidecar's runs
    (command, abbreviated commit) and the view (:meth:`Study.view`) as HTML, its cells
    to ``study.digits`` significant digits."""
    note, runs = study.runs(root)
    view = study.view(root)

    def cell(v: object) -> str:
        if isinstance(v, float) and v == v and abs(v) < 1e5:
            return f"{v:.{study.digits}g}"
        return _format_value(v)

    shown = view.copy()
    for c in view.columns:
        shown[c] = view[c].map(_format_value if c in study.index else cell)
    return {
        "title": study.title,
        "description": study.description,
        "csv": study.csv,
        "sidecar": study.sidecar,
        "note": note,
        "runs": [
            {"command": r["command"], "commit": commit_label(r), "note": r["note"]} for r in runs
        ],
        "html": _table_html(shown),
        "figures": [
            {"caption": Path(f).stem.replace("_", " "), "src": _embed_image(root / f)}
            for f in study.figures
        ],
    }


def _embed_image(path: Path) -> str:
    mime = {".png": "image/png", ".gif": "image/gif"}.get(path.suffix.lower())
    if mime is None:
        raise ValueError(f"figure {path}: expected a .png or .gif file")
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def headline_values(method: Method, tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """``method``'s headline numbers (its ``headlines`` table) from its run's tables
    (``tables``: name, as :func:`table_name` gives it, to frame), each beside the paper's:
    columns ``method, label, ours, paper, source`` (NaN where a table or a paper's number is
    missing), in the headlines' order."""
    published = method.table("paper_numbers")
    rows = []
    for h in method.table("headlines").itertuples():
        table = tables.get(h.table)
        ours = math.nan
        if table is not None and set(TIDY_COLUMNS) <= set(table.columns):
            ours = lookup(table, dataset=h.dataset, model=h.model, split=h.split, metric=h.metric)
        paper = math.nan
        if h.paper_source:
            sel = published[
                (published.source == h.paper_source)
                & (published.setting == h.paper_setting)
                & (published.model == h.paper_model)
                & (published.metric == h.paper_metric)
            ]
            paper = float(sel.value.iloc[0]) if len(sel) else math.nan
        rows.append((method.key, h.label, ours, paper, h.paper_source))
    return pd.DataFrame(rows, columns=["method", "label", "ours", "paper", "source"])


def _headline_rows(method: Method, tables: dict[str, pd.DataFrame]) -> list[dict]:
    return [
        {
            "label": h.label,
            "ours": _format_value(h.ours),
            "paper": _format_value(h.paper) if h.source else "not reported",
            "source": h.source,
        }
        for h in headline_values(method, tables).itertuples()
    ]


def _targets(table: pd.DataFrame | None) -> dict:
    if table is None or not {"check", "met"} <= set(table.columns):
        return {"met": 0, "missed": []}
    met = table["met"].astype(str).str.lower() == "true"
    missed = [
        f"{r.subject}: {r.check} (measured {_format_value(float(r.measured))})"
        for r in table[~met].itertuples()
    ]
    return {"met": int(met.sum()), "missed": missed}


def _short_title(key: str) -> str:
    return methods.by_key(key).short_title


def _bytes(n: float) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"


def deployment_summary(tables: Sequence[Path]) -> dict | None:
    """The summary's deployment table: every network of the
    ``results/<method>/deployment.csv`` files among ``tables`` (methods in report order) and
    the papers' network times beside it; the hardware our times were measured on. ``None``
    when no method has deployed anything."""
    files = [t for t in tables if (key := _method_of(t)) and table_name(t, key) == "deployment"]
    if not files:
        return None
    ours = pd.concat([read_deployment(f) for f in files], ignore_index=True)
    order = {m.key: i for i, m in enumerate(methods.METHODS)}
    ours = ours.sort_values("method", key=lambda m: m.map(order), kind="stable")
    shown = pd.DataFrame(
        {
            "method": ours.method.map(_short_title),
            "network": ours.network.map(html.escape),
            "resolution": ours.resolution.map(html.escape),
            "parameters": ours.parameters.map(lambda n: f"{int(n):,}"),
            "ONNX file": ours.onnx_bytes.map(_bytes),
            "max |ONNX - PyTorch|": ours.max_abs_diff_vs_pytorch.map(lambda e: f"{e:.2g}"),
            **{
                f"{ENGINE_NAMES[engine]} ms": ours[column].map(_format_value)
                for engine, column in ENGINE_COLUMNS.items()
            },
        }
    )
    published = paper_numbers()
    published = published[published.method.isin(set(ours.method))]
    sizes = published[published.metric == "parameters"]
    sizes = dict(zip(zip(sizes.method, sizes.model, strict=True), sizes.value, strict=True))
    times = published[published.metric == PAPER_TIME]
    times = times.sort_values("method", key=lambda m: m.map(order), kind="stable")
    papers = [
        {
            "method": _short_title(row.method),
            "network": html.escape(row.model),
            "setting": html.escape(row.setting),
            "parameters": (
                f"{int(sizes[row.method, row.model]):,}"
                if (row.method, row.model) in sizes
                else "not stated"
            ),
            "ms per frame": _format_value(float(row.value)),
            "hardware and notes": html.escape(row.note),
            "source": html.escape(row.source),
        }
        for row in times.itertuples()
    ]
    return {
        "ours": _table_html(shown),
        "rows": len(shown),
        "paper": _table_html(pd.DataFrame(papers)) if papers else "",
        "hardware": list(dict.fromkeys(ours.hardware)),
    }


def equal_quality_summary(tables: Sequence[Path]) -> str:
    """The summary's equal-quality tables (HTML, "" when no method has one): every network
    of every method's ``results/<method>/equal_quality.csv`` among ``tables`` (methods in
    report order, :mod:`neurender.equal_quality`'s rows), its ratio to the cheapest
    setting of its reference renderer that reaches its quality, stated with its bound,
    and that setting; one table per cost (:data:`neurender.equal_quality.COSTS`: the
    speed-ups, the triangle ratios), each headed by what it counts."""
    files = [t for t in tables if (key := _method_of(t)) and table_name(t, key) == "equal_quality"]
    if not files:
        return ""
    order = {m.key: i for i, m in enumerate(methods.METHODS)}
    files.sort(key=lambda t: order[_method_of(t)])
    frames = [io.read_csv(f) for f in files]
    parts = []
    for cost in equal_quality.COSTS:
        rows = pd.concat([equal_quality.ratios(f, cost) for f in frames], ignore_index=True)
        if rows.empty:
            continue
        shown = pd.DataFrame(
            {
                "method": rows.method.map(_short_title),
                "dataset": rows.dataset.map(html.escape),
                cost.subject: rows.model.map(html.escape),
                f"x {cost.cheaper} at equal quality": [
                    html.escape(equal_quality.stated(r.ratio, r.bound)) for r in rows.itertuples()
                ],
                "against": rows.setting.map(html.escape),
            }
        )
        parts.append(_table_html(shown))
    return "\n".join(parts)


def _viewer(path: Path, index: int) -> dict:
    viewer = viewer_data.read(path)
    return {
        "id": f"viewer-{index}",
        "kind": viewer["kind"],
        "title": viewer["title"],
        "json": script_json(viewer["data"]),
    }


def script_json(data: dict) -> str:
    """``data`` as compact JSON to embed in a ``<script>`` element, whose raw text no
    ``<`` may open a tag inside."""
    return json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")


def table_name(table: Path, key: str) -> str:
    """A table's name in the section of method ``key``: its path under ``results/<key>/``
    without ``.csv`` (``metrics``, ``head_linear/experiment``), unique where stems are not;
    a headline row's ``table`` (:data:`neurender.method.TABLE_COLUMNS`)."""
    parts = table.with_suffix("").parts
    return "/".join(parts[parts.index(key) + 1 :])


def _section(
    section: Method,
    tables: list[Path],
    figures: list[Path],
    viewers: list[dict],
    root: Path | None,
):
    frames = {table_name(t, section.key): io.read_csv(t) for t in tables}
    paper = section.table("paper_numbers").drop(columns="method")
    rendered = []
    for t in tables:
        name = table_name(t, section.key)
        body, rows = _render_table(frames[name])
        rendered.append(
            {
                "caption": name.replace("_", " "),
                "path": str(t),
                "href": Path(*t.parts[t.parts.index(section.key) :]).as_posix(),
                "html": body,
                "budget": training_budget(frames[name]),
                "collapsed": rows > LONG_TABLE_ROWS and name != "targets",
            }
        )
    ran = bool(tables or figures)
    return {
        "key": section.key,
        "title": section.title,
        "citation": section.citation,
        "link": section.link,
        "ran": ran,
        "data_only": ran and "metrics" not in frames,
        "headlines": _headline_rows(section, frames),
        "targets": _targets(frames.get("targets")),
        "budget": training_budget(frames["metrics"]) if "metrics" in frames else "",
        "tables": rendered,
        "figures": [{"caption": f.stem.replace("_", " "), "src": _embed_image(f)} for f in figures],
        "viewers": viewers,
        "paper": _table_html(paper.map(_format_value)) if len(paper) else "",
        "studies": [_study(s, root) for s in section.studies] if root is not None else [],
    }


def build_report(
    tables: Sequence[str | Path],
    figures: Sequence[str | Path],
    output: str | Path,
    title: str = "neurender report",
    run_info: dict[str, str] | None = None,
    viewers: Sequence[str | Path] = (),
    provenance: Mapping[str, Any] | None = None,
    root: str | Path | None = None,
) -> None:
    """Write the HTML report.

    Args:
        tables: CSV files under ``results/<method>/``; tidy metric tables (columns
            ``method, dataset, model, split, metric, value``) are pivoted to one column
            per metric, other tables (targets, timings) are shown as they are.
        figures: PNG/GIF files under ``results/<method>/``; the file stem is the caption.
        output: the ``.html`` file.
        run_info: key -> value pairs shown at the top (config file, seed, ...).
        viewers: viewer files (:mod:`neurender.viewer_data`) under ``results/<method>/``.
        provenance: the run's :mod:`neurender.provenance` record, shown collapsed.
        root: the repository root, which the methods' committed studies' paths
            (:class:`neurender.method.Study`) are relative to; ``None``: no studies shown.
            ``ValueError`` naming the file for a study's malformed CSV or sidecar.
    """
    sections = []
    for index, section in enumerate(methods.METHODS):
        own_viewers = [
            _viewer(Path(v), 100 * index + k)
            for k, v in enumerate(p for p in viewers if _method_of(Path(p)) == section.key)
        ]
        sections.append(
            _section(
                section,
                [Path(t) for t in tables if _method_of(Path(t)) == section.key],
                [Path(f) for f in figures if _method_of(Path(f)) == section.key],
                own_viewers,
                None if root is None else Path(root),
            )
        )
    code = ""
    if any(s["viewers"] for s in sections):
        code = resources.files("neurender.report").joinpath("static/viewers.min.js").read_text()
        code = code.replace("</script", "<\\/script")  # raw text inside <script>
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("neurender.report", "templates"),
        autoescape=jinja2.select_autoescape(default=True),
    )
    page = env.get_template("report.html.j2").render(
        title=title,
        sections=sections,
        run_info=run_info or {},
        viewer_code=code,
        deployment=deployment_summary([Path(t) for t in tables]),
        equal_quality=equal_quality_summary([Path(t) for t in tables]),
        bounds=equal_quality.BOUNDS,
        provenance=provenance,
        generated=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
    )
    with io.atomic_path(output) as tmp:
        tmp.write_text(page, encoding="utf-8")
