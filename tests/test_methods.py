"""The method registry: every rule belongs to a registered method, each method's tables
lie beside its code and hold its rows only, the records load at DAG time without torch or
Mitsuba, and a method registered only here (a toy fifth one, with its own published
numbers, headline rows and targets) reaches the config checks, the cost model, the plan,
the targets' thresholds and the report."""

import dataclasses
import fnmatch
import importlib
import re
import subprocess
import sys
import tomllib
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from neurender import config, costs, io, methods, plan, tables
from neurender.method import STAGES, TABLE_COLUMNS, Method, ReportInputs, Rule, Units
from neurender.report import build
from neurender.user_paths import UserPath

ROOT = Path(__file__).resolve().parents[1]

#: Modules that must not load when the Snakefile builds the DAG.
HEAVY = ("torch", "mitsuba", "drjit", "pyvista", "vtk", "embree")


def _toy_problems(cfg: Mapping) -> Iterator[str]:
    if cfg["toy"]["size"] < 1:
        yield f"toy.size = {cfg['toy']['size']}: expected at least 1"


def _toy_work(cfg: Mapping, wildcards: Mapping[str, str]) -> Units:
    return cfg["toy"]["size"] ** 2 * int(wildcards["count"]) / 1e6, 2.0


def _toy_user_paths(cfg: Mapping) -> Iterator[UserPath]:
    yield UserPath("toy.scenes", cfg["toy"].get("scenes", ""))


def _toy_inputs(cfg: Mapping) -> ReportInputs:
    return ReportInputs(
        tables=["results/toy/metrics.csv"],
        figures=["results/toy/figures/picture.png"],
        viewers=[],
    )


TOY = Method(
    key="toy",
    title="Toy: a method registered by a test",
    citation="A. Nobody. A Toy Method. Journal of Tests 1, 2026.",
    link="https://example.org/toy",
    config_sections=("toy",),
    problems=_toy_problems,
    report_inputs=_toy_inputs,
    rules={"toy_render": Rule("toy stage", _toy_work, gpu=True), "toy_summary": Rule("toy stage")},
    tables_dir=Path("written by the toy fixture"),
    user_paths=_toy_user_paths,
    # One rule does every stage but the summary: a toy's whole pipeline is one render.
    stage_rules={stage: "toy_render" for stage in STAGES if stage != "summary"},
)

#: The toy method's own tables, as its package would hold them.
TOY_TABLES = {
    "paper_numbers": [("toy", "Toy Table 2", "all scenes", "ToyNet", "psnr", 29.5, "")],
    "headlines": [
        ("toy", "test PSNR", "metrics", "d", "m", "test", "psnr")
        + ("Toy Table 2", "all scenes", "ToyNet", "psnr")
    ],
    "targets": [("toy", "psnr", 28.0, "test PSNR at least")],
}


@pytest.fixture
def toy(monkeypatch, tmp_path):
    """The registry with the toy method after the four built-in ones, its tables in a
    folder of its own."""
    for kind, rows in TOY_TABLES.items():
        pd.DataFrame(rows, columns=TABLE_COLUMNS[kind]).to_csv(
            tmp_path / f"{kind}.csv", index=False
        )
    record = dataclasses.replace(TOY, tables_dir=tmp_path)
    monkeypatch.setattr(methods, "METHODS", (*methods.METHODS, record))
    return record


@pytest.fixture(scope="module")
def smoke():
    return plan.load_config([str(ROOT / "config/smoke.yaml")])


def _workflow_rules() -> set[str]:
    names = set()
    for path in (ROOT / "workflow/rules").glob("*.smk"):
        names |= set(re.findall(r"^(?:local)?rule (\w+):", path.read_text(), re.M))
    return names


def test_every_rule_of_the_workflow_is_registered_once():
    assert set(methods.rules()) == _workflow_rules()
    owned = [name for m in methods.METHODS for name in m.rules]
    owned += list(methods.WORKFLOW_RULES)
    assert len(owned) == len(set(owned))


def test_every_config_section_of_the_schema_belongs_to_one_method_or_to_all():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    sections = {k for k, v in schema["properties"].items() if v.get("type") == "object"}
    claimed = [s for m in methods.METHODS for s in m.config_sections]
    assert len(claimed) == len(set(claimed))
    assert sections - set(claimed) == {"report"}  # the report's title: every method's


def test_every_methods_tables_lie_in_its_package_and_hold_only_its_rows():
    records = {}
    for path in (ROOT / "src/neurender").glob("*/method.py"):
        module = importlib.import_module(f"neurender.{path.parent.name}.method")
        records[module.METHOD.key] = module.METHOD, path.parent
    assert set(records) == {m.key for m in methods.METHODS}
    for key, (method, package) in records.items():
        assert Path(str(method.tables_dir)) == package, key
        for kind, columns in TABLE_COLUMNS.items():
            raw = pd.read_csv(package / f"{kind}.csv", keep_default_na=False)
            assert tuple(raw.columns) == columns, (key, kind)
            assert set(raw.method) == {key}, (key, kind)
            assert len(method.table(kind)) == len(raw)
    # no shared copy is left to drift from them
    assert not list((ROOT / "src/neurender/report").glob("*.csv"))


