"""Stand-alone run of the DeepPRT ray benchmark (the pipeline runs it as rule prt_benchmark).

python benchmarks/prt_rays.py results/prt/head/sequence.npz results/prt/probes/sky_sh.csv out.csv
"""

import argparse

from neurender.prt.benchmark import run_benchmark
from neurender.prt.frames import read_sh_light

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("sequence")
parser.add_argument("light_csv")
parser.add_argument("out")
parser.add_argument("--threads", type=int, default=2)
parser.add_argument("--directions", type=int, default=256)
parser.add_argument("--paper-scale", action="store_true")
args = parser.parse_args()
cfg = {
    "seed": 0,
    "n_bands": 4,
    "direction_sets": 16,
    "ray_offset": 1e-3,
    "directions": args.directions,
    "benchmark_paper_scale": args.paper_scale,
}
print(
    run_benchmark(
        args.sequence, read_sh_light(args.light_csv), cfg, args.threads, args.out
    ).to_string()
)
