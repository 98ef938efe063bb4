"""The metaballs' learning curve: the thesis's network (pix2pix from the circle image)
against the isolated spheres at more training examples and epochs than the default run.

The study config (``config/studies/metaballs_learning_curve.yaml``, whose comment gives the
commands) names the variant and two sweeps: examples at a fixed number of epochs, and
epochs at a fixed number of examples. Every other setting is the pipeline's config
(``config/config.yaml`` and ``--configfile`` files, with the schema's defaults, checked as
the workflow checks it), and every step is the pipeline's own job function
(:mod:`neurender.metaballs.jobs`) with the params its rule gives it
(``neurender.methods.rule(name).job_params``), so a run of ``n`` examples and ``e`` epochs
trains and scores exactly what ``snakemake`` does with ``metaballs.examples.train: n`` and
``metaballs_model.epochs: e``: each run from scratch, with its own cosine schedule over its
epochs (never a checkpoint of a longer run).

Three steps:

* ``data``: the train split at the most examples any run trains on, the val and test
  splits at the config's counts, by the ``metaballs_examples`` job (``--workers``
  processes). Example ``i`` of a split depends on the seed, the split and ``i`` only
  (:func:`neurender.metaballs.data.example_scene`), so the first ``n`` examples of the
  largest split are the split a run of ``n`` examples generates (a test checks it); a run
  takes them (:func:`prefix_split`: hard links and the manifest's and balls' rows).
* ``run``: trains each of ``--runs`` (``EXAMPLESxEPOCHS``; default every run of the study)
  by the ``metaballs_train`` job, one torch thread, and scores it with the
  ``metaballs_evaluate`` job on the test split (the metrics of the default run's
  ``metrics.csv``); the isolated spheres, which need no training, are scored by the same
  job (rows with 0 examples and 0 epochs). Writes a tidy CSV (``examples, epochs, model,
  metric, value, train_seconds``) and its sidecar ``.json`` (command, commit, budget,
  seconds) after each run.
* ``merge``: one CSV and sidecar from the runs' (split over processes side by side, or
  an earlier merge's CSV that later runs extend): the isolated spheres' rows kept once
  (refused if the runs disagree), every run once, the rows by examples and epochs; and the
  figure (``.png`` beside the CSV).
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import os
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from neurender import io, methods
from neurender.config import check
from neurender.metaballs import jobs
from neurender.plan import load_config
from neurender.provenance import cpu_model, git_state

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "config/studies/metaballs_learning_curve.yaml"
OUT = ROOT / "benchmarks/results/metaball_learning_curve.csv"
#: The no-learning baseline scored beside every run (0 examples, 0 epochs).
BASELINE = "isolated spheres"
#: How far the baseline's scores may differ between runs' tables: float rounding on
#: different CPUs (the same test scenes scored on an Intel Xeon and on an AMD EPYC differ by
#: about 7e-6 relative at most, in the median normal error); other test scenes differ by far more.
BASELINE_RTOL = 1e-4
COLUMNS = ["examples", "epochs", "model", "metric", "value", "train_seconds"]
#: The figure's metrics and whether higher is better.
SHOWN = {
    "iou_depth": True,
    "normal_error_mean_deg": False,
    "normal_error_median_deg": False,
    "ssim_normal": True,
    "l1_normal": False,
}
#: The training job's file keys, in the order of the ``metaballs_train`` rule's inputs
#: (their checksum is the training data's fingerprint, as in the pipeline).
TRAIN_KEYS = ("train_dir", "train_manifest", "train_balls", "val_dir", "val_manifest")
TRAIN_KEYS += ("val_balls",)


@dataclasses.dataclass(frozen=True)
class Run:
    """One training: ``epochs`` over the first ``examples`` training examples."""

    examples: int
    epochs: int

    @property
    def label(self) -> str:
        return f"{self.examples}x{self.epochs}"

    @classmethod
    def parse(cls, text: str) -> Run:
        """``EXAMPLESxEPOCHS``, e.g. ``1200x2``."""
        try:
            examples, epochs = (int(part) for part in text.lower().split("x"))
        except ValueError:
            raise ValueError(f"run {text!r}: expected EXAMPLESxEPOCHS, e.g. 1200x2") from None
        if examples < 1 or epochs < 1:
            raise ValueError(f"run {text!r}: examples and epochs must be positive")
        return cls(examples, epochs)


def study_runs(study: Mapping[str, Any]) -> list[Run]:
    """Every run of the study, each once: the examples sweep (at its epochs), the epochs
    sweep (at its examples), then the runs of ``both`` (``EXAMPLESxEPOCHS``, if any)."""
    by_examples, by_epochs = study["examples"], study["epochs"]
    runs = [Run(n, by_examples["epochs"]) for n in by_examples["examples"]]
    runs += [Run(by_epochs["examples"], e) for e in by_epochs["epochs"]]
    runs += [Run.parse(text) for text in study.get("both", [])]
    return list(dict.fromkeys(runs))


def pipeline_config(configfiles: list[str]) -> dict:
    """The config the workflow sees (schema defaults filled in, its rules checked)."""
    config = load_config(configfiles)
    check(config)
    return config


def with_keys(config: Mapping, section: str, **values) -> dict:
    """A copy of ``config`` with ``values`` set in ``section``."""
    out = copy.deepcopy(dict(config))
    out[section] = {**out[section], **values}
    return out


def examples_params(config: Mapping, split: str, count: int) -> dict:
    """The ``metaballs_examples`` job's params of ``split`` with ``count`` examples."""
    examples = {**config["metaballs"]["examples"], split: count}
    cfg = with_keys(config, "metaballs", examples=examples)
    return methods.rule("metaballs_examples").job_params(cfg, {"split": split})


