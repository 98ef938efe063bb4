import json
import logging
import sys

import pytest
import torch
from torch.utils.data import TensorDataset

from neurender import tensorboard_log, train


def _problem():
    """Images in [0, 1]: the target is a fixed per-channel mix of the input."""
    g = torch.Generator().manual_seed(0)
    x = torch.rand(12, 3, 8, 8, generator=g)
    y = 0.5 * x.flip(1) + 0.25
    return TensorDataset(x[:8], y[:8]), TensorDataset(x[8:], y[8:])


def _model():
    torch.manual_seed(0)
    return torch.nn.Sequential(torch.nn.Conv2d(3, 3, 1), torch.nn.Dropout(0.1))


def _loss(model, batch):
    x, y = batch
    return torch.nn.functional.l1_loss(model(x), y), {}


def _images(model, batch):
    x, y = batch
    return model(x), y


PREVIEWS = tensorboard_log.Previews(_images, tensorboard_log.ssim_metric, count=3)


def _cfg(epochs=4):
    return train.TrainConfig(
        epochs=epochs, batch_size=4, lr=0.05, lr_schedule="cosine", seed=3, device="cpu", threads=1
    )


def _fit(tmp_path, name, epochs=4, loss=_loss, previews=PREVIEWS):
    train_set, val_set = _problem()
    marker = tmp_path / "tensorboard" / name / tensorboard_log.MARKER
    history = train.fit(
        _model(),
        train.FitData(train_set, val_set),
        loss,
        _cfg(epochs),
        train.FitOutputs(
            tmp_path / f"{name}.pt", tmp_path / f"{name}.csv", tensorboard=marker, previews=previews
        ),
    )
    return history, marker


def _events(folder):
    """TensorBoard's own reader of ``folder`` (a hard dependency: its absence fails)."""
    from tensorboard.backend.event_processing import event_accumulator as reader

    acc = reader.EventAccumulator(str(folder), size_guidance={"scalars": 0, "images": 0})
    acc.Reload()
    return acc


def test_event_files_hold_every_scalar_and_preview_of_every_epoch(tmp_path):
    history, marker = _fit(tmp_path, "net")
    acc = _events(marker.parent)
    tags = set(acc.Tags()["scalars"])
    assert tags == {"train/loss", "val/loss", "lr", "seconds_per_epoch", "previews/ssim"}
    for tag in tags:
        assert [e.step for e in acc.Scalars(tag)] == [1, 2, 3, 4], tag
    val = history[(history.split == "val") & (history.metric == "loss")].value.tolist()
    assert [e.value for e in acc.Scalars("val/loss")] == pytest.approx(val)
    # The cosine schedule's learning rate at each epoch's end falls from below the start.
    lr = [e.value for e in acc.Scalars("lr")]
    assert lr[0] < 0.05 and all(a > b for a, b in zip(lr, lr[1:], strict=False))
    shown = {f"previews/{k}" for k in ("prediction", "reference", "error")}
    assert set(acc.Tags()["images"]) == shown
    assert [e.step for e in acc.Images("previews/error")] == [1, 2, 3, 4]
    summary = json.loads(marker.read_text())
    assert summary["tensorboard"] and summary["steps_this_process"] == [1, 2, 3, 4]


def test_the_preview_metric_is_the_ssim_of_the_last_epochs_previews(tmp_path):
    _, marker = _fit(tmp_path, "net")
    model = _model()
    model.load_state_dict(train.load_checkpoint(tmp_path / "net.pt")["last_model"])
    model.eval()
    _, val_set = _problem()
    x, y = val_set[:3]
    with torch.no_grad():
        expected = tensorboard_log.ssim_metric(model(x).clamp(0, 1), y)["ssim"]
    last = _events(marker.parent).Scalars("previews/ssim")[-1].value
    assert last == pytest.approx(expected, rel=1e-5)


def _interrupt_resume_save(monkeypatch, after: int):
    """Make the ``after + 1``-th resume save raise: that epoch's events are written, its
    resume file is not (the worst moment to be interrupted)."""
    real, calls = train._atomic_torch_save, {"n": 0}

    def save(obj, path):
        calls["n"] += 1
        if path.suffix == ".resume" and calls["n"] > after:
            raise KeyboardInterrupt
        real(obj, path)

    monkeypatch.setattr(train, "_atomic_torch_save", save)


