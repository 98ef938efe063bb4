"""benchmarks/run_profile.py: jobs' figures read from Snakemake's benchmark files, the
whole run's from /usr/bin/time -v, summed by stage."""

import json
from pathlib import Path

import pandas as pd
import pytest

from . import scripts

profile = scripts.load("run_profile")

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
TIME_REPORT = """\tCommand being timed: "snakemake --cores 2 results/report.html"
\tUser time (seconds): 5400.50
\tSystem time (seconds): 599.50
\tPercent of CPU this job got: 180%
\tElapsed (wall clock) time (h:mm:ss or m:ss): 1:02:03.60
\tMaximum resident set size (kbytes): 3276800
"""


def _benchmark(results: Path, rule: str, job: str, wall: float, cpu: float, rss: float):
    path = results / "benchmarks" / rule / f"{job}.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{wall}\t0:00:01\t{rss}\t0\t0\t0\t0\t0\t90\t{cpu}\n")


@pytest.fixture
def results(tmp_path):
    out = tmp_path / "results"
    _benchmark(out, "prt_train", "head/shadowing_diffuse", 120.0, 115.0, 900.0)
    _benchmark(out, "prt_train", "head/paper_glossy", 60.0, 58.0, 1100.0)
    _benchmark(out, "report", "report", 30.0, 20.0, 400.0)
    return out


def test_every_job_gives_its_wall_cpu_and_memory_under_its_rule_and_stage(results):
    rows = profile.job_rows(results)
    assert len(rows) == 3 * 3
    wide = rows.pivot_table(index=["rule", "job"], columns="metric", values="value")
    assert wide.loc[("prt_train", "head/shadowing_diffuse")].to_dict() == {
        "cpu_s": 115.0,
        "max_rss_mb": 900.0,
        "wall_s": 120.0,
    }
    stages = dict(zip(rows.rule, rows.stage, strict=False))
    assert stages["report"] != stages["prt_train"]


def test_stages_sum_their_jobs_minutes_and_keep_the_largest_memory(results):
    table = profile.by_stage(profile.job_rows(results))
    train = table.loc[profile.methods.rule("prt_train").stage]
    assert train.jobs == 2
    assert train.wall_min == pytest.approx(3.0) and train.cpu_min == pytest.approx(173 / 60)
    assert train.max_rss_mb == 1100.0
    assert table.index[0] == profile.methods.rule("prt_train").stage  # the largest first


def test_the_whole_run_is_read_from_the_time_report():
    run = profile.whole_run(TIME_REPORT)
    assert run["wall_min"] == pytest.approx((3600 + 2 * 60 + 3.6) / 60)
    assert run["cpu_min"] == pytest.approx(100.0)
    assert run["max_rss_mb"] == pytest.approx(3200.0)
    assert profile.seconds("4:05.5") == pytest.approx(245.5)


def test_a_time_report_without_a_line_names_it():
    with pytest.raises(ValueError, match="Maximum resident set size"):
        profile.whole_run(TIME_REPORT.replace("Maximum resident", "Peak"))


def test_main_writes_the_tidy_csv_and_the_sidecar(results, tmp_path):
    (tmp_path / "run.time").write_text(TIME_REPORT)
    out = tmp_path / "profile"
    profile.main([str(results), str(out), "--time", str(tmp_path / "run.time"), "--cores", "2"])
    rows = pd.read_csv(f"{out}.csv")
    assert list(rows.columns) == ["rule", "stage", "job", "metric", "value"]
    stages = pd.read_csv(f"{out}_stages.csv").set_index("stage")
    assert stages.loc[profile.methods.rule("prt_train").stage, "jobs"] == 2
    assert stages["wall_min"].sum() == pytest.approx(210 / 60)
    sidecar = json.loads(Path(f"{out}.json").read_text())
    assert sidecar["whole_run"]["cpu_min"] == pytest.approx(100.0)
    assert sidecar["machine"]["snakemake_cores"] == 2


def test_no_benchmark_files_is_an_error_naming_the_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "benchmarks")):
        profile.job_rows(tmp_path)


def test_the_ndr_stage_is_the_sum_of_every_ndr_jobs_minutes(tmp_path):
    """NDR's stage time, no target of its own (``results/ndr/targets.csv`` reads only
    results), is this profile's: every NDR rule's jobs under the stage ``NDR``."""
    from neurender.ndr.method import METHOD, STAGE

    out = tmp_path / "results"
    for rule in METHOD.rules:
        _benchmark(out, rule, rule, 90.0, 60.0, 500.0)
    _benchmark(out, "ndr_train", "pix2pix", 90.0, 60.0, 700.0)
    table = profile.by_stage(profile.job_rows(out))
    assert list(table.index) == [STAGE]
    ndr = table.loc[STAGE]
    assert ndr.jobs == len(METHOD.rules) + 1
    assert ndr.wall_min == pytest.approx(1.5 * (len(METHOD.rules) + 1))
    assert ndr.cpu_min == pytest.approx(len(METHOD.rules) + 1)
    assert ndr.max_rss_mb == 700.0
