"""NDR against Mitsuba at equal quality, as DeepPRT's equal-quality ratio
(:mod:`neurender.prt.equal_quality`) and the metaballs' (:mod:`neurender.metaballs.
equal_quality`).

Mitsuba renders the first test samples again (the same object, map and render seed as the
test split's noise-floor render, :data:`neurender.ndr.data.NOISY_SEED_OFFSET`, so the row
at the training ``spp`` is that render) at every sample count of a sweep; each render is
scored as :func:`neurender.ndr.evaluate.score` scores the networks: DSSIM of ``I_R``,
Reinhard tone-mapped, within the eroded mask, against the clean test reference
(``reference_spp``). NDR's quality is its mean DSSIM on the same samples in the
evaluation's per-sample table. The cheapest sample count whose mean DSSIM is at most
NDR's is its equal-quality render (:func:`pick`); the ratio of that render's milliseconds
to NDR's end to end (the coarse shading by the data's estimator,
:func:`neurender.ndr.data.coarse_maps`, with the map's lighting made once per map, plus
the network at batch 1; the G-buffers, which a rasteriser makes, are not counted) is the
equal-quality speed-up. A sweep is coarse: the true cheapest render of NDR's quality costs
at most the pick's, so the speed-up is that of the sweep's grid; where no sample count
reaches NDR the most expensive one gives a lower bound, and where the fewest already beats
NDR an upper bound (:data:`BOUNDS`).

Times are wall-clock medians of :func:`neurender.timing.timed` per sample (after one
uncounted call) averaged over the samples, on the same machine, samples and threads. A
frame counts only per-frame work on both sides: Mitsuba's two renders (both maps,
:func:`neurender.ndr.render.render_shading`) of a scene already built, NDR's coarse
shading and network; building Mitsuba's scene (its map's sampling tables, the mesh) is
timed apart (``scene_ms``; the data stage's ``render_seconds`` include it), as NDR's map
lighting and G-buffers are not counted.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Sequence
from types import ModuleType

import numpy as np
import pandas as pd
import torch
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from neurender.ndr import DATASETS, EQUAL_QUALITY_REPEATS, data, environments, prefiltered, render
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.evaluate import score
from neurender.ndr.model import NDRModel, compose
from neurender.ndr.objects import ProceduralObject
from neurender.ndr.shipped import INPUTS as SHIPPED_INPUTS
from neurender.ndr.shipped import ShippedNDR, gbuffer_groups
from neurender.nn.inference import OnnxNetwork, export_onnx
from neurender.plots import plt, save_figure
from neurender.tables import tidy_rows
from neurender.timing import timed

#: The quality compared (lower is better) and the ``model`` and ``split`` of the rows.
METRIC = "dssim_I_R"
MITSUBA = "mitsuba"
NETWORK = "ndr"
SPLIT = "equal quality"
#: What a network's ``equal_quality_speedup`` is: the sweep's pick, or a bound on it.
WITHIN, LOWER, UPPER = "within the sweep", "lower bound", "upper bound"
BOUNDS = {
    WITHIN: "against the cheapest sample count of the sweep whose DSSIM reaches NDR's",
    LOWER: "no sample count of the sweep reaches NDR's DSSIM: against the most samples",
    UPPER: "the sweep's fewest samples already beat NDR's DSSIM: against them",
}


def sweep(spps: Sequence[int], training_spp: int) -> list[int]:
    """The sample counts rendered: ``spps`` and the training ``training_spp``, ascending."""
    if not spps or min(spps) < 1:
        raise ValueError(f"ndr.equal_quality_spp = {list(spps)}: expected sample counts >= 1")
    return sorted({*spps, training_spp})


@dataclasses.dataclass(frozen=True)
class Scene:
    """Test sample ``index``: its object, map ``(H, 2H, 3)`` and Mitsuba seed."""

    index: int
    obj: ProceduralObject
    environment: np.ndarray
    seed: int


def scene_of(cfg: dict, index: int) -> Scene:
    """Test sample ``index`` as :func:`neurender.ndr.data.make_sample` draws it, seeded as
    its noise-floor render."""
    obj, env, _, rng = data.sample_scene(cfg, "test", index)
    seed = int(rng.integers(2**30)) + data.NOISY_SEED_OFFSET  # as make_sample draws it
    return Scene(index, obj, env, seed)


def _chw(image: np.ndarray) -> torch.Tensor:
    """``(H, W, 3)`` to ``(3, H, W)`` float32."""
    return torch.from_numpy(np.ascontiguousarray(image, np.float32)).permute(2, 0, 1)


def load_scene(mi: ModuleType, cfg: dict, scene: Scene, spp: int):
    """Mitsuba's scene of ``scene``'s shading maps at ``spp`` samples per pixel."""
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    return render.shading_scene(mi, scene.obj, scene.environment, view, cfg["width"], spp)


def render_maps(mi: ModuleType, loaded, scene: Scene) -> dict[str, np.ndarray]:
    """Mitsuba's ``I_D`` and ``I_S`` ``(W, W, 3)`` of ``scene`` from its ``loaded`` scene."""
    return render.render_shading(mi, loaded, scene.seed)


