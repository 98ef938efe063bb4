"""Wall-clock timing and peak memory of one operation, for the timing tables (never for
tests).

A 2-core machine's timings have outliers, so every figure is a median over repeats after
uncounted warm-up calls; on a GPU the clock stops only when the queued kernels are done.
Peak memory is the process's resident set sampled by a thread while the operation runs,
less its size before: what the operation added at its peak, to within the sampling interval.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from neurender.provenance import cpu_model


def timed(
    fn: Callable[..., Any], *args: Any, repeats: int = 1, warmup: int = 0, **kwargs: Any
) -> tuple[Any, float]:
    """``fn(*args, **kwargs)``'s last result and its median wall time in seconds over
    ``repeats`` calls, after ``warmup`` calls that are not counted."""
    sync = torch.cuda.synchronize if torch.cuda.is_available() else lambda: None
    times = []
    out = None
    for k in range(warmup + repeats):
        sync()
        start = time.perf_counter()
        out = fn(*args, **kwargs)
        sync()
        if k >= warmup:
            times.append(time.perf_counter() - start)
    return out, float(np.median(times))


def hardware(threads: int, device: str | torch.device | None = None) -> str:
    """What a timing ran on: the GPU's name on CUDA, else the CPU's model and threads.

    Args:
        device: where the timed work ran; ``None``: on the GPU when there is one.
    """
    on_gpu = torch.cuda.is_available() if device is None else torch.device(device).type == "cuda"
    if on_gpu:
        return f"{torch.cuda.get_device_name()} (CUDA)"
    return f"{cpu_model()}, {threads} thread{'s' * (threads != 1)}"


#: How often :func:`peak_memory` samples the resident set (seconds).
MEMORY_INTERVAL = 0.002


def _resident_bytes() -> int:
    """The process's resident set (Linux ``/proc/self/statm``; 0 where there is none)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return 0


def peak_memory(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """``fn(*args, **kwargs)``'s result and the most bytes of resident memory it added
    over the process's before the call (sampled every :data:`MEMORY_INTERVAL` seconds and
    once after; 0 where the platform does not say)."""
    before = _resident_bytes()
    peak = before
    done = threading.Event()

    def sample() -> None:
        nonlocal peak
        while not done.wait(MEMORY_INTERVAL):
            peak = max(peak, _resident_bytes())

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        out = fn(*args, **kwargs)
    finally:
        done.set()
        sampler.join()
    peak = max(peak, _resident_bytes())
    return out, float(peak - before)
