"""Deterministic seeds derived from the config seed and names (never Python's salted ``hash``)."""

from __future__ import annotations

import zlib
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import torch


def stable_seed(*parts: Any) -> list[int]:
    """A numpy seed sequence from ints and strings (strings hashed with CRC32)."""
    return [p if isinstance(p, int) else zlib.crc32(str(p).encode()) for p in parts]


def torch_generator(*parts: Any) -> torch.Generator:
    """A torch CPU generator seeded from :func:`stable_seed` of ``parts``."""
    import torch  # here, so the data jobs that only need numpy seeds never load torch

    seed = np.random.SeedSequence(stable_seed(*parts)).generate_state(1, np.uint64)[0]
    return torch.Generator().manual_seed(int(seed >> np.uint64(1)))