def dssim(i_d: torch.Tensor, i_s: torch.Tensor, reference: dict[str, torch.Tensor]) -> torch.Tensor:
    """Per-sample DSSIM of ``I_R`` ``(N,)`` of the shading maps ``i_d``, ``i_s``
    ``(N, 3, H, W)`` against ``reference`` (test buffers ``(N, C, H, W)``: its ``I_D``,
    ``I_S``, albedos and eroded mask), as the evaluation scores every method."""
    truth = compose(reference["I_D"], reference["I_S"], reference)
    return score(compose(i_d, i_s, reference), truth, reference["mask"])[METRIC]


def score_sweep(
    mi: ModuleType,
    cfg: dict,
    scenes: Sequence[Scene],
    reference: dict[str, torch.Tensor],
    spps: Sequence[int],
    repeats: int = EQUAL_QUALITY_REPEATS,
) -> pd.DataFrame:
    """One row per sample count: ``spp``, ``ms_per_frame`` (the mean over ``scenes`` of
    the median of ``repeats`` renders of both maps of the loaded scene), ``scene_ms`` (the
    mean time of building the scene, once per scene: the map's sampling tables and the
    mesh's BVH, as NDR's map lighting not counted in a frame) and ``dssim_I_R`` (the mean
    over ``scenes`` against ``reference``, their test buffers in that order)."""
    rows = []
    for spp in spps:
        maps, seconds, loads = [], [], []
        for scene in scenes:
            loaded, s = timed(load_scene, mi, cfg, scene, spp)
            loads.append(s)
            out, s = timed(render_maps, mi, loaded, scene, repeats=repeats, warmup=1)
            maps.append(out)
            seconds.append(s)
        i_d = torch.stack([_chw(m["I_D"]) for m in maps])
        i_s = torch.stack([_chw(m["I_S"]) for m in maps])
        rows.append(
            {
                "spp": spp,
                "ms_per_frame": 1e3 * float(np.mean(seconds)),
                "scene_ms": 1e3 * float(np.mean(loads)),
                METRIC: float(dssim(i_d, i_s, reference).mean()),
            }
        )
    return pd.DataFrame(rows)