def test_every_headline_names_one_published_number_of_its_method():
    for method in methods.METHODS:
        published = method.table("paper_numbers")
        keys = ["source", "setting", "model", "metric"]
        for h in method.table("headlines").itertuples():
            if h.paper_source:
                wanted = (h.paper_source, h.paper_setting, h.paper_model, h.paper_metric)
                found = sum(row == wanted for row in published[keys].itertuples(False, None))
                assert found == 1, (method.key, h.label)


def test_every_methods_tables_ship_in_the_wheel():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = pyproject["tool"]["setuptools"]["package-data"]["neurender"]
    for method in methods.METHODS:
        folder = Path(str(method.tables_dir)).relative_to(ROOT / "src/neurender")
        for kind in TABLE_COLUMNS:
            name = (folder / f"{kind}.csv").as_posix()
            assert any(fnmatch.fnmatch(name, g) for g in globs), name


def test_a_table_with_other_columns_or_another_methods_rows_is_refused(tmp_path):
    record = dataclasses.replace(TOY, tables_dir=tmp_path)
    rows = pd.DataFrame(
        [("toy", "psnr", 28.0, ""), ("prt", "ssim", 0.97, "")], columns=TABLE_COLUMNS["targets"]
    )
    rows.drop(columns="description").to_csv(tmp_path / "targets.csv", index=False)
    with pytest.raises(ValueError, match=r"targets.csv: columns .*; expected .*'description'"):
        record.table("targets")
    rows.to_csv(tmp_path / "targets.csv", index=False)
    with pytest.raises(ValueError, match=r"rows of method \['prt'\]; expected only 'toy'"):
        record.table("targets")


def test_every_report_input_lies_in_its_methods_results_folder(smoke):
    for method in methods.METHODS:
        inputs = method.report_inputs(smoke)
        files = inputs.tables + inputs.figures + inputs.viewers
        assert files, method.key
        assert all(f.startswith(f"results/{method.key}/") for f in files), method.key
        assert all(f.endswith(".csv") for f in inputs.tables)
        assert all(f.endswith((".png", ".gif")) for f in inputs.figures)


