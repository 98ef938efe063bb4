import pytest
import torch

from neurender.metaball import Scene

from .keys import THESIS_SCENES


@pytest.fixture
def make_scene():
    """Factory: a float64 :class:`Scene` of the given centres and radii, random colours
    (seeded)."""

    def make(centres, radii):
        c = torch.tensor(centres, dtype=torch.float64)
        colours = torch.rand(
            len(c), 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0)
        )
        return Scene(c, torch.tensor(radii, dtype=torch.float64), colours)

    return make


@pytest.fixture
def write_split(tmp_path):
    """Factory: ``write(split, count)`` writes a split's AB examples (width 32) under
    ``tmp_path`` as the ``metaballs_examples`` job does and returns the job's params."""
    from neurender.metaballs import jobs

    def write(split: str, count: int) -> dict:
        params = {"seed": 1, "width": 32, "balls": [2, 4], "radius": [1, 2], **THESIS_SCENES}
        params |= {"split": split, "examples": count}
        outputs = {
            "examples": str(tmp_path / split),
            "manifest": str(tmp_path / f"{split}_manifest.csv"),
            "balls": str(tmp_path / f"{split}_balls.csv"),
        }
        jobs.metaballs_examples({}, outputs, params, 1)
        return params

    return write


@pytest.fixture
def split_files(tmp_path):
    """The training job's inputs for the train and val splits :func:`write_split` writes:
    ``{split}_dir``, ``{split}_manifest``, ``{split}_balls``."""
    return {
        f"{s}_{k}": str(tmp_path / (s if k == "dir" else f"{s}_{k}.csv"))
        for s in ("train", "val")
        for k in ("dir", "manifest", "balls")
    }
