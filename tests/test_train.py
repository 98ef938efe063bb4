import pickle
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from torch.utils.data import TensorDataset

from neurender import devices, train


def _problem():
    g = torch.Generator().manual_seed(0)
    x = torch.randn(40, 3, generator=g)
    y = x @ torch.tensor([[1.0], [-2.0], [0.5]]) + 0.3
    return TensorDataset(x[:32], y[:32]), TensorDataset(x[32:], y[32:])


def _model():
    torch.manual_seed(0)
    return torch.nn.Sequential(torch.nn.Linear(3, 8), torch.nn.Dropout(0.1), torch.nn.Linear(8, 1))


def _loss(model, batch):
    x, y = batch
    loss = torch.nn.functional.mse_loss(model(x), y)
    return loss, {"mae": float((model(x) - y).detach().abs().mean())}


def _data(key=""):
    return train.FitData(*_problem(), key)


def _outputs(tmp_path, name, **kwargs):
    """The checkpoint ``{name}.pt`` and loss log ``{name}.csv`` in ``tmp_path``."""
    return train.FitOutputs(tmp_path / f"{name}.pt", tmp_path / f"{name}.csv", **kwargs)


def _cfg(epochs, device="cpu", seed=3):
    return train.TrainConfig(
        epochs=epochs,
        batch_size=8,
        lr=0.05,
        lr_schedule="cosine",
        seed=seed,
        device=device,
        threads=1,
    )


def test_training_reduces_loss_and_writes_tidy_log(tmp_path):
    hist = train.fit(_model(), _data(), _loss, _cfg(8), _outputs(tmp_path, "m"))
    log = pd.read_csv(tmp_path / "m.csv")
    assert list(log.columns) == ["epoch", "split", "metric", "value"]
    val = hist[(hist.split == "val") & (hist.metric == "loss")].value.to_numpy()
    assert val[-1] < 0.2 * val[0]
    ckpt = train.load_checkpoint(tmp_path / "m.pt")
    assert ckpt["best_val"] == pytest.approx(val.min())
    assert not train.resume_path_for(tmp_path / "m.pt").exists()


def test_resume_after_interruption_is_identical(tmp_path):
    train.fit(_model(), _data(), _loss, _cfg(4), _outputs(tmp_path, "full"))
    resume = _interrupted_run(tmp_path, _cfg(4), epochs_done=2)
    assert torch.load(resume, weights_only=True)["epoch"] == 2  # tensors and plain types only
    train.fit(_model(), _data(), _loss, _cfg(4), _outputs(tmp_path, "r"))
    a = torch.load(tmp_path / "full.pt", weights_only=True)
    b = torch.load(tmp_path / "r.pt", weights_only=True)
    for k in a["last_model"]:
        torch.testing.assert_close(a["last_model"][k], b["last_model"][k])
    assert [h["epoch"] for h in b["history"]] == [1, 2, 3, 4]


def test_nan_loss_raises_clear_error(tmp_path):
    def nan_loss(model, batch):
        x, y = batch
        return (model(x) * float("nan")).mean(), {}

    with pytest.raises(FloatingPointError, match="epoch 1, step 1"):
        train.fit(_model(), _data(), nan_loss, _cfg(1), _outputs(tmp_path, "m"))
    assert not (tmp_path / "m.pt").exists()


def test_resolve_device_and_config_errors():
    assert devices.resolve_device("auto", 2).type in ("cpu", "cuda")
    if not torch.cuda.is_available():
        with pytest.raises(RuntimeError, match="CUDA is not available"):
            devices.resolve_device("cuda")
    with pytest.raises(KeyError, match="unknown training keys \\['epochz'\\]"):
        train.TrainConfig.from_dict({"epochz": 3})


def test_adversary_is_trained_after_each_step_and_saved(tmp_path):
    critic = torch.nn.Linear(1, 1)
    before = critic.weight.detach().clone()
    seen = {"aux": 0}

    def gen_loss(model, batch):
        x, y = batch
        fake = model(x)
        # the model is also pushed by the critic (its gradient must not update the critic)
        return torch.nn.functional.mse_loss(fake, y) + 0.01 * critic(fake).mean(), {}, fake.detach()

    def critic_loss(module, batch, fake):
        seen["aux"] += 1
        _, y = batch
        return module(fake).mean() - module(y).mean(), {"gap": 0.0}

    adv = train.Adversary(critic, critic_loss)
    train.fit(_model(), _data(), gen_loss, _cfg(2), _outputs(tmp_path, "g"), adv)
    assert seen["aux"] == 2 * 4  # one adversary step per model step
    assert not torch.equal(before, critic.weight.detach())
    ckpt = train.load_checkpoint(tmp_path / "g.pt")
    torch.testing.assert_close(ckpt["adversary"]["weight"], critic.weight.detach())
    assert "adversary_loss" in set(pd.read_csv(tmp_path / "g.csv").metric)


