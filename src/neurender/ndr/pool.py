"""Rendering many samples with Mitsuba, in forked worker processes or in this one.

A failure ends the job with its real cause, as one ``SystemExit`` message:

* a task (or a worker's Mitsuba setup) that raises: the task's number and the worker's
  traceback text, caught in the worker (so an exception that cannot be pickled, or one
  raised while the worker starts, still arrives);
* a worker process that dies (a crash in native code, a kill by the memory limit): its
  exit code or the signal that ended it.
"""

from __future__ import annotations

import signal
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from typing import Any

import torch
from tqdm import tqdm

#: Chunk of tasks one worker takes at a time.
CHUNK = 4

_WORKER: dict[str, Any] = {}


class TaskFailed(RuntimeError):
    """A task raised; the message holds the worker's traceback text (always picklable)."""


def _init_worker(device: str, threads: int) -> None:
    """Set up Mitsuba in this process; an error is kept and reported by the first task."""
    _WORKER.clear()
    try:
        from neurender.mitsuba_setup import require_mitsuba

        mi, dr = require_mitsuba(device)
        dr.set_thread_count(threads)
        torch.set_num_threads(threads)
        _WORKER["mi"] = mi
    except (Exception, SystemExit):
        _WORKER["error"] = traceback.format_exc()


def _call(job: tuple[Callable, int, tuple]) -> Any:
    fn, number, task = job
    if "error" in _WORKER:
        raise TaskFailed(f"task {number}: setting up Mitsuba failed:\n{_WORKER['error']}")
    try:
        return fn(_WORKER["mi"], *task)
    except (Exception, SystemExit):
        trace = traceback.format_exc()
        raise TaskFailed(f"task {number} ({fn.__name__}) failed:\n{trace}") from None


def _describe_exit(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        return f"killed by signal {signal.Signals(-code).name}"
    return f"exit code {code}"


def _deaths(processes: dict) -> str:
    """The exit of the workers that died, not of those the pool then terminated."""
    codes = [p.exitcode for p in processes.values()]
    died = [c for c in codes if c not in (0, -signal.SIGTERM)] or codes
    return ", ".join(_describe_exit(c) for c in died) or "no exit code recorded"


def render_all(
    fn: Callable[..., Any], tasks: Sequence[tuple], device: str, workers: int, desc: str
) -> list[Any]:
    """``[fn(mi, *task) for task in tasks]`` with Mitsuba's module ``mi`` on ``device``, in
    ``workers`` forked single-threaded processes (``1``: in this process), in order.

    Raises:
        SystemExit: naming ``desc``, with the failed task's traceback or the exit code of
            the worker that died.
    """
    jobs = [(fn, k, task) for k, task in enumerate(tasks)]
    executor, processes = None, {}
    if workers > 1:
        executor = ProcessPoolExecutor(
            workers, mp_context=get_context("fork"), initializer=_init_worker, initargs=(device, 1)
        )
        # Private, but the only record of a dead worker's exit code (kept by reference: the
        # executor forgets it on shutdown).
        processes = getattr(executor, "_processes", {})
        results = executor.map(_call, jobs, chunksize=CHUNK)
    else:
        _init_worker(device, 1)
        results = map(_call, jobs)
    try:
        return list(tqdm(results, total=len(jobs), desc=desc, mininterval=5))
    except TaskFailed as err:
        raise SystemExit(f"error: {desc}: {err}") from None
    except BrokenProcessPool as err:
        executor.shutdown(wait=True)
        cause = f"\n{err.__cause__}" if err.__cause__ is not None else ""
        raise SystemExit(
            f"error: {desc}: a rendering process died ({_deaths(processes)}){cause}"
        ) from None
    finally:
        if executor is not None:
            executor.shutdown(cancel_futures=True)
