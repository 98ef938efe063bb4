"""The image-space metaballs stage's jobs, one per rule of ``workflow/rules/metaballs.smk``.

Each job is named after its rule and has the signature of :data:`neurender.jobs.Job`:
``(inputs, outputs, params, threads)``; each imports the modules it drives when it runs,
so a job loads only the libraries it uses (torch, matplotlib). ``params`` holds exactly
the config keys the job reads (keys of ``metaballs`` and ``metaballs_model``, ``seed``,
``device``) and the wildcard values.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from neurender import io
from neurender.metaballs import REFINED_BASELINE

if TYPE_CHECKING:
    from neurender.metaballs.renderer import MetaballRenderer

log = logging.getLogger(__name__)

#: AB examples shown in the data summary figure (from the first split).
SHOWN_EXAMPLES = 4
#: The network the scale figure's equal-quality lines and the trajectory's animation show.
SCALE_NETWORK = "sphere_residual"


def metaballs_examples(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """One split's AB examples (``examples`` of them, ``split``), its manifest and balls."""
    from neurender.metaballs import data

    manifest, balls = data.generate_split(
        params, params["split"], params["examples"], threads, outputs["examples"]
    )
    io.write_csv(outputs["balls"], balls)
    io.write_csv(outputs["manifest"], manifest)


def metaballs_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Tidy statistics of every split's examples and a figure of the first few."""
    from neurender.metaballs import figures, summary

    rows = []
    for path in inputs["manifests"]:
        manifest = io.read_csv(path, ["split", "balls", "coverage", "seconds"])
        rows += summary.data_rows(manifest)
    io.write_csv(outputs["csv"], pd.DataFrame(rows))
    files = sorted(Path(inputs["examples"][0]).glob("example_*.png"))[:SHOWN_EXAMPLES]
    figures.examples_figure(files, outputs["figure"])


