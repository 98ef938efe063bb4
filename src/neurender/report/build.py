"""Self-contained HTML report: one section per method, our measurements beside the papers'.

The report only shows what the pipeline measured (tidy CSV tables and PNG figures that
stages wrote under ``results/<method>/``) and the published numbers in
``paper_numbers.csv`` (each row cites its table or section). A method whose stage has not
produced anything says so. Figures are embedded as data URIs so the file opens from disk.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime
import html
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import jinja2
import pandas as pd

from neurender import io

TIDY_COLUMNS = ("method", "dataset", "model", "split", "metric", "value")


@dataclasses.dataclass(frozen=True)
class Section:
    key: str  # the method's folder under results/ and its value in the ``method`` column
    title: str
    citation: str  # the publication the method and the published numbers come from
    link: str  # its DOI (or URL)


SECTIONS = (
    Section(
        "prt",
        "DeepPRT: deep precomputed radiance transfer for deformable objects",
        "Yue Li, Pablo Wiedemann, Kenny Mitchell. Deep Precomputed Radiance Transfer for "
        "Deformable Objects. Proceedings of the ACM on Computer Graphics and Interactive "
        "Techniques 2(1), 2019 (I3D 2019).",
        "https://doi.org/10.1145/3320284",
    ),
    Section(
        "ndr",
        "NDR: neural direct-illumination renderer",
        "Christian Suppan, Andrew Chalmers, Junhong Zhao, Alex Doronin, Taehyun Rhee. Neural "
        "Screen Space Rendering of Direct Illumination. Pacific Graphics 2021 Short Papers, "
        "The Eurographics Association, 2021.",
        "https://doi.org/10.2312/pg.20211385",
    ),
    Section(
        "metaballs",
        "Image-space metaballs (pix2pix)",
        "Robert Horvath. Image-Space Metaballs Using Deep Learning. Master's thesis, TU Wien, "
        "Faculty of Informatics, 2019 (advisor Ivan Viola).",
        "https://repositum.tuwien.at",
    ),
    Section(
        "simplification",
        "Appearance-driven simplification",
        "Jon Hasselgren, Jacob Munkberg, Jaakko Lehtinen, Miika Aittala, Samuli Laine. "
        "Appearance-Driven Automatic 3D Model Simplification. Eurographics Symposium on "
        "Rendering 2021.",
        "https://doi.org/10.2312/sr.20211293",
    ),
)


def paper_numbers() -> pd.DataFrame:
    """Published numbers: columns ``method, source, setting, model, metric, value, note``."""
    with resources.files("neurender.report").joinpath("paper_numbers.csv").open() as f:
        return pd.read_csv(f, keep_default_na=False)


def _method_of(path: Path) -> str | None:
    keys = {s.key for s in SECTIONS}
    return next((part for part in path.parts if part in keys), None)


def _format_value(v: object) -> str:
    if isinstance(v, float):
        if v != v:  # NaN
            return "&ndash;"
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:,.0f}"
    return html.escape(str(v))  # cells are inserted unescaped so that NaN can be a dash


def _table_html(frame: pd.DataFrame) -> str:
    table = frame.to_html(
        index=False, border=0, classes="table", na_rep="&ndash;", escape=False, justify="left"
    )
    return '<div class="scroll">' + table.replace("<td>nan</td>", "<td>&ndash;</td>") + "</div>"


def _render_table(frame: pd.DataFrame) -> str:
    """A tidy metric table becomes one pivoted table per split (one column per metric, so
    timing rows do not widen the test table); anything else is shown as is."""
    if not set(TIDY_COLUMNS) <= set(frame.columns):
        return _table_html(frame.map(_format_value))
    parts = []
    for split, rows in frame.groupby("split", sort=False):
        index = [c for c in rows.columns if c not in ("method", "split", "metric", "value")]
        # Metrics with one value per frame are averaged; the CSV keeps every row.
        wide = rows.pivot_table(
            index=index, columns="metric", values="value", aggfunc="mean", sort=False
        )
        wide = wide.dropna(axis=1, how="all").reset_index()
        wide.columns.name = None
        parts.append(f"<h4>{split}</h4>" + _table_html(wide.map(_format_value)))
    return "\n".join(parts)


def _embed_image(path: Path) -> str:
    mime = {".png": "image/png", ".gif": "image/gif"}.get(path.suffix.lower())
    if mime is None:
        raise ValueError(f"figure {path}: expected a .png or .gif file")
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def build_report(
    tables: Sequence[str | Path],
    figures: Sequence[str | Path],
    output: str | Path,
    title: str = "neurender report",
    run_info: dict[str, str] | None = None,
) -> None:
    """Write the HTML report.

    Args:
        tables: CSV files under ``results/<method>/``; tidy metric tables (columns
            ``method, dataset, model, split, metric, value``) are pivoted to one column
            per metric, other tables (targets, timings) are shown as they are.
        figures: PNG files under ``results/<method>/``; the file stem is the caption.
        output: the ``.html`` file.
        run_info: key -> value pairs shown at the top (config file, seed, ...).
    """
    published = paper_numbers()
    sections = []
    for section in SECTIONS:
        own_tables = [Path(t) for t in tables if _method_of(Path(t)) == section.key]
        own_figures = [Path(f) for f in figures if _method_of(Path(f)) == section.key]
        paper = published[published["method"] == section.key].drop(columns="method")
        sections.append(
            {
                "key": section.key,
                "title": section.title,
                "citation": section.citation,
                "link": section.link,
                "ran": bool(own_tables or own_figures),
                # A stage's model results always land in metrics.csv; without it only data exist.
                "data_only": bool(own_tables or own_figures)
                and not any(t.stem == "metrics" for t in own_tables),
                "tables": [
                    {
                        "caption": t.stem.replace("_", " "),
                        "path": str(t),
                        "html": _render_table(io.read_csv(t)),
                    }
                    for t in own_tables
                ],
                "figures": [
                    {"caption": f.stem.replace("_", " "), "src": _embed_image(f)}
                    for f in own_figures
                ],
                "paper": _table_html(paper.map(_format_value)) if len(paper) else "",
            }
        )
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("neurender.report", "templates"),
        autoescape=jinja2.select_autoescape(default=True),
    )
    html = env.get_template("report.html.j2").render(
        title=title,
        sections=sections,
        run_info=run_info or {},
        generated=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
    )
    with io.atomic_path(output) as tmp:
        tmp.write_text(html, encoding="utf-8")
