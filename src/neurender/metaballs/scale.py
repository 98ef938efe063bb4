"""Metaballs at scale: every renderer's cost and quality against the number of balls.

The thesis's case for the method (Horvath 2019, 7.4) is that a network's frame costs the
same whatever the number of balls. Here each renderer draws the same scenes of the
``cluster`` family (:func:`neurender.metaballs.families.cluster`: constant density, no
wall) at each ball count and width, scored against the exact renderer
(:func:`neurender.metaballs.raymarch.render_gbuffers`, cell lists for a finite kernel) by
the test set's metrics (:func:`neurender.metaballs.evaluate.example_metrics`):

- the networks: their inputs drawn from the scene (circles; impostors for ours), then the
  network (its shipped graph on the CPU), timed apart (``ms_inputs``, ``ms_network``);
- the no-learning renderers, each over its settings from cheap to exact
  (:data:`BASELINES`): a cheaper exact marcher (coarser bisection, lower resolution),
  screen-space fluid rendering, a density grid meshed by marching cubes, the refined
  impostors and the isolated spheres.

A network trained at the config's width is scored there; at other widths it is timed only
(a generator of the same size built for that width: the time of a frame does not depend on
the weights), its quality left empty. Times are medians of :func:`neurender.timing.timed`
on one thread, peak memory the resident memory a frame added
(:func:`neurender.timing.peak_memory`).

The equal-quality speed-up at each count and width (:func:`equal_quality_rows`): for each
network and each no-learning renderer, the fastest of its settings whose mean quality
over the scenes reaches the network's on every metric of
:data:`neurender.metaballs.equal_quality.QUALITY`, and the ratio of its time to the
network's, or a bound on it: the shared rule of :mod:`neurender.equal_quality`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import pandas as pd
import torch
from tqdm import tqdm

from neurender import equal_quality as shared
from neurender.metaball import Scene
from neurender.metaballs import (
    density_mesh,
    evaluate,
    families,
    inputs,
    model,
    raymarch,
    refined,
    screen_space,
)
from neurender.metaballs.equal_quality import QUALITY
from neurender.metaballs.gbuffers import GBuffers
from neurender.metaballs.renderer import MetaballRenderer
from neurender.plots import plt, save_figure
from neurender.rng import torch_generator
from neurender.timing import peak_memory, timed

#: The reference renderer's name in the rows.
EXACT = "exact"
#: Frames slower than this (seconds) are timed once; faster ones are the median of repeats.
SLOW_FRAME = 2.0
#: The most grid points a density grid may hold; finer settings are skipped (their grid
#: would not fit a laptop's memory).
MAX_GRID_POINTS = 1 << 24


@dataclasses.dataclass(frozen=True)
class Setting:
    """One renderer at one setting: ``renderer`` (a name of the table), ``setting`` (its
    label) and ``render(scene, width) -> GBuffers``."""

    renderer: str
    setting: str
    render: Callable


def _marcher(resolution: float, bisections: int) -> Callable:
    def render(scene, width):
        marched = max(1, round(resolution * width))
        buffers = raymarch.render_gbuffers(scene, marched, bisections=bisections)
        if marched == width:
            return buffers
        up = torch.nn.functional.interpolate(buffers.stack()[None], size=(width, width))[0]
        return _from_stack(up)

    return render


def _from_stack(stack: torch.Tensor) -> GBuffers:
    """G-buffers of a ``(7, W, W)`` stack (the mask by depth)."""
    return GBuffers(stack[:3], stack[3:4], stack[4:], stack[3] < 1)


#: The screen-space fluid settings of the sweep (a subset of
#: :func:`neurender.metaballs.screen_space.screen_space_settings`, cheap to expensive).
SCREEN_SPACE = (
    screen_space.ScreenSpace(filter_radius=0.0),
    screen_space.ScreenSpace(filter_radius=1.5, separable=True),
    screen_space.ScreenSpace(filter_radius=3.0),
    screen_space.ScreenSpace(filter_radius=3.0, iterations=2),
)


def baselines() -> list[Setting]:
    """Every no-learning renderer's settings, cheap to expensive within each."""
    out = [
        Setting("ray marcher", f"{r:g} width, {b} bisections", _marcher(r, b))
        for r in (0.5, 1.0)
        for b in (4, 12)
    ]
    out += [Setting("screen-space fluid", s.label, _screen_space(s)) for s in SCREEN_SPACE]
    out += [
        Setting("density mesh", f"spacing {share:g} r", _density(share))
        for share in density_mesh.SPACING_SHARES
    ]
    out.append(Setting("refined impostors", f"{refined.STEPS} steps", refined.refined_spheres))
    out.append(Setting("isolated spheres", "spheres of radius r", inputs.draw_spheres))
    return out


