"""NDR's coarse shading: the prefiltered estimator (:mod:`neurender.ndr.prefiltered`)
against today's importance-sampled one (:mod:`neurender.ndr.shading`), speed and agreement.

nice -n 15 python benchmarks/coarse_shading.py benchmarks/results/coarse_shading

One random object of the default config's data (64 x 64, camera 3.9 at 30 degrees) under
built-in, procedural and real-world-like maps (environment 128 rows, coarse map 16 rows).
Writes ``<out>.csv``: per estimator and thread count, the median milliseconds per image
(the estimators timed in turn, the least loaded of :data:`ROUNDS` rounds)
over the object's pixels (the importance estimator with 64 samples per lobe and at most
16 bright texels, as the data stage calls it; the prefiltered one in float32, and the
once-per-map preparation of its lighting: SH projection, bright lights and prefilter);
``<out>_accuracy.csv``: per map, shading, estimator (both as the data stage calls them) and
reference, the mean |estimate - reference| / mean reference over the object's pixels and
the ratio of the means. References: the importance estimator at 1024 samples per lobe on
the coarse map (what both estimators read) and on the full map (the light the renders
see: a sun keeps its place and size); ``<out>.json`` and ``<out>_accuracy.json``: the
command and commit.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io, lights
from neurender.ndr import environments, objects, render
from neurender.ndr import prefiltered as pf
from neurender.ndr.shading import coarse_shading
from neurender.provenance import git_state
from neurender.timing import hardware, timed

WIDTH, ENV_HEIGHT, COARSE_HEIGHT, SAMPLES, BRIGHT = 64, 128, 16, 64, 16
REFERENCE_SAMPLES = 1024
#: Rounds of timing per thread count (the least loaded is kept).
ROUNDS = 3
ROOT = Path(__file__).resolve().parents[1]


def scene(seed: int) -> dict[str, torch.Tensor]:
    """The object's pixels: normals, view directions ``(P, 3)``, GGX width ``(P,)``."""
    rng = np.random.default_rng(seed)
    obj = objects.random_object(rng, (2, 7), 0.2)
    g = render.g_buffers(obj, render.camera(3.9, 30.0), WIDTH)
    m = g["mask"].reshape(-1) > 0
    return {
        "normals": torch.from_numpy(g["normal"].reshape(-1, 3)[m]),
        "view_dirs": torch.from_numpy(g["view_dir"].reshape(-1, 3)[m]),
        "alpha": torch.from_numpy(g["roughness"].reshape(-1)[m] ** 2),
    }


def maps(seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    out = {name: lights.procedural_probe(name, ENV_HEIGHT) for name in lights.BUILTIN_PROBES}
    for i in range(2):
        out[f"procedural {i}"] = environments.random_environment(rng, ENV_HEIGHT)
    for i in range(2):
        out[f"sunlit {i}"] = environments.sunlit_environment(rng, ENV_HEIGHT)
    return out


def importance(px, small, samples, seed=0):
    return coarse_shading(
        px["normals"],
        px["view_dirs"],
        px["alpha"],
        small,
        samples,
        torch.Generator().manual_seed(seed),
        max_bright=BRIGHT,
    )


def fast(px, light: pf.MapLighting):
    return pf.prefiltered_shading(px["normals"], px["view_dirs"], px["alpha"], light)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="output prefix, e.g. benchmarks/results/coarse_shading")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    # The checkout's state before this run rewrites its own (tracked) results.
    sidecar = {"command": " ".join(["python", *sys.argv]), **git_state(ROOT)}
    px = scene(args.seed)
    env = maps(args.seed)["sunlit 0"]
    small = environments.resize_latlong(env, COARSE_HEIGHT)
    lighting32 = pf.MapLighting(*(x.float() for x in pf.lighting(env, small)))
    pf.albedo_table()  # built once per process, not per image
    px32 = {k: v.float() for k, v in px.items()}
    cases = {
        "importance (64 samples, bright texels)": (
            importance,
            (px, torch.from_numpy(small), SAMPLES),
        ),
        "prefiltered (per image)": (fast, (px32, lighting32)),
        "prefiltered lighting (per map)": (pf.lighting, (env, small)),
    }
    rows = []
    for threads in (1, 2):
        torch.set_num_threads(threads)
        # The machine is shared: the cases are timed in turn, ROUNDS times, and each
        # keeps its least loaded round.
        best = {}
        for _ in range(ROUNDS):
            for name, (fn, fargs) in cases.items():
                with torch.inference_mode():
                    _, seconds = timed(fn, *fargs, repeats=11, warmup=2)
                best[name] = min(seconds, best.get(name, seconds))
        for name, seconds in best.items():
            rows.append(
                {
                    "estimator": name,
                    "threads": threads,
                    "pixels": len(px["normals"]),
                    "ms": 1000 * seconds,
                    "hardware": hardware(threads, "cpu"),
                }
            )
            print(rows[-1], flush=True)
    out = Path(args.out)
    io.write_csv(out.with_suffix(".csv"), pd.DataFrame(rows))

    torch.set_num_threads(2)
    accuracy = []
    for name, image in maps(args.seed).items():
        small = environments.resize_latlong(image, COARSE_HEIGHT)
        sun_share = environments.sun_share(image, COARSE_HEIGHT)
        references = {
            "coarse map": importance(px, torch.from_numpy(small), REFERENCE_SAMPLES, seed=1),
            "full map": importance(px, torch.from_numpy(image), REFERENCE_SAMPLES, seed=1),
        }
        estimates = {
            "importance (64 samples)": importance(px, torch.from_numpy(small), SAMPLES, seed=2),
            "prefiltered": fast(px, pf.lighting(image, small)),
        }
        for (estimator, est), (reference, ref) in itertools.product(
            estimates.items(), references.items()
        ):
            for k, lobe in enumerate(("S_D", "S_S")):
                mean = float(ref[k].mean())
                accuracy.append(
                    {
                        "map": name,
                        "sun_share": sun_share,
                        "shading": lobe,
                        "estimator": estimator,
                        "reference": reference,
                        "rel_diff": float((est[k] - ref[k]).abs().mean()) / mean,
                        "mean_ratio": float(est[k].mean()) / mean,
                    }
                )
                print(accuracy[-1], flush=True)
    io.write_csv(Path(f"{out}_accuracy.csv"), pd.DataFrame(accuracy))
    for name in (f"{out}.json", f"{out}_accuracy.json"):
        io.write_json(name, sidecar)


if __name__ == "__main__":
    main()
