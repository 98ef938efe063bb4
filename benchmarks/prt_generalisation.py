"""Study (issue 27): does DeepPRT learn shadowing or the training animation?

For each object (default: head and cloth) at the default config's sizes (resolution,
directions, frames; ``config/config.yaml`` with the schema's defaults) this builds the data
through the library the pipeline's jobs call (geometry image, sequence, ray-traced
transfer with the pipeline's seeds: the test frames at ``reference_directions``), trains

* ``paper``: the paper's form (:func:`neurender.prt.training.train_deepprt`, the shipped
  ResNet U-Net and its normalisation), and
* ``shadowing``: the variant of :mod:`neurender.prt.local_model` (dilated core),

for the same number of epochs over the same frames (``--epochs``; both cosine schedules
over that many epochs, each at its own learning rate and batch size of the config, as the
pipeline trains them: ``lr`` and ``batch_size`` the paper form's, ``shadowing_lr`` and
``shadowing_batch_size`` the shadowing variant's), and scores them with
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

Learning curves (``benchmarks/results/prt_learning_curve.csv``): ``--study
config/studies/deepprt.yaml`` trains each model at every budget of the study config (error
against epochs; error against the number of distinct training shapes at equal optimiser
steps, :func:`study_runs`) instead of ``--epochs``; the config's comment gives the
commands. Rows carry ``train_frames`` and ``steps``; the baselines, which need no training,
have 0 epochs, frames and steps.

Cost and width (``benchmarks/results/prt_width.csv``): ``--width`` and ``--dilations`` set
the shadowing variant's :class:`~neurender.prt.local_model.LocalConfig`, ``--skip-paper``
trains only that variant. Every trained network is exported as the pipeline ships it
(:func:`neurender.prt.model.export_deepprt`) and timed: rows with ``family = timing``
(strength 0), metrics ``onnx_ms_per_frame`` and ``pytorch_ms_per_frame`` (median of one
64x64 frame, batch 1, one thread) and ``parameters``. ``--time-only`` times freshly
initialised networks of every ``--width`` (and the paper's form unless ``--skip-paper``;
object ``untrained``, epochs 0; the cost of a convolution does not depend on its weights)
without data or training, interleaved over ``--rounds`` rounds, the median kept. Every
row carries the run's ``shadowing_width`` and ``shadowing_dilations``::

    nice -n 10 python benchmarks/prt_generalisation.py --objects head --epochs 14 \
        --skip-paper --width 24 --strengths 0.25 0.5 1.0 --per-strength 1 --out /tmp/w24_head.csv
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io, lights, sh
from neurender.nn.inference import engine_milliseconds, export_onnx
from neurender.nn.unet import count_parameters
from neurender.plan import load_config
from neurender.prt import data_jobs, frames, unseen, unseen_scores
from neurender.prt.local_model import LocalConfig, ShadowingTransfer
from neurender.prt.model import (
    DeepPRT,
    Normalisation,
    TransferNetwork,
    build_network,
    export_deepprt,
    load_transfer_module,
    raw_inputs,
)
from neurender.prt.training import shadowing_training, train_deepprt, train_local

ROOT = Path(__file__).resolve().parents[1]


def network_timing(module: torch.nn.Module, onnx_file: Path, frame: np.ndarray) -> dict:
    """Cost of a network exported to ``onnx_file``: median milliseconds of one ``(1, 6, n, n)``
    frame (batch 1) in ONNX Runtime and in PyTorch, one thread each
    (:func:`neurender.nn.inference.engine_milliseconds`), and its parameter count."""
    ms = engine_milliseconds(module, onnx_file, (torch.from_numpy(frame[:1]),), threads=1)
    return {
        "onnx_ms_per_frame": ms["onnxruntime"],
        "pytorch_ms_per_frame": ms["pytorch"],
        "parameters": count_parameters(module),
    }


def untrained_frames(n: int, seed: int) -> np.ndarray:
    """Two random raw P and N frames ``(2, 6, n, n)`` (positions in [-1, 1], unit normals):
    the input of a timing that does not depend on the data (nor on the weights)."""
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-1, 1, (2, 3, n, n))
    normals = rng.normal(size=(2, 3, n, n))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return np.concatenate([positions, normals], axis=1).astype(np.float32)


def tidy(rows: list[dict]) -> pd.DataFrame:
    """The rows as a table; ``shadowing_width`` an integer, empty for the paper form's
    timing (``--time-only``), which has none."""
    return pd.DataFrame(rows).astype({"shadowing_width": "Int64"})


def frame_scores(split: frames.Split, preds: dict, light: np.ndarray, cfg: dict) -> dict:
    """``model -> metric -> (F,)``: relative L1 of diffuse radiance and diffuse SSIM
    (:func:`neurender.prt.unseen_scores.frame_scores`, under this study's names)."""
    values = unseen_scores.frame_scores(split, preds, light, cfg)
    names = {"rel_l1_radiance_diffuse": "rel_l1_diffuse", "ssim_diffuse": "ssim_diffuse"}
    return {m: {names[k]: v for k, v in metrics.items()} for m, metrics in values.items()}


def build_object(name: str, config: dict, tmp: Path) -> tuple[dict, dict]:
    """The geometry image and sequence arrays of a built-in object, by the pipeline's jobs."""
    prt = config["prt"]
    base = {"seed": config["seed"], "object": name}
    gim_file, seq_file = tmp / f"{name}_gim.npz", tmp / f"{name}_seq.npz"
    data_jobs.prt_geometry_image(
        {},
        {"gim": str(gim_file), "stats": str(tmp / f"{name}_stats.csv")},
        {**base, "resolution": prt["resolution"], "source_vertices": prt["source_vertices"]},
        1,
    )
    keys = ("frames", "experiment_points", "experiment_train_frames", "linear_range")
    keys += ("excluded_expression",)
    data_jobs.prt_sequence(
        {"gim": str(gim_file)}, {"seq": str(seq_file)}, {**base, **{k: prt[k] for k in keys}}, 1
    )
    return io.load_npz(gim_file), io.load_npz(seq_file)


def merge(csvs: list[str], out: Path, note: str | None = None) -> None:
    """One CSV and sidecar from several runs' (e.g. one object and width each, run side by
    side); ``note`` says how they shared the machine (default: niced side by side)."""
    parts, runs = [], []
    for csv in csvs:
        parts.append(pd.read_csv(csv))
        meta = json.loads(Path(csv).with_suffix(".json").read_text())
        meta["command"] = meta["command"].split(" --out ")[0]
        runs.append(meta)
    table = pd.concat(parts, ignore_index=True)
    if "shadowing_width" in table:  # runs of this script before --width have none
        table = table.astype({"shadowing_width": "Int64"})
    io.write_csv(out, table)
    note = note or (
        "One run per object, budget and shadowing width (two runs side by side, each one "
        "torch thread, niced, on the shared 2-core machine; each run's command says its "
        "nice), merged with --merge. Seconds and milliseconds are wall times under that "
        "sharing."
    )
    io.write_json(out.with_suffix(".json"), {"note": note, "runs": runs})


@dataclasses.dataclass(frozen=True)
class Run:
    """One training of one model (``paper`` or ``shadowing``): ``epochs`` over the first
    ``train_frames`` of the evenly spaced training frames (:func:`subset`)."""

    model: str
    epochs: int
    train_frames: int


@dataclasses.dataclass
class ObjectData:
    """An object's traced frames: ``split`` (train, val, test), the mean training shape's
    ``mean_split`` (the static baseline) and ``unseen`` (family, strength) -> frames."""

    name: str
    split: dict[str, frames.Split]
    mean_split: frames.Split
    unseen: dict[tuple[str, float], frames.Split]


def study_runs(study: dict, models: list[str]) -> list[Run]:
    """Every run of a learning-curve study (``config/studies/deepprt.yaml``), each once:
    every model at every ``epochs`` over ``equal_steps.frames`` training frames, and at
    every ``train_frames`` n for ``equal_steps.epochs x equal_steps.frames / n`` epochs
    (rounded), i.e. the same optimiser steps over fewer or more distinct shapes."""
    base = study["equal_steps"]
    runs = [Run(m, e, base["frames"]) for m in models for e in study["epochs"]]
    for n in study["train_frames"]:
        epochs = max(1, round(base["epochs"] * base["frames"] / n))
        runs += [Run(m, epochs, n) for m in models]
    return list(dict.fromkeys(runs))


def subset(split: frames.Split, n: int) -> frames.Split:
    """``n`` frames of a split, evenly spaced over it (all of them if it has ``n``)."""
    total = len(split.positions)
    if not 1 <= n <= total:
        raise ValueError(f"{n} training frames: the split has {total}")
    index = np.unique(np.linspace(0, total - 1, n).round().astype(int))
    fields = (f.name for f in dataclasses.fields(split))
    return frames.Split(*(getattr(split, f)[index] for f in fields))


def object_data(
    name: str, config: dict, strengths: list[float], per_strength: int, tmp: Path
) -> tuple[ObjectData, dict[str, float]]:
    """Trace an object's splits (test at ``reference_directions``), its mean training shape
    and every unseen-deformation case; also the seconds of each part."""
    prt = config["prt"]
    transfer_cfg = {"seed": config["seed"], **{k: prt[k] for k in ("direction_sets", "n_bands")}}
    start, seconds = time.perf_counter(), {}
    gim, seq = build_object(name, config, tmp)
    split = {}
    for s in ("train", "val", "test"):
        pos = seq[f"{s}_positions"]
        directions = prt["reference_directions" if s == "test" else "directions"]
        offset = frames.ray_offset(pos[0], prt["ray_offset"])
        split[s] = unseen_scores.traced(pos, directions, transfer_cfg, offset, None, 1, name, s)
    seconds[f"{name}_data"] = time.perf_counter() - start
    print(f"{name}: data in {seconds[f'{name}_data']:.0f} s", flush=True)
    start = time.perf_counter()
    mean = seq["train_positions"].astype(np.float64).mean(0)
    ref = prt["reference_directions"]
    offset = frames.ray_offset(mean, prt["ray_offset"])
    mean_split = unseen_scores.traced(
        mean[None], ref, transfer_cfg, offset, None, 1, name, "unseen_mean"
    )
    families = unseen.families_for(len(gim["deltas"]) > 0)
    unseen_splits = {
        (case.family, case.strength): unseen_scores.traced(
            case.positions, ref, transfer_cfg, offset, None, 1, name, case.tag
        )
        for case in unseen_scores.cases(
            mean, families, strengths, per_strength, config["seed"], gim["deltas"]
        )
    }
    seconds[f"{name}_unseen_data"] = time.perf_counter() - start
    print(f"{name}: unseen data in {seconds[f'{name}_unseen_data']:.0f} s", flush=True)
    return ObjectData(name, split, mean_split, unseen_splits), seconds


def train_run(
    run: Run, data: ObjectData, shadowing_cfg: LocalConfig, train_cfg: dict, tmp: Path
) -> tuple[Path, Callable[[frames.Split], np.ndarray]]:
    """Train one run's model; its checkpoint and its diffuse prediction ``(F, K, n, n)``."""
    train = subset(data.split["train"], run.train_frames)
    cfg = {**train_cfg, "epochs": run.epochs}
    ckpt = tmp / f"{data.name}_{run.model}_{run.epochs}_{run.train_frames}.pt"
    losses = str(ckpt.with_suffix(".csv"))
    if run.model == "paper":
        train_deepprt(train, data.split["val"], "diffuse", cfg, 1, str(ckpt), losses)
        return ckpt, DeepPRT(ckpt, device="cpu").predict
    local = train_local(
        train, data.split["val"], shadowing_cfg, shadowing_training(cfg), 1, str(ckpt), losses
    )

    def predict(split: frames.Split) -> np.ndarray:
        with torch.no_grad():
            x = torch.from_numpy(raw_inputs(split))
            return np.concatenate([local(x[i : i + 8]).numpy() for i in range(0, len(x), 8)])

    return ckpt, predict


def baselines(
    data: frames.Split, mean_split: frames.Split, n_bands: int
) -> dict[tuple[str, str], np.ndarray]:
    """``(model, "diffuse") -> (F, K, n, n)`` of the two baselines that need no learning."""
    return {
        ("unshadowed", "diffuse"): unseen.unshadowed_baseline(data.positions, n_bands),
        ("static", "diffuse"): unseen.static_baseline(
            mean_split.targets("diffuse")[0], len(data.positions)
        ),
    }


def cases_of(data: ObjectData) -> dict[tuple[str, float], frames.Split]:
    """The test frames (family ``test``, strength 0) and every unseen case."""
    return {("test", 0.0): data.split["test"], **data.unseen}


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", nargs="+", default=["head", "cloth"])
    parser.add_argument("--epochs", type=int, default=8, help="epochs of both models")
    parser.add_argument("--strengths", nargs="+", type=float, default=[0.25, 0.5, 0.75, 1.0])
    parser.add_argument("--per-strength", type=int, default=2, help="frames per strength")
    parser.add_argument("--configfile", nargs="*", default=[], help="as snakemake's (smoke)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/prt_generalisation.csv"))
    parser.add_argument("--merge", nargs="+", help="merge these runs' CSVs (and sidecars) only")
    parser.add_argument("--note", help="--merge: how the runs shared the machine")
    parser.add_argument(
        "--study",
        help="a learning-curve study config (config/studies/deepprt.yaml): its runs instead "
        "of --epochs, its objects, strengths and frames per strength unless given",
    )
    default = LocalConfig(n_bands=1, widths=(), blocks=1)  # the variant's own constants
    parser.add_argument(
        "--width",
        nargs="+",
        type=int,
        default=[default.width],
        help="shadowing: channels (several only with --time-only)",
    )
    parser.add_argument(
        "--dilations", nargs="+", type=int, default=list(default.dilations), help="shadowing"
    )
    parser.add_argument("--skip-paper", action="store_true", help="train the shadowing only")
    parser.add_argument(
        "--time-only",
        action="store_true",
        help="only time freshly initialised networks of every --width (no data, no training)",
    )
    parser.add_argument(
        "--rounds", type=int, default=5, help="--time-only: interleaved timings, median kept"
    )
    args = parser.parse_args()
    if min(args.width) < 1 or not args.dilations or min(args.dilations) < 1:
        parser.error(f"--width {args.width} --dilations {args.dilations}: expected integers >= 1")
    if len(args.width) > 1 and not args.time_only:
        parser.error(f"--width {args.width}: one width per training run (several: --time-only)")
    if args.rounds < 1:
        parser.error(f"--rounds {args.rounds}: expected at least 1")
    return args