def _screen_space(setting: screen_space.ScreenSpace) -> Callable:
    options = dataclasses.asdict(setting)
    return lambda scene, width: screen_space.screen_space_fluid(scene, width, **options)


def _density(share: float) -> Callable:
    """The density mesh at a grid spacing of ``share`` times the scene's median radius;
    ``None`` (skipped) where its grid would hold more than :data:`MAX_GRID_POINTS`."""

    def render(scene, width):
        spacing = share * float(scene.radii.median())
        extent = scene.centres.amax(0) - scene.centres.amin(0) + 2 * float(scene.reach.max())
        if float((extent / spacing).prod()) > MAX_GRID_POINTS:
            return None
        return density_mesh.density_mesh(scene, width, spacing)

    return render


def scale_scene(count: int, index: int, cfg: Mapping) -> Scene:
    """Scene ``index`` at ``count`` balls (float32): the cluster family at ``packing`` of
    the config's ``kernel``, seeded by ``seed``, count and index."""
    gen = torch_generator(cfg["seed"], "metaballs scale", count, index)
    return families.cluster(count, gen, packing=cfg["packing"], kernel=cfg["kernel"]).to(
        torch.float32
    )


def _timed(render: Callable, *args, repeats: int) -> tuple[object, float, float]:
    """``render(*args)``'s result, its seconds (the median of ``repeats`` unless one call
    takes :data:`SLOW_FRAME`) and the bytes it added at its peak."""
    out, added = peak_memory(timed, render, *args)
    result, seconds = out
    if seconds < SLOW_FRAME and repeats > 1:
        _, seconds = timed(render, *args, repeats=repeats)
    return result, seconds, added


@dataclasses.dataclass
class Measured:
    """Every renderer's measurements on one scene at one width.

    Attributes:
        rows: tidy rows ``renderer, setting, engine, metric, value``: every renderer's
            times, ``peak_mb`` and, where scored, the metrics of
            :func:`neurender.metaballs.evaluate.example_metrics` (the exact renderer's
            against itself), and the exact frame's statistics
            (:func:`neurender.metaballs.families.frame_stats`).
        stacks: ``(renderer, setting)`` to its ``(7, W, W)`` stack (the exact one's under
            ``(EXACT, "reference")``).
    """

    rows: list[dict]
    stacks: dict[tuple[str, str], torch.Tensor]


def _rows(renderer: str, setting: str, engine: str, values: Mapping[str, float]) -> list[dict]:
    head = {"renderer": renderer, "setting": setting, "engine": engine}
    return [{**head, "metric": k, "value": float(v)} for k, v in values.items()]


