"""The shipped NDR graph (:mod:`neurender.ndr.shipped`) timed per part by ONNX Runtime.

nice -n 15 python benchmarks/ndr_graph.py benchmarks/results/ndr_graph

The default config's network (variant ``ndr``, widths 16 32 64 128, SH layers 64; its
weights at initialisation: the time does not depend on them) at 64 x 64, one random object
of the data under a real-world-like map, its sun and six lights without power: 7 lights, as
many as the median test map of the default config has bright texels (a frame's shading
grows with them; :func:`neurender.ndr.prefiltered.bright_lights`). Three ONNX files, each
checked against PyTorch by :func:`neurender.nn.inference.export_onnx`: the prefiltered
coarse shading alone, the network alone (:class:`neurender.ndr.deploy.NDRGraph`, what
``ndr_deploy`` ships today) and the two in one graph. Each also as an int8 graph (``...
int8 convolutions``): its convolutions quantized by ONNX Runtime's static QDQ quantizer
(:func:`neurender.nn.inference.quantize_convolutions`: weights per channel, activations
calibrated on this frame), timed by ONNX Runtime alone.
The int8 rows measure speed only: with weights at initialisation their difference from
float32 says nothing about a trained network's quality, which is not measured here.
Writes ``<out>.csv``: per part and thread count, the median milliseconds of one frame by
ONNX Runtime and by PyTorch (the parts timed in turn, the least loaded of :data:`ROUNDS`
rounds), and the check's largest difference (for int8, from the float32 graph's output);
``<out>.json``: the command, commit and hardware.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.ndr import environments, objects, render
from neurender.ndr import prefiltered as pf
from neurender.ndr.deploy import INPUTS as NETWORK_INPUTS
from neurender.ndr.deploy import NDRGraph, graph_groups
from neurender.ndr.model import NDRModel
from neurender.ndr.shipped import DYNAMIC_AXES, INPUTS, ShadingPart, ShippedNDR, gbuffer_groups
from neurender.ndr.variants import VARIANTS
from neurender.nn.inference import (
    OnnxNetwork,
    export_onnx,
    part_rows,
    quantize_convolutions,
)
from neurender.provenance import git_state
from neurender.timing import hardware, timed

WIDTH, DISTANCE, FOV, ENV_HEIGHT, COARSE_HEIGHT = 64, 3.9, 30.0, 128, 16
#: Lights of the timed frame (see main).
LIGHTS = 7
ROOT = Path(__file__).resolve().parents[1]
#: Rounds of timing per thread count (the least loaded is kept).
ROUNDS = 3


def buffers(seed: int) -> dict[str, torch.Tensor]:
    """One sample's G-buffers ``(1, C, W, W)`` by group, as the data stage stores them."""
    rng = np.random.default_rng(seed)
    obj = objects.random_object(rng, (2, 7), 0.2)
    g = render.g_buffers(obj, render.camera(DISTANCE, FOV), WIDTH)
    names = {"N": "normal", "R": "roughness", "D": "depth", "mask": "mask"}
    names |= {"A_D": "albedo_diffuse", "A_S": "albedo_specular"}
    out = {}
    for group, key in names.items():
        x = torch.from_numpy(np.ascontiguousarray(g[key], np.float32))
        out[group] = (x[..., None] if x.ndim == 2 else x).permute(2, 0, 1)[None]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="output prefix, e.g. benchmarks/results/ndr_graph")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    # The checkout's state before this run rewrites its own (tracked) results.
    sidecar = {"command": " ".join(["python", *sys.argv]), **git_state(ROOT)}
    torch.manual_seed(args.seed)
    model = NDRModel(VARIANTS["ndr"], widths=[16, 32, 64, 128], sh_hidden=64).eval()
    shipped = ShippedNDR(model, DISTANCE, FOV, WIDTH)
    g = buffers(args.seed)
    env = environments.sunlit_environment(np.random.default_rng(args.seed), ENV_HEIGHT)
    light = pf.lighting(env, environments.resize_latlong(env, COARSE_HEIGHT))
    # As many lights as the median test map of the default config has bright texels (its
    # sunlit map has one): a frame's time grows with them.
    lights = pf.stack_lights([light.lights, pf.no_lights(LIGHTS)])[:1, :LIGHTS]
    gbuffers = torch.cat([g[k] for k in gbuffer_groups(model)], 1)
    per_map = (light.coefficients.reshape(1, -1), light.irradiance[None], light.cells[None])
    inputs = tuple(x.float() for x in (gbuffers, *per_map, lights))
    with torch.inference_mode():
        batch = shipped.batch(*inputs)
    network_inputs = (torch.cat([batch[k] for k in graph_groups(model)], 1), batch["light"])
    parts = {
        "coarse shading (prefiltered)": (ShadingPart(shipped.shading), inputs, INPUTS),
        "network": (NDRGraph(model), network_inputs, NETWORK_INPUTS),
        "shading + network (one graph)": (shipped, inputs, INPUTS),
    }
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files, errors = {}, {}
        for k, (name, (module, x, names)) in enumerate(parts.items()):
            files[name] = Path(tmp) / f"{k}.onnx"
            pair = tuple(torch.cat([t, t]) for t in x)  # the export needs a batch of 2
            errors[name] = export_onnx(
                module,
                pair,
                files[name],
                atol=1e-3,
                rtol=1e-4,
                input_names=names,
                dynamic_axes=DYNAMIC_AXES,
            )
        # The int8 graphs, each against its float32 graph's output on the same frame.
        int8 = {}
        for name, (_, x, names) in parts.items():
            arrays = [t.numpy() for t in x]
            target = files[name].with_suffix(".int8.onnx")
            quantize_convolutions(files[name], target, [dict(zip(names, arrays, strict=True))])
            reference, quantized = (OnnxNetwork(f)(*arrays) for f in (files[name], target))
            int8[f"{name}, int8 convolutions"] = (target, arrays, np.abs(quantized - reference))
        timed_parts = {name: (m, files[name], x) for name, (m, x, _) in parts.items()}
        for threads in (1, 2):
            for row in part_rows(timed_parts, errors, threads, ROUNDS):
                rows.append(row)
                print(row, flush=True)
            for name, (target, arrays, difference) in int8.items():
                session = OnnxNetwork(target, threads)
                ms = min(timed(session, *arrays, repeats=21, warmup=2)[1] for _ in range(ROUNDS))
                rows.append(
                    {
                        "part": name,
                        "threads": threads,
                        "onnxruntime_ms": 1000 * ms,
                        "pytorch_ms": np.nan,
                        "max_abs_diff_vs_pytorch": float(difference.max()),
                        "onnx_bytes": target.stat().st_size,
                        "hardware": hardware(threads, "cpu"),
                    }
                )
                print(rows[-1], flush=True)
    io.write_csv(Path(args.out).with_suffix(".csv"), pd.DataFrame(rows))
    io.write_json(f"{args.out}.json", sidecar)


if __name__ == "__main__":
    main()