@torch.no_grad()
def shipped_inputs(
    cfg: dict, model: NDRModel, scene: Scene, sample: dict[str, torch.Tensor]
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The shipped graph's inputs (:mod:`neurender.ndr.shipped`) of one test ``sample``
    (a dataset item, ``(C, H, W)`` per group; read without mask erosion, the graph gives
    the network's output on the stored sample exactly as a renderer's raw mask would) under
    its scene's map: the G-buffers ``(1, C, H, W)``, the map's 5-band SH ``(1, 75)``, its
    prefiltered copies ``(1, L, h, 2h, 3)`` and lights ``(1, K, 7)``, made as the data
    stage makes them for ``prefiltered``."""
    gbuffers = torch.cat([sample[g][None] for g in gbuffer_groups(model)], 1)
    small = environments.resize_latlong(scene.environment, cfg["coarse_height"])
    coefficients, maps, lights = prefiltered.lighting(scene.environment, small)
    return (
        gbuffers.float(),
        coefficients.reshape(1, -1).float(),
        maps[None].float(),
        lights[None].float(),
    )


def export_shipped(
    cfg: dict, model: NDRModel, inputs: tuple[torch.Tensor, ...], path: str
) -> float:
    """Write ``model`` with the prefiltered coarse shading as one ONNX graph
    (:class:`neurender.ndr.shipped.ShippedNDR`: G-buffers, SH, maps and lights in, ``I_R``
    out),
    checked against PyTorch on ``inputs`` (a batch of two copies); the largest
    difference."""
    cpu = copy.deepcopy(model).cpu().eval()  # the model may stay on the GPU for its timing
    shipped = ShippedNDR(cpu, cfg["camera_distance"], cfg["fov"], cfg["width"])
    pair = tuple(torch.cat([t, t]) for t in inputs)  # a batch of one would fix the batch axis
    return export_onnx(shipped, pair, path, atol=1e-3, rtol=1e-4, input_names=SHIPPED_INPUTS)


def network_milliseconds(
    cfg: dict,
    model: NDRModel,
    scenes: Sequence[Scene],
    test: NDRDataset,
    device: torch.device,
    graph: str,
    threads: int,
    repeats: int = EQUAL_QUALITY_REPEATS,
) -> dict[str, float]:
    """NDR's milliseconds per frame, means over ``scenes`` of per-sample medians:
    ``coarse_shading_ms`` (:func:`neurender.ndr.data.coarse_maps` from the map's lighting,
    made once per map and not counted), ``network_ms`` (``model`` on the sample of
    ``test``, batch 1, on ``device``), ``shipped_graph_ms`` (the one-graph NDR exported to
    ``graph`` by :func:`export_shipped`, ONNX Runtime on ``threads`` threads) and
    ``ms_per_frame``, NDR's frame: the shipped graph when the data's coarse shading is
    ``prefiltered`` (the graph computes exactly what the network was trained on), else
    the importance-sampled shading plus the network (the graph's shading would not be the
    training input; its time is then for comparison only)."""
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    coarse, network, shipped = [], [], []
    for scene in scenes:
        g = render.g_buffers(scene.obj, view, cfg["width"])
        lighting = data.coarse_lighting(cfg, scene.environment)
        _, s = timed(
            data.coarse_maps,
            cfg,
            g,
            scene.environment,
            "test",
            scene.index,
            lighting=lighting,
            repeats=repeats,
            warmup=1,
        )
        coarse.append(s)
        sample = test[scene.index]
        batch = {k: v[None].to(device) for k, v in sample.items()}
        network.append(timed(model, batch, repeats=repeats, warmup=1)[1])
        inputs = shipped_inputs(cfg, model, scene, sample)
        if not shipped:
            export_shipped(cfg, model, inputs, graph)
            session = OnnxNetwork(graph, threads)
        arrays = [x.numpy() for x in inputs]
        shipped.append(timed(session, *arrays, repeats=repeats, warmup=1)[1])
    ms = {"coarse_shading_ms": 1e3 * float(np.mean(coarse))}
    ms["network_ms"] = 1e3 * float(np.mean(network))
    ms["shipped_graph_ms"] = 1e3 * float(np.mean(shipped))
    if cfg["coarse_shading"] == "prefiltered":
        return {**ms, "ms_per_frame": ms["shipped_graph_ms"]}
    return {**ms, "ms_per_frame": ms["coarse_shading_ms"] + ms["network_ms"]}


def network_dssim(per_sample: pd.DataFrame, samples: Sequence[int], model: str = NETWORK) -> float:
    """``model``'s mean DSSIM of ``I_R`` over ``samples`` of the complex test set in the
    evaluation's per-sample rows (``metrics_samples.csv``)."""
    part = per_sample[
        (per_sample["dataset"] == DATASETS["complex"])
        & (per_sample["model"] == model)
        & (per_sample["metric"] == METRIC)
        & per_sample["sample"].isin(samples)
    ]
    missing = sorted(set(samples) - set(part["sample"]))
    if missing:
        raise ValueError(f"the per-sample scores have no {METRIC} of {model} for samples {missing}")
    return float(part["value"].mean())


@dataclasses.dataclass(frozen=True)
class Pick:
    """The render a network is compared with: its ``spp`` (None where none reaches the
    network), its ``ms_per_frame`` and what the ratio to it is (:data:`BOUNDS`)."""

    spp: int | None
    ms_per_frame: float
    bound: str


def pick(scores: pd.DataFrame, target: float) -> Pick:
    """The fastest row of :func:`score_sweep`'s ``scores`` whose DSSIM is at most
    ``target`` (equal times: the fewer samples); where none is, the most samples
    (:data:`LOWER`); :data:`UPPER` where the fewest samples of the sweep reach it."""
    reached = scores[scores[METRIC] <= target]
    if reached.empty:
        most = scores.loc[scores["spp"].idxmax()]
        return Pick(None, float(most["ms_per_frame"]), LOWER)
    best = reached.sort_values(["ms_per_frame", "spp"]).iloc[0]
    fewest = scores["spp"].min() in set(reached["spp"])
    return Pick(int(best["spp"]), float(best["ms_per_frame"]), UPPER if fewest else WITHIN)


def label(spp: int | None) -> str:
    return "none" if spp is None else f"{spp} spp"


def table(
    scores: pd.DataFrame, target: float, network: dict[str, float], training_spp: int
) -> pd.DataFrame:
    """Tidy rows (key columns ``setting``, ``bound``): per sample count (model
    :data:`MITSUBA`, setting ``<spp> spp``) its ``ms_per_frame``, ``scene_ms`` and DSSIM; NDR's
    (``network``: :func:`network_milliseconds`; its DSSIM ``target``) times and DSSIM,
    ``training_spp``, ``speedup_vs_training_spp`` (Mitsuba at ``training_spp`` over NDR's frame),
    ``equal_quality_spp`` (NaN where none), ``equal_quality_mitsuba_ms`` and
    ``equal_quality_speedup``; its setting the pick's (``none``), its bound the pick's
    (:data:`BOUNDS`; the Mitsuba rows' ``measured``)."""
    dataset, rows = DATASETS["complex"], []
    for r in scores.itertuples():
        values = {"ms_per_frame": r.ms_per_frame, "scene_ms": r.scene_ms}
        values[METRIC] = getattr(r, METRIC)
        rows += tidy_rows(
            "ndr", dataset, MITSUBA, SPLIT, values, setting=label(r.spp), bound="measured"
        )
    chosen = pick(scores, target)
    training = scores.loc[scores["spp"] == training_spp, "ms_per_frame"]
    if training.empty:
        raise ValueError(f"the sweep has no row at the training spp {training_spp}")
    ms = network["ms_per_frame"]
    values = {
        **network,
        METRIC: target,
        "training_spp": training_spp,
        "speedup_vs_training_spp": float(training.iloc[0]) / ms,
        "equal_quality_spp": np.nan if chosen.spp is None else chosen.spp,
        "equal_quality_mitsuba_ms": chosen.ms_per_frame,
        "equal_quality_speedup": chosen.ms_per_frame / ms,
    }
    setting = label(chosen.spp)
    rows += tidy_rows("ndr", dataset, NETWORK, SPLIT, values, setting=setting, bound=chosen.bound)
    return pd.DataFrame(rows)


def quality_figure(
    scores: pd.DataFrame, target: float, network: dict[str, float], training_spp: int, path: str
) -> None:
    """DSSIM of ``I_R`` against milliseconds per frame, both on log axes: Mitsuba per
    sample count (labelled, the training count ringed), NDR a star on the dashed line of
    its DSSIM, the picked render crossed; the title states both speed-ups."""
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.plot(scores["ms_per_frame"], scores[METRIC], "o-", ms=5, label="Mitsuba")
    for r in scores.itertuples():
        ax.annotate(
            f"{r.spp}",
            (r.ms_per_frame, getattr(r, METRIC)),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=7,
        )
    train = scores[scores["spp"] == training_spp]
    ax.scatter(
        train["ms_per_frame"],
        train[METRIC],
        s=110,
        facecolors="none",
        edgecolors="k",
        label=f"Mitsuba at the training {training_spp} spp",
    )
    ms = network["ms_per_frame"]
    ax.scatter([ms], [target], marker="*", s=220, color="C3", zorder=3, label="NDR")
    ax.axhline(target, color="C3", ls="--", lw=0.8)
    chosen = pick(scores, target)
    if chosen.spp is not None:
        row = scores[scores["spp"] == chosen.spp].iloc[0]
        ax.scatter(
            [row["ms_per_frame"]],
            [row[METRIC]],
            marker="x",
            s=90,
            color="C3",
            zorder=3,
            label=f"cheapest of NDR's DSSIM ({chosen.spp} spp)",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):  # after the scales, which reset them; 1-2-5 ticks
        axis.set_major_locator(LogLocator(subs=(1, 2, 5)))
        axis.set_major_formatter(FormatStrFormatter("%g"))
        axis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("ms per frame")
    ax.set_ylabel(f"{METRIC} (lower is better)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ratio = float(train["ms_per_frame"].iloc[0]) / ms
    equal = chosen.ms_per_frame / ms
    note = "" if chosen.bound == WITHIN else f" ({chosen.bound})"
    ax.set_title(
        f"NDR {ratio:.2g}x faster than Mitsuba at {training_spp} spp; "
        f"{equal:.2g}x at equal DSSIM{note}",
        fontsize=9,
    )
    fig.tight_layout()
    save_figure(fig, path)