def measure_scene(
    scene: Scene, width: int, networks: Mapping[str, tuple], scored: bool, repeats: int
) -> Measured:
    """Every renderer on one scene at ``width`` (:class:`Measured`).

    Args:
        networks: name to ``(draw(scene) -> (C, W, W), network(x (1, C, W, W)) ->
            (1, 7, W, W), engine)``.
        scored: whether the networks' quality is scored (else they are timed only).
        repeats: timed calls per frame faster than :data:`SLOW_FRAME`.
    """
    truth, seconds, added = _timed(raymarch.render_gbuffers, scene, width, repeats=1)
    stats = families.frame_stats(scene, truth)
    target = truth.stack()
    exact = {"ms_per_frame": 1e3 * seconds, "peak_mb": added / 2**20, **stats}
    exact |= evaluate.example_metrics(target, target)  # its own quality: the best there is
    rows = _rows(EXACT, "reference", "pytorch", exact)
    stacks = {(EXACT, "reference"): target}
    for s in baselines():
        out, seconds, added = _timed(s.render, scene, width, repeats=repeats)
        if out is None:
            continue
        values = {"ms_per_frame": 1e3 * seconds, "peak_mb": added / 2**20}
        values |= evaluate.example_metrics(out.stack(), target)
        rows += _rows(s.renderer, s.setting, "pytorch", values)
        stacks[s.renderer, s.setting] = out.stack()
    for name, (draw, network, engine) in networks.items():
        x, t_in, added_in = _timed(draw, scene, repeats=repeats)
        y, t_net, added_net = _timed(network, x[None], repeats=repeats)
        values = {
            "ms_inputs": 1e3 * t_in,
            "ms_network": 1e3 * t_net,
            "ms_per_frame": 1e3 * (t_in + t_net),
            "peak_mb": max(added_in, added_net) / 2**20,
        }
        setting = "trained" if scored else "timed only (untrained, same size)"
        if scored:
            values |= evaluate.example_metrics(y[0], target)
            stacks[name, setting] = y[0]
        rows += _rows(name, setting, engine, values)
    return Measured(rows, stacks)


def untrained_network(width: int, ngf: int, variant: str) -> tuple[Callable, Callable, str]:
    """``(draw, network, engine)`` of a generator of the given size built for ``width``,
    untrained: its frame costs what a trained one's does (weights do not change the work)."""
    net = model.build_generator(width, ngf, variant).eval()

    @torch.no_grad()
    def run(x: torch.Tensor) -> torch.Tensor:
        return ((net(x.float() * 2 - 1) + 1) / 2).clamp(0, 1)

    return (lambda scene: model.network_inputs(scene, width, variant)), run, "pytorch"


def measure(
    renderers: Mapping[str, MetaballRenderer], cfg: Mapping, trained_width: int
) -> pd.DataFrame:
    """Tidy rows of every renderer at every count of ``balls`` and width of ``widths``,
    ``scenes`` scenes each (:func:`measure_count`); the trained ``renderers`` at
    ``trained_width``, untrained ones of the same size elsewhere."""
    rows = []
    jobs = [(w, n, k) for w in cfg["widths"] for n in cfg["balls"] for k in range(cfg["scenes"])]
    for width, count, index in tqdm(jobs, desc="metaballs at scale", mininterval=10):
        if width == trained_width:
            networks = {n: (r.inputs, r, r.engine) for n, r in renderers.items()}
        else:
            networks = {n: untrained_network(width, r.ngf, r.variant) for n, r in renderers.items()}
        scene = scale_scene(count, index, cfg)
        measured = measure_scene(scene, width, networks, width == trained_width, cfg["repeats"])
        keys = {"balls": count, "width": width, "scene": index}
        rows += [{**keys, **row} for row in measured.rows]
    return pd.DataFrame(rows)


def means(rows: pd.DataFrame) -> pd.DataFrame:
    """The mean of each metric over the scenes, per renderer, setting, engine, count and
    width."""
    keys = ["renderer", "setting", "engine", "balls", "width", "metric"]
    return rows.groupby(keys, sort=False, as_index=False)["value"].mean()


