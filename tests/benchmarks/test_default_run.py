"""benchmarks/default_run.py: a run's headline rows and targets, as the report shows them."""

import json
from pathlib import Path

import pandas as pd
import pytest

from neurender import methods

from . import scripts

default_run = scripts.load("default_run")


@pytest.fixture
def results(tmp_path):
    """NDR's metrics and targets of a run: NDR's DSSIM of I_R 0.03, one target met."""
    out = tmp_path / "results"
    (out / "ndr").mkdir(parents=True)
    metrics = pd.DataFrame(
        {
            "method": ["ndr", "ndr"],
            "dataset": ["complex", "complex"],
            "model": ["ndr", "shading_input"],
            "split": ["test", "test"],
            "metric": ["dssim_I_R", "dssim_I_R"],
            "value": [0.03, 0.05],
        }
    )
    metrics.to_csv(out / "ndr" / "metrics.csv", index=False)
    targets = pd.DataFrame(
        {
            "method": ["ndr"],
            "subject": ["ndr"],
            "check": ["below"],
            "measured": [0.6],
            "met": [True],
        }
    )
    targets.to_csv(out / "ndr" / "targets.csv", index=False)
    return out


def test_headlines_are_the_reports_rows_with_the_runs_values(results):
    headlines, targets = default_run.run_tables(default_run.report_tables(results, []), results)
    assert set(headlines.method) == {"ndr"}  # methods without tables are left out
    ndr = headlines.set_index("label")
    labels = list(methods.by_key("ndr").table("headlines").label)
    assert list(ndr.index) == labels
    assert ndr.loc["DSSIM of I_R: NDR", "ours"] == pytest.approx(0.03)
    assert ndr.loc["DSSIM of I_R: shading input", "ours"] == pytest.approx(0.05)
    assert ndr.loc["DSSIM of I_R: NDR", "paper"] > 0  # the paper's Table 1 value beside it
    assert targets.to_dict("records") == [
        {"method": "ndr", "subject": "ndr", "check": "below", "measured": 0.6, "met": True}
    ]


def test_main_writes_both_tables_and_the_sidecar(results, tmp_path):
    out = tmp_path / "run"
    default_run.main([str(results), str(out), "--command", "snakemake x", "--cores", "2"])
    assert len(pd.read_csv(f"{out}_headlines.csv")) == len(methods.by_key("ndr").table("headlines"))
    assert pd.read_csv(f"{out}_targets.csv").met.tolist() == [True]
    for table in ("metrics", "targets"):  # the report's tables, copied as they are
        copied = (out / "ndr" / f"{table}.csv").read_text()
        assert copied == (results / "ndr" / f"{table}.csv").read_text()
    sidecar = json.loads(Path(f"{out}.json").read_text())
    assert sidecar["command"] == "snakemake x" and sidecar["configfiles"] == ["config/config.yaml"]


def test_a_folder_without_tables_is_an_error_naming_it(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path)):
        results = tmp_path / "results"
        default_run.run_tables(default_run.report_tables(results, []), results)
