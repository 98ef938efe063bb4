"""Inference time against ray tracing: speed-up and the equal-quality ratio (paper 3.2.4).

The network's time is the median of 51 predictions of one frame (inputs, network and
decoding) by the engine it ships with (``ms_per_frame``; ONNX Runtime on the CPU); every
other engine it holds is timed beside it (``inference_ms_per_frame_<engine>``). The
equal-quality ratio compares that time with the time of the fastest ray-traced ground
truth (direction counts from ``equal_quality_directions``) whose mean diffuse SSIM
against the clean reference reaches the network's, on the first test frames: the shared
rule of :mod:`neurender.equal_quality`, with its bounds. All on the
same machine and threads. Every variant's diffuse network (its model name,
:data:`neurender.prt.VARIANTS`) gets its own rows beside the same ray-traced estimates.
The same times of every network (each variant, diffuse and glossy) are its rows of the
deployment table (:func:`deployment_rows`).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from neurender import equal_quality as shared
from neurender.deployment import deployment_row, onnx_check_error
from neurender.prt import transfer
from neurender.prt.frames import Split, ray_offset
from neurender.prt.model import DeepPRT
from neurender.prt.scores import diffuse_ssim
from neurender.timing import hardware, timed


def inference_seconds(net: DeepPRT, split: Split) -> dict[str, float]:
    """Median seconds per prediction of the first frame of ``split`` by each of the
    network's engines."""
    frame = Split(split.positions[:1], split.normals[:1], None, None, None)
    return {
        engine: timed(net.predict, frame, engine=engine, repeats=51, warmup=1)[1]
        for engine in net.engines
    }


def deployment_rows(
    name: str,
    nets: dict[str, DeepPRT],
    onnx_files: dict[str, str],
    engine_s: dict[str, dict[str, float]],
    test: Split,
    threads: int,
    model: str = "DeepPRT",
) -> list[dict]:
    """One object's rows of the deployment table (:mod:`neurender.deployment`) for one
    variant (``model``, its name in the tables), one per material: the network
    ``nets[m]``, its ONNX file ``onnx_files[m]`` and its times ``engine_s[m]``
    (:func:`inference_seconds`; ONNX Runtime NaN where the network ran on a GPU) at the
    resolution of the ``test`` frames; named ``"<object> <material> (<model>)"``."""
    rows = []
    for material, net in nets.items():
        onnx_file = onnx_files[material]
        rows.append(
            deployment_row(
                "prt",
                f"{name} {material} ({model})",
                onnx_file,
                test.positions.shape[1:3],
                net.parameters,
                onnx_check_error(onnx_file),
                {engine: 1000 * s for engine, s in engine_s[material].items()},
                threads,
                hardware(threads, net.device),
            )
        )
    return rows


def ray_traced_estimates(
    name: str, test: Split, count: int, light: np.ndarray, cfg: dict, threads: int
) -> tuple[dict[int, tuple[float, float]], float]:
    """``directions -> (median seconds per frame, mean diffuse SSIM)`` of ray-traced ground
    truth of the first ``count`` test frames for every ``equal_quality_directions`` count, and
    the seconds per frame of the clean reference's own count (``reference_directions``;
    traced again only when the sweep does not hold that count)."""
    offset = ray_offset(test.positions[0], cfg["ray_offset"])

    def sample(directions: int, f: int) -> np.ndarray:
        return transfer.sample_frame(
            test.positions[f],
            directions,
            cfg,
            offset,
            None,
            threads,
            name,
            "equal-quality",
            f,
            directions,
        )[1]

    def trace(directions: int, scored: bool) -> tuple[float, float]:
        sample(directions, 0)  # warm-up, not counted: the first trace pays one-time costs
        ssims, seconds = [], []
        for f in range(count):
            t0 = time.perf_counter()
            d = sample(directions, f)
            seconds.append(time.perf_counter() - t0)
            if scored:
                ssims.append(
                    diffuse_ssim(
                        test.positions[f], d, test.diffuse[f], cfg["render_resolution"], light
                    )
                )
        # The median frame, as the networks' median time: one slow trace moves a mean of a
        # few frames by tens of percent.
        return float(np.median(seconds)), float(np.mean(ssims)) if ssims else math.nan

    out = {d: trace(d, True) for d in sorted(set(cfg["equal_quality_directions"]))}
    reference = cfg["reference_directions"]
    return out, (out[reference] if reference in out else trace(reference, False))[0]


#: The reference renderer's name in the table and the quality compared (higher is better).
RAY_TRACED = "ray traced"
QUALITY = {"ssim_diffuse": True}


def label(directions: int) -> str:
    """A direction count's ``setting``."""
    return f"{directions} directions"


def network_row(
    net: DeepPRT, engine_s: dict[str, float], ssim: float, reference_s: float
) -> shared.Network:
    """A diffuse network's side of the comparison: its frame by the engine it ships with,
    its mean diffuse ``ssim`` on the sweep's frames, its time by every other engine
    (``inference_ms_per_frame_<engine>``) and ``speedup_vs_reference_gt``: the clean
    reference's seconds per frame (``reference_s``) over its own."""
    net_s = engine_s[net.engine]
    extra = {
        f"inference_ms_per_frame_{engine}": 1000 * s
        for engine, s in engine_s.items()
        if engine != net.engine
    }
    extra["speedup_vs_reference_gt"] = reference_s / net_s
    return shared.Network({"ssim_diffuse": ssim}, 1000 * net_s, extra)


def table(
    name: str,
    nets: dict[str, DeepPRT],
    engine_s: dict[str, dict[str, float]],
    test: Split,
    light: np.ndarray,
    cfg: dict,
    threads: int,
    frames: pd.DataFrame,
) -> pd.DataFrame:
    """The equal-quality table of one object (:func:`neurender.equal_quality.table`,
    dataset ``name``): the ray-traced estimates per direction count (model
    :data:`RAY_TRACED`, traced once for all variants) and every diffuse network against
    the fastest of its SSIM (:func:`network_row`).

    Args:
        nets: model name (:data:`neurender.prt.VARIANTS`) -> its diffuse network.
        engine_s: model name -> its seconds per frame by engine (:func:`inference_seconds`).
        frames: the object's per-frame scores (:func:`neurender.prt.scores.score_frames`),
            for each network's diffuse SSIM on the same test frames.
    """
    count = min(cfg["noise_floor_frames"], len(test.positions))
    test_ssim = frames[
        (frames.split == "test") & (frames.metric == "ssim_diffuse") & (frames.frame < count)
    ]
    estimates, reference_s = ray_traced_estimates(name, test, count, light, cfg, threads)
    scores = pd.DataFrame(
        [
            {"setting": label(d), "ms_per_frame": 1000 * seconds, "ssim_diffuse": ssim}
            for d, (seconds, ssim) in estimates.items()
        ]
    )
    networks = {
        model: network_row(
            net,
            engine_s[model],
            float(test_ssim[test_ssim.model == model].value.mean()),
            reference_s,
        )
        for model, net in nets.items()
    }
    return shared.table("prt", name, RAY_TRACED, scores, networks, QUALITY)