def equal_quality_rows(mean: pd.DataFrame, networks: Sequence[str]) -> pd.DataFrame:
    """Per network, count, width and no-learning renderer (the exact one included): the
    fastest setting whose mean quality reaches the network's on every metric of
    :data:`QUALITY` (the network's quality at its trained width where it was only timed at
    this one), its time, the network's and their ratio ``speedup``, and its ``bound``: the
    shared rule, :func:`neurender.equal_quality.pick` (where none reaches it, the slowest
    setting and a lower bound)."""
    wide = mean.pivot_table(
        index=["renderer", "setting", "balls", "width"],
        columns="metric",
        values="value",
        sort=False,
    ).reset_index()
    out = []
    for net in networks:
        mine = wide[wide.renderer == net]
        scored = mine.dropna(subset=list(QUALITY))
        for row in mine.itertuples():
            source = scored[scored.balls == row.balls]
            if source.empty:
                continue
            target = {m: float(source.iloc[0][m]) for m in QUALITY}
            others = wide[(wide.balls == row.balls) & (wide.width == row.width)]
            for name, settings in others[~others.renderer.isin(networks)].groupby(
                "renderer", sort=False
            ):
                pick = shared.pick(settings, target, QUALITY)
                out.append(
                    {
                        "network": net,
                        "renderer": name,
                        "balls": row.balls,
                        "width": row.width,
                        "setting": pick.setting,
                        "renderer_ms": pick.cost,
                        "network_ms": row.ms_per_frame,
                        "speedup": pick.cost / row.ms_per_frame,
                        "bound": pick.bound,
                        "quality_from_width": int(source.iloc[0].width),
                    }
                )
    return pd.DataFrame(out)


def scale_figure(mean: pd.DataFrame, equal: pd.DataFrame, network: str, path: str) -> None:
    """Per width, milliseconds per frame against the number of balls (log-log) of the
    exact renderer, every network (inputs and network; the inputs alone dashed) and every
    no-learning renderer at its setting of ``network``'s quality (hollow markers: none
    reaches it, its most expensive setting shown); then the networks' and the best
    settings' IoU and normal error against the count at the trained width."""
    widths = sorted(mean.width.unique())
    fig, axes = plt.subplots(1, len(widths) + 2, figsize=(5.2 * (len(widths) + 2), 4.4))
    frame = mean[mean.metric == "ms_per_frame"]
    for ax, width in zip(axes, widths, strict=False):
        exact = frame[(frame.renderer == EXACT) & (frame.width == width)]
        ax.plot(exact.balls, exact.value, "k-o", label="exact (cell lists)")
        nets = frame[(frame.width == width) & frame.renderer.isin(equal.network.unique())]
        for name, rows in nets.groupby("renderer", sort=False):
            line = ax.plot(rows.balls, rows.value, "-s", label=f"{name} (network)")[0]
            drawn = mean[
                (mean.renderer == name) & (mean.width == width) & (mean.metric == "ms_inputs")
            ]
            ax.plot(drawn.balls, drawn.value, "--", color=line.get_color(), lw=1)
        picks = equal[(equal.network == network) & (equal.width == width)]
        for name, rows in picks[picks.renderer != EXACT].groupby("renderer", sort=False):
            line = ax.plot(rows.balls, rows.renderer_ms, "-", label=f"{name} (equal quality)")[0]
            for bound, part in rows.groupby("bound"):
                face = "none" if bound == shared.LOWER else line.get_color()
                ax.scatter(part.balls, part.renderer_ms, color=line.get_color(), facecolors=face)
        ax.set(xscale="log", yscale="log", xlabel="balls", ylabel="ms per frame")
        ax.set_title(f"{width} x {width} px, 1 thread")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    scored = mean[mean.width == min(widths)]
    for ax, metric, label in zip(
        axes[len(widths) :],
        ("iou_depth", "normal_error_mean_deg"),
        ("silhouette IoU", "mean normal error (degrees)"),
        strict=True,
    ):
        rows = scored[scored.metric == metric]
        for name, part in rows.groupby("renderer", sort=False):
            best = part.groupby("balls").value.max() if metric == "iou_depth" else None
            best = part.groupby("balls").value.min() if best is None else best
            ax.plot(best.index, best.values, "-o", label=name, ms=3)
        ax.set(xscale="log", xlabel="balls", ylabel=label)
        ax.set_title(f"{label}, best setting, {min(widths)} px")
        ax.grid(True, which="both", alpha=0.3)
    axes[-1].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)
