"""The prepared GPU check: the networks at the papers' widths and resolutions on a GPU.

    # here (CPU), once: a small sample of a finished smoke or default run
    python benchmarks/gpu_check.py make-data results benchmarks/gpu_check_data.npz
    # on the GPU machine (benchmarks/gpu_check.sh does this), or on the CPU with --dry
    python benchmarks/gpu_check.py run benchmarks/gpu_check_data.npz out.csv

For each network (DeepPRT's ResUNet, NDR, the thesis's pix2pix and our sphere_residual
metaball generator) at its ``config/paper.yaml`` widths and resolution:

* training steps through the project's own loop (:func:`neurender.train.fit`) on the
  sample resized to that resolution: seconds per step and peak GPU memory;
* a resume on the device: a run interrupted after its first epoch continues from its
  resume file (CUDA RNG included) and ends with the weights of an uninterrupted run
  (deterministic kernels for this part; the largest difference is reported);
* the ONNX export with its check against PyTorch;
* milliseconds per frame at batch one: PyTorch on the device, ONNX Runtime on the CPU.

One CSV row per network. ``rule`` and ``units_per_step`` (the work of one step in
:func:`neurender.costs.work`'s units) let ``python -m neurender.plan`` turn the rates into
GPU-hours. ``--dry`` runs it all on the CPU at tiny widths for two steps (CI keeps it
working that way).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import torch.nn.functional as F
from torch import nn
from torch.utils.data import Dataset

from neurender import train
from neurender.metaballs.method import gan_step_cost
from neurender.method import unet_work
from neurender.nn.inference import OnnxNetwork, export_onnx
from neurender.nn.unet import count_parameters
from neurender.timing import hardware, timed

NDR_GROUPS = {"N": 3, "R": 1, "D": 1, "A_D": 3, "A_S": 3, "S_D": 3, "S_S": 3, "I_D": 3, "I_S": 3}


def make_data(results: Path, out: Path, count: int = 4) -> None:
    """A few samples of each method's training data from a finished run, as one NPZ."""
    from neurender import io
    from neurender.metaballs.ab import read_ab
    from neurender.prt.frames import read_frame

    prt = [read_frame(p, 4) for p in sorted((results / "prt/head/train").glob("*.exr"))[:count]]
    ndr = [io.read_exr(p) for p in sorted((results / "ndr/train").glob("*.exr"))[:count]]
    ab = [read_ab(p) for p in sorted((results / "metaballs/train").glob("*.png"))[:count]]
    arrays = {
        "prt_inputs": np.stack([np.concatenate([f["P"], f["N"]], -1) for f in prt]),
        "prt_targets": np.stack([f["T"] for f in prt]),
        "metaballs_inputs": np.stack([e["inputs"].permute(1, 2, 0).numpy() for e in ab]),
        "metaballs_targets": np.stack([e["target"].permute(1, 2, 0).numpy() for e in ab]),
    }
    for group in NDR_GROUPS:
        names = sorted(k for k in ndr[0] if k == group or k.startswith(f"{group}."))
        arrays[f"ndr_{group}"] = np.stack([np.stack([b[n] for n in names], -1) for b in ndr])
    io.save_npz(out, **arrays)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)")


def resized(images: np.ndarray, side: int, count: int) -> torch.Tensor:
    """``(N, H, W, C)`` samples, repeated to ``count`` and resized (bilinear) to
    ``(count, C, side, side)`` float32."""
    x = torch.from_numpy(np.asarray(images, np.float32)).permute(0, 3, 1, 2)
    x = F.interpolate(x, size=(side, side), mode="bilinear")
    return x[torch.arange(count) % len(x)].contiguous()


class Samples(Dataset):
    """Equally long tensors: each item a tuple of their rows, or a dict with ``keys``."""

    def __init__(self, tensors: list[torch.Tensor], keys: list[str] | None = None):
        self.tensors, self.keys = tensors, keys

    def __len__(self) -> int:
        return len(self.tensors[0])

    def __getitem__(self, i: int):
        rows = [t[i] for t in self.tensors]
        return dict(zip(self.keys, rows, strict=True)) if self.keys else tuple(rows)

    def first(self, n: int) -> tuple[torch.Tensor, ...]:
        return tuple(t[:n] for t in self.tensors)


