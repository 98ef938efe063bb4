"""Study (issue 27): does DeepPRT learn shadowing or the training animation?

For each object (default: head and cloth) at the default config's sizes (resolution,
directions, frames; ``config/config.yaml`` with the schema's defaults) this builds the data
through the library the pipeline's jobs call (geometry image, sequence, ray-traced
transfer with the pipeline's seeds: the test frames at ``reference_directions``), trains

* ``paper``: the paper's form (:func:`neurender.prt.training.train_deepprt`, the shipped
  ResNet U-Net and its normalisation), and
* ``shadowing``: the variant of :mod:`neurender.prt.local_model` (dilated core),

for the same number of epochs over the same frames (``--epochs``; both cosine schedules
over that many epochs, the config's learning rate and batch size), and scores them with
the ``unshadowed`` and ``static`` baselines (:mod:`neurender.prt.unseen`) on the test
frames and on every unseen-deformation family and strength, whose ground truth is traced
at ``reference_directions``. Metrics per frame, averaged per (family, strength):

* ``rel_l1_diffuse``: ``sum |R_pred - R_gt| / sum |R_gt|`` of per-vertex diffuse
  radiance ``R`` (RGB) under the config's light probe (sky);
* ``ssim_diffuse``: SSIM of the rendered diffuse images (:mod:`neurender.prt.scores`).

Writes ``benchmarks/results/prt_generalisation.csv`` (tidy: object, epochs, model,
family, strength, metric, value; ``family = test`` for the test frames, strength 0 there)
and a sidecar ``.json`` with the command, commit, budget and seconds of every stage. A study,
outside CI. Run with ``nice -n 15`` (torch uses one thread)::

    nice -n 15 python benchmarks/prt_generalisation.py --epochs 8

The committed CSV merges runs of one object each (``--out`` per run, then ``--merge``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io, lights, sh
from neurender.plan import load_config
from neurender.prt import frames, jobs, render, scores, transfer, unseen
from neurender.prt.local_model import LocalConfig
from neurender.prt.model import DeepPRT, raw_inputs
from neurender.prt.training import train_deepprt, train_local

ROOT = Path(__file__).resolve().parents[1]


def traced(positions, directions, cfg, offset, name, split, threads=1) -> frames.Split:
    """A split of frames ``(F, n, n, 3)`` with their diffuse transfer (the pipeline's seeds)."""
    normals, diffuse = [], []
    for f, p in enumerate(positions):
        nrm, d, _, _ = transfer.sample_frame(
            p, directions, cfg, offset, None, threads, name, split, f, directions
        )
        normals.append(nrm)
        diffuse.append(d)
    n = positions.shape[1]
    return frames.Split(
        np.asarray(positions, np.float32),
        np.stack(normals).astype(np.float32),
        np.stack(diffuse).astype(np.float32),
        np.zeros((len(positions), n, n, 3, 1), np.float32),
        np.zeros((len(positions), 1), np.float32),
    )


def predictions(
    data: frames.Split, paper: DeepPRT, local, mean_split: frames.Split, n_bands: int
) -> dict[str, np.ndarray]:
    """``(F, K, n, n)`` diffuse transfer of every model and baseline."""
    with torch.no_grad():
        x = torch.from_numpy(raw_inputs(data))
        shadowing = np.concatenate([local(x[i : i + 8]).numpy() for i in range(0, len(x), 8)])
    return {
        "paper": paper.predict(data),
        "shadowing": shadowing,
        "unshadowed": unseen.unshadowed_baseline(data.positions, n_bands),
        "static": unseen.static_baseline(
            np.moveaxis(mean_split.diffuse[0], -1, 0), len(data.positions)
        ),
    }


def frame_scores(split: frames.Split, pred: np.ndarray, light: np.ndarray, res: int) -> dict:
    """Per-frame relative L1 of diffuse radiance and diffuse SSIM, ``(F,)`` each."""
    n = split.positions.shape[1]
    rel, ssim = [], []
    for f in range(len(pred)):
        gt_t = split.diffuse[f].reshape(n * n, -1)
        pr_t = np.moveaxis(pred[f], 0, -1).reshape(n * n, -1)
        gt_r, pr_r = render.diffuse_radiance(gt_t, light), render.diffuse_radiance(pr_t, light)
        rel.append(scores.relative_l1(pr_r, gt_r))
        ssim.append(
            scores.diffuse_ssim(
                split.positions[f], np.moveaxis(pred[f], 0, -1), split.diffuse[f], res, light
            )
        )
    return {"rel_l1_diffuse": np.array(rel), "ssim_diffuse": np.array(ssim)}


def build_object(name: str, config: dict, tmp: Path) -> tuple[dict, dict]:
    """The geometry image and sequence arrays of a built-in object, by the pipeline's jobs."""
    prt = config["prt"]
    base = {"seed": config["seed"], "object": name}
    gim_file, seq_file = tmp / f"{name}_gim.npz", tmp / f"{name}_seq.npz"
    jobs.prt_geometry_image(
        {},
        {"gim": str(gim_file), "stats": str(tmp / f"{name}_stats.csv")},
        {**base, "resolution": prt["resolution"], "source_vertices": prt["source_vertices"]},
        1,
    )
    keys = ("frames", "experiment_points", "experiment_train_frames", "linear_range")
    keys += ("excluded_expression",)
    jobs.prt_sequence(
        {"gim": str(gim_file)}, {"seq": str(seq_file)}, {**base, **{k: prt[k] for k in keys}}, 1
    )
    return io.load_npz(gim_file), io.load_npz(seq_file)


def merge(csvs: list[str], out: Path) -> None:
    """One CSV and sidecar from several runs' (e.g. one object each, run side by side)."""
    parts, runs = [], []
    for csv in csvs:
        parts.append(pd.read_csv(csv))
        meta = json.loads(Path(csv).with_suffix(".json").read_text())
        meta["command"] = meta["command"].split(" --out ")[0]
        runs.append(meta)
    io.write_csv(out, pd.concat(parts, ignore_index=True))
    note = (
        "One run per object and budget (the objects' runs side by side, each one torch "
        "thread at nice 15 on the shared 2-core machine), merged with --merge. Seconds are "
        "wall seconds under that sharing."
    )
    with io.atomic_path(out.with_suffix(".json")) as tmp_path:
        tmp_path.write_text(json.dumps({"note": note, "runs": runs}, indent=2) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", nargs="+", default=["head", "cloth"])
    parser.add_argument("--epochs", type=int, default=8, help="epochs of both models")
    parser.add_argument("--strengths", nargs="+", type=float, default=[0.25, 0.5, 0.75, 1.0])
    parser.add_argument("--per-strength", type=int, default=2, help="frames per strength")
    parser.add_argument("--configfile", nargs="*", default=[], help="as snakemake's (smoke)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/prt_generalisation.csv"))
    parser.add_argument("--merge", nargs="+", help="merge these runs' CSVs (and sidecars) only")
    args = parser.parse_args()
    if args.merge:
        merge(args.merge, Path(args.out))
        return
    torch.set_num_threads(1)
    commit = subprocess.run(  # at the start: the code that measured
        ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=False
    ).stdout.strip()
    config = load_config(args.configfile)
    prt, model_cfg = config["prt"], config["prt_model"]
    transfer_cfg = {
        "seed": config["seed"],
        "direction_sets": prt["direction_sets"],
        "n_bands": prt["n_bands"],
    }
    # The variant's config keys from the same config (its dilated core uses neither widths
    # nor blocks; they are stored with it).
    shadowing_cfg = LocalConfig(
        n_bands=prt["n_bands"], widths=model_cfg["widths"], blocks=model_cfg["blocks"]
    )
    train_cfg = {**model_cfg, "seed": config["seed"], "epochs": args.epochs, "device": "cpu"}
    image = lights.procedural_probe(prt["light"], prt["probe_height"])
    light = sh.project_latlong(image, prt["n_bands"])
    res = model_cfg["render_resolution"]
    rows, seconds = [], {}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)

    def add(name, model, family, strength, values):
        for metric, v in values.items():
            rows.append(
                {
                    "object": name,
                    "epochs": args.epochs,
                    "model": model,
                    "family": family,
                    "strength": strength,
                    "metric": metric,
                    "value": float(np.mean(v)),
                }
            )

    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        for name in args.objects:
            start = time.perf_counter()
            gim, seq = build_object(name, config, tmp)
            split = {}
            for s in ("train", "val", "test"):
                pos = seq[f"{s}_positions"]
                directions = prt["reference_directions" if s == "test" else "directions"]
                offset = frames.ray_offset(pos[0], prt["ray_offset"])
                split[s] = traced(pos, directions, transfer_cfg, offset, name, s)
            seconds[f"{name}_data"] = time.perf_counter() - start
            print(f"{name}: data in {seconds[f'{name}_data']:.0f} s", flush=True)

            start = time.perf_counter()
            mean = seq["train_positions"].astype(np.float64).mean(0)
            ref = prt["reference_directions"]
            offset = frames.ray_offset(mean, prt["ray_offset"])
            mean_split = traced(mean[None], ref, transfer_cfg, offset, name, "unseen_mean")
            families = unseen.families_for(len(gim["deltas"]) > 0)
            unseen_splits = {}
            for family in families:
                for strength in args.strengths:
                    pos = np.stack(
                        [
                            unseen.deform(mean, family, strength, config["seed"], i, gim["deltas"])
                            for i in range(args.per_strength)
                        ]
                    )
                    unseen_splits[(family, strength)] = traced(
                        pos, ref, transfer_cfg, offset, name, f"unseen_{family}_{strength}"
                    )
            seconds[f"{name}_unseen_data"] = time.perf_counter() - start
            print(f"{name}: unseen data in {seconds[f'{name}_unseen_data']:.0f} s", flush=True)

            start = time.perf_counter()
            ckpt = tmp / f"{name}_paper.pt"
            train_deepprt(
                split["train"], split["val"], "diffuse", train_cfg, 1, str(ckpt), str(tmp / "l.csv")
            )
            paper = DeepPRT(ckpt, device="cpu")
            seconds[f"{name}_train_paper"] = time.perf_counter() - start
            start = time.perf_counter()
            local = train_local(
                split["train"],
                split["val"],
                shadowing_cfg,
                train_cfg,
                1,
                str(tmp / f"{name}_local.pt"),
                str(tmp / "l2.csv"),
            )
            seconds[f"{name}_train_shadowing"] = time.perf_counter() - start
            print(
                f"{name}: trained paper {seconds[f'{name}_train_paper']:.0f} s, "
                f"shadowing {seconds[f'{name}_train_shadowing']:.0f} s",
                flush=True,
            )

            start = time.perf_counter()
            cases = {("test", 0.0): split["test"], **unseen_splits}
            for (family, strength), data in cases.items():
                preds = predictions(data, paper, local, mean_split, prt["n_bands"])
                for model, pred in preds.items():
                    add(name, model, family, strength, frame_scores(data, pred, light, res))
            seconds[f"{name}_score"] = time.perf_counter() - start
            table = pd.DataFrame(rows)
            io.write_csv(out, table)  # after every object: a partial run keeps what it measured
            print(
                table[(table.object == name) & (table.metric == "rel_l1_diffuse")]
                .pivot_table(index=["family", "strength"], columns="model", values="value")
                .round(4)
                .to_string(),
                flush=True,
            )
    meta = {
        "command": "nice -n 15 python " + " ".join(sys.argv),
        "commit": commit,
        "budget": f"equal epochs: {args.epochs} for both models over the same "
        f"{prt['frames']['train']} training frames (val {prt['frames']['val']} picks the epoch)",
        "config": {
            "resolution": prt["resolution"],
            "directions": prt["directions"],
            "reference_directions": prt["reference_directions"],
            "frames": prt["frames"],
            "light": prt["light"],
            "paper": {k: model_cfg[k] for k in ("widths", "blocks", "lr", "batch_size")},
            "shadowing": vars(shadowing_cfg),
        },
        "seconds": {k: round(v, 1) for k, v in seconds.items()},
        "torch_threads": 1,
    }
    with io.atomic_path(out.with_suffix(".json")) as tmp_path:
        tmp_path.write_text(json.dumps(meta, indent=2, default=list) + "\n")


if __name__ == "__main__":
    main()
