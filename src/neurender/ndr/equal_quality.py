"""NDR against Mitsuba at equal quality, as DeepPRT's equal-quality ratio
(:mod:`neurender.prt.equal_quality`) and the metaballs' (:mod:`neurender.metaballs.
equal_quality`).

Mitsuba renders the first test samples again (the same object, map and render seed as the
test split's noise-floor render, :data:`neurender.ndr.data.NOISY_SEED_OFFSET`, so the row
at the training ``spp`` is that render) at every sample count of a sweep; each render is
scored as :func:`neurender.ndr.evaluate.score` scores the networks: DSSIM of ``I_R``,
Reinhard tone-mapped, within the eroded mask, against the clean test reference
(``reference_spp``). NDR's quality is its mean DSSIM on the same samples in the
evaluation's per-sample table. The fastest sample count whose mean DSSIM is at most
NDR's is its equal-quality render (:func:`pick`, the shared rule of
:mod:`neurender.equal_quality`); the ratio of that render's milliseconds
to NDR's end to end (the coarse shading by the data's estimator,
:func:`neurender.ndr.data.coarse_maps`, with the map's lighting made once per map, plus
the network at batch 1; the G-buffers, which a rasteriser makes, are not counted) is the
equal-quality speed-up, or a bound on it
(:data:`neurender.equal_quality.BOUNDS`).

Times are wall-clock medians of :func:`neurender.timing.timed` per sample (after one
uncounted call) averaged over the samples, on the same machine, samples and threads. A
frame counts only per-frame work on both sides: Mitsuba's two renders (both maps,
:func:`neurender.ndr.render.render_shading`) of a scene already built, NDR's coarse
shading and network; building Mitsuba's scene (its map's sampling tables, the mesh) is
timed apart (``scene_ms``; the data stage's ``render_seconds`` include it), as NDR's map
lighting and G-buffers are not counted.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from types import ModuleType

import numpy as np
import pandas as pd
import torch
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from neurender import equal_quality as shared
from neurender.ndr import DATASETS, EQUAL_QUALITY_REPEATS, data, render
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.evaluate import score
from neurender.ndr.graph_scores import graph_inputs
from neurender.ndr.model import NDRModel, compose
from neurender.ndr.objects import ProceduralObject
from neurender.nn.inference import OnnxNetwork
from neurender.plots import plt, save_figure
from neurender.tables import tidy_rows
from neurender.timing import timed

#: The quality compared (lower is better) and the ``model`` and ``split`` of the rows.
METRIC = "dssim_I_R"
MITSUBA = "mitsuba"
NETWORK = "ndr"
NETWORK_INT8 = "ndr_int8"
SPLIT = shared.SPLIT
#: The ``split`` of the shipped graphs' scores on whole test splits.
GRAPH_SPLIT = "test (shipped graph)"
#: What each NDR model of the table is.
GRAPH_LABELS = {NETWORK: "NDR", NETWORK_INT8: "NDR, int8 graph"}


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


def network_milliseconds(
    cfg: dict,
    model: NDRModel,
    scenes: Sequence[Scene],
    test: NDRDataset,
    device: torch.device,
    graphs: dict[str, str],
    threads: int,
    repeats: int = EQUAL_QUALITY_REPEATS,
) -> dict[str, float]:
    """NDR's milliseconds per frame, means over ``scenes`` of per-sample medians:
    ``coarse_shading_ms`` (:func:`neurender.ndr.data.coarse_maps` from the map's lighting,
    made once per map and not counted), ``network_ms`` (``model`` on the sample of
    ``test``, batch 1, on ``device``), ``shipped_graph_ms`` and ``shipped_int8_graph_ms``
    (the one-graph NDR files ``graphs["float32"]`` and ``graphs["int8"]``,
    :mod:`neurender.ndr.graph_scores`, by ONNX Runtime on ``threads`` threads) and
    ``ms_per_frame``, NDR's float32 frame: the shipped graph when the data's coarse shading
    is ``prefiltered`` (the graph computes exactly what the network was trained on), else
    the importance-sampled shading plus the network (the graph's shading would not be the
    training input; its time is then for comparison only)."""
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    sessions = {k: OnnxNetwork(graphs[k], threads) for k in ("float32", "int8")}
    coarse, network, shipped = [], [], {k: [] for k in sessions}
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
        arrays = [x.numpy() for x in graph_inputs(cfg, model, "test", scene.index, sample)]
        for k, session in sessions.items():
            shipped[k].append(timed(session, *arrays, repeats=repeats, warmup=1)[1])
    ms = {"coarse_shading_ms": 1e3 * float(np.mean(coarse))}
    ms["network_ms"] = 1e3 * float(np.mean(network))
    ms["shipped_graph_ms"] = 1e3 * float(np.mean(shipped["float32"]))
    ms["shipped_int8_graph_ms"] = 1e3 * float(np.mean(shipped["int8"]))
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


#: The quality compared, lower is better (:mod:`neurender.equal_quality`).
QUALITY = {METRIC: False}


def label(spp: int) -> str:
    """A sample count's ``setting``."""
    return f"{spp} spp"