def test_a_resumed_run_has_one_value_per_step_of_every_scalar(tmp_path, monkeypatch):
    full_history, _ = _fit(tmp_path, "full")
    with monkeypatch.context() as m:
        _interrupt_resume_save(m, after=2)  # epochs 1-3 logged, resume file after epoch 2
        with pytest.raises(KeyboardInterrupt):
            _fit(tmp_path, "run")
    marker = tmp_path / "tensorboard/run" / tensorboard_log.MARKER
    assert not marker.exists()
    before = _events(marker.parent)
    assert [e.step for e in before.Scalars("val/loss")] == [1, 2, 3]
    _fit(tmp_path, "run")
    assert len(list(marker.parent.glob("events.out.tfevents.*"))) == 2
    acc = _events(marker.parent)
    for tag in acc.Tags()["scalars"]:
        assert [e.step for e in acc.Scalars(tag)] == [1, 2, 3, 4], tag
    for tag in acc.Tags()["images"]:
        assert [e.step for e in acc.Images(tag)] == [1, 2, 3, 4], tag
    full = full_history[full_history.metric == "loss"]
    val = full[full.split == "val"].value.tolist()
    assert [e.value for e in acc.Scalars("val/loss")] == pytest.approx(val)
    assert json.loads(marker.read_text())["steps_this_process"] == [3, 4]


def test_a_fresh_run_replaces_an_earlier_runs_event_files(tmp_path):
    _, marker = _fit(tmp_path, "net", epochs=4)
    _fit(tmp_path, "net", epochs=2)  # retrained from scratch (its checkpoint is final)
    assert len(list(marker.parent.glob("events.out.tfevents.*"))) == 1
    assert [e.step for e in _events(marker.parent).Scalars("train/loss")] == [1, 2]


def test_logging_does_not_change_training(tmp_path):
    train_set, val_set = _problem()
    plain = _model()
    outputs = train.FitOutputs(tmp_path / "a.pt", tmp_path / "a.csv")
    train.fit(plain, train.FitData(train_set, val_set), _loss, _cfg(), outputs)
    _fit(tmp_path, "b")
    a = train.load_checkpoint(tmp_path / "a.pt")["last_model"]
    b = train.load_checkpoint(tmp_path / "b.pt")["last_model"]
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=0, atol=0)


def test_training_without_tensorboard_warns_once_and_writes_the_marker(
    tmp_path, monkeypatch, caplog
):
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)  # import fails
    monkeypatch.setattr(tensorboard_log, "_warned_missing", False)
    with caplog.at_level(logging.WARNING, logger="neurender.tensorboard_log"):
        _, marker = _fit(tmp_path, "a", epochs=2)
        _fit(tmp_path, "b", epochs=2)
    assert caplog.text.count("no TensorBoard event files") == 1
    assert json.loads(marker.read_text())["tensorboard"] is False
    assert not list(marker.parent.glob("events.out.tfevents.*"))
    assert train.epochs_trained(tmp_path / "a.pt") == 2


@pytest.mark.parametrize(
    ("key", "tag"),
    [("train_loss", "train/loss"), ("val_dssim_I_R", "val/dssim_I_R"), ("lr", "lr")],
)
def test_scalar_tags_split_the_history_key_at_its_first_underscore(key, tag):
    assert tensorboard_log.scalar_tag(key) == tag


def test_previews_are_shrunk_to_the_preview_size_keeping_their_aspect():
    big = torch.rand(2, 3, 256, 64) * 3 - 1
    small = tensorboard_log._shrink(big, 128)
    assert small.shape == (2, 3, 128, 32)
    assert small.min() >= 0 and small.max() <= 1
    assert tensorboard_log._shrink(small, 128).shape == small.shape


def test_image_metrics_of_equal_images_are_perfect():
    a = torch.rand(2, 3, 16, 16)
    assert tensorboard_log.ssim_metric(a, a)["ssim"] == pytest.approx(1.0)
    assert tensorboard_log.dssim_metric(a, a)["dssim"] == pytest.approx(0.0, abs=1e-6)
    assert tensorboard_log.dssim_metric(a, 1 - a)["dssim"] > 0.1
