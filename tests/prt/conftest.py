import copy
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

#: What DeepPRT's tests shrink of the smoke config (and the seed their data are drawn
#: with), the one place their sizes are written: an 8^2 head of 3 train, 1 val and 2 test
#: frames (2 of them for the experiments, 3 points on their paths), 16 directions in 2
#: sets (64 for the references, 4 and 16 in the equal-quality sweep), 16^2 probes and
#: renders, one-epoch networks of widths 4 and 8 (each variant its own batch size and
#: learning rate), MoMoPRT of 2 components; a config the workflow accepts
#: (:func:`prt_config`).
SMALL = {
    "seed": 5,
    "device": "cpu",
    "prt": {
        "resolution": 8,
        "source_vertices": 300,
        "frames": {"train": 3, "val": 1, "test": 2},
        "directions": 16,
        "reference_directions": 64,
        "direction_sets": 2,
        "probe_height": 16,
        "experiment_train_frames": 2,
        "experiment_points": 3,
    },
    "prt_model": {
        "widths": [4, 8],
        "epochs": 1,
        "batch_size": 2,
        "lr": 1e-3,
        "shadowing_batch_size": 1,
        "shadowing_lr": 5e-4,
        "render_resolution": 16,
        "equal_quality_directions": [4, 16],
        "pca_components": 2,
        "ridges": [1e-3, 1e-1],
    },
}


@pytest.fixture(scope="session")
def prt_config() -> dict:
    """The smoke config (``config/smoke.yaml`` over ``config/config.yaml``, the schema's
    defaults filled) with :data:`SMALL`'s sizes, checked as the workflow checks a config."""
    from snakemake.utils import update_config

    from neurender import config, plan

    cfg = plan.load_config([str(ROOT / "config/smoke.yaml")])
    update_config(cfg, copy.deepcopy(SMALL))
    config.check(cfg)
    return cfg


@pytest.fixture(scope="session")
def prt_params(prt_config):
    """Factory: ``prt_params(rule, config=None, **wildcards)``, the params the workflow gives
    the job of DeepPRT's ``rule`` with ``wildcards`` under :func:`prt_config`, ``config``
    merged over it as another config file would be: its registry entry's
    (:meth:`neurender.method.Rule.job_params`), a new dict each call."""
    from snakemake.utils import update_config

    import neurender.methods

    def params(rule: str, config: dict | None = None, **wildcards: str) -> dict:
        cfg = copy.deepcopy(prt_config)
        update_config(cfg, copy.deepcopy(config or {}))
        return neurender.methods.rule(rule).job_params(cfg, wildcards)

    return params


@pytest.fixture
def bowl_positions():
    """Factory: ``(F, n, n, 3)`` geometry images of a shallow bowl (it shadows itself),
    frame ``f`` of depth ``1 + 0.5 f`` times the first's."""

    def make(n: int = 6, frames: int = 2) -> np.ndarray:
        u = np.linspace(-1, 1, n)
        x, y = np.meshgrid(u, u, indexing="ij")
        bowl = np.stack([x, y, 0.6 * (x**2 + y**2)], -1)
        return np.stack([bowl * [1, 1, 1 + 0.5 * f] for f in range(frames)]).astype(np.float32)

    return make