@dataclasses.dataclass
class Check:
    """One network: the module trained, its data and loss, what ships (``graph`` with
    ``graph_inputs`` of a batch) and the work of one step."""

    name: str
    rule: str
    model: nn.Module
    data: Samples
    loss: object
    batch_size: int
    units_per_step: float
    graph: nn.Module
    graph_inputs: tuple[torch.Tensor, ...]
    adversary: train.Adversary | None = None


def _l1(model, batch):
    x, y = batch
    return F.l1_loss(model(x), y), {}


def deepprt_check(data: dict, count: int, dry: bool) -> Check:
    from neurender.prt.model import build_network

    side, widths = (16, [8, 16]) if dry else (256, [64, 128, 256, 512])
    samples = Samples([resized(data["prt_inputs"], side, count), torch.rand(count, 16, side, side)])
    model = build_network(16, widths, 1)
    units = 5 * side * side * unet_work(widths) / 1e6
    return Check(
        "deepprt_diffuse", "prt_train", model, samples, _l1, 5, units, model, samples.first(2)[:1]
    )


def ndr_check(data: dict, count: int, dry: bool) -> Check:
    from neurender.ndr.deploy import NDRGraph, graph_inputs
    from neurender.ndr.model import NDRModel, loss_terms
    from neurender.ndr.variants import VARIANTS

    side, widths, hidden = (32, [8, 16], 8) if dry else (256, [32, 64, 128, 256, 512, 512], 256)
    groups = {g: resized(data[f"ndr_{g}"], side, count) for g in NDR_GROUPS}
    groups |= {"mask": torch.ones(count, 1, side, side), "light": torch.rand(count, 75)}
    samples = Samples(list(groups.values()), list(groups))
    model = NDRModel(VARIANTS["ndr"], widths=widths, sh_hidden=hidden, shading_residual=True)
    example = graph_inputs(model, {k: v[:2] for k, v in groups.items()})
    units = 16 * side * side * unet_work(widths) / 1e6
    return Check(
        "ndr",
        "ndr_train",
        model,
        samples,
        lambda m, b: loss_terms(m, b)[:2],
        16,
        units,
        NDRGraph(model),
        example,
    )


def metaballs_check(data: dict, count: int, dry: bool, variant: str) -> Check:
    from neurender.metaballs.deploy import GeneratorGraph
    from neurender.metaballs.model import build_discriminator, build_generator, input_channels
    from neurender.metaballs.training import discriminator_loss, generator_loss

    side, ngf = (32, 4) if dry else (512, 64)
    x = resized(data["metaballs_inputs"], side, count)
    pad = input_channels(variant) - x.shape[1]  # impostor channels: zero for timing
    x = torch.cat([x, torch.zeros(count, pad, side, side)], 1) * 2 - 1
    samples = Samples([x, resized(data["metaballs_targets"], side, count) * 2 - 1])
    generator = build_generator(side, ngf, variant)
    gan = variant == "pix2pix"
    discriminator = build_discriminator(ngf, variant) if gan else None
    adversary = train.Adversary(discriminator, discriminator_loss) if gan else None
    units = side * side * ngf**2 * (gan_step_cost(ngf, ngf) if gan else 1.0) / 1e9
    return Check(
        f"metaballs_{variant}",
        "metaballs_train",
        generator,
        samples,
        generator_loss(100.0 if gan else 1.0, 1.0 if gan else 0.0, discriminator),
        1,
        units,
        GeneratorGraph(generator, gan),
        ((x[:2] + 1) / 2,),
        adversary,
    )


def _fit(check: Check, device: str, epochs: int, folder: Path, name: str, data=None, loss=None):
    config = train.TrainConfig(
        epochs=epochs,
        batch_size=check.batch_size,
        lr=1e-4,
        lr_schedule="cosine",
        device=device,
        seed=0,
        threads=os.cpu_count() or 1,
    )
    torch.manual_seed(0)
    train.fit(
        check.model,
        train.FitData(data or check.data, None),
        loss or check.loss,
        config,
        train.FitOutputs(folder / f"{name}.pt", folder / f"{name}.csv"),
        check.adversary,
    )
    return config