def train_params(config: Mapping, variant: str, epochs: int) -> dict:
    """The ``metaballs_train`` job's params of ``variant`` trained ``epochs`` epochs."""
    cfg = with_keys(config, "metaballs_model", epochs=epochs)
    return methods.rule("metaballs_train").job_params(cfg, {"variant": variant})


def evaluate_params(config: Mapping) -> dict:
    """The ``metaballs_evaluate`` job's params."""
    return methods.rule("metaballs_evaluate").job_params(config, {})


def split_files(root: Path, split: str) -> dict[str, str]:
    """The examples job's outputs of ``split`` under ``root`` (the workflow's names)."""
    return {
        "examples": str(root / split),
        "manifest": str(root / f"{split}_manifest.csv"),
        "balls": str(root / f"{split}_balls.csv"),
    }


def _same_scenes(a: Mapping, b: Mapping) -> bool:
    """Whether two examples jobs' params draw the same scenes (all but the count)."""
    drop = ("examples",)
    return {k: v for k, v in a.items() if k not in drop} == {
        k: v for k, v in b.items() if k not in drop
    }


def make_data(config: Mapping, study: Mapping, root: Path, workers: int) -> dict:
    """Every split the study reads under ``root`` (train at the most examples of its runs,
    val and test at the config's counts) by the examples job; their params and seconds,
    also written to ``root/data.json``."""
    most = max(run.examples for run in study_runs(study))
    counts = {**config["metaballs"]["examples"], "train": most}
    record = {"params": {}, "seconds": {}}
    for split in ("train", "val", "test"):
        params = examples_params(config, split, counts[split])
        start = time.perf_counter()
        jobs.metaballs_examples({}, split_files(root, split), params, workers)
        record["params"][split] = params
        record["seconds"][split] = round(time.perf_counter() - start, 1)
        print(f"{split}: {counts[split]} examples in {record['seconds'][split]} s", flush=True)
    return record