def test_train_config_from_stage_picks_training_keys():
    cfg = {"epochs": 3, "lr": 0.01, "widths": [8], "seed": 4, "device": "cpu", "threads": 9}
    cfg |= {"batch_size": 2, "lr_schedule": "constant"}
    c = train.TrainConfig.from_stage(cfg, threads=2, betas=(0.5, 0.999))
    assert (c.epochs, c.lr, c.seed, c.threads, c.betas) == (3, 0.01, 4, 2, (0.5, 0.999))


def test_a_training_key_missing_from_the_stage_is_named_not_defaulted():
    """The schema holds the defaults: a stage's params without one of its keys fail."""
    cfg = {"epochs": 3, "lr": 0.01, "seed": 4, "device": "cpu", "lr_schedule": "cosine"}
    with pytest.raises(KeyError, match=r"\['batch_size'\] missing"):
        train.TrainConfig.from_stage(cfg, threads=1)


def _interrupted_run(tmp_path, cfg, data_key="", epochs_done=1):
    """A run stopped by an exception after ``epochs_done`` epochs: its resume file stays."""
    calls = {"n": 0}

    def interrupting_loss(model, batch):
        calls["n"] += 1
        if calls["n"] > epochs_done * (4 + 1):  # 4 train steps + 1 val batch per epoch
            raise KeyboardInterrupt
        return _loss(model, batch)

    with pytest.raises(KeyboardInterrupt):
        train.fit(_model(), _data(data_key), interrupting_loss, cfg, _outputs(tmp_path, "r"))
    return train.resume_path_for(tmp_path / "r.pt")


@pytest.mark.parametrize(
    "change",
    [
        {"data_key": "other data"},
        {"config": {"lr": 0.01}},
        {"model": torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.Linear(4, 1))},
    ],
    ids=["data", "config", "architecture"],
)
def test_a_stale_resume_file_is_discarded_with_a_log_line(tmp_path, caplog, change):
    resume = _interrupted_run(tmp_path, _cfg(3), data_key="data v1")
    assert resume.exists()
    cfg = train.TrainConfig(**{**vars(_cfg(3)), **change.get("config", {})})
    model, data = change.get("model", _model()), _data(change.get("data_key", "data v1"))
    with caplog.at_level("WARNING", logger="neurender.train"):
        train.fit(model, data, _loss, cfg, _outputs(tmp_path, "r"))
    assert "discarding stale resume file" in caplog.text and str(resume) in caplog.text
    history = train.load_checkpoint(tmp_path / "r.pt")["history"]
    assert [h["epoch"] for h in history] == [1, 2, 3]  # trained from scratch


def test_a_matching_resume_file_is_continued(tmp_path, caplog):
    _interrupted_run(tmp_path, _cfg(3), data_key="data v1")
    with caplog.at_level("INFO", logger="neurender.train"):
        train.fit(_model(), _data("data v1"), _loss, _cfg(3), _outputs(tmp_path, "r"))
    assert "resuming from" in caplog.text and "after epoch 1" in caplog.text


def test_nan_validation_loss_stops_training_naming_epoch_and_batch(tmp_path):
    def nan_in_eval(model, batch):
        loss, logs = _loss(model, batch)
        return (loss * float("nan") if not model.training else loss), logs

    with pytest.raises(FloatingPointError, match="validation loss became nan at epoch 1, batch 1"):
        train.fit(_model(), _data(), nan_in_eval, _cfg(2), _outputs(tmp_path, "m"))
    assert not (tmp_path / "m.pt").exists()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_resume_on_cuda_restores_the_cuda_rng(tmp_path):
    cfg = _cfg(3, device="cuda")
    train.fit(_model(), _data(), _loss, cfg, _outputs(tmp_path, "full"))
    _interrupted_run(tmp_path, cfg)
    train.fit(_model(), _data(), _loss, cfg, _outputs(tmp_path, "r"))
    a = train.load_checkpoint(tmp_path / "full.pt")["last_model"]
    b = train.load_checkpoint(tmp_path / "r.pt")["last_model"]
    for k in a:  # dropout draws from the CUDA generator: equal only if it was restored
        torch.testing.assert_close(a[k], b[k])


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_two_cuda_runs_with_one_seed_are_identical(tmp_path):
    cfg = _cfg(2, device="cuda", seed=5)
    runs = []
    for name in ("a", "b"):
        train.fit(_model(), _data(), _loss, cfg, _outputs(tmp_path, name))
        runs.append(train.load_checkpoint(tmp_path / f"{name}.pt")["last_model"])
    for k in runs[0]:
        torch.testing.assert_close(runs[0][k], runs[1][k], rtol=0, atol=0)