def resume_difference(check: Check, device: str, folder: Path) -> float:
    """Largest weight difference between an uninterrupted two-epoch run and one killed
    after its first epoch and resumed (deterministic kernels)."""
    torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark = True, False
    small = Samples(list(check.data.first(2 * check.batch_size)), check.data.keys)
    initial = {k: v.clone() for k, v in check.model.state_dict().items()}
    _fit(check, device, 2, folder, "full", small)
    full = {k: v.detach().cpu().clone() for k, v in check.model.state_dict().items()}
    check.model.load_state_dict(initial)
    calls = {"n": 0}

    def interrupting(model, batch):
        calls["n"] += 1
        if calls["n"] > 2:  # two steps per epoch: stop in the second epoch
            raise KeyboardInterrupt
        return check.loss(model, batch)

    try:
        _fit(check, device, 2, folder, "resumed", small, interrupting)
    except KeyboardInterrupt:
        pass
    check.model.load_state_dict(initial)
    _fit(check, device, 2, folder, "resumed", small)
    resumed = check.model.state_dict()
    return max(float((full[k] - resumed[k].detach().cpu()).abs().max()) for k in full)


def run_check(check: Check, device: str, steps: int, folder: Path) -> dict:
    cuda = device.startswith("cuda")
    check.model.to(device)
    # A warm-up (kernel selection, allocator), then the timed steps.
    _fit(
        check,
        device,
        1,
        folder,
        "warmup",
        Samples(list(check.data.first(check.batch_size)), check.data.keys),
    )
    if cuda:
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
    started = time.perf_counter()
    _fit(check, device, 1, folder, "timed")
    seconds = (time.perf_counter() - started) / steps
    peak = torch.cuda.max_memory_allocated() / 2**20 if cuda else float("nan")
    difference = resume_difference(check, device, folder)
    graph = check.graph.cpu().eval()
    onnx_error = export_onnx(
        graph,
        check.graph_inputs,
        folder / f"{check.name}.onnx",
        atol=1e-2,
        input_names=tuple(f"x{i}" for i in range(len(check.graph_inputs))),
    )
    one = tuple(x[:1] for x in check.graph_inputs)
    graph.to(device)
    with torch.inference_mode():
        _, torch_s = timed(graph, *(x.to(device) for x in one), repeats=11, warmup=2)
    session = OnnxNetwork(folder / f"{check.name}.onnx", os.cpu_count() or 1)
    _, onnx_s = timed(session, *(x.numpy() for x in one), repeats=5, warmup=1)
    return {
        "network": check.name,
        "rule": check.rule,
        "device": device,
        "hardware": hardware(os.cpu_count() or 1),
        "parameters": count_parameters(check.model),
        "batch_size": check.batch_size,
        "steps": steps,
        "seconds_per_step": seconds,
        "steps_per_s": 1 / seconds,
        "units_per_step": check.units_per_step,
        "peak_gpu_memory_mb": peak,
        "resume_max_abs_diff": difference,
        "onnx_max_abs_diff": onnx_error,
        "ms_per_frame_pytorch": 1000 * torch_s,
        "ms_per_frame_onnxruntime_cpu": 1000 * onnx_s,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    make = sub.add_parser("make-data")
    make.add_argument("results", type=Path)
    make.add_argument("out", type=Path)
    run = sub.add_parser("run")
    run.add_argument("data", type=Path)
    run.add_argument("out", type=Path)
    run.add_argument("--steps", type=int, default=20)
    run.add_argument("--dry", action="store_true", help="CPU, tiny widths, two steps")
    args = parser.parse_args(argv)
    if args.command == "make-data":
        make_data(args.results, args.out)
        return 0
    device = "cpu" if args.dry else "cuda"
    steps = 2 if args.dry else args.steps
    from neurender import io

    data = io.load_npz(args.data)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for build in (deepprt_check, ndr_check):
            check = build(data, steps * (5 if build is deepprt_check else 16), args.dry)
            rows.append(run_check(check, device, steps, Path(tmp)))
            print(pd.DataFrame(rows[-1:]).T.to_string(header=False), flush=True)
        for variant in ("pix2pix", "sphere_residual"):
            check = metaballs_check(data, steps, args.dry, variant)
            rows.append(run_check(check, device, steps, Path(tmp)))
            print(pd.DataFrame(rows[-1:]).T.to_string(header=False), flush=True)
    io.write_csv(args.out, pd.DataFrame(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