def check_data(config: Mapping, root: Path, runs: list[Run]) -> dict:
    """``root``'s ``data.json``, refused unless its splits are the config's (same scenes,
    val and test counts) and its train split holds every run's examples."""
    path = root / "data.json"
    if not path.is_file():
        raise SystemExit(f"{path}: missing; run the 'data' step first")
    record = json.loads(path.read_text())
    for split in ("train", "val", "test"):
        made = record["params"][split]
        wanted = examples_params(config, split, config["metaballs"]["examples"][split])
        if not _same_scenes(made, wanted) or (split != "train" and made != wanted):
            raise SystemExit(f"{path}: its {split} split was made with {made}; expected {wanted}")
    most = max(run.examples for run in runs)
    if record["params"]["train"]["examples"] < most:
        raise SystemExit(
            f"{path}: {record['params']['train']['examples']} training examples; a run needs {most}"
        )
    return record


def prefix_split(root: Path, count: int, out: Path) -> dict[str, str]:
    """The first ``count`` examples of ``root``'s train split as the examples job writes
    a split of ``count``: the ``train_dir`` folder under ``out`` (hard links to the PNGs,
    copies where links fail), its manifest's and balls' rows; the training job's
    ``train_*`` file keys."""
    files = split_files(root, "train")
    manifest = io.read_csv(files["manifest"], ["example", "file"])
    balls = io.read_csv(files["balls"], ["example"])
    if len(manifest) < count:
        raise ValueError(f"{files['manifest']}: {len(manifest)} examples; {count} wanted")
    manifest = manifest[manifest["example"] < count]
    if sorted(manifest["example"]) != list(range(count)):
        raise ValueError(f"{files['manifest']}: examples 0 to {count - 1} are not all there")
    target = split_files(out, "train")
    folder = Path(target["examples"])
    folder.mkdir(parents=True, exist_ok=True)
    for name in manifest["file"]:
        link, source = folder / name, Path(files["examples"]) / name
        if link.exists():
            link.unlink()
        try:
            os.link(source, link)
        except OSError:
            io.copy_file(source, link)
    io.write_csv(target["manifest"], manifest)
    io.write_csv(target["balls"], balls[balls["example"] < count])
    return {
        "train_dir": target["examples"],
        "train_manifest": target["manifest"],
        "train_balls": target["balls"],
    }


def train_inputs(train: Mapping[str, str], root: Path) -> dict[str, str]:
    """The training job's inputs: ``train`` (:func:`prefix_split`) and ``root``'s val
    split, in the rule's order."""
    val = split_files(root, "val")
    files = {**train, "val_dir": val["examples"], "val_manifest": val["manifest"]}
    files["val_balls"] = val["balls"]
    return {k: files[k] for k in TRAIN_KEYS}


def evaluate(config: Mapping, root: Path, checkpoint: Path, out: Path) -> pd.DataFrame:
    """The evaluation job's ``metrics.csv`` of one checkpoint on ``root``'s test split
    (its other outputs under ``out``)."""
    test = split_files(root, "test")
    inputs = {
        "test_dir": test["examples"],
        "test_manifest": test["manifest"],
        "test_balls": test["balls"],
        "checkpoints": [str(checkpoint)],
    }
    outputs = {
        "metrics": str(out / "metrics.csv"),
        "examples": str(out / "metrics_examples.csv"),
        "by_scene": str(out / "accuracy_by_scene.csv"),
        "figure": str(out / "comparison.png"),
        "scene_figure": str(out / "accuracy_by_scene.png"),
    }
    jobs.metaballs_evaluate(inputs, outputs, evaluate_params(config), 1)
    return io.read_csv(outputs["metrics"], ["model", "metric", "value"])


def rows_of(metrics: pd.DataFrame, model: str, run: Run | None, seconds: float) -> list[dict]:
    """Tidy rows (:data:`COLUMNS`) of one model's metrics; ``run`` None: the baseline's."""
    examples, epochs = (0, 0) if run is None else (run.examples, run.epochs)
    mine = metrics[metrics["model"] == model]
    if mine.empty:
        raise ValueError(f"no metrics of {model!r} in the evaluation")
    return [
        dict(
            examples=examples,
            epochs=epochs,
            model=model,
            metric=m,
            value=float(v),
            train_seconds=seconds,
        )
        for m, v in zip(mine["metric"], mine["value"], strict=True)
    ]


