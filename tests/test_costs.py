import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from neurender import costs, plan

ROOT = Path(__file__).resolve().parents[1]


def _config(*overrides: str) -> dict:
    return plan.load_config([str(ROOT / p) for p in overrides])


def _rules() -> set[str]:
    names = set()
    for path in (ROOT / "workflow/rules").glob("*.smk"):
        names |= set(re.findall(r"^(?:local)?rule (\w+):", path.read_text(), re.M))
    return names


def test_every_rule_of_the_workflow_has_measured_coefficients():
    missing = _rules() - set(costs.coefficients().index)
    assert not missing, f"calibrate costs.csv (python -m neurender.plan --calibrate): {missing}"


def test_every_rule_asks_for_its_scheduler_resources():
    for path in (ROOT / "workflow/rules").glob("*.smk"):
        text = path.read_text()
        for name in re.findall(r"^(?:local)?rule (\w+):", text, re.M):
            assert f'scheduler_resources("{name}")' in text, f"{path.name}: rule {name}"


def test_training_work_is_proportional_to_epochs_and_pixels():
    cfg = _config()
    units = costs.work("prt_train", cfg, {"object": "head", "material": "diffuse"})[0]
    cfg["prt_model"]["epochs"] *= 2
    assert costs.work("prt_train", cfg, {"object": "head", "material": "diffuse"})[0] == (
        pytest.approx(2 * units)
    )
    cfg["prt"]["resolution"] *= 2
    assert costs.work("prt_train", cfg, {"object": "head", "material": "diffuse"})[0] == (
        pytest.approx(8 * units)
    )


def test_ray_tracing_work_is_proportional_to_rays():
    cfg = _config()
    wildcards = {"object": "head", "split": "train"}
    units = costs.work("prt_transfer", cfg, wildcards)[0]
    cfg["prt"]["directions"] *= 4
    assert costs.work("prt_transfer", cfg, wildcards)[0] == pytest.approx(4 * units)


def test_the_paper_config_costs_more_than_the_default_and_the_default_more_than_smoke():
    sizes = {}
    for name, files in {
        "smoke": ["config/smoke.yaml"],
        "default": [],
        "paper": ["config/paper.yaml"],
    }.items():
        cfg = _config(*files)
        sizes[name] = costs.work("ndr_train", cfg, {"variant": "ndr"})[0]
    assert sizes["smoke"] < sizes["default"] < sizes["paper"]


def test_scheduler_requests_carry_the_safety_factor_and_floors():
    estimate = costs.Estimate(seconds=600.0, mem_mb=2000.0)
    assert estimate.runtime_min == 10 * costs.SAFETY
    assert estimate.mem_limit_mb == 3000
    tiny = costs.Estimate(seconds=1.0, mem_mb=10.0)
    assert tiny.runtime_min == costs.MIN_RUNTIME_MIN
    assert tiny.mem_limit_mb == costs.MIN_MEM_MB


def test_line_fit_recovers_an_exact_line_and_never_goes_negative():
    x = np.array([1.0, 2.0, 5.0, 9.0])
    assert plan._line(x, 3.0 + 0.5 * x) == pytest.approx((3.0, 0.5))
    a, b = plan._line(x, 10.0 - 0.5 * x)  # falling: no negative per-unit cost
    assert (a, b) == (pytest.approx(np.mean(10.0 - 0.5 * x)), 0.0)
    a, b = plan._line(x, -1.0 + 2.0 * x)  # negative intercept: a line through 0
    assert a == 0.0 and b > 0


def test_beyond_limits_lists_exactly_the_jobs_over_either_limit():
    table = pd.DataFrame(
        {
            "rule": ["a", "b", "c"],
            "wildcards": ["", "", ""],
            "runtime_min": [10, 3000, 10],
            "mem_limit_mb": [1000, 1000, 300000],
        }
    )
    assert list(plan.beyond_limits(table, 2880, 256000).rule) == ["b", "c"]


