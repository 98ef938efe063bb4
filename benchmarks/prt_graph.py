"""The shipped shadowing DeepPRT graph (:class:`neurender.prt.local_model.ShadowingTransfer`)
timed per part by ONNX Runtime.

nice -n 15 python benchmarks/prt_graph.py benchmarks/results/prt_graph

The default config's architecture (4 bands; dilated core of width 48, dilations 1 2 4 8 1;
disks on a 16 x 16 grid read by the core and gating its correction; local mean over 15
pixels) at 64 x 64, diffuse and glossy, with weights at initialisation (the time does not
depend on them; the core's head, zero at initialisation, drawn small and random instead)
and one frame of a bumpy height field (the time does not depend on the shape either).
Each part is its own ONNX file, checked against PyTorch by
:func:`neurender.nn.inference.export_onnx`; each maps the raw ``(1, 6, 64, 64)`` P and N
images to what the whole graph computes from them, except the core network, which reads
the features and the normalised occlusion the graph gives it. The whole graph is the
inference form :func:`neurender.prt.model.export_deepprt` ships.

Writes ``<out>.csv``: per material, part and thread count, the median milliseconds of one
frame by ONNX Runtime and by PyTorch (the parts timed in turn, the least loaded of
:data:`ROUNDS` rounds) and the export check's largest difference; ``<out>.json``: the
command, commit and hardware.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from torch import nn

from neurender import io
from neurender.nn.inference import export_onnx, part_rows, prepare_for_inference
from neurender.provenance import git_state
from neurender.prt import unshadowed
from neurender.prt.local_model import LocalConfig, ShadowingTransfer, local_features

#: Geometry image side, pixels; SH bands of the transfer.
SIDE, N_BANDS = 64, 4
ROOT = Path(__file__).resolve().parents[1]
#: Rounds of timing per thread count (the least loaded is kept).
ROUNDS = 3


class Part(nn.Module):
    """One computation of a :class:`ShadowingTransfer` as a module of the raw inputs
    ``(B, 6, n, n)``, named by ``part`` (one of :data:`PARTS`; the core reads ``(B, 6 + C,
    n, n)`` features instead)."""

    def __init__(self, model: ShadowingTransfer, part: str):
        super().__init__()
        self.model, self.part = model, part

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.part == "unshadowed transfer":
            return self.model.unshadowed(x[:, 3:])
        if self.part == "disks' occlusion":
            return self.model.occlusion(x)
        if self.part == "local features":
            return local_features(x, self.model.cfg.window)
        return self.model.core(x)


#: The parts timed, besides the whole graph.
PARTS = ("unshadowed transfer", "disks' occlusion", "local features", "core network")


def frame(side: int = SIDE) -> torch.Tensor:
    """``(1, 6, side, side)`` P and N images of the height field ``z = 0.1 sin(6u) cos(5v)``
    over the unit square (world units; unit normals)."""
    u, v = torch.meshgrid(torch.linspace(0, 1, side), torch.linspace(0, 1, side), indexing="xy")
    z = 0.1 * torch.sin(6 * u) * torch.cos(5 * v)
    dz_du, dz_dv = (
        0.6 * torch.cos(6 * u) * torch.cos(5 * v),
        -0.5 * torch.sin(6 * u) * torch.sin(5 * v),
    )
    normals = torch.nn.functional.normalize(
        torch.stack([-dz_du, -dz_dv, torch.ones_like(z)]), dim=0
    )
    return torch.cat([torch.stack([u, v, z]), normals])[None]


def shadowing_model(material: str, seed: int) -> ShadowingTransfer:
    """The default config's shadowing variant for ``material`` at initialisation (head
    drawn at random, std 0.01), in the inference form that is shipped; glossy under a
    random SH light whose DC term dominates."""
    torch.manual_seed(seed)
    light = glossy_coeffs = None
    if material == "glossy":
        rng = np.random.default_rng(seed)
        light = 0.2 * rng.normal(size=(N_BANDS**2, 3))
        light[0] = 1.0
        glossy_coeffs = unshadowed.glossy_polynomial(light)
    cfg = LocalConfig(n_bands=N_BANDS, material=material, widths=(16,), blocks=1)
    model = ShadowingTransfer(cfg, glossy_coeffs, light)
    nn.init.normal_(model.core.head.weight, std=0.01)
    for p in model.parameters():
        p.requires_grad_(False)
    return prepare_for_inference(model)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="output prefix, e.g. benchmarks/results/prt_graph")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    # The checkout's state before this run rewrites its own (tracked) results.
    sidecar = {"command": " ".join(["python", *sys.argv]), **git_state(ROOT)}
    x = frame()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for material in ("diffuse", "glossy"):
            model = shadowing_model(material, args.seed)
            with torch.inference_mode():
                occlusion = model.occlusion(x)
                core_input = torch.cat([local_features(x, model.cfg.window), occlusion], 1)
            parts = {name: (Part(model, name), x) for name in PARTS}
            parts["core network"] = (Part(model, "core network"), core_input)
            parts["whole graph"] = (model, x)
            files, errors = {}, {}
            for k, (name, (module, inputs)) in enumerate(parts.items()):
                files[name] = Path(tmp) / f"{material}_{k}.onnx"
                pair = torch.cat([inputs, inputs])  # the export needs a batch of 2
                errors[name] = export_onnx(module, pair, files[name], rtol=1e-4)
            timed_parts = {name: (m, files[name], (x_,)) for name, (m, x_) in parts.items()}
            for threads in (1, 2):
                for row in part_rows(timed_parts, errors, threads, ROUNDS):
                    rows.append({"material": material, **row})
                    print(rows[-1], flush=True)
    io.write_csv(Path(args.out).with_suffix(".csv"), pd.DataFrame(rows))
    io.write_json(f"{args.out}.json", sidecar)


if __name__ == "__main__":
    main()
