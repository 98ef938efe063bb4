import os
import signal

import pytest

from neurender.ndr import pool


def _square(mi, k):
    return mi, k * k


def _fails(mi, k):
    if k == 2:
        raise ValueError(f"boom in sample {k}")
    return k


def _dies(mi, k):
    if k == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return k


@pytest.fixture
def fake_mitsuba(monkeypatch):
    """Workers that skip Mitsuba: ``mi`` is a string, as a forked child sees it too."""

    def init(device, threads):
        pool._WORKER.clear()
        pool._WORKER["mi"] = f"mi on {device}"

    monkeypatch.setattr(pool, "_init_worker", init)


@pytest.mark.parametrize("workers", [1, 2])
def test_results_come_back_in_order(fake_mitsuba, workers):
    results = pool.render_all(_square, [(k,) for k in range(9)], "cpu", workers, "squares")
    assert results == [("mi on cpu", k * k) for k in range(9)]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_task_reports_its_own_error(fake_mitsuba, workers):
    with pytest.raises(SystemExit) as err:
        pool.render_all(_fails, [(k,) for k in range(6)], "cpu", workers, "ndr test")
    message = str(err.value.code)
    assert message.startswith("error: ndr test: task 2 (_fails) failed")
    assert "ValueError: boom in sample 2" in message and "Traceback" in message
    assert "Mitsuba" not in message


def test_a_dead_worker_reports_how_it_died(fake_mitsuba):
    with pytest.raises(SystemExit) as err:
        pool.render_all(_dies, [(k,) for k in range(4)], "cpu", 2, "ndr train")
    message = str(err.value.code)
    assert message.startswith("error: ndr train: a rendering process died")
    assert "SIGKILL" in message


def test_a_setup_failure_reports_its_cause():
    """The real ``_init_worker`` with a device Mitsuba does not know."""
    with pytest.raises(SystemExit) as err:
        pool.render_all(_square, [(0,)], "tpu", 1, "ndr val")
    message = str(err.value.code)
    assert "task 0: setting up Mitsuba failed" in message
    assert "device 'tpu'" in message