def settings(scores: pd.DataFrame) -> pd.DataFrame:
    """:func:`score_sweep`'s rows as the shared rule reads them: ``setting`` (the sample
    count's label) for ``spp``."""
    return scores.assign(setting=scores["spp"].map(label)).drop(columns="spp")


def pick(scores: pd.DataFrame, target: float) -> shared.Pick:
    """The fastest sample count of :func:`score_sweep`'s ``scores`` whose DSSIM is at most
    ``target``, or the bound (:func:`neurender.equal_quality.pick`)."""
    return shared.pick(settings(scores), {METRIC: target}, QUALITY)


def table(
    scores: pd.DataFrame, networks: dict[str, dict[str, float]], training_spp: int
) -> pd.DataFrame:
    """The equal-quality table (:func:`neurender.equal_quality.table`, model
    :data:`MITSUBA` per sample count, of the complex test set): per NDR graph
    (``networks``: model name, :data:`NETWORK` or :data:`NETWORK_INT8`, -> its times, at
    least ``ms_per_frame``, and its DSSIM) beside the shared rows its ``training_spp`` and
    ``speedup_vs_training_spp`` (Mitsuba at ``training_spp`` over the graph's frame)."""
    training = scores.loc[scores["spp"] == training_spp, "ms_per_frame"]
    if training.empty:
        raise ValueError(f"the sweep has no row at the training spp {training_spp}")
    graphs = {}
    for name, network in networks.items():
        ms = network["ms_per_frame"]
        extra = {k: v for k, v in network.items() if k not in ("ms_per_frame", METRIC)}
        extra |= {
            "training_spp": training_spp,
            "speedup_vs_training_spp": float(training.iloc[0]) / ms,
        }
        graphs[name] = shared.Network({METRIC: network[METRIC]}, ms, extra)
    return shared.table("ndr", DATASETS["complex"], MITSUBA, settings(scores), graphs, QUALITY)


def quality_figure(
    scores: pd.DataFrame, networks: dict[str, dict[str, float]], training_spp: int, path: str
) -> None:
    """DSSIM of ``I_R`` against milliseconds per frame, both on log axes: Mitsuba per
    sample count (labelled, the training count ringed), each NDR graph of ``networks`` (as
    :func:`table`'s) a star on the dashed line of its DSSIM, its picked render crossed; the
    title states the speed-ups."""
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
    titles = []
    for (name, network), colour in zip(networks.items(), ("C3", "C2"), strict=False):
        ms, target = network["ms_per_frame"], network[METRIC]
        graph = GRAPH_LABELS[name]
        ax.scatter([ms], [target], marker="*", s=220, color=colour, zorder=3, label=graph)
        ax.axhline(target, color=colour, ls="--", lw=0.8)
        chosen = pick(scores, target)
        if chosen.bound != shared.LOWER:
            row = settings(scores).set_index("setting").loc[chosen.setting]
            ax.scatter(
                [row["ms_per_frame"]],
                [row[METRIC]],
                marker="x",
                s=90,
                color=colour,
                zorder=3,
                label=f"cheapest of its DSSIM ({chosen.setting})",
            )
        ratio = float(train["ms_per_frame"].iloc[0]) / ms
        equal = shared.stated(chosen.cost / ms, chosen.bound)
        titles.append(f"{graph} {ratio:.2g}x at {training_spp} spp, {equal} at equal DSSIM")
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
    ax.set_title("faster than Mitsuba: " + "; ".join(titles), fontsize=8, wrap=True)
    fig.tight_layout()
    save_figure(fig, path)


def graph_table(per_sample: dict[tuple[str, str], dict[str, torch.Tensor]]) -> pd.DataFrame:
    """Tidy rows (split :data:`GRAPH_SPLIT`) of the shipped graphs' means on whole test
    splits: ``per_sample`` maps (dataset label, model name) to per-sample scores ``(N,)``
    (:func:`neurender.ndr.graph_scores.score_graphs`)."""
    rows = []
    for (dataset, name), values in per_sample.items():
        means = {k: float(v.mean()) for k, v in values.items()}
        rows += tidy_rows(
            "ndr", dataset, name, GRAPH_SPLIT, means, setting="all samples", bound="measured"
        )
    return pd.DataFrame(rows)