def read_study(path: str, args: argparse.Namespace) -> dict:
    """A study config, its keys checked, with the command line's explicit choices applied."""
    study = io.read_yaml(path)
    keys = {"objects", "models", "epochs", "train_frames", "equal_steps"}
    keys |= {"strengths", "per_strength"}
    if not isinstance(study, dict) or set(study) != keys:
        found = sorted(study) if isinstance(study, dict) else type(study).__name__
        raise SystemExit(f"{path}: expected the keys {sorted(keys)}, found {found}")
    explicit = set(sys.argv)
    for key, flag in (("objects", "--objects"), ("strengths", "--strengths")):
        if flag in explicit:
            study[key] = getattr(args, key)
    if "--per-strength" in explicit:
        study["per_strength"] = args.per_strength
    return study


class Rows:
    """The study's tidy rows (object, epochs, train_frames, steps, shadowing width and
    dilations, model, family, strength, metric, value)."""

    def __init__(self, shadowing_cfg: LocalConfig, batch_sizes: dict[str, int]) -> None:
        self.rows: list[dict] = []
        self.width = shadowing_cfg.width
        self.dilations = "-".join(map(str, shadowing_cfg.dilations))
        self.batch_sizes = batch_sizes  # model -> its batch size (a baseline has none)

    def add(self, name, model, family, strength, values, run: Run | None, width=...) -> None:
        """Mean of each metric's values; ``run`` None for a baseline (0 epochs, frames and
        steps)."""
        width = self.width if width is ... else width
        epochs, n = (run.epochs, run.train_frames) if run else (0, 0)
        for metric, v in values.items():
            self.rows.append(
                {
                    "object": name,
                    "epochs": epochs,
                    "train_frames": n,
                    "steps": epochs * -(-n // self.batch_sizes.get(model, 1)),
                    "shadowing_width": width,
                    "shadowing_dilations": None if width is None else self.dilations,
                    "model": model,
                    "family": family,
                    "strength": strength,
                    "metric": metric,
                    "value": float(np.mean(v)),
                }
            )

    def table(self) -> pd.DataFrame:
        return tidy(self.rows)


def time_untrained(args, config, shadowing_cfg: LocalConfig, rows: Rows, tmp: Path) -> None:
    """``--time-only``: the cost of a shape, not of a training (random weights and inputs),
    every width (and the paper's form) interleaved over ``--rounds`` rounds, median kept."""
    prt, model_cfg = config["prt"], config["prt_model"]
    torch.manual_seed(config["seed"])
    n, c = prt["resolution"], shadowing_cfg.out_channels
    fresh = {  # (model, width) -> network; the paper's form has no shadowing width
        ("shadowing", w): ShadowingTransfer(dataclasses.replace(shadowing_cfg, width=w))
        for w in args.width
    }
    if not args.skip_paper:  # the paper's form with an identity normalisation
        norm = Normalisation(np.zeros(3), np.ones(3), np.zeros((c, n, n)), np.ones((c, 1, 1)))
        net = build_network(c, model_cfg["widths"], model_cfg["blocks"])
        fresh[("paper", None)] = TransferNetwork(net, norm)
    x = untrained_frames(n, config["seed"])
    for (model, w), module in fresh.items():
        export_onnx(module.eval(), torch.from_numpy(x), tmp / f"{model}{w}.onnx", rtol=1e-4)
    timings = {key: [] for key in fresh}
    for _ in range(args.rounds):  # interleaved: a change of the machine's load hits all
        for (model, w), module in fresh.items():
            timings[(model, w)].append(network_timing(module, tmp / f"{model}{w}.onnx", x))
    for (model, w), per_round in timings.items():
        median = pd.DataFrame(per_round).median().to_dict()
        rows.add("untrained", model, "timing", 0.0, median, Run(model, 0, 0), width=w)


def study_object(name, runs, strengths, per_strength, ctx, rows: Rows, tmp: Path, save) -> None:
    """Data, every run's training (timed through its shipped ONNX export unless in a
    learning-curve study) and scores, for one object, into ``rows``; ``save(seconds)``
    after each part (a stopped study keeps what it measured)."""
    config, shadowing_cfg, train_cfg, light, timed = ctx
    data, seconds = object_data(name, config, strengths, per_strength, tmp)
    n_bands, model_cfg = config["prt"]["n_bands"], config["prt_model"]
    start = time.perf_counter()
    for case, split in cases_of(data).items():
        preds = baselines(split, data.mean_split, n_bands)
        for model, values in frame_scores(split, preds, light, model_cfg).items():
            rows.add(name, model, *case, values, None)
    seconds[f"{name}_score_baselines"] = time.perf_counter() - start
    save(seconds)
    for run in runs:
        tag = f"{name}_{run.model}_{run.epochs}_{run.train_frames}"
        start = time.perf_counter()
        ckpt, predict = train_run(run, data, shadowing_cfg, train_cfg, tmp)
        seconds[f"{tag}_train"] = time.perf_counter() - start
        print(f"{tag}: trained in {seconds[f'{tag}_train']:.0f} s", flush=True)
        if timed:  # the shipped file's cost: its ONNX export
            onnx_file = ckpt.with_suffix(".onnx")
            export_deepprt(ckpt, data.split["test"], onnx_file)
            module = load_transfer_module(ckpt)
            timing = network_timing(module, onnx_file, raw_inputs(data.split["test"]))
            rows.add(name, run.model, "timing", 0.0, timing, run)
        start = time.perf_counter()
        for case, split in cases_of(data).items():
            preds = {(run.model, "diffuse"): predict(split)}
            for model, values in frame_scores(split, preds, light, model_cfg).items():
                rows.add(name, model, *case, values, run)
        seconds[f"{tag}_score"] = time.perf_counter() - start
        save(seconds)


def main() -> None:
    args = parse_args()
    if args.merge:
        merge(args.merge, Path(args.out), args.note)
        return
    torch.set_num_threads(1)
    commit = subprocess.run(  # at the start: the code that measured
        ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=False
    ).stdout.strip()
    config = load_config(args.configfile)
    prt, model_cfg = config["prt"], config["prt_model"]
    models = ["shadowing"] if args.skip_paper else ["paper", "shadowing"]
    if args.study:
        study = read_study(args.study, args)
        models = [m for m in study["models"] if m in models]
        runs = study_runs(study, models)
        # The sequence holds the most frames any run trains on; each run takes a subset.
        most = max(r.train_frames for r in runs)
        config["prt"]["frames"] = {**prt["frames"], "train": most}
        objects, strengths, per_strength = (
            study[k] for k in ("objects", "strengths", "per_strength")
        )
    else:
        study, objects = None, args.objects
        runs = [Run(m, args.epochs, prt["frames"]["train"]) for m in models]
        strengths, per_strength = args.strengths, args.per_strength
    # The variant's config keys from the same config (its dilated core uses neither widths
    # nor blocks; they are stored with it).
    shadowing_cfg = LocalConfig(
        n_bands=prt["n_bands"],
        widths=model_cfg["widths"],
        blocks=model_cfg["blocks"],
        width=args.width[0],
        dilations=tuple(args.dilations),
    )
    train_cfg = {**model_cfg, "seed": config["seed"], "epochs": args.epochs, "device": "cpu"}
    light = sh.project_latlong(
        lights.procedural_probe(prt["light"], prt["probe_height"]), prt["n_bands"]
    )
    batch_sizes = {"paper": model_cfg["batch_size"], "shadowing": model_cfg["shadowing_batch_size"]}
    rows, seconds = Rows(shadowing_cfg, batch_sizes), {}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ctx = (config, shadowing_cfg, train_cfg, light, study is None)

    def save(more: dict[str, float]) -> None:
        seconds.update(more)
        io.write_csv(out, rows.table())
        write_sidecar(out, args, commit, config, shadowing_cfg, study, runs, seconds)

    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        if args.time_only:
            start = time.perf_counter()
            time_untrained(args, config, shadowing_cfg, rows, tmp)
            save({"time_only": time.perf_counter() - start})
            objects = []
        for name in objects:
            study_object(name, runs, strengths, per_strength, ctx, rows, tmp, save)
            table = rows.table()
            print(
                table[(table.object == name) & (table.metric == "rel_l1_diffuse")]
                .pivot_table(
                    index=["family", "strength"],
                    columns=["model", "epochs", "train_frames"],
                    values="value",
                )
                .round(4)
                .to_string(),
                flush=True,
            )


def write_sidecar(out, args, commit, config, shadowing_cfg, study, runs, seconds) -> None:
    """``out``'s ``.json``: the command, commit, budget, config and seconds of each part."""
    prt, model_cfg = config["prt"], config["prt_model"]
    if args.time_only:
        budget = "timing only (a freshly initialised network)"
    elif study:
        budget = (
            f"learning curves: every model at {study['epochs']} epochs over "
            f"{study['equal_steps']['frames']} training frames, and at "
            f"{study['train_frames']} evenly spaced training frames of a sequence of "
            f"{prt['frames']['train']} for the steps of {study['equal_steps']['epochs']} "
            f"epochs over {study['equal_steps']['frames']} (batch {model_cfg['batch_size']} "
            f"for the paper's form, {model_cfg['shadowing_batch_size']} for the shadowing "
            "variant); "
            f"val {prt['frames']['val']} picks the epoch"
        )
    else:
        who = "the shadowing variant" if args.skip_paper else "both models"
        budget = (
            f"equal epochs: {args.epochs} for {who} over the same {prt['frames']['train']} "
            f"training frames (val {prt['frames']['val']} picks the epoch)"
        )
    meta = {
        "command": f"nice -n {os.nice(0)} python " + " ".join(sys.argv),
        "commit": commit,
        "budget": budget,
        "runs": [dataclasses.asdict(r) for r in runs],
        "config": {
            "resolution": prt["resolution"],
            "directions": prt["directions"],
            "reference_directions": prt["reference_directions"],
            "frames": prt["frames"],
            "light": prt["light"],
            "paper": {k: model_cfg[k] for k in ("widths", "blocks", "lr", "batch_size")},
            "shadowing": vars(shadowing_cfg),
            "shadowing_training": {k: model_cfg[f"shadowing_{k}"] for k in ("lr", "batch_size")},
        },
        "seconds": {k: round(v, 1) for k, v in seconds.items()},
        "torch_threads": 1,
    }
    io.write_json(out.with_suffix(".json"), meta, default=list)


if __name__ == "__main__":
    main()
