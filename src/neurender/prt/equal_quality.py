"""Inference time against ray tracing: speed-up and the equal-quality ratio (paper 3.2.4).

The network's time is the median of 51 predictions of one frame (inputs, network and
decoding) by the engine it ships with (``inference_ms_per_frame``; ONNX Runtime on the
CPU); every other engine it holds is timed beside it (``inference_ms_per_frame_<engine>``).
The equal-quality ratio compares that time with the time of the cheapest ray-traced
ground truth (direction counts from ``equal_quality_directions``) whose mean diffuse SSIM
against the clean reference reaches the network's, on the first test frames. All on the
same machine and threads. The same times of every network (diffuse and glossy) are its
rows of the deployment table (:func:`deployment_rows`).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from neurender.deployment import deployment_row, onnx_check_error
from neurender.prt import transfer
from neurender.prt.frames import Split, ray_offset
from neurender.prt.model import DeepPRT
from neurender.prt.scores import diffuse_ssim
from neurender.tables import tidy_rows
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
) -> list[dict]:
    """One object's rows of the deployment table (:mod:`neurender.deployment`), one per
    material: the network ``nets[m]``, its ONNX file ``onnx_files[m]`` and its times
    ``engine_s[m]`` (:func:`inference_seconds`; ONNX Runtime NaN where the network ran on
    a GPU) at the resolution of the ``test`` frames."""
    rows = []
    for material, net in nets.items():
        onnx_file = onnx_files[material]
        rows.append(
            deployment_row(
                "prt",
                f"{name} {material}",
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
) -> dict[int, tuple[float, float]]:
    """``directions -> (seconds per frame, mean diffuse SSIM)`` of ray-traced ground truth
    of the first ``count`` test frames for every ``equal_quality_directions`` count, and
    ``reference_directions -> (seconds, nan)`` for the clean reference's own cost."""
    offset = ray_offset(test.positions[0], cfg["ray_offset"])
    reference = cfg["reference_directions"]
    out = {}
    for directions in sorted(cfg["equal_quality_directions"]) + [reference]:
        ssims, seconds = [], []
        for f in range(count):
            t0 = time.perf_counter()
            _, d, _, _ = transfer.sample_frame(
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
            )
            seconds.append(time.perf_counter() - t0)
            if directions != reference:
                ssims.append(
                    diffuse_ssim(
                        test.positions[f], d, test.diffuse[f], cfg["render_resolution"], light
                    )
                )
        out[directions] = (float(np.mean(seconds)), float(np.mean(ssims)) if ssims else math.nan)
    return out


def timing_rows(
    name: str,
    net: DeepPRT,
    engine_s: dict[str, float],
    test: Split,
    light: np.ndarray,
    cfg: dict,
    threads: int,
    frames: pd.DataFrame,
) -> pd.DataFrame:
    """Timing rows of one object: the network's time per engine, the ray-traced estimates'
    times and SSIMs, the speed-up over the reference and the equal-quality ratio.

    Args:
        engine_s: the network's seconds per frame by engine (:func:`inference_seconds`).
        frames: the object's per-frame scores (:func:`neurender.prt.scores.score_frames`),
            for the network's diffuse SSIM on the same test frames.
    """
    net_s = engine_s[net.engine]
    count = min(cfg["noise_floor_frames"], len(test.positions))
    deep = frames[
        (frames.model == "DeepPRT") & (frames.split == "test") & (frames.metric == "ssim_diffuse")
    ]
    target = float(deep[deep.frame < count].value.mean())
    estimates = ray_traced_estimates(name, test, count, light, cfg, threads)
    reference = estimates.pop(cfg["reference_directions"])[0]
    rows = tidy_rows("prt", name, "DeepPRT", "timing", {"inference_ms_per_frame": 1000 * net_s})
    rows += tidy_rows(
        "prt",
        name,
        "DeepPRT",
        "timing",
        {
            f"inference_ms_per_frame_{engine}": 1000 * s
            for engine, s in engine_s.items()
            if engine != net.engine
        },
    )
    equal = equal_directions = math.nan
    for directions, (seconds, ssim) in estimates.items():
        rows += tidy_rows(
            "prt",
            name,
            "ground truth",
            "timing",
            {
                f"gt_seconds_per_frame_{directions}_dirs": seconds,
                f"gt_ssim_{directions}_dirs": ssim,
            },
        )
        if math.isnan(equal) and ssim >= target:
            equal, equal_directions = seconds, directions
    gt = {"gt_seconds_per_frame_reference": reference}
    rows += tidy_rows("prt", name, "ground truth", "timing", gt)
    net_rows = {"speedup_vs_reference_gt": reference / net_s, "equal_quality_ssim_target": target}
    rows += tidy_rows("prt", name, "DeepPRT", "timing", net_rows)
    gt = {"equal_quality_directions": equal_directions}
    rows += tidy_rows("prt", name, "ground truth", "timing", gt)
    speedup = equal / net_s if not math.isnan(equal) else math.nan
    rows += tidy_rows("prt", name, "DeepPRT", "timing", {"equal_quality_speedup": speedup})
    return pd.DataFrame(rows)
