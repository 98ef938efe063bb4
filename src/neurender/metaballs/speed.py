"""Frame times of the networks against the ray marcher (thesis 6.3) and the demo's timing
table.

Times are milliseconds of wall clock, medians of :func:`neurender.timing.timed`; a
network's frame is drawing its inputs plus the network, whose cost does not depend on the
number of balls. Each row names the ``engine`` that ran it: the ray marcher is PyTorch's,
a network on the CPU its shipped ONNX graph (:class:`MetaballRenderer`'s ``engine``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import pandas as pd
import torch

from neurender.metaball import kernel_from_config
from neurender.metaballs import raymarch, scenes
from neurender.metaballs.demo import RAY_MARCHING
from neurender.metaballs.renderer import MetaballRenderer
from neurender.metaballs.user_scenes import near_plane_cut
from neurender.rng import torch_generator
from neurender.tables import tidy_rows
from neurender.timing import timed

RAY_MARCHER = "ray marcher"
#: Centre depths kept this far inside the depth range (world units), as the demo's: with
#: the default radii no ball then reaches the near plane alone (the thesis's scenes' margin
#: of 1 let one ball wall off a fifth of a 10-ball frame).
MARGIN = 3.0
#: The most of a frame the near plane may cut for its speed-up to be a headline: beyond,
#: the frame is mostly a flat wall at the near depth (the thesis's scenes from some 50
#: balls), which no renderer needs to resolve.
HEADLINE_NEAR_PLANE = 0.05


def frame_time_vs_balls(
    renderers: Mapping[str, MetaballRenderer], cfg: Mapping, repeats: int = 5
) -> pd.DataFrame:
    """Rows ``balls, model, engine, ms_per_frame, near_plane`` for a random scene of each
    of ``timing_balls`` (``seed``, ``radius`` [min, max], ``kernel``, ``width``; centres
    :data:`MARGIN` inside the depth range): the ray marcher, then each network;
    ``near_plane`` is the share of the frame the near plane cuts
    (:func:`neurender.metaballs.user_scenes.near_plane_cut`)."""
    rows = []
    for n in cfg["timing_balls"]:
        gen = torch_generator(cfg["seed"], "timing", n)
        scene = scenes.sample_scene(n, tuple(cfg["radius"]), gen, margin=MARGIN)
        scene = scene.to(torch.float32)
        scene = dataclasses.replace(scene, kernel=kernel_from_config(cfg["kernel"]))
        _, t_march = timed(raymarch.render_gbuffers, scene, cfg["width"], repeats=repeats)
        cut = near_plane_cut(scene, cfg["width"])
        rows.append(
            {
                "balls": n,
                "model": RAY_MARCHER,
                "engine": "pytorch",
                "ms_per_frame": 1e3 * t_march,
                "near_plane": cut,
            }
        )
        for name, r in renderers.items():
            x, t_in = timed(r.inputs, scene, repeats=repeats)
            _, t_net = timed(r, x[None], repeats=repeats)
            ms = 1e3 * (t_in + t_net)
            rows.append(
                {
                    "balls": n,
                    "model": name,
                    "engine": r.engine,
                    "ms_per_frame": ms,
                    "near_plane": cut,
                }
            )
    return pd.DataFrame(rows)


def timing_table(timings: pd.DataFrame, flips: pd.DataFrame, balls: pd.DataFrame) -> pd.DataFrame:
    """Tidy ``timing.csv``: per network the demo's mean times per frame, its silhouette
    flips (and the ray marcher's) and its speed-up over ray marching at the most balls of a
    frame the near plane cuts on at most :data:`HEADLINE_NEAR_PLANE` (the most balls when
    the frames say nothing of it); then every ``ms_per_frame`` and ``near_plane`` of
    ``balls``; each row with the ``engine`` of its model.

    Args:
        timings: :attr:`neurender.metaballs.demo.Sequence.timings`.
        flips: :func:`neurender.metaballs.demo.silhouette_flips`.
        balls: :func:`frame_time_vs_balls`.
    """
    clear = balls if "near_plane" not in balls else balls[balls.near_plane <= HEADLINE_NEAR_PLANE]
    most = int((clear if len(clear) else balls)["balls"].max())
    at_most = balls[balls["balls"] == most].drop_duplicates("model")
    at_most = at_most.set_index("model")["ms_per_frame"]
    engine = balls.drop_duplicates("model").set_index("model")["engine"]
    rows = []
    for name, part in timings.groupby("model", sort=False):
        summary = {
            "input_ms_per_frame": part.input_ms.mean(),
            "network_ms_per_frame": part.network_ms.mean(),
            "shading_ms_per_frame": part.shading_ms.mean(),
            "raymarch_ms_per_frame": part.raymarch_ms.mean(),
            "silhouette_flips": flips[name].mean(),
            "silhouette_flips_raymarch": flips[RAY_MARCHING].mean(),
            f"speedup_at_{most}_balls": at_most[RAY_MARCHER] / at_most[name],
        }
        rows += tidy_rows("metaballs", "demo", name, "timing", summary, engine=engine[name])
    for r in balls.itertuples():
        dataset, values = f"{int(r.balls)} balls", {"ms_per_frame": r.ms_per_frame}
        if "near_plane" in balls:
            values["near_plane"] = r.near_plane
        rows += tidy_rows("metaballs", dataset, r.model, "timing", values, engine=r.engine)
    return pd.DataFrame(rows)
