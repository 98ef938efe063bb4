"""Where a run's tensors live: the torch device a config's ``device`` names, and batches
moved to it. Shared by the training loop (:mod:`neurender.train`), its TensorBoard log and
the methods' inference, none of which needs the other's module for it."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import torch


def resolve_device(name: str = "auto", threads: int = 1) -> torch.device:
    """Torch device for a config value; on the CPU also sets the torch thread count, on
    CUDA picks deterministic kernels (a fixed seed then gives the same run: cuDNN without
    autotuning, cuBLAS with a fixed workspace; ops without a deterministic kernel warn)."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(
            f"device {name!r} requested but CUDA is not available; use device: auto or cpu"
        )
    if device.type == "cpu":
        torch.set_num_threads(max(1, threads))
    else:
        # Read by cuBLAS when its first handle is made, i.e. after this on a fresh process.
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        torch.backends.cudnn.benchmark = False
        torch.backends.cudnn.deterministic = True
        torch.use_deterministic_algorithms(True, warn_only=True)
    return device


def to_device(batch: Any, device: torch.device) -> Any:
    """Move tensors in a (nested) batch to ``device``."""
    if isinstance(batch, torch.Tensor):
        return batch.to(device, non_blocking=True)
    if isinstance(batch, Mapping):
        return {k: to_device(v, device) for k, v in batch.items()}
    if isinstance(batch, list | tuple):
        return type(batch)(to_device(v, device) for v in batch)
    return batch