def run_study(
    config: Mapping,
    variant: str,
    runs: list[Run],
    root: Path,
    work: Path,
    save,
) -> None:
    """Train and score every run (checkpoints under ``work``); ``save(rows, seconds)``
    after each."""
    rows, seconds = [], {}
    for i, run in enumerate(runs):
        folder = work / run.label
        folder.mkdir(parents=True, exist_ok=True)
        inputs = train_inputs(prefix_split(root, run.examples, folder), root)
        checkpoint = folder / f"{variant}.pt"
        outputs = {
            "checkpoint": str(checkpoint),
            "loss": str(folder / f"{variant}_loss.csv"),
            "tensorboard": str(folder / "tensorboard" / "run.json"),
        }
        start = time.perf_counter()
        jobs.metaballs_train(inputs, outputs, train_params(config, variant, run.epochs), 1)
        train_s = time.perf_counter() - start
        start = time.perf_counter()
        metrics = evaluate(config, root, checkpoint, folder / "evaluation")
        seconds[f"{run.label}_train"] = train_s
        seconds[f"{run.label}_evaluate"] = time.perf_counter() - start
        if i == 0:
            rows += rows_of(metrics, BASELINE, None, 0.0)
        rows += rows_of(metrics, variant, run, round(train_s, 1))
        print(f"{run.label}: trained in {train_s:.0f} s", flush=True)
        save(rows, seconds)


def order(table: pd.DataFrame) -> pd.DataFrame:
    """The rows by examples, then epochs (the baseline's, 0 and 0, first), each run's
    metrics those of :data:`SHOWN` first, in its order, then the others as they came: the
    order of the report's view."""
    shown = list(SHOWN)
    rank = [shown.index(m) if m in SHOWN else len(shown) for m in table["metric"]]
    return (
        table.assign(_rank=rank, _row=range(len(table)))
        .sort_values(["examples", "epochs", "_rank", "_row"])
        .drop(columns=["_rank", "_row"])
        .reset_index(drop=True)
    )


