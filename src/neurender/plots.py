"""Matplotlib helpers: a headless backend and atomic PNG output."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display on CI or cluster nodes
import matplotlib.pyplot as plt  # noqa: E402

from neurender import io  # noqa: E402


def save_figure(fig: plt.Figure, path: str | Path, dpi: int = 90) -> None:
    """Write ``fig`` as PNG atomically and close it."""
    with io.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