def test_the_registry_loads_without_torch_or_mitsuba():
    code = (
        "import sys, neurender.config, neurender.costs, neurender.methods, neurender.plan; "
        f"print([m for m in sys.modules if m.split('.')[0] in {HEAVY!r}])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert out.stdout.strip() == "[]"


def test_a_registered_method_is_checked_with_the_config(toy, smoke):
    assert config.problems({**smoke, "toy": {"size": 4}}) == []
    with pytest.raises(config.ConfigError, match=r"toy.size = 0: expected at least 1"):
        config.check({**smoke, "toy": {"size": 0}})


def test_a_registered_methods_user_paths_are_checked_for_braces(toy, smoke, tmp_path):
    scenes = tmp_path / "scenes{v2}.csv"
    scenes.write_text("x\n")
    (found,) = config.problems({**smoke, "toy": {"size": 4, "scenes": str(scenes)}})
    assert found.startswith(f"toy.scenes = {str(scenes)!r}: {scenes} contains '{{v2}}'")
    # a folder stands for its files: the braces of one of them are refused too
    (found,) = config.problems({**smoke, "toy": {"size": 4, "scenes": str(tmp_path)}})
    assert found.startswith(f"toy.scenes = {str(tmp_path)!r}: {scenes} contains")
    (tmp_path / "scenes.csv").write_text("x\n")
    cfg = {**smoke, "toy": {"size": 4, "scenes": str(tmp_path / "scenes.csv")}}
    assert config.problems(cfg) == []


def test_a_method_without_user_files_declares_no_user_paths(smoke):
    fields = {f.name: getattr(TOY, f.name) for f in dataclasses.fields(Method)}
    bare = Method(**{k: v for k, v in fields.items() if k != "user_paths"})
    assert list(bare.user_paths(smoke)) == []


def test_each_methods_user_paths_lie_in_its_own_config_sections():
    own = plan.load_config([str(ROOT / "config/examples/own_assets.yaml")])
    listed = {m.key: [e for e in m.user_paths(own) if e.path] for m in methods.METHODS}
    assert all(listed.values()), listed  # the example gives every method a user file
    for method in methods.METHODS:
        for entry in listed[method.key]:
            assert entry.key.split(".")[0] in method.config_sections, entry
            assert entry.asset == entry.key.startswith(
                ("ndr.user_objects.", "simplification.user_assets.")
            ), entry


def test_a_registered_methods_rules_are_costed_and_planned(toy, smoke):
    cfg = {**smoke, "toy": {"size": 1000}}
    assert costs.work("toy_render", cfg, {"count": "3"}) == (3.0, 2.0)
    assert costs.stage("toy_render") == "toy stage" and costs.uses_gpu("toy_render")
    assert costs.work("toy_summary", cfg, {}) == (0.0, 0.0)
    assert not costs.uses_gpu("toy_summary")
    jobs = [
        plan.PlannedJob("toy_render", {"count": "3"}, 2, ""),
        plan.PlannedJob("toy_summary", {}, 1, ""),
        plan.PlannedJob("prt_train", {"object": "head", "material": "diffuse"}, 1, ""),
    ]
    table = plan.estimates(cfg, jobs)
    assert list(table.stage) == ["toy stage", "toy stage", "DeepPRT models"]
    # No measured coefficients yet: a minute per job, times its threads.
    assert table.core_seconds.iloc[:2].tolist() == [120.0, 60.0]
    assert plan.summary(table).loc["toy stage", "jobs"] == 2


def test_a_registered_methods_targets_are_read_from_its_own_table(toy):
    assert tables.threshold("toy", "psnr") == 28.0
    assert tables.threshold("prt", "ssim") == 0.97  # the built-in ones are still found
    with pytest.raises(KeyError, match=r"method 'toy' has no target 'ssim'"):
        tables.threshold("toy", "ssim")


def test_a_registered_method_gets_a_report_section(toy, tmp_path):
    res = tmp_path / "results" / "toy"
    rows = {"method": "toy", "dataset": "d", "model": "m", "split": "test", "metric": "psnr"}
    io.write_csv(res / "metrics.csv", pd.DataFrame([{**rows, "value": 31.25}]))
    io.write_png(res / "figures" / "picture.png", np.zeros((4, 4, 3), np.uint8))
    out = tmp_path / "report.html"
    build.build_report([res / "metrics.csv"], [res / "figures" / "picture.png"], out)
    html = out.read_text()
    assert '<h2 id="toy">Toy: a method registered by a test</h2>' in html
    assert "A Toy Method" in html and "<td>31.25</td>" in html
    assert html.count("has not been run") == 4  # the four built-in methods
    # its headline row: our 31.25 beside the 29.5 of its own published numbers
    assert "test PSNR" in html and "<td>29.5</td>" in html and "Toy Table 2" in html


def test_the_report_rule_reads_every_methods_report_inputs_and_studies(smoke):
    out = subprocess.run(
        [sys.executable, "-m", "snakemake", "results/report.html", "-n", "--forceall"]
        + ["--cores", "2", "--configfile", "config/smoke.yaml"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    block = out.stdout.split("\nrule report:\n", 1)[1]
    listed = re.search(r"^\s+input: (.*)$", block, re.M).group(1).split(", ")
    expected = []
    for kind in ("tables", "figures", "viewers"):
        expected += [f for m in methods.METHODS for f in getattr(m.report_inputs(smoke), kind)]
    # every committed study's CSV and sidecar, each once (two views may share a CSV)
    studies = [
        p for m in methods.METHODS for s in m.studies for p in (s.csv, s.sidecar, *s.figures)
    ]
    assert studies
    expected += list(dict.fromkeys(studies))
    assert listed == [*expected, "results/provenance.json"]
    # the provenance record does not read them: a new study reruns the report only
    block = out.stdout.split("\nrule provenance:\n", 1)[1]
    provenance = re.search(r"^\s+input: (.*)$", block, re.M).group(1).split(", ")
    assert not set(studies) & set(provenance)


@pytest.mark.parametrize("method", methods.METHODS, ids=lambda m: m.key)
def test_every_method_has_every_stage_as_a_rule_of_its_rules_file(method):
    rules_file = (ROOT / "workflow/rules" / f"{method.key}.smk").read_text()
    defined = set(re.findall(r"^rule (\w+):", rules_file, flags=re.MULTILINE))
    assert tuple(method.stages) == STAGES
    assert set(method.stages.values()) <= defined
    # Each stage its own rule: no rule does two stages' work.
    assert len(set(method.stages.values())) == len(STAGES)


def test_a_method_whose_stage_names_no_rule_or_no_stage_is_refused():
    with pytest.raises(ValueError, match=r"stages \{'deploy': 'toy_export'\} name no rule"):
        dataclasses.replace(TOY, stage_rules={**TOY.stage_rules, "deploy": "toy_export"})
    with pytest.raises(ValueError, match=r"stage_rules \['export'\]; expected stages of"):
        dataclasses.replace(TOY, stage_rules={**TOY.stage_rules, "export": "toy_render"})
    # By default a stage's rule is <key>_<stage>: the toy has toy_summary but no toy_data.
    with pytest.raises(ValueError, match=r"'data': 'toy_data'") as refused:
        dataclasses.replace(TOY, stage_rules={})
    assert "toy_summary" not in str(refused.value)
    assert TOY.stages["summary"] == "toy_summary"
