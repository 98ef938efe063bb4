"""The NDR stage's jobs, one per rule of ``workflow/rules/ndr.smk``.

Each job is named after its rule and has the signature of :data:`neurender.jobs.Job`:
``(inputs, outputs, params, threads)``; each imports the modules it drives when it runs,
so a job loads only the libraries it uses (torch, Mitsuba, matplotlib). A split's files
are ``<split>_dir``, ``<split>_manifest`` and ``<split>_lighting`` (see
:mod:`neurender.ndr.buffers`); the variants are those of :mod:`neurender.ndr.variants`.
"""

from __future__ import annotations

import logging
import sys

import pandas as pd

from neurender import io
from neurender.ndr import CALIBRATION_SAMPLES, DATASETS, KINDS, VARIANTS, split_name

log = logging.getLogger(__name__)

SPLIT_FILES = ("dir", "manifest", "lighting")


def _split_files(inputs: dict, split: str) -> dict[str, str]:
    return {key: inputs[f"{split}_{key}"] for key in SPLIT_FILES}


def ndr_data(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Render split ``params["split"]`` (``count`` samples) with ``threads`` processes."""
    from neurender.ndr import data

    data.generate_split(
        params,
        params["split"],
        params["count"],
        outputs["samples"],
        outputs["manifest"],
        outputs["lighting"],
        threads,
    )


def ndr_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Per-split statistics (the ``manifests`` of ``params["splits"]``), the white-furnace
    and sun checks and the buffers figure of the ``example`` split."""
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.ndr import figures, furnace, summary
    from neurender.tables import target_table

    manifests = dict(zip(params["splits"], inputs["manifests"], strict=True))
    io.write_csv(outputs["csv"], summary.split_statistics(manifests))
    mi, _ = require_mitsuba(params["device"])
    checks = furnace.furnace(
        mi,
        params["width"],
        params["furnace_spp"],
        params["coarse_samples"],
        params["seed"],
        params["coarse_height"],
    )
    io.write_csv(outputs["furnace"], target_table("ndr", checks))
    figures.buffers_figure(inputs["example"], outputs["figure"])


def ndr_train(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Train variant ``params["variant"]`` on the ``train`` and ``val`` split files."""
    from neurender.ndr.training import train_variant

    train_variant(
        params["variant"],
        _split_files(inputs, "train"),
        _split_files(inputs, "val"),
        params,
        threads,
        outputs["checkpoint"],
        outputs["loss"],
        io.checksum(list(inputs.values())),
        outputs.get("tensorboard"),
    )


def ndr_evaluate(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Score every variant (``checkpoint_<variant>``) on its test split; the per-sample
    scores, NDR's timing table, the comparison figure and the training curves."""
    from neurender.devices import resolve_device
    from neurender.ndr import figures, summary
    from neurender.ndr.buffers import NDRDataset
    from neurender.ndr.evaluate import score_split
    from neurender.ndr.model import load_model

    device = resolve_device(params["device"], threads)
    checkpoints = {v: inputs[f"checkpoint_{v}"] for v in params["variants"]}
    rows, per_sample, tests = [], [], {}
    for kind in KINDS:
        split = split_name(kind, "test")
        if f"{split}_dir" not in inputs:
            continue
        tests[kind] = NDRDataset.from_files(_split_files(inputs, split), params["mask_erosion"])
        scores = score_split(kind, tests[kind], checkpoints, device)
        rows += scores.rows
        per_sample += scores.per_sample
        if kind == "complex":
            figures.comparison_figure(
                scores.buffers, scores.truth, scores.methods, outputs["figure"]
            )
    io.write_csv(outputs["metrics"], pd.DataFrame(rows))
    io.write_csv(outputs["samples"], pd.DataFrame(per_sample))
    model = load_model(checkpoints["ndr"], device)
    seconds = summary.network_seconds(model, tests["complex"], device)
    where = f"cpu, {threads} threads" if device.type == "cpu" else device.type
    io.write_csv(
        outputs["timing"],
        summary.timing_table(seconds, inputs["train_manifest"], inputs["test_manifest"], where),
    )
    figures.loss_figure({v: inputs[f"loss_{v}"] for v in params["variants"]}, outputs["curves"])


def ndr_deploy(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every trained variant (``checkpoint_<variant>`` for ``params["variants"]``) as the
    ONNX file a renderer ships (``onnx``, in that order), checked against PyTorch on the
    first samples of the test split of its data and timed by both engines on the CPU with
    ``threads`` threads (:mod:`neurender.ndr.deploy`); one row per variant in ``table``
    (:mod:`neurender.deployment`). One job for all variants: their times are taken back to
    back under the same load, and re-exporting all of them costs little beside retraining
    the one variant that triggers it.

    NDR (``checkpoint_ndr``) also as the shipped one-graph renderer, its prefiltered coarse
    shading and network in one file: in float32 (``shipped``, checked against PyTorch on
    the first test sample, :func:`neurender.ndr.deploy.export_shipped`) and in int8
    (``shipped_int8``, calibrated on the first training samples). Its inputs are remade
    from a sample's stored G-buffers and its map, drawn again from ``params``' scene keys
    (``seed``, ``primitives``, ``edge_length``, ``environment_height``, ``user_probes_dir``
    with the user's maps, ``user_probe_fraction``, ``small_sun_fraction``,
    ``coarse_height``); its camera and width are ``camera_distance``, ``fov`` and
    ``width``."""
    import torch

    from neurender.deployment import deployment_table
    from neurender.ndr import deploy
    from neurender.ndr.buffers import NDRDataset
    from neurender.ndr.model import load_model

    cpu = torch.device("cpu")
    examples, rows = {}, []
    for variant, onnx_out in zip(params["variants"], outputs["onnx"], strict=True):
        split = split_name(VARIANTS[variant].data, "test")
        if split not in examples:
            files = _split_files(inputs, split)
            examples[split] = deploy.example_batch(NDRDataset.from_files(files, 0, deploy.EXAMPLES))
        model = load_model(inputs[f"checkpoint_{variant}"], cpu)
        rows.append(deploy.deploy_variant(variant, model, examples[split], onnx_out, threads))
    io.write_csv(outputs["table"], deployment_table(rows))
    ndr = load_model(inputs["checkpoint_ndr"], cpu)
    test = NDRDataset.from_files(_split_files(inputs, "test"), 0, 1)  # the stored masks
    error = deploy.export_shipped(params, ndr, test, outputs["shipped"])
    log.info("shipped graph %s: max |ONNX - PyTorch| %.3g", outputs["shipped"], error)
    train = NDRDataset.from_files(_split_files(inputs, "train"), 0, CALIBRATION_SAMPLES)
    deploy.export_shipped_int8(params, ndr, train, outputs["shipped"], outputs["shipped_int8"])


def ndr_equal_quality(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """NDR (``checkpoint``) against Mitsuba at every sample count of ``equal_quality_spp``
    and the training ``spp`` on the first ``equal_quality_samples`` test samples
    (:mod:`neurender.ndr.equal_quality`), Mitsuba and NDR timed on ``threads`` threads in
    this process. The shipped one-graph NDR (coarse shading and network in one ONNX file,
    written by :func:`ndr_deploy`) in float32 (``graph``) and in int8 (``graph_int8``),
    each timed and scored on every test split of the complex-trained networks
    (:mod:`neurender.ndr.graph_scores`). NDR's DSSIM: the evaluation's per-sample
    ``samples`` for the float32 network, the int8 graph's own scores for it; Mitsuba's
    against the test split's references. The table and the figure."""
    from neurender.devices import resolve_device
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.ndr import equal_quality, graph_scores
    from neurender.ndr.buffers import NDRDataset
    from neurender.ndr.model import load_model
    from neurender.nn.inference import OnnxNetwork

    mi, dr = require_mitsuba(params["device"])
    dr.set_thread_count(threads)
    device = resolve_device(params["device"], threads)
    count = params["equal_quality_samples"]
    test = NDRDataset.from_files(_split_files(inputs, "test"), params["mask_erosion"], count)
    if len(test) < count:
        raise ValueError(
            f"ndr.equal_quality_samples = {count}: the test split {inputs['test_manifest']} "
            f"has {len(test)} samples"
        )
    model = load_model(inputs["checkpoint"], device)
    graphs = {"float32": inputs["graph"], "int8": inputs["graph_int8"]}
    names = {equal_quality.NETWORK: "float32", equal_quality.NETWORK_INT8: "int8"}
    sessions = {name: OnnxNetwork(graphs[precision], threads) for name, precision in names.items()}
    scored = {}
    for kind in ("complex", "sunlit"):
        split = split_name(kind, "test")
        if f"{split}_dir" not in inputs:
            continue
        raw = NDRDataset.from_files(_split_files(inputs, split), 0)  # the stored masks
        per_graph = graph_scores.score_graphs(
            params, model, sessions, split, raw, params["mask_erosion"]
        )
        scored |= {(DATASETS[kind], name): v for name, v in per_graph.items()}
    scenes = [equal_quality.scene_of(params, i) for i in range(count)]
    spps = equal_quality.sweep(params["equal_quality_spp"], params["spp"])
    scores = equal_quality.score_sweep(mi, params, scenes, test.buffers, spps)
    per_sample = io.read_csv(inputs["samples"], ["dataset", "model", "sample", "metric", "value"])
    metric = equal_quality.METRIC
    ms = equal_quality.network_milliseconds(params, model, scenes, test, device, graphs, threads)
    int8_dssim = scored[DATASETS["complex"], equal_quality.NETWORK_INT8][metric][:count]
    networks = {
        equal_quality.NETWORK: {
            **ms,
            metric: equal_quality.network_dssim(per_sample, range(count)),
        },
        equal_quality.NETWORK_INT8: {
            "ms_per_frame": ms["shipped_int8_graph_ms"],
            metric: float(int8_dssim.mean()),
        },
    }
    table = equal_quality.table(scores, networks, params["spp"])
    io.write_csv(outputs["table"], pd.concat([table, equal_quality.graph_table(scored)]))
    equal_quality.quality_figure(scores, networks, params["spp"], outputs["figure"])


def ndr_targets(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The targets of the test ``metrics`` and of the speed against Mitsuba and the int8
    graph's quality (``equal_quality``), :func:`neurender.ndr.summary.targets`."""
    from neurender.ndr import summary

    metrics = io.read_csv(inputs["metrics"], ["dataset", "model", "metric", "value"])
    columns = ["method", "dataset", "model", "split", "setting", "bound", "metric", "value"]
    equal = io.read_csv(inputs["equal_quality"], columns)
    io.write_csv(outputs["targets"], summary.targets(metrics, equal))


def ndr_relight(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Test sample ``relight_sample`` under ``relight_turns`` rotations of its map: the
    scores of NDR and of the shading input per rotation, and the figure."""
    from neurender.devices import resolve_device
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.ndr import figures, relight
    from neurender.ndr.model import SHADING_INPUT, load_model

    mi, _ = require_mitsuba(params["device"])
    sample = params["relight_sample"]
    shifts, degrees = relight.rotations(params["environment_height"], params["relight_turns"])
    buffers = relight.relit_buffers(mi, params, sample, shifts)
    device = resolve_device(params["device"], threads)
    images = relight.relight(load_model(inputs["checkpoint"], device), buffers, device)
    table = relight.relight_table(images, buffers["mask"], sample, degrees)
    io.write_csv(outputs["csv"], table)
    figures.relighting_figure(
        degrees,
        images["truth"]["I_R"],
        images["ndr"]["I_R"],
        images[SHADING_INPUT]["I_R"],
        table[table.metric == "dssim_I_R"],
        outputs["figure"],
    )


def ndr_viewer(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The report's interactive view (:mod:`neurender.ndr.viewer`): test sample
    ``relight_sample`` under its map turned in :data:`neurender.viewer_data.TURNS` steps
    (at most one per map column), by Mitsuba, NDR (``checkpoint``) and the shading input."""
    from neurender import viewer_data
    from neurender.devices import resolve_device
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.ndr import relight
    from neurender.ndr.model import load_model
    from neurender.ndr.viewer import relight_view

    mi, _ = require_mitsuba(params["device"])
    sample = params["relight_sample"]
    turns = min(viewer_data.TURNS, 2 * params["environment_height"])
    shifts, degrees = relight.rotations(params["environment_height"], turns)
    buffers = relight.relit_buffers(mi, params, sample, shifts)
    device = resolve_device(params["device"], threads)
    images = relight.relight(load_model(inputs["checkpoint"], device), buffers, device)
    viewer_data.write(
        outputs["viewer"],
        "frames",
        f"NDR: unseen test sample {sample} under its map turned about +y",
        relight_view(images, degrees),
    )


def ndr_user_objects(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every user object (``user_objects``: name -> mesh file) under the test maps, the
    real-world-like maps and the user's maps (:func:`user_objects.object_maps`): Mitsuba's
    reference, NDR (``checkpoint``) and the shading input; the scores per map, their means
    per object and map set, and the figure "your objects"."""
    from neurender.devices import resolve_device
    from neurender.ndr import figures, pool, user_objects
    from neurender.ndr.model import load_model

    if not params["user_objects"]:
        raise ValueError("ndr.user_objects is empty: name at least one mesh file to render")
    defaults = params["user_object_defaults"]
    objects = {}
    for name, path in params["user_objects"].items():
        objects[name] = user_objects.load_user_object(path, defaults)
        log.info("user object %s (%s): %s", name, path, user_objects.description(objects[name]))
    entries = user_objects.object_maps(params)
    tasks = [(params, name, obj, entry) for name, obj in objects.items() for entry in entries]
    workers = 1 if "drjit" in sys.modules else threads
    renders = pool.render_all(
        user_objects.render_object, tasks, params["device"], workers, "ndr your objects"
    )
    device = resolve_device(params["device"], threads)
    labels = [(name, entry) for _, name, _, entry in tasks]
    scores = user_objects.score_objects(
        renders, labels, load_model(inputs["checkpoint"], device), params["mask_erosion"], device
    )
    per_map = pd.DataFrame(scores.rows)
    io.write_csv(outputs["maps"], per_map)
    io.write_csv(outputs["table"], user_objects.mean_rows(per_map))
    figures.user_objects_figure(
        [(name, entry.map_set, entry.name) for name, entry in labels],
        scores.buffers,
        scores.truth,
        scores.methods,
        per_map,
        outputs["figure"],
    )