def metaballs_train(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """One variant's generator, trained on the train split and validated on val."""
    from neurender.metaballs import training

    data_key = io.checksum(list(inputs.values()))
    training.train_generator(
        inputs,
        params,
        threads,
        outputs["checkpoint"],
        outputs["loss"],
        data_key,
        outputs.get("tensorboard"),
    )


def metaballs_evaluate(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant trained (``checkpoints``) and the sphere baselines scored on the
    held-out scenes: per example, means, by scene complexity, and their figures."""
    from neurender.metaball import kernel_from_config
    from neurender.metaballs import data, evaluate, figures
    from neurender.metaballs.renderer import load_renderers

    columns = ["example", "file", "balls", "min_depth_separation"]
    manifest = io.read_csv(inputs["test_manifest"], columns)
    scene_of = data.read_scenes(inputs["test_balls"], kernel_from_config(params["kernel"]))
    renderers = load_renderers(inputs["checkpoints"], params["device"], threads)
    frame, showcase = evaluate.score_test_set(
        inputs["test_dir"], manifest, scene_of, renderers, params["width"]
    )
    io.write_csv(outputs["examples"], frame)
    budgets = evaluate.budget_rows(dict(zip(renderers, inputs["checkpoints"], strict=True)))
    io.write_csv(outputs["metrics"], pd.concat([evaluate.mean_metrics(frame), budgets]))
    by_scene = evaluate.accuracy_by_scene(frame)
    io.write_csv(outputs["by_scene"], by_scene)
    figures.accuracy_figure(by_scene, outputs["scene_figure"])
    figures.comparison_figure(showcase, outputs["figure"])


def metaballs_equal_quality(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant trained (``checkpoints`` and their shipped graphs ``onnx``, same order;
    on the CPU the graphs are timed) against the cheapest ray marcher of its quality
    (:mod:`neurender.metaballs.equal_quality`) on the first ``equal_quality_examples`` test
    examples: their quality from the evaluation's per-example rows (``examples``), every
    marcher of the sweep rendered, scored and timed beside each network's frame time and the
    refined impostors' (the strongest no-learning renderer, :data:`REFINED_BASELINE`), all
    with ``threads`` torch threads (the rule asks for one: on a shared 2-core machine two
    threads of small tensor operations measured up to 20 times slower); the tidy ``table``
    and the ``figure``."""
    from neurender.metaball import kernel_from_config
    from neurender.metaballs import ab, data, equal_quality
    from neurender.metaballs.refined import refined_spheres
    from neurender.metaballs.renderer import load_renderers

    manifest = io.read_csv(inputs["test_manifest"], ["example", "file"]).sort_values("example")
    manifest = manifest.head(params["equal_quality_examples"])
    scene_of = data.read_scenes(inputs["test_balls"], kernel_from_config(params["kernel"]))
    examples = [
        (scene_of[int(ex.example)], ab.read_ab(Path(inputs["test_dir"]) / ex.file)["target"])
        for ex in manifest.itertuples()
    ]
    # Loading sets the torch threads: the marchers are timed with the networks' threads.
    renderers = load_renderers(inputs["checkpoints"], params["device"], threads, inputs["onnx"])
    scores = equal_quality.score_settings(examples, params["width"], equal_quality.sweep())
    rows = io.read_csv(inputs["examples"], ["example", "model", "metric", "value"])
    targets = equal_quality.network_targets(rows, manifest["example"].tolist())
    scenes = [scene for scene, _ in examples]
    networks = {
        name: (targets[name], equal_quality.network_ms_per_frame(r.inputs, r, scenes))
        for name, r in renderers.items()
    }
    width = params["width"]
    refined_ms = equal_quality.renderer_ms_per_frame(lambda s: refined_spheres(s, width), scenes)
    networks[REFINED_BASELINE] = (targets[REFINED_BASELINE], refined_ms)
    io.write_csv(outputs["table"], equal_quality.table(scores, networks))
    equal_quality.quality_figure(scores, networks, outputs["figure"])


def metaballs_demo(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The animated demo by each of :data:`DEMO_VARIANTS` (``checkpoints`` and their shipped
    graphs ``onnx``, same order; on the CPU the graphs run) and by ray marching: frames
    as GIF and strip, per-frame times, temporal stability, frame time against the number of
    balls, and the timing table, all timed with ``threads`` threads (the rule asks for one,
    as :func:`metaballs_equal_quality`)."""
    from neurender.metaballs import demo, figures, speed
    from neurender.metaballs.renderer import load_renderers

    renderers = load_renderers(inputs["checkpoints"], params["device"], threads, inputs["onnx"])
    sequence = demo.render_sequence(
        renderers, demo.demo_scene(params), params["demo_frames"], params["width"]
    )
    io.write_csv(outputs["frames"], sequence.timings)
    frames = figures.demo_frames(sequence.pictures)
    figures.demo_gif(frames, outputs["gif"])
    figures.demo_strip(frames, outputs["strip"])
    flips = demo.silhouette_flips(sequence.silhouettes, [*renderers, demo.RAY_MARCHING])
    figures.stability_figure(flips, outputs["stability"])
    balls = speed.frame_time_vs_balls(renderers, params)
    figures.frame_time_figure(balls, outputs["balls_png"])
    io.write_csv(outputs["timing"], speed.timing_table(sequence.timings, flips, balls))
    io.write_csv(outputs["balls"], balls)


def metaballs_deploy(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant trained (``checkpoints``) as the ONNX file a renderer ships (``onnx``,
    same order), checked against PyTorch on the inputs of the
    first test scenes (``test_balls``) and timed by both engines on the CPU with
    ``threads`` threads (:mod:`neurender.metaballs.deploy`); one row per variant in
    ``table`` (:mod:`neurender.deployment`)."""
    from neurender.deployment import deployment_table
    from neurender.metaball import kernel_from_config
    from neurender.metaballs import data, deploy
    from neurender.metaballs.renderer import MetaballRenderer

    scenes = data.read_scenes(inputs["test_balls"], kernel_from_config(params["kernel"]))
    rows = []
    for checkpoint, onnx_out in zip(inputs["checkpoints"], outputs["onnx"], strict=True):
        renderer = MetaballRenderer(checkpoint, "cpu", threads)
        x = deploy.example_inputs(renderer, scenes)
        rows.append(deploy.deploy_generator(renderer.variant, renderer, x, onnx_out, threads))
    io.write_csv(outputs["table"], deployment_table(rows))


def metaballs_targets(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The stage's targets, each stated as met or missed, at image width ``width``."""
    from neurender.metaballs import summary

    metrics = io.read_csv(inputs["metrics"], ["model", "metric", "value"])
    timing = io.read_csv(inputs["timing"], ["model", "metric", "value"])
    columns = ["method", "dataset", "model", "setting", "bound", "metric", "value"]
    equal = io.read_csv(inputs["equal_quality"], columns)
    table = summary.targets(metrics, timing, equal, params["width"])
    io.write_csv(outputs["targets"], table)


def metaballs_user_scenes(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The user's scenes (``scenes``, a CSV of balls) rendered by every variant trained
    (``checkpoints``), the sphere baselines and the ray marcher at width ``width``: the test
    set's metrics per scene and the figure. A scene whose surface holds the camera is
    refused as the file is read; an empty frame or one the near plane cuts is warned about
    (:func:`neurender.metaballs.user_scenes.view_notes`)."""
    from neurender.metaball import kernel_from_config
    from neurender.metaballs import figures, scene_file, user_scenes
    from neurender.metaballs.renderer import load_renderers

    balls = scene_file.read_user_scenes(inputs["scenes"])
    for note in user_scenes.outside_training(balls):
        log.warning("%s: %s", inputs["scenes"], note)
    renderers = load_renderers(inputs["checkpoints"], params["device"], threads)
    frame, shown = user_scenes.score_user_scenes(
        user_scenes.to_scenes(balls, kernel_from_config(params["kernel"])),
        renderers,
        params["width"],
    )
    for note in user_scenes.view_notes(frame):
        log.warning("%s: %s", inputs["scenes"], note)
    io.write_csv(outputs["table"], frame)
    figures.user_scenes_figure(shown, list(renderers), outputs["figure"])


def metaballs_viewer(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The report's interactive view (:mod:`neurender.metaballs.viewer`): the demo animation
    by every network trained (``checkpoints``) and by the ray marcher, with each network's
    silhouette difference as an overlay."""
    from neurender import viewer_data
    from neurender.metaballs import demo
    from neurender.metaballs.renderer import load_renderers
    from neurender.metaballs.viewer import demo_view

    renderers = load_renderers(inputs["checkpoints"], params["device"], threads)
    sequence = demo.render_sequence(
        renderers, demo.demo_scene(params), params["demo_frames"], params["width"]
    )
    viewer_data.write(
        outputs["viewer"],
        "frames",
        "Metaballs: the demo animation, networks against the ray marcher",
        demo_view(sequence, list(renderers), params["width"]),
    )


def _scale_networks(renderers: dict[str, MetaballRenderer]) -> dict[str, tuple]:
    """:func:`neurender.metaballs.scale.measure_scene`'s networks of trained renderers."""
    return {name: (r.inputs, r, r.engine) for name, r in renderers.items()}


def metaballs_scale(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every renderer's cost and quality against the number of balls
    (:mod:`neurender.metaballs.scale`): the networks (``checkpoints`` and their shipped
    graphs ``onnx``, same order) on the cluster scenes of each count of
    ``scale.balls`` at each of ``scale.widths``, one thread as the other timings; the tidy
    ``rows``, the ``equal_quality`` table and the ``figure``."""
    from neurender.metaball import kernel_from_config
    from neurender.metaballs import scale
    from neurender.metaballs.renderer import load_renderers

    renderers = load_renderers(inputs["checkpoints"], params["device"], threads, inputs["onnx"])
    cfg = {
        **params["scale"],
        "seed": params["seed"],
        "packing": params["packing"],
        "kernel": kernel_from_config(params["kernel"]),
    }
    rows = scale.measure(renderers, cfg, params["width"])
    io.write_csv(outputs["rows"], rows)
    mean = scale.means(rows)
    equal = scale.equal_quality_rows(mean, list(renderers))
    io.write_csv(outputs["equal_quality"], equal)
    scale.scale_figure(mean, equal, SCALE_NETWORK, outputs["figure"])


def metaballs_real_scenes(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The shipped real scenes of ``scale.structures`` and your structure files
    (``user_structures``; :mod:`neurender.metaballs.real_scenes`) drawn by every renderer at
    ``width`` and scored against the exact one: the tidy ``table`` (a row per scene,
    renderer, setting and metric), the ``figure`` (each scene by the exact renderer, the
    networks and each no-learning renderer's most exact setting) and the trajectory's
    animation by the exact renderer beside :data:`SCALE_NETWORK` (``trajectory``)."""
    import torch

    from neurender.metaball import kernel_from_config
    from neurender.metaballs import figures, real_scenes, scale
    from neurender.metaballs.renderer import load_renderers

    renderers = load_renderers(inputs["checkpoints"], params["device"], threads, inputs["onnx"])
    cfg, width = params["scale"], params["width"]
    kernel = kernel_from_config(params["kernel"])
    scenes = real_scenes.real_scenes(
        tuple(cfg["structures"]), kernel, cfg["ball_scale"], cfg["trajectory_frames"]
    )
    scenes |= real_scenes.user_structure_scenes(
        tuple(inputs["user_structures"]), kernel, cfg["ball_scale"], cfg["trajectory_frames"]
    )
    networks = _scale_networks(renderers)
    rows, shown = [], {}
    for label, scene in scenes.items():
        measured = scale.measure_scene(scene, width, networks, True, cfg["repeats"])
        rows += [{"scene": label, "balls": len(scene), **row} for row in measured.rows]
        shown[label] = real_scenes.showcase(scene, measured, width)
    io.write_csv(outputs["table"], pd.DataFrame(rows))
    figures.user_scenes_figure(shown, real_scenes.shown_models(shown), outputs["figure"])
    if "adk_dims" in cfg["structures"]:
        pictures = real_scenes.trajectory_pictures(
            real_scenes.trajectory(kernel, cfg["ball_scale"]), renderers[SCALE_NETWORK], width
        )
    else:
        pictures = [torch.zeros(3, width, 2 * width)]
    figures.demo_gif(figures.demo_frames(pictures), outputs["trajectory"], ms_per_frame=200)
