"""Merging DeepPRT model-stage runs (benchmarks/prt_correction_runs.py)."""

from pathlib import Path

import pandas as pd
import pytest

from neurender import io

from . import scripts

runs_script = scripts.load("prt_correction_runs")


def _results(folder: Path, offset: float) -> Path:
    """A results folder with one shipped test score, one paper-form score (not merged) and
    one unseen row, their values shifted by ``offset``."""
    metrics = pd.DataFrame(
        {
            "dataset": ["head", "head"],
            "model": ["DeepPRT shadowing", "DeepPRT"],
            "split": ["test", "test"],
            "metric": ["ssim_diffuse", "ssim_diffuse"],
            "value": [0.9 + offset, 0.8],
        }
    )
    unseen = pd.DataFrame(
        {
            "method": ["prt"],
            "dataset": ["head"],
            "model": ["static"],
            "split": ["unseen"],
            "family": ["bend"],
            "strength": [0.5],
            "metric": ["rel_l1_radiance_diffuse"],
            "value": [0.01 + offset],
        }
    )
    io.write_csv(folder / "prt" / "metrics.csv", metrics)
    io.write_csv(folder / "prt" / "unseen.csv", unseen)
    return folder


def test_each_runs_shipped_and_unseen_rows_are_named_in_the_given_column(tmp_path):
    runs = {"5": _results(tmp_path / "a", 0.0), "2": _results(tmp_path / "b", 0.05)}
    table = runs_script.merged(runs, column="batch")
    assert list(table.columns[:2]) == ["batch", "dataset"]
    assert "correction" not in table.columns
    assert set(table.model) == {"DeepPRT shadowing", "static"}  # the paper form's row left out
    by_run = table.set_index(["batch", "model"]).value
    assert by_run["5", "DeepPRT shadowing"] == 0.9
    assert by_run["2", "static"] == pytest.approx(0.06)
