"""The method registry: every rule and table row belongs to a registered method, the
records load at DAG time without torch or Mitsuba, and a method registered only here (a
toy fifth one) reaches the config checks, the cost model, the plan and the report."""

import re
import subprocess
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from neurender import config, costs, io, methods, plan
from neurender.method import Method, ReportInputs, Rule, Units
from neurender.report import build

ROOT = Path(__file__).resolve().parents[1]

#: Modules that must not load when the Snakefile builds the DAG.
HEAVY = ("torch", "mitsuba", "drjit", "pyvista", "vtk", "embree")


def _toy_problems(cfg: Mapping) -> Iterator[str]:
    if cfg["toy"]["size"] < 1:
        yield f"toy.size = {cfg['toy']['size']}: expected at least 1"


def _toy_work(cfg: Mapping, wildcards: Mapping[str, str]) -> Units:
    return cfg["toy"]["size"] ** 2 * int(wildcards["count"]) / 1e6, 2.0


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
)


@pytest.fixture
def toy(monkeypatch):
    """The registry with the toy method after the four built-in ones."""
    monkeypatch.setattr(methods, "METHODS", (*methods.METHODS, TOY))
    return TOY


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


def test_every_row_of_the_shared_tables_belongs_to_a_registered_method():
    keys = {m.key for m in methods.METHODS}
    for name in ("paper_numbers.csv", "headlines.csv", "targets.csv"):
        table = pd.read_csv(ROOT / "src/neurender/report" / name, keep_default_na=False)
        assert set(table.method) <= keys, name
    # and every method has targets, as its summary checks them
    targets = pd.read_csv(ROOT / "src/neurender/report/targets.csv")
    assert keys <= set(targets.method)


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


def test_the_report_rule_reads_every_methods_report_inputs(smoke):
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
    assert listed == [*expected, "results/provenance.json"]
