"""Tiny metaballs runs for job tests: splits of AB examples and every variant trained for a
step, as the workflow's jobs make them."""

from pathlib import Path

from neurender.metaballs import GAN_VARIANTS, VARIANTS, jobs


def write_splits(root: Path, scene: dict, counts: dict[str, int]) -> dict[str, str]:
    """Each split's examples (``counts``: split to examples) of the scene keys ``scene``
    (``seed``, ``width`` and the examples job's scene keys) under ``root``; the training
    job's file keys ``{split}_dir``, ``{split}_manifest``, ``{split}_balls``."""
    files = {}
    for split, count in counts.items():
        outputs = {
            "examples": str(root / split),
            "manifest": str(root / f"{split}_manifest.csv"),
            "balls": str(root / f"{split}_balls.csv"),
        }
        jobs.metaballs_examples({}, outputs, scene | {"split": split, "examples": count}, 1)
        files |= {f"{split}_dir": outputs["examples"]}
        files |= {f"{split}_{k}": outputs[k] for k in ("manifest", "balls")}
    return files


def train_variants(files: dict[str, str], root: Path, width: int) -> list[str]:
    """Every variant's checkpoint under ``root`` (in the order of ``VARIANTS``), trained one
    epoch of batch 2 without mirrorings by a generator of 4 filters."""
    checkpoints = []
    for variant in VARIANTS:
        params = {"seed": 1, "device": "cpu", "width": width, "variant": variant, "ngf": 4}
        params |= {"l1_weight": 100.0, "flips": False, "epochs": 1, "batch_size": 2, "lr": 1e-3}
        params |= {"lr_schedule": "constant", "ndf": 4}
        params |= {"gan_weight": 1.0 if variant in GAN_VARIANTS else 0.0}
        checkpoints.append(str(root / f"{variant}.pt"))
        outputs = {"checkpoint": checkpoints[-1], "loss": str(root / f"{variant}.csv")}
        jobs.metaballs_train(files, outputs, params, 1)
    return checkpoints