class _RunsCode:
    """Unpickling this writes ``marker``: what a hostile checkpoint would do."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('ran')",)


def test_the_hostile_payload_runs_when_unpickled(tmp_path):
    """The payload of the two tests below is live: plain unpickling runs it."""
    pickle.loads(pickle.dumps(_RunsCode(tmp_path / "ran")))
    assert (tmp_path / "ran").read_text() == "ran"


def test_a_checkpoint_holding_a_pickled_object_is_refused_naming_the_file(tmp_path):
    path, marker = tmp_path / "foreign.pt", tmp_path / "ran"
    torch.save({"model": {"w": torch.zeros(2)}, "extra": {"x": _RunsCode(marker)}}, path)
    with pytest.raises(OSError, match=f"refusing to load checkpoint {path}: it holds objects"):
        train.load_checkpoint(path)
    assert not marker.exists()  # the code did not run


def test_a_resume_file_holding_a_pickled_object_is_discarded_unrun(tmp_path, caplog):
    resume, marker = train.resume_path_for(tmp_path / "r.pt"), tmp_path / "ran"
    torch.save({"key": "k", "epoch": 2, "history": [_RunsCode(marker)]}, resume)
    with caplog.at_level("WARNING", logger="neurender.train"):
        train.fit(_model(), _data(), _loss, _cfg(2), _outputs(tmp_path, "r"))
    assert not marker.exists()
    assert f"discarding unreadable resume file {resume}" in caplog.text
    assert "objects other than tensors and plain types" in caplog.text
    history = train.load_checkpoint(tmp_path / "r.pt")["history"]
    assert [h["epoch"] for h in history] == [1, 2]  # trained from scratch


@pytest.mark.parametrize(
    ("value", "where"),
    [
        ({"offset": np.zeros(3, np.float32)}, r"\['norm'\]\['offset'\] is a numpy.ndarray"),
        ([4, np.float64(0.5)], r"\['norm'\]\[1\] is a numpy.float64"),  # a float subclass
        ({3.5: 1}, r"\['norm'\] has a key 3.5 of type float"),
    ],
    ids=["array", "numpy scalar", "float key"],
)
def test_extra_other_than_tensors_and_plain_types_fails_before_training(tmp_path, value, where):
    extra = {"norm": value, "widths": [4, 8]}
    with pytest.raises(TypeError, match=r"FitOutputs\(checkpoint='.*m.pt'\).extra" + where):
        train.fit(_model(), _data(), _loss, _cfg(1), _outputs(tmp_path, "m", extra=extra))
    assert list(tmp_path.iterdir()) == []


def test_a_checkpoint_with_tensors_and_plain_types_loads_with_weights_only(tmp_path):
    extra = {"offset": torch.arange(3.0), "widths": [4, 8], "name": "a", "betas": (0.5, 0.9)}
    train.fit(_model(), _data(), _loss, _cfg(1), _outputs(tmp_path, "m", extra=extra))
    ckpt = torch.load(tmp_path / "m.pt", weights_only=True)
    assert ckpt["extra"]["widths"] == [4, 8] and ckpt["extra"]["betas"] == (0.5, 0.9)
    torch.testing.assert_close(ckpt["extra"]["offset"], torch.arange(3.0))
    assert ckpt["config"]["betas"] == (0.9, 0.999) and ckpt["config"]["seed"] == 3


_VALID = {
    train.FitData: {"train": TensorDataset(torch.zeros(4, 3)), "val": None, "key": ""},
    train.FitOutputs: {"checkpoint": "m.pt", "log": "m.csv", "extra": {}, "tensorboard": None},
}


@pytest.mark.parametrize(
    ("cls", "field", "value", "expected"),
    [
        (train.FitData, "train", object(), "a map-style dataset"),
        (train.FitData, "val", 3, "a map-style dataset"),
        (train.FitData, "key", None, "a str"),
        (train.FitOutputs, "checkpoint", None, "a str or Path"),
        (train.FitOutputs, "log", 3, "a str or Path"),
        (train.FitOutputs, "tensorboard", ["tb"], "a str or Path"),
        (train.FitOutputs, "extra", [("a", 1)], "a mapping"),
        (train.FitOutputs, "previews", _loss, "Previews"),
    ],
)
def test_a_field_of_the_wrong_type_is_named_with_what_was_expected(cls, field, value, expected):
    message = f"{cls.__name__}.{field} is a {type(value).__name__}; expected {expected}"
    with pytest.raises(TypeError, match=f"^{re.escape(message)}$"):
        cls(**_VALID[cls] | {field: value})


def test_an_empty_training_set_is_refused():
    with pytest.raises(ValueError, match="^FitData.train is empty; expected at least one sample$"):
        train.FitData(TensorDataset(torch.zeros(0, 3)), None)


def test_fit_outputs_keep_paths_as_path_and_a_copy_of_extra(tmp_path):
    extra = {"widths": [4, 8]}
    outputs = train.FitOutputs(
        str(tmp_path / "m.pt"), str(tmp_path / "m.csv"), extra, "tb/run.json"
    )
    extra["widths"] = [16]  # the caller's dict changing later does not change the checkpoint
    assert outputs.checkpoint == tmp_path / "m.pt" and outputs.tensorboard == Path("tb/run.json")
    assert isinstance(outputs.log, Path) and outputs.extra == {"widths": [4, 8]}


def test_an_unchanged_run_keeps_its_resume_key():
    """A resume file written by an earlier version is continued only while the key of the
    same config, architecture and data stays what it was (this one: d4ed726's)."""
    key = train.resume_key(_cfg(3), _model(), "data v1")
    assert key == "5a5b156482d0d822add2e1f132670e00ccc117313b469fc11687755ad6780b79"
