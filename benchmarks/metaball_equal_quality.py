"""The metaballs' equal-quality speed-up on default-size data made by the library (not the
workflow): the first ``--examples`` test scenes of the default config (seeded as the
``metaballs_examples`` rule's), their reference ray-marched targets through the AB image's
8-bit round trip (as the evaluation reads them), every setting of
:func:`neurender.metaballs.equal_quality.sweep` scored and timed, and the cheapest one whose
IoU and normal error reach the network's.

The network: a ``--checkpoint`` (its quality measured on the same examples), or without
one an untrained generator of the default size (its time does not depend on its weights)
against the quality given by ``--target-iou`` and ``--target-normal`` (defaults: ours in
the README's default-config row, IoU 0.928 and 7.8 degrees).

python benchmarks/metaball_equal_quality.py benchmarks/results/metaball_equal_quality.csv \\
    --figure benchmarks/results/metaball_equal_quality.png
"""

import argparse
import shlex
import sys
from pathlib import Path

import pandas as pd
import torch

from neurender.io import write_csv
from neurender.metaballs import ab, data, evaluate, inputs, model
from neurender.metaballs import equal_quality as eq
from neurender.metaballs.renderer import MetaballRenderer
from neurender.provenance import git_state
from neurender.timing import hardware

ROOT = Path(__file__).resolve().parent.parent


def untrained(width: int, ngf: int, variant: str):
    """``draw, network`` of an untrained generator, as :class:`MetaballRenderer` runs one."""
    net = model.build_generator(width, ngf, variant).eval()

    @torch.no_grad()
    def run(x: torch.Tensor) -> torch.Tensor:
        return ((net(x.float() * 2 - 1) + 1) / 2).clamp(0, 1)

    return (lambda scene: model.network_inputs(scene, width, variant)), run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out")
    parser.add_argument("--figure")
    parser.add_argument("--examples", type=int, default=12)
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--balls", type=int, nargs=2, default=[3, 20])
    parser.add_argument("--radius", type=float, nargs=2, default=[0.6, 1.6])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--checkpoint")
    parser.add_argument("--variant", default="sphere_residual")
    parser.add_argument("--ngf", type=int, default=16)
    parser.add_argument("--target-iou", type=float, default=0.928)
    parser.add_argument("--target-normal", type=float, default=7.8)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    state = git_state(ROOT)  # of the code measured: before any edit during the run
    cfg = {"seed": args.seed, "balls": args.balls, "radius": args.radius}
    scenes = [data.example_scene(cfg, "test", i) for i in range(args.examples)]
    examples = []
    for scene in scenes:
        reference = eq.render(scene, args.width, eq.REFERENCE)
        packed = ab.pack(inputs.draw_inputs(scene, args.width), reference)
        examples.append((scene, ab.unpack(packed)["target"]))
    if args.checkpoint:
        renderer = MetaballRenderer(args.checkpoint, "cpu", args.threads)
        draw, network, name = renderer.inputs, renderer, renderer.variant
        rows = [evaluate.example_metrics(renderer(draw(s)[None])[0], t) for s, t in examples]
        target = pd.DataFrame(rows)[list(eq.QUALITY)].mean().to_dict()
    else:
        (draw, network), name = untrained(args.width, args.ngf, args.variant), args.variant
        target = {"iou_depth": args.target_iou, "normal_error_mean_deg": args.target_normal}
    network_ms = eq.network_ms_per_frame(draw, network, scenes, repeats=2 * args.repeats + 1)
    scores = eq.score_settings(examples, args.width, eq.sweep(), repeats=args.repeats)
    best = eq.cheapest(scores, target)
    reference_ms = float(scores.loc[scores.label == eq.REFERENCE.label, "ms_per_frame"].iloc[0])
    scores["model"] = "ray marcher"
    scores["equal_quality_pick"] = scores.label == (best["label"] if best is not None else None)
    net_row = {"model": name, "label": "network (inputs + network)", "ms_per_frame": network_ms}
    net_row |= {m: target[m] for m in eq.QUALITY}
    net_row |= {
        "speedup_vs_reference": reference_ms / network_ms,
        "equal_quality_speedup": eq.equal_quality_speedup(scores, target, network_ms),
        "trained": bool(args.checkpoint),
    }
    frame = pd.concat([scores, pd.DataFrame([net_row])], ignore_index=True)
    frame["examples"] = args.examples
    frame["width"] = args.width
    frame["commit"] = state["commit"] + ("-dirty" if state["dirty"] else "")
    frame["hardware"] = hardware(args.threads, "cpu")
    frame["command"] = shlex.join(["python", *sys.argv])
    write_csv(args.out, frame)
    if args.figure:
        eq.quality_figure(scores, {name: (target, network_ms)}, args.figure)
    print(scores.drop(columns=["model", "label"]).to_string())
    print(pd.Series(net_row).to_string())
    print("pick:", None if best is None else best["label"])


if __name__ == "__main__":
    main()