def merge_tables(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """One table of several runs' tables: the baseline's rows once, the first table's
    (``ValueError`` when the tables disagree on them beyond :data:`BASELINE_RTOL`),
    ``ValueError`` for a run of the variant in two tables."""
    baselines = [t[t["model"] == BASELINE].reset_index(drop=True) for t in tables]
    baselines = [b for b in baselines if len(b)]
    for other in baselines[1:]:
        first = baselines[0]
        same_rows = other.drop(columns="value").equals(first.drop(columns="value"))
        if not same_rows or not np.allclose(other["value"], first["value"], rtol=BASELINE_RTOL):
            raise ValueError(
                f"the runs' {BASELINE} rows differ beyond a relative {BASELINE_RTOL:g}; "
                "expected the same test scenes scored alike"
            )
    trained = pd.concat([t[t["model"] != BASELINE] for t in tables], ignore_index=True)
    keys = ["examples", "epochs", "model", "metric"]
    twice = trained[trained.duplicated(keys, keep=False)]
    if len(twice):
        found = sorted({f"{n}x{e}" for n, e in zip(twice.examples, twice.epochs, strict=True)})
        raise ValueError(f"runs {found} are in more than one table; expected each once")
    table = pd.concat([*baselines[:1], trained], ignore_index=True)
    return order(table)[COLUMNS]


def beats(table: pd.DataFrame, variant: str) -> pd.DataFrame:
    """Per run of ``variant`` and :data:`SHOWN` metric: its value, the baseline's and
    whether it is better (strictly)."""
    base = table[table["model"] == BASELINE].set_index("metric")["value"]
    mine = table[(table["model"] == variant) & table["metric"].isin(list(SHOWN))].copy()
    mine["baseline"] = mine["metric"].map(base)
    higher = mine["metric"].map(SHOWN)
    mine["better"] = (mine["value"] > mine["baseline"]).where(
        higher, mine["value"] < mine["baseline"]
    )
    return mine[["examples", "epochs", "metric", "value", "baseline", "better"]].reset_index(
        drop=True
    )


def figure(table: pd.DataFrame, study: Mapping, variant: str, path: Path) -> None:
    """Each :data:`SHOWN` metric of ``variant`` against the examples (top row, at the
    examples sweep's epochs), against the epochs (middle row, at the epochs sweep's
    examples) and against examples x epochs (bottom row: both sweeps and the runs off
    them, labelled), the isolated spheres as a dashed line."""
    from neurender.plots import plt, save_figure

    base = table[table["model"] == BASELINE].set_index("metric")["value"]
    mine = table[table["model"] == variant].assign(budget=lambda t: t["examples"] * t["epochs"])
    at_epochs, at_examples = study["examples"]["epochs"], study["epochs"]["examples"]
    by_examples = mine[mine["epochs"] == at_epochs]
    by_epochs = mine[mine["examples"] == at_examples]
    off = mine[(mine["epochs"] != at_epochs) & (mine["examples"] != at_examples)]
    rows = [
        ("examples", [(by_examples, "o-", variant)], f"training examples (epochs {at_epochs})"),
        ("epochs", [(by_epochs, "o-", variant)], f"epochs (examples {at_examples})"),
        (
            "budget",
            [
                (by_examples, "o-", f"more examples (epochs {at_epochs})"),
                (by_epochs, "s-", f"more epochs (examples {at_examples})"),
                (off, "*", "both (labelled)"),
            ],
            "examples x epochs",
        ),
    ]
    fig, axes = plt.subplots(3, len(SHOWN), figsize=(3.0 * len(SHOWN), 8.4), squeeze=False)
    for row, (x, lines, label) in enumerate(rows):
        for col, (metric, higher) in enumerate(SHOWN.items()):
            ax = axes[row, col]
            ticks = set()
            for part, style, name in lines:
                values = part[part["metric"] == metric].sort_values(x)
                ax.plot(values[x], values["value"], style, label=name, markersize=5)
                ticks |= set(values[x])
                for _, point in values.iterrows() if style == "*" else ():
                    run = f"{point['examples']}x{point['epochs']}"
                    ax.annotate(
                        run,
                        (point[x], point["value"]),
                        xytext=(-4, 4),
                        textcoords="offset points",
                        ha="right",
                        fontsize=7,
                    )
            ax.axhline(base[metric], color="grey", linestyle="--", label=BASELINE)
            ax.set_xscale("log", base=2)
            ticks = sorted(ticks)
            ax.set_xticks(ticks, [str(v) for v in ticks], rotation=45 if x == "budget" else 0)
            ax.minorticks_off()
            ax.set_xlabel(label)
            if row == 0:
                ax.set_title(f"{metric}\n({'higher' if higher else 'lower'} is better)", fontsize=9)
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7)
    axes[2, 0].legend(fontsize=7)
    fig.suptitle(f"{variant} against the isolated spheres on the test scenes", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def merge(csvs: list[str], out: Path, study_path: Path, note: str | None) -> None:
    """One CSV, sidecar and figure of several runs' (``csvs`` and their sidecars; a CSV
    may be an earlier merge's, whose sidecar lists its steps): the sidecar lists each data
    step once, before the runs that read it."""
    study = io.read_yaml(study_path)
    records = [json.loads(Path(csv).with_suffix(".json").read_text()) for csv in csvs]
    table = merge_tables([pd.read_csv(csv) for csv in csvs])
    io.write_csv(out, table)
    runs = []
    for record in records:
        if "runs" in record:  # an earlier merge's: its steps as they were
            runs += [r for r in record["runs"] if r not in runs]
            continue
        data = {k: record["data"][k] for k in ("command", "commit", "dirty", "note")}
        runs += [data] if data not in runs else []
        runs.append({k: v for k, v in record.items() if k != "data"})
    note = note or (
        "The data step made the examples once; the runs' processes ran side by side, one "
        "torch thread each, niced, on the shared 2-core machine (their commands say the "
        "nice), then merged by 'python benchmarks/metaball_learning_curve.py merge'. "
        "Seconds are wall times under that sharing."
    )
    io.write_json(out.with_suffix(".json"), {"note": note, "runs": runs})
    figure(table, study, study["variant"], out.with_suffix(".png"))
    verdict = beats(table, study["variant"])
    print(verdict.to_string(), flush=True)


def machine_note() -> str:
    """The CPU, its cores and the load when a step starts."""
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    return f"{cpu_model()}, {os.cpu_count()} cores, load average {load} at the start"


def command_line(argv: list[str]) -> str:
    """The command that runs this script with ``argv``, with its nice."""
    script = Path(__file__).resolve().relative_to(ROOT)
    return f"nice -n {os.nice(0)} python {script} " + " ".join(argv)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    steps = parser.add_subparsers(dest="step", required=True)
    for name in ("data", "run"):
        step = steps.add_parser(name)
        step.add_argument("--study", default=str(STUDY), help="the study config")
        step.add_argument("--data", required=True, help="the examples' folder")
        step.add_argument("--configfile", nargs="*", default=[], help="as snakemake's")
    steps.choices["data"].add_argument("--workers", type=int, default=2)
    run = steps.choices["run"]
    run.add_argument("--runs", nargs="+", type=Run.parse, help="EXAMPLESxEPOCHS (all)")
    run.add_argument("--work", help="checkpoints' folder (default: DATA/runs)")
    run.add_argument("--out", default=str(OUT))
    merged = steps.add_parser("merge")
    merged.add_argument("csvs", nargs="+")
    merged.add_argument("--study", default=str(STUDY))
    merged.add_argument("--out", default=str(OUT))
    merged.add_argument("--note", help="how the runs shared the machine")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    if args.step == "merge":
        merge(args.csvs, Path(args.out), Path(args.study), args.note)
        return
    import torch

    torch.set_num_threads(1)
    state = git_state(ROOT)  # at the start: the code that measured
    study = io.read_yaml(args.study)
    config = pipeline_config(args.configfile)
    root = Path(args.data)
    if args.step == "data":
        root.mkdir(parents=True, exist_ok=True)
        record = {"command": command_line(argv), **state, "note": machine_note()}
        start = time.perf_counter()
        record |= make_data(config, study, root, args.workers)
        seconds = time.perf_counter() - start
        record["note"] += f"; {seconds:.0f} s with {args.workers} example processes"
        io.write_json(root / "data.json", record)
        return
    runs = args.runs or study_runs(study)
    data = check_data(config, root, runs)
    work = Path(args.work) if args.work else root / "runs"
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    variant = study["variant"]
    params = train_params(config, variant, 0)
    meta = {
        "command": command_line(argv),
        **state,
        "note": machine_note(),
        "budget": (
            f"{variant} trained from scratch at each of {[r.label for r in runs]} "
            "(EXAMPLESxEPOCHS; each its own cosine schedule), every other setting the "
            "config's; scored on the test split by the metaballs_evaluate job"
        ),
        "train_params": {k: v for k, v in params.items() if k != "epochs"},
        "evaluate_params": evaluate_params(config),
        "data": data,
        "torch_threads": 1,
    }

    def save(rows: list[dict], seconds: dict[str, float]) -> None:
        io.write_csv(out, order(pd.DataFrame(rows, columns=COLUMNS)))
        meta["seconds"] = {k: round(v, 1) for k, v in seconds.items()}
        io.write_json(out.with_suffix(".json"), meta)

    run_study(config, variant, runs, root, work, save)


if __name__ == "__main__":
    main()
