"""The learning-curve study's budgets (benchmarks/prt_generalisation.py --study)."""

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from neurender.prt import frames

from . import scripts

ROOT = Path(__file__).resolve().parents[2]
study_script = scripts.load("prt_generalisation")


def _steps(run, batch_size):
    return run.epochs * math.ceil(run.train_frames / batch_size)


# The paper form's batch_size and the shadowing variant's shadowing_batch_size (schema
# defaults), each model's sweep at its own.
@pytest.mark.parametrize("batch_size", [5, 2])
def test_the_shapes_sweep_trains_every_count_for_the_same_optimiser_steps(batch_size):
    study = yaml.safe_load((ROOT / "config/studies/deepprt.yaml").read_text())
    runs = study_script.study_runs(study, study["models"])
    base = study["equal_steps"]
    steps = base["epochs"] * math.ceil(base["frames"] / batch_size)
    for n in study["train_frames"]:
        for model in study["models"]:
            matching = [r for r in runs if r.model == model and r.train_frames == n]
            assert [_steps(r, batch_size) for r in matching].count(steps) == 1, (model, n)
    for e in study["epochs"]:
        for model in study["models"]:
            assert study_script.Run(model, e, base["frames"]) in runs
    assert len(runs) == len(set(runs))  # the run in both sweeps is trained once


def test_a_subset_is_evenly_spaced_over_the_whole_split_and_refuses_too_many():
    count = 12
    split = frames.Split(*(np.arange(count, dtype=np.float32).reshape(count, 1) for _ in range(5)))
    sub = study_script.subset(split, 4)
    assert sub.positions[:, 0].tolist() == [0, 4, 7, 11]  # first and last kept
    assert study_script.subset(split, count).positions[:, 0].tolist() == list(range(count))
    with pytest.raises(ValueError, match="13 training frames: the split has 12"):
        study_script.subset(split, 13)