def test_check_flags_stages_outside_the_factor(tmp_path):
    bench = tmp_path / "results/benchmarks"
    bench.mkdir(parents=True)
    for name, seconds in (("a", 10.0), ("b", 100.0)):
        pd.DataFrame({"s": [seconds], "max_rss": [100.0]}).to_csv(
            bench / f"{name}.tsv", sep="\t", index=False
        )
    table = pd.DataFrame(
        {
            "stage": ["x", "y"],
            "benchmark": ["results/benchmarks/a.tsv", "results/benchmarks/b.tsv"],
            "seconds": [12.0, 900.0],
        }
    )
    result = plan.check(table, tmp_path / "results", factor=3.0)
    assert bool(result.loc["x", "within_factor"]) and not bool(result.loc["y", "within_factor"])
    assert result.loc["y", "ratio"] == pytest.approx(9.0)


def test_check_accepts_a_stage_of_a_few_seconds_whatever_the_ratio(tmp_path):
    bench = tmp_path / "results/benchmarks"
    bench.mkdir(parents=True)
    pd.DataFrame({"s": [4.65], "max_rss": [100.0]}).to_csv(bench / "a.tsv", sep="\t", index=False)
    table = pd.DataFrame(
        {"stage": ["x"], "benchmark": ["results/benchmarks/a.tsv"], "seconds": [1.31]}
    )
    result = plan.check(table, tmp_path / "results", factor=3.0, slack_s=10.0)
    assert result.loc["x", "ratio"] < 1 / 3 and bool(result.loc["x", "within_factor"])
    strict = plan.check(table, tmp_path / "results", factor=3.0, slack_s=3.0)
    assert not bool(strict.loc["x", "within_factor"])


def test_the_profiles_parse_and_the_slurm_one_names_the_executor():
    slurm = yaml.safe_load((ROOT / "profiles/slurm/config.yaml").read_text())
    assert slurm["executor"] == "slurm"
    assert yaml.safe_load((ROOT / "profiles/default/config.yaml").read_text())


def _fit(rule: str, fixed_s: float, per_unit_s: float, mb: float, samples: int) -> pd.DataFrame:
    return pd.DataFrame(
        [(rule, fixed_s, per_unit_s, mb, mb / 100, samples)], columns=list(plan.FIT_COLUMNS)
    )


def test_averaged_fits_take_the_mean_time_and_the_largest_memory():
    fast = pd.concat([_fit("a", 1.0, 0.1, 400.0, 3), _fit("b", 2.0, 0.0, 300.0, 1)])
    slow = pd.concat([_fit("a", 4.0, 0.3, 380.0, 5), _fit("c", 6.0, 1.0, 200.0, 2)])
    out = plan.average_fits([fast, slow]).set_index("rule")
    assert list(out.index) == ["a", "b", "c"]
    assert out.loc["a", ["fixed_s", "per_unit_s"]].tolist() == pytest.approx([2.5, 0.2])
    assert out.loc["a", ["fixed_mb", "per_unit_mb"]].tolist() == pytest.approx([400.0, 4.0])
    assert out.loc["a", "samples"] == 8
    # a rule in one fit only keeps that fit's values
    assert out.loc["b"].tolist() == pytest.approx([2.0, 0.0, 300.0, 3.0, 1])
    assert out.loc["c"].tolist() == pytest.approx([6.0, 1.0, 200.0, 2.0, 2])


def test_an_averaged_fit_is_within_3x_of_machines_5x_apart():
    # A job of 10 units measured on a machine and on one 5x slower: the average of the two
    # fits is within 3x of both (the plan check's factor), which neither fit alone is.
    fast, slow = _fit("a", 1.0, 0.5, 400.0, 2), _fit("a", 5.0, 2.5, 400.0, 2)
    measured = {"fast": 1.0 + 0.5 * 10, "slow": 5.0 + 2.5 * 10}
    c = plan.average_fits([fast, slow]).iloc[0]
    estimate = c.fixed_s + c.per_unit_s * 10
    for seconds in measured.values():
        assert 1 / 3 <= estimate / seconds <= 3
    assert measured["slow"] / measured["fast"] > 3
