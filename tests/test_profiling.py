import pstats

import pytest
import torch
from torch.utils.data import TensorDataset

from neurender import profiling, train


def _fit_and_an_outside_backward(tmp_path):
    """A short fit, and one backward pass outside it (no part of its training steps)."""
    g = torch.Generator().manual_seed(0)
    x = torch.randn(64, 16, generator=g)
    y = x.sum(1, keepdim=True)
    model = torch.nn.Sequential(torch.nn.Linear(16, 64), torch.nn.ReLU(), torch.nn.Linear(64, 1))

    def loss_fn(model, batch):
        return torch.nn.functional.mse_loss(model(batch[0]), batch[1]), {}

    config = train.TrainConfig(
        epochs=2, batch_size=8, lr=1e-3, lr_schedule="constant", seed=1, device="cpu", threads=1
    )
    sets = TensorDataset(x[:48], y[:48]), TensorDataset(x[48:], y[48:])
    outputs = train.FitOutputs(tmp_path / "m.pt", tmp_path / "loss.csv")
    train.fit(model, train.FitData(*sets), loss_fn, config, outputs)
    big = torch.randn(256, 256, requires_grad=True)
    (big @ big).square().sum().backward()


def test_profile_file_is_the_logs_rule_and_job(tmp_path):
    path = profiling.profile_file("results/logs/ndr_train/ndr.log", tmp_path)
    assert path == tmp_path / "ndr_train" / "ndr.pstats"


def test_run_profiled_writes_nothing_without_the_variable(tmp_path, monkeypatch):
    monkeypatch.delenv(profiling.PROFILE_ENV, raising=False)
    calls = []
    profiling.run_profiled(lambda: calls.append(1), tmp_path / "logs" / "r" / "j.log")
    assert calls == [1]
    assert list(tmp_path.rglob("*.pstats")) == []


def test_run_profiled_keeps_the_profile_of_a_job_that_raises(tmp_path, monkeypatch):
    monkeypatch.setenv(profiling.PROFILE_ENV, str(tmp_path / "profiles"))

    def failing():
        raise ValueError("bad input")

    with pytest.raises(ValueError, match="bad input"):
        profiling.run_profiled(failing, tmp_path / "logs" / "rule" / "job.log")
    stats = pstats.Stats(str(tmp_path / "profiles" / "rule" / "job.pstats"))
    assert any(name == "failing" for _, _, name in stats.stats)  # type: ignore[attr-defined]
    assert [p.name for p in (tmp_path / "profiles" / "rule").iterdir()] == ["job.pstats"]


@pytest.fixture(scope="module")
def profiled_fit(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("profiled_fit")
    profile = tmp / "fit.pstats"
    import cProfile

    profiler = cProfile.Profile()
    profiler.runcall(_fit_and_an_outside_backward, tmp)
    profiler.dump_stats(str(profile))
    stats = pstats.Stats(str(profile))
    return stats, profiling.stage_seconds(stats).set_index("stage").seconds


def test_stage_seconds_training_steps_match_pstats_own_cumulative_time(profiled_fit):
    stats, seconds = profiled_fit
    profile = stats.get_stats_profile().func_profiles
    # pstats' own table rounds to the millisecond.
    ms = {"abs": 1e-3}
    assert seconds["training steps"] == pytest.approx(profile["train_epoch"].cumtime, **ms)
    assert seconds["validation"] == pytest.approx(profile["validate"].cumtime, **ms)
    total = profile["_fit_and_an_outside_backward"].cumtime
    assert seconds["total"] == pytest.approx(total, **ms)


def test_stage_seconds_parts_of_the_training_steps_sum_to_them(profiled_fit):
    _, seconds = profiled_fit
    parts = ["backward", "optimiser step", "batches", "forward and loss"]
    assert all(seconds[p] > 0 for p in parts)
    assert sum(seconds[p] for p in parts) == pytest.approx(seconds["training steps"])


def test_stage_seconds_count_a_backward_outside_training_in_no_part_of_it(profiled_fit):
    stats, seconds = profiled_fit
    every_backward = stats.get_stats_profile().func_profiles["backward"].cumtime
    # The outside pass (a 256 x 256 matrix product's) is counted in "other", not "backward".
    assert seconds["backward"] < every_backward
    assert seconds["other"] >= every_backward - seconds["backward"] - 1e-9


def test_stage_seconds_top_level_stages_and_other_sum_to_the_total(profiled_fit):
    _, seconds = profiled_fit
    top = profiling.STAGES.loc[profiling.STAGES.part_of == "", "stage"].unique()
    assert sum(seconds[s] for s in top) + seconds["other"] == pytest.approx(seconds["total"])
