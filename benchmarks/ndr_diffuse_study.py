"""Study (issue 25): why Real Shading beats ``ndr_diffuse`` on the diffuse, fixed-light data.

On the default config's diffuse data (``ndr.diffuse_samples``: train 300, val 24, test 60
at 64 x 64; specular albedo 0, one built-in map for every sample) this trains, at the same
epochs and with the same training function the pipeline's ``ndr_train`` jobs call
(:func:`neurender.ndr.training.train_variant`, the config's ``ndr_model`` keys, cosine
schedule over that many epochs, the best validation epoch kept), ``real_shading``,
``ndr_diffuse`` and the ablations in :data:`STUDY` that each isolate one difference between
them, and scores each as ``ndr_evaluate`` does (:func:`neurender.ndr.evaluate.predict` and
:func:`~neurender.ndr.evaluate.score`: DSSIM and L2 of the Reinhard tone-mapped ``I_R``
and ``I_D`` within the eroded mask against the clean 512-spp references) on the diffuse
test split and, to choose between designs without looking at the test set, on the val
split (against its 64-spp renders). Rows ``shading_input`` and ``noise floor`` are the
untrained coarse shading and an independent 64-spp render, as in ``results/ndr/metrics.csv``.
``--coarse-shading prefiltered`` trains and scores on a copy of the data whose ``S_D`` and
``S_S`` are remade as ``ndr.coarse_shading: prefiltered`` would make them (same objects,
G-buffers and Mitsuba targets; :func:`prefiltered_copy`); ``--seeds`` are added to the
config's seed (initialisation and batch order). The committed rows with ``coarse_shading``
``S_D prefiltered, S_S importance`` come from this script at commit 08e5191 (``--prior sh``:
``S_D`` replaced by the map's SH irradiance only); the conclusions are in
``docs/methods/ndr.md`` ("NDR on diffuse data against Real Shading").

Writes ``--out`` (default ``benchmarks/results/ndr_diffuse_study.csv``; tidy: variant,
coarse_shading, epochs, seed, split, metric, value; metrics ``dssim_I_R``, ``dssim_I_D``,
``l2_I_R``, ``l2_I_D``, ``parameters``, ``seconds`` (wall seconds of the training, one
torch thread on the shared machine) and ``best_epoch``) and a sidecar ``.json`` with the
command, commit, config and what each variant is. Needs the diffuse data in
``results/ndr`` (or ``--data``)::

    nice -n 10 snakemake --cores 2 results/ndr/diffuse_{train,val,test}_manifest.csv
    nice -n 10 python benchmarks/ndr_diffuse_study.py --variants real_shading ndr_diffuse \\
        --seeds 0 1 2 --out /tmp/a.csv
    python benchmarks/ndr_diffuse_study.py --merge /tmp/a.csv /tmp/b.csv

The committed CSV merges runs of a few variants each, two processes side by side.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.ndr import VARIANTS, data, render
from neurender.ndr.buffers import NDRDataset, channels
from neurender.ndr.evaluate import NOISE_FLOOR, predict, score
from neurender.ndr.model import SHADING_INPUT, compose, shading_input
from neurender.ndr.training import train_variant
from neurender.ndr.variants import Variant
from neurender.nn.unet import count_parameters
from neurender.plan import load_config
from neurender.provenance import git_state

ROOT = Path(__file__).resolve().parents[1]
_NDR = VARIANTS["ndr_diffuse"]
_RS = VARIANTS["real_shading"]

#: name -> (variant, overrides of the ``ndr_model`` architecture keys). Each ablation
#: changes one thing of ``ndr_diffuse`` (or of ``real_shading``).
STUDY: dict[str, tuple[Variant, dict]] = {
    "real_shading": (_RS, {}),
    "ndr_diffuse": (_NDR, {}),
    "ndr_diffuse-sh": (dataclasses.replace(_NDR, light=False), {}),
    "ndr_diffuse-residual": (dataclasses.replace(_NDR, residual=False), {}),
    "ndr_diffuse-decoder_I_S": (dataclasses.replace(_NDR, targets=("I_D",), decoders=1), {}),
    "ndr_diffuse-decoder_I_S-sh": (
        dataclasses.replace(_NDR, targets=("I_D",), decoders=1, light=False),
        {},
    ),
    "ndr_diffuse-decoder_I_S-sh-residual": (
        dataclasses.replace(_NDR, targets=("I_D",), decoders=1, light=False, residual=False),
        {},
    ),
    "ndr_diffuse_inputs_N_D": (dataclasses.replace(_NDR, inputs=("N", "D")), {}),
    # NDR with its specular half skipped for a material of zero specular albedo: no R, S_S
    # inputs (the roughness and shading of a lobe that is not there), no I_S decoder.
    "ndr_diffuse-specular": (
        dataclasses.replace(_NDR, inputs=("N", "D", "S_D"), targets=("I_D",), decoders=1),
        {},
    ),
    "ndr_diffuse-specular-sh": (
        dataclasses.replace(
            _NDR, inputs=("N", "D", "S_D"), targets=("I_D",), decoders=1, light=False
        ),
        {},
    ),
    "real_shading+sh": (dataclasses.replace(_RS, light=True), {}),
    "real_shading+two_decoders": (
        dataclasses.replace(_RS, targets=("I_D", "I_S"), decoders=2),
        {},
    ),
}


def dataset(folder: Path, split: str) -> dict[str, str]:
    return {
        "dir": str(folder / split),
        "manifest": str(folder / f"{split}_manifest.csv"),
        "lighting": str(folder / f"{split}_lighting.csv"),
    }


def prefiltered_copy(folder: Path, split: str, cfg: dict, out: Path) -> dict[str, str]:
    """A copy of ``split`` as the data stage (``cfg``: ``ndr`` with ``seed``) writes it
    with ``ndr.coarse_shading: prefiltered``: ``S_D`` (the fixed map's 5-band SH
    irradiance at ``N``, noise-free) and ``S_S`` (split sum) by
    :func:`neurender.ndr.data.coarse_maps` from each sample's G-buffers, remade from its
    seed; everything else (Mitsuba's ``I_D``) as rendered."""
    pf_cfg = {**cfg, "coarse_shading": "prefiltered"}
    files = dataset(folder, split)
    (out / split).mkdir(parents=True)
    manifest = io.read_csv(files["manifest"], ["sample", "file"])
    env = None
    for index, name in zip(manifest["sample"], manifest["file"], strict=True):
        obj, env, _, _ = data.sample_scene(cfg, split, int(index))
        g = render.g_buffers(obj, render.camera(cfg["camera_distance"], cfg["fov"]), cfg["width"])
        c = io.read_exr(Path(files["dir"]) / name)
        stored = np.stack([c[f"N.{a}"] for a in "XYZ"], -1)
        if not np.allclose(stored, g["normal"], atol=1e-5):
            raise ValueError(f"{name}: the remade G-buffers are not the stored sample's")
        lighting = data.coarse_lighting(pf_cfg, env)
        s_d, s_s = data.coarse_maps(pf_cfg, g, env, split, int(index), lighting=lighting)
        c |= channels("S_D", s_d) | channels("S_S", s_s)
        io.write_exr(out / split / name, c)
    for key in ("manifest", "lighting"):
        (out / Path(files[key]).name).write_bytes(Path(files[key]).read_bytes())
    return dataset(out, split)


def scored(pred, data: NDRDataset) -> dict[str, float]:
    """``ndr_evaluate``'s scores of a diffuse split (``I_R`` and ``I_D``), split means."""
    b = data.buffers
    truth = compose(b["I_D"], b["I_S"], b)
    values = score(pred, truth, b["mask"])
    return {k: float(v.mean()) for k, v in values.items() if k.endswith(("I_R", "I_D"))}


def run_one(name, epochs, seed, shading, cfg, files, tests, tmp: Path) -> list[dict]:
    variant, overrides = STUDY[name]
    run_cfg = {**cfg, **overrides, "epochs": epochs, "seed": seed}
    start = time.perf_counter()
    model = train_variant(
        name,
        files["diffuse_train"],
        files["diffuse_val"],
        run_cfg,
        1,
        str(tmp / f"{name}_{epochs}_{seed}.pt"),
        str(tmp / f"{name}_{epochs}_{seed}_loss.csv"),
        variant=variant,
    )
    seconds = time.perf_counter() - start
    model.eval()
    history = train_state(tmp / f"{name}_{epochs}_{seed}.pt")
    rows = []
    for split, split_data in tests.items():
        values = scored(predict(model, split_data, torch.device("cpu")), split_data)
        if split == "test":
            values |= {
                "parameters": float(count_parameters(model.net)),
                "seconds": seconds,
                "best_epoch": float(history),
            }
        key = {
            "variant": name,
            "coarse_shading": shading,
            "epochs": epochs,
            "seed": seed,
            "split": split,
        }
        rows += [{**key, "metric": k, "value": v} for k, v in values.items()]
    return rows


def train_state(checkpoint: Path) -> int:
    """The epoch (1-based) whose weights the checkpoint keeps: the best validation loss."""
    state = torch.load(checkpoint, weights_only=True)
    losses = [h["val_loss"] for h in state["history"]]
    return 1 + losses.index(min(losses))


def baselines(tests: dict[str, NDRDataset], shading: str) -> list[dict]:
    rows = []
    for split, split_data in tests.items():
        b = split_data.buffers
        methods = {SHADING_INPUT: shading_input(b)}
        if "I_D_noisy" in b:
            methods[NOISE_FLOOR] = compose(b["I_D_noisy"], b["I_S_noisy"], b)
        for name, pred in methods.items():
            key = {
                "variant": name,
                "coarse_shading": shading,
                "epochs": 0,
                "seed": -1,
                "split": split,
            }
            rows += [{**key, "metric": k, "value": v} for k, v in scored(pred, split_data).items()]
    return rows


def merge(parts: list[str], out: Path) -> None:
    frames = [io.read_csv(p) for p in parts]
    keys = ["variant", "coarse_shading", "epochs", "seed", "split", "metric"]
    table = pd.concat(frames).fillna({"coarse_shading": "importance"}).drop_duplicates(keys)
    runs = [json.loads(Path(p).with_suffix(".json").read_text()) for p in parts]
    io.write_csv(out, table[[*keys, "value"]].sort_values(keys))
    note = (
        "One process per group of variants, two side by side, each training with one torch "
        "thread at nice 10 on the shared 2-core machine; merged with --merge. Seconds are "
        "wall seconds under that sharing."
    )
    io.write_json(out.with_suffix(".json"), {"note": note, "runs": runs})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--variants", nargs="+", default=list(STUDY), choices=list(STUDY))
    parser.add_argument("--epochs", nargs="+", type=int, help="budgets (default ndr_model.epochs)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0], help="added to config seed")
    parser.add_argument("--baselines", action="store_true", help="add shading_input, noise floor")
    parser.add_argument(
        "--coarse-shading",
        choices=["importance", "prefiltered"],
        default="importance",
        help="S_D, S_S as rendered (ndr.coarse_shading importance) or remade as prefiltered",
    )
    parser.add_argument("--data", default=str(ROOT / "results/ndr"))
    parser.add_argument("--configfile", nargs="*", default=[], help="as snakemake's")
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/ndr_diffuse_study.csv"))
    parser.add_argument("--merge", nargs="+", help="merge these runs' CSVs (and sidecars) only")
    args = parser.parse_args()
    out = Path(args.out)
    if args.merge:
        merge(args.merge, out)
        return
    torch.set_num_threads(1)
    state = git_state(ROOT)  # at the start: the code that measured
    config = load_config(args.configfile)
    cfg = {**config["ndr_model"], "seed": config["seed"], "device": "cpu"}
    epochs = args.epochs or [cfg["epochs"]]
    folder = Path(args.data)
    splits = ("diffuse_train", "diffuse_val", "diffuse_test")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp_dir:
        if args.coarse_shading == "prefiltered":
            copy = Path(tmp_dir) / "prefiltered"
            data_cfg = {**config["ndr"], "seed": config["seed"], "device": "cpu"}
            files = {s: prefiltered_copy(folder, s, data_cfg, copy) for s in splits}
        else:
            files = {s: dataset(folder, s) for s in splits}
        erosion = cfg["mask_erosion"]
        tests = {
            "test": NDRDataset.from_files(files["diffuse_test"], erosion),
            "val": NDRDataset.from_files(files["diffuse_val"], erosion),
        }
        rows = baselines(tests, args.coarse_shading) if args.baselines else []
        for e in epochs:
            for seed in args.seeds:
                for name in args.variants:
                    s = config["seed"] + seed
                    rows += run_one(
                        name, e, s, args.coarse_shading, cfg, files, tests, Path(tmp_dir)
                    )
                    io.write_csv(out, pd.DataFrame(rows))
                    write_sidecar(out, state, started, epochs, config, cfg, args.variants)
                    print(name, e, seed, [r["value"] for r in rows[-9:]], file=sys.stderr)


def write_sidecar(out: Path, state, started, epochs, config, cfg, names) -> None:
    """The run's ``.json`` beside ``out`` (rewritten after every variant)."""
    sidecar = {
        "command": " ".join(["python", *sys.argv]),
        **state,
        "seconds": time.perf_counter() - started,
        "budget": f"equal epochs {epochs}, batch {cfg['batch_size']}, lr {cfg['lr']} "
        f"({cfg['lr_schedule']}); the best of the epochs by validation loss",
        "config": {
            "ndr": {k: config["ndr"][k] for k in ("width", "diffuse_samples", "fixed_probe")}
            | {k: config["ndr"][k] for k in ("spp", "reference_spp", "coarse_shading")},
            "ndr_model": cfg,
        },
        "variants": {
            n: {**dataclasses.asdict(STUDY[n][0]), "overrides": STUDY[n][1]} for n in names
        },
    }
    io.write_json(out.with_suffix(".json"), sidecar)


if __name__ == "__main__":
    main()
