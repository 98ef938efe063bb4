"""Milliseconds per frame of the metaball networks' inputs: the circles, the sphere
impostors and the inflated impostors (ours' prior), and a variant's whole input, drawn by
this checkout's :mod:`neurender.metaballs.inputs` and, interleaved with it on the same
scenes, by the version of that file at ``--before`` (a git revision).

Scenes as the speed table's (:func:`neurender.metaballs.speed.frame_time_vs_balls`): float32,
``timing`` seeds, radius [0.6, 1.6]. Per part and version the median of ``--repeats`` calls
after 2 warm-ups, ``--rounds`` times interleaved, the fastest round kept: wall clock
(``ms_per_frame``, as the speed table) and this process's CPU time (``cpu_ms_per_frame``,
which other jobs on a shared machine disturb less).

python benchmarks/metaball_inputs.py --before e09b589 benchmarks/results/metaball_inputs.csv
"""

import argparse
import importlib.util
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender.io import write_csv
from neurender.metaball import Scene
from neurender.metaballs import inputs, scenes
from neurender.provenance import git_state
from neurender.rng import torch_generator
from neurender.timing import hardware

ROOT = Path(__file__).resolve().parent.parent


def module_at(revision: str):
    """``src/neurender/metaballs/inputs.py`` as it was at ``revision``, imported."""
    text = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{revision}:src/neurender/metaballs/inputs.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "inputs_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("inputs_before", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def parts(module, scene: Scene, width: int) -> dict:
    """The timed calls of one implementation: name to a thunk."""

    def whole():  # network_inputs of sphere_residual: circles, then inflated impostors
        return torch.cat(
            [module.draw_inputs(scene, width), module.inflated_spheres(scene, width).stack()]
        )

    return {
        "circles": lambda: module.draw_inputs(scene, width),
        "spheres": lambda: module.draw_spheres(scene, width),
        "inflated spheres": lambda: module.inflated_spheres(scene, width),
        "sphere_residual inputs": whole,
    }


def median_ms(fn, repeats: int) -> tuple[float, float]:
    """Median wall and CPU milliseconds of ``repeats`` calls of ``fn`` after 2 warm-ups."""
    for _ in range(2):
        fn()
    wall, cpu = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return 1e3 * float(np.median(wall)), 1e3 * float(np.median(cpu))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out")
    parser.add_argument("--before", required=True, help="git revision of the old inputs.py")
    parser.add_argument("--balls", type=int, nargs="+", default=[3, 25, 145])
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    before = module_at(args.before)
    state = git_state(ROOT)
    commit = state["commit"] + ("-dirty" if state["dirty"] else "")
    before_commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", args.before],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    rows = []
    for n in args.balls:
        gen = torch_generator(args.seed, "timing", n)
        scene = scenes.sample_scene(n, (0.6, 1.6), gen).to(torch.float32)
        old, new = parts(before, scene, args.width), parts(inputs, scene, args.width)
        for name in new:
            for _ in range(args.rounds):  # interleaved: the machine's load hits both alike
                for version, fns, rev in (("before", old, before_commit), ("after", new, commit)):
                    wall, cpu = median_ms(fns[name], args.repeats)
                    rows.append(
                        {
                            "balls": n,
                            "width": args.width,
                            "part": name,
                            "version": version,
                            "commit": rev,
                            "ms_per_frame": wall,
                            "cpu_ms_per_frame": cpu,
                        }
                    )
    frame = pd.DataFrame(rows)
    # The fastest of the interleaved rounds: the least disturbed by other jobs.
    frame = frame.groupby(
        ["balls", "width", "part", "version", "commit"], as_index=False, sort=False
    )[["ms_per_frame", "cpu_ms_per_frame"]].min()
    frame["hardware"] = hardware(args.threads, "cpu")
    frame["command"] = shlex.join(["python", *sys.argv])
    write_csv(args.out, frame)
    print(
        frame.pivot_table(
            index=["balls", "part"],
            columns="version",
            values=["ms_per_frame", "cpu_ms_per_frame"],
            sort=False,
        ).to_string()
    )


if __name__ == "__main__":
    main()
