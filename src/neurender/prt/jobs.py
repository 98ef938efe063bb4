"""DeepPRT's model and evaluation jobs, one per rule of ``workflow/rules/prt.smk`` (whose
params and input functions are in ``workflow/rules/helpers/prt.smk``); the jobs that build
the data (probes, geometry images, sequences, transfer, MoMoPRT) are in
:mod:`neurender.prt.data_jobs`, which loads no torch.

Each job is named after its rule and has the signature of :data:`neurender.jobs.Job`:
``(inputs, outputs, params, threads)``. Each imports the modules it drives when it runs,
so a job loads only the libraries it uses (torch alone takes 1 to 2 s to import on a
laptop core, longer than many a job's own work). Their files are under ``results/prt/``:
``probes/`` (the light probes and their SH), ``<object>/`` (geometry image, sequence,
one folder of frames and a manifest per split, scores, deployment rows, the shipped
networks ``deepprt_<material>``, every variant's networks in ``variants/``) and
``figures/``. Formats of the probes' SH, the sequences and the frames:
:mod:`neurender.prt.frames`; of the deployment rows: :mod:`neurender.deployment`.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from tqdm import tqdm

from neurender import io
from neurender.jobs import input_name
from neurender.prt import (
    CALIBRATION_FRAMES,
    CHECK_FRAMES,
    MATERIALS,
    SPLITS,
    VARIANTS,
    frames,
    int8_name,
)
from neurender.prt.frames import split_frames
from neurender.prt.momoprt import MoMoPRT
from neurender.tables import tidy_rows

if TYPE_CHECKING:
    from neurender.prt.model import DeepPRT

log = logging.getLogger(__name__)


def prt_noise_floor(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The noise floor of the training-quality ground truth (:mod:`neurender.prt.noise`)."""
    from neurender.prt import noise

    positions = io.load_npz(inputs["seq"])["test_positions"]
    light = frames.read_sh_light(inputs["light"], params["n_bands"])
    rows = noise.noise_floor_rows(
        params["object"], positions, inputs["reference"], light, params, threads
    )
    io.write_csv(outputs["csv"], pd.DataFrame(rows))


def prt_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    from neurender.prt import figures

    figures.frames_figure(
        params["object"], inputs["frames"], inputs["light"], params["n_bands"], outputs["png"]
    )


def prt_mesh_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The object's geometry-image mesh and deformation frames in 3D (PyVista)."""
    from neurender.prt import figures

    gim, seq = io.load_npz(inputs["gim"]), io.load_npz(inputs["seq"])
    figures.meshes_figure(
        params["object"], gim["rest"], seq["train_positions"], seq["test_positions"], outputs["png"]
    )


def prt_probes_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    from neurender.prt import figures

    figures.probes_figure(inputs["exrs"], inputs["sh"], outputs["png"])


def prt_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Per-object data statistics and the noise floor of every object in two tables."""
    from neurender.prt import summary

    io.write_csv(outputs["data"], summary.data_table(inputs["gim"], inputs["manifests"]))
    noise_rows = pd.concat([io.read_csv(p) for p in inputs["noise"]], ignore_index=True)
    io.write_csv(outputs["noise"], noise_rows.drop(columns="frame"))


def prt_train(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """One network of one variant (``params["variant"]``, :data:`neurender.prt.VARIANTS`)
    trained on an object's train split (val for model selection; :func:`prt_deploy`
    exports it): ``paper``, the paper's U-Net
    (:func:`~neurender.prt.training.train_deepprt`, ``batch_size`` and ``lr``);
    ``shadowing``, the unshadowed transfer plus a local network
    (:func:`~neurender.prt.training.train_local`, ``shadowing_batch_size`` and
    ``shadowing_lr``; glossy reads the SH ``light``)."""
    from neurender.prt.local_model import LocalConfig
    from neurender.prt.training import shadowing_training, train_deepprt, train_local

    seq = io.load_npz(inputs["seq"])
    train_split, val_split = (
        split_frames(inputs, seq, s, params["n_bands"]) for s in ("train", "val")
    )
    material, data_key = params["material"], io.checksum(list(inputs.values()))
    common = (threads, outputs["checkpoint"], outputs["loss"])
    tensorboard = outputs.get("tensorboard")
    if params["variant"] == "paper":
        train_deepprt(train_split, val_split, material, params, *common, data_key, tensorboard)
    elif params["variant"] == "shadowing":
        local_cfg = LocalConfig(
            n_bands=params["n_bands"],
            material=material,
            widths=params["widths"],
            blocks=params["blocks"],
        )
        light = (
            frames.read_sh_light(inputs["light"], params["n_bands"]) if "light" in inputs else None
        )
        train_local(
            train_split,
            val_split,
            local_cfg,
            shadowing_training(params),
            *common,
            light,
            data_key,
            tensorboard,
        )
    else:
        raise ValueError(
            f"prt_train: variant {params['variant']!r}; expected one of {list(VARIANTS)}"
        )


def prt_deploy(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """One trained network (``checkpoint``) as the graphs a renderer ships: its ONNX file
    (``onnx``, checked against PyTorch on the first val frames,
    :func:`~neurender.prt.model.export_deepprt`) and its int8 form (``int8``, its
    convolutions calibrated on the first train frames,
    :func:`~neurender.prt.model.export_int8`). Its own rule, so that a change to the export
    reruns this and what reads the graphs, never the training."""
    from neurender.prt.model import export_deepprt, export_int8

    seq, n_bands = io.load_npz(inputs["seq"]), params["n_bands"]
    val_split = split_frames(inputs, seq, "val", n_bands, first=CHECK_FRAMES)
    export_deepprt(inputs["checkpoint"], val_split, outputs["onnx"])
    train_split = split_frames(inputs, seq, "train", n_bands, first=CALIBRATION_FRAMES)
    export_int8(outputs["onnx"], train_split, outputs["int8"])


def _variant_files(
    inputs: dict, kind: str, variants: list[str], materials: tuple[str, ...] = MATERIALS
) -> dict:
    """``(variant, material) -> file`` of a rule's per-variant ``kind`` files, named
    ``input_name(kind, variant, material)``."""
    return {(v, m): inputs[input_name(kind, v, m)] for v in variants for m in materials}


def _momoprt(inputs: dict) -> dict[str, MoMoPRT]:
    """MoMoPRT's fit of each material (inputs ``input_name("momoprt", material)``)."""
    return {m: MoMoPRT.load(inputs[input_name("momoprt", m)]) for m in MATERIALS}


def _evaluation_scores(
    inputs: dict, params: dict, seq: dict, light: np.ndarray, nets: dict, threads: int
) -> tuple[pd.DataFrame, dict, frames.Split]:
    """Per-frame scores of every network (keys ``(model name, material)``), MoMoPRT and
    the noise floor on val and test, Fig. 7's panels and the test split."""
    from neurender.prt import noise
    from neurender.prt.scores import score_frames

    name, n_bands = params["object"], params["n_bands"]
    linear = _momoprt(inputs)
    rows, panels = [], {}
    for split in ("val", "test"):
        data = split_frames(inputs, seq, split, n_bands)
        preds = {key: net.predict(data) for key, net in nets.items()}
        preds |= {("MoMoPRT", m): linear[m].predict(data) for m in MATERIALS}
        extrapolated = np.zeros(len(data.positions), bool)
        if split == "test":
            preds |= noise.noise_floor_predictions(
                name, seq["test_positions"], light, params, threads
            )
            extrapolated = seq["test_extrapolated"]
        split_rows, split_panels = score_frames(
            name, split, data, preds, extrapolated, light, params
        )
        rows += split_rows
        panels |= split_panels
    return pd.DataFrame(rows), panels, data


def _networks(
    inputs: dict, params: dict, threads: int
) -> tuple[dict[tuple[str, str], DeepPRT], dict[tuple[str, str], str], dict]:
    """Every variant's networks (``params["variants"]``) by ``(model name, material)``:
    the float32 graph on ``params["device"]`` (PyTorch) and the int8 graph
    (:func:`neurender.prt.int8_name`, ONNX Runtime on the CPU whatever the device); their
    ONNX files by the same keys; the checkpoints by ``(variant, material)``."""
    from neurender.prt.model import DeepPRT

    checkpoints = _variant_files(inputs, "pt", params["variants"])
    graphs = {"onnx": VARIANTS, "int8.onnx": {v: int8_name(m) for v, m in VARIANTS.items()}}
    nets, files = {}, {}
    for kind, names in graphs.items():
        device, pytorch = (params["device"], True) if kind == "onnx" else ("cpu", False)
        for (v, m), onnx_file in _variant_files(inputs, kind, params["variants"]).items():
            files[names[v], m] = onnx_file
            nets[names[v], m] = DeepPRT(checkpoints[v, m], onnx_file, device, threads, pytorch)
    return nets, files, checkpoints


def prt_evaluate(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant's networks (``params["variants"]``, named by
    :data:`neurender.prt.VARIANTS`) and their int8 graphs, MoMoPRT and the noise floor
    scored on the val and test frames of one object (:mod:`neurender.prt.scores`): per
    frame (``frames``), their means with each network's training budget
    (``epochs_<material>``) (``scores``), and Fig. 7. Times nothing: the rule runs on one
    thread beside other jobs (:func:`prt_equal_quality` times)."""
    from neurender import train
    from neurender.prt import figures
    from neurender.prt.scores import aggregate

    name, variants = params["object"], params["variants"]
    seq = io.load_npz(inputs["seq"])
    light = frames.read_sh_light(inputs["light"], params["n_bands"])
    nets, _, checkpoints = _networks(inputs, params, threads)
    scores, panels, _ = _evaluation_scores(inputs, params, seq, light, nets, threads)
    io.write_csv(outputs["frames"], scores)
    budget = []
    for v in variants:
        epochs = {f"epochs_{m}": train.epochs_trained(checkpoints[v, m]) for m in MATERIALS}
        for model in (VARIANTS[v], int8_name(VARIANTS[v])):
            budget += tidy_rows("prt", name, model, "test", epochs)
    io.write_csv(outputs["metrics"], pd.concat([aggregate(scores), pd.DataFrame(budget)]))
    int8 = {int8_name(m) for m in VARIANTS.values()}
    float32 = {k: p for k, p in panels.items() if k[0] not in int8}
    figures.prediction_figure(name, float32, outputs["figure"])


def prt_equal_quality(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every network of :func:`prt_evaluate` timed on the first test frame by each of its
    engines and against ray-traced ground truth of its quality
    (:mod:`neurender.prt.equal_quality`), all on this job's ``threads`` (the rule takes
    every core): the object's ``equal_quality`` table and its ``deployment`` rows (each
    network's times and ONNX file)."""
    from neurender.deployment import deployment_table
    from neurender.prt import equal_quality

    name, variants = params["object"], params["variants"]
    seq = io.load_npz(inputs["seq"])
    light = frames.read_sh_light(inputs["light"], params["n_bands"])
    test = split_frames(inputs, seq, "test", params["n_bands"])
    nets, files, _ = _networks(inputs, params, threads)
    engine_s = {key: equal_quality.inference_seconds(net, test) for key, net in nets.items()}
    models = [m for v in variants for m in (VARIANTS[v], int8_name(VARIANTS[v]))]
    equal = equal_quality.table(
        name,
        {model: nets[model, "diffuse"] for model in models},
        {model: engine_s[model, "diffuse"] for model in models},
        test,
        light,
        params,
        threads,
        io.read_csv(inputs["frames"], ["split", "model", "metric", "frame", "value"]),
    )
    deployment = []
    for model in models:
        deployment += equal_quality.deployment_rows(
            name,
            {m: nets[model, m] for m in MATERIALS},
            {m: files[model, m] for m in MATERIALS},
            {m: engine_s[model, m] for m in MATERIALS},
            test,
            threads,
            model,
        )
    io.write_csv(outputs["deployment"], deployment_table(deployment))
    io.write_csv(outputs["equal_quality"], equal)


def prt_model_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every object's results in the report's DeepPRT tables (its ``deployment`` rows
    too), every variant's compression rows and loss curves, the shipped variant's
    (``params["shipped"]``) files' sizes (their int8 forms' too, ``shipped_int8``) and the
    equal-quality figure."""
    from neurender.deployment import read_deployment
    from neurender.prt import figures, summary

    names, variants = params["objects"], params["variants"]
    table = pd.concat([io.read_csv(p) for p in inputs["metrics"]], ignore_index=True)
    io.write_csv(outputs["metrics"], table)
    equal = pd.concat([io.read_csv(p) for p in inputs["equal_quality"]], ignore_index=True)
    io.write_csv(outputs["equal_quality"], equal)
    deployment = [read_deployment(p) for p in inputs["deployment"]]
    io.write_csv(outputs["deployment"], pd.concat(deployment, ignore_index=True))
    frame_dirs = {o: [inputs[input_name("frames", o, s)] for s in SPLITS] for o in names}
    triples = [(o, v, m) for o in names for v in variants for m in MATERIALS]
    keys = {(o, VARIANTS[v], m): (o, v, m) for o, v, m in triples}

    def by_key(kind: str) -> dict:
        return {key: inputs[input_name(kind, *parts)] for key, parts in keys.items()}

    compression = summary.compression_rows(
        names,
        by_key("pt"),
        by_key("onnx"),
        frame_dirs,
        params["resolution"],
        params["n_bands"],
    )
    shipped = VARIANTS[params["shipped"]]
    pairs = [(o, m) for o in names for m in MATERIALS]
    compression = pd.concat(
        [compression]
        + [
            summary.shipped_rows({p: inputs[input_name(kind, *p)] for p in pairs}, model)
            for kind, model in (("shipped", shipped), ("shipped_int8", int8_name(shipped)))
        ]
    )
    io.write_csv(outputs["compression"], compression.reset_index(drop=True))
    figures.loss_figure(by_key("loss.csv"), outputs["loss"])
    models = [m for v in variants for m in (VARIANTS[v], int8_name(VARIANTS[v]))]
    figures.equal_quality_figure(equal, models, outputs["equal_quality_figure"])


def prt_targets(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The targets of the shipped variant (``params["shipped"]``): of every object's test
    ``metrics`` and ``equal_quality`` table, of the held-out ``experiments`` and of the
    ``unseen``-deformation benchmark (:func:`neurender.prt.summary.target_frame`)."""
    from neurender.prt import summary

    metrics = io.read_csv(inputs["metrics"])
    equal = io.read_csv(inputs["equal_quality"])
    experiments = [io.read_csv(p) for p in inputs["experiments"]]
    unseen = io.read_csv(inputs["unseen"])
    shipped = VARIANTS[params["shipped"]]
    io.write_csv(
        outputs["targets"], summary.target_frame(metrics, equal, experiments, shipped, unseen)
    )


def prt_experiment(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Paper section 4.2.2 / Fig. 6: diffuse L2-RGB along the experiment's test path for
    every variant's diffuse network (``params["variants"]``) and MoMoPRT; each network's
    ``deployment`` row (timed as in :func:`prt_evaluate`)."""
    from neurender.deployment import deployment_table
    from neurender.prt import figures
    from neurender.prt.equal_quality import deployment_rows, inference_seconds
    from neurender.prt.experiments import path_coordinate, path_rows
    from neurender.prt.model import DeepPRT

    name = params["object"]
    seq = io.load_npz(inputs["seq"])
    light = frames.read_sh_light(inputs["light"], params["n_bands"])
    data = split_frames(inputs, seq, "test", params["n_bands"])
    x, label = path_coordinate(name, data)
    checkpoints = _variant_files(inputs, "pt", params["variants"], ("diffuse",))
    graphs = _variant_files(inputs, "onnx", params["variants"], ("diffuse",))
    nets = {
        VARIANTS[v]: (DeepPRT(ckpt, graphs[v, m], params["device"], threads), graphs[v, m])
        for (v, m), ckpt in checkpoints.items()
    }
    preds = {model: net.predict(data) for model, (net, _) in nets.items()}
    preds["MoMoPRT"] = MoMoPRT.load(inputs["momoprt"]).predict(data)
    table = pd.DataFrame(path_rows(name, data, x, preds, light, params["render_resolution"]))
    io.write_csv(outputs["csv"], table)
    figures.experiment_figure(name, table, label, outputs["figure"])
    rows = []
    for model, (net, onnx) in nets.items():
        seconds = {"diffuse": inference_seconds(net, data)}
        rows += deployment_rows(
            name, {"diffuse": net}, {"diffuse": onnx}, seconds, data, threads, model
        )
    io.write_csv(outputs["deployment"], deployment_table(rows))


def prt_relight(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Paper Fig. 2: test frame 0 relit while the light blends from one probe to another."""
    from neurender.prt import figures
    from neurender.prt.experiments import relight_rows
    from neurender.prt.model import DeepPRT

    if len(inputs["probes"]) < 2:
        raise ValueError(f"dynamic lighting needs two light probes, got {inputs['probes']}")
    seq = io.load_npz(inputs["seq"])
    probes = [frames.read_sh_light(p, params["n_bands"]) for p in inputs["probes"][:2]]
    data = split_frames(inputs, seq, "test", params["n_bands"])
    net = DeepPRT(inputs["deepprt"], inputs["onnx"], params["device"], threads)
    rows, blends = relight_rows(
        params["object"], data, net.predict(data)[0], probes, params["render_resolution"]
    )
    figures.relight_figure(params["object"], blends, outputs["figure"])
    io.write_csv(outputs["csv"], pd.DataFrame(rows))


def prt_unseen(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The unseen-deformation benchmark of one object (:mod:`neurender.prt.unseen_scores`):
    every family of :func:`neurender.prt.unseen.families_for` at every strength, its
    ground truth traced here, scored for each DeepPRT variant, MoMoPRT (where it can
    predict: on positions for every family, on blendshape weights for ``extrapolation``)
    and the unshadowed, static and disk-occlusion baselines; the table and the
    error-against-strength figure (paper Fig. 6 generalised)."""
    from neurender.prt import figures, unseen, unseen_scores, unshadowed
    from neurender.prt.model import DeepPRT

    name, n_bands = params["object"], params["n_bands"]
    gim, seq = io.load_npz(inputs["gim"]), io.load_npz(inputs["seq"])
    light = frames.read_sh_light(inputs["light"], n_bands)
    graphs = _variant_files(inputs, "onnx", params["variants"])
    nets = {
        (VARIANTS[v], m): DeepPRT(ckpt, graphs[v, m], params["device"], threads)
        for (v, m), ckpt in _variant_files(inputs, "pt", params["variants"]).items()
    }
    linear = _momoprt(inputs)
    mean = seq["train_positions"].astype(np.float64).mean(0)
    deltas = gim["deltas"]
    families = unseen.families_for(len(deltas) > 0)
    # Blendshape weights are the shape parameters only where they drive the sequence.
    weights = seq["train_params"]
    mean_params = weights.mean(0) if len(deltas) and weights.shape[1] == len(deltas) else None
    directions = params["reference_directions"]
    offset = frames.ray_offset(mean, params["ray_offset"])
    trace = {"seed": params["seed"], "direction_sets": params["direction_sets"], "n_bands": n_bands}
    mean_split = unseen_scores.traced(
        mean[None], directions, trace, offset, light, threads, name, "unseen_mean"
    )
    coeffs = unshadowed.glossy_polynomial(light)
    rows = []
    cases = unseen_scores.cases(
        mean,
        families,
        params["unseen_strengths"],
        params["unseen_frames"],
        params["seed"],
        deltas,
        mean_params,
    )
    for case in tqdm(cases, desc=f"{name} unseen", mininterval=2.0):
        data = unseen_scores.traced(
            case.positions, directions, trace, offset, light, threads, name, case.tag, case.params
        )
        preds = {key: net.predict(data) for key, net in nets.items()}
        for material, model in linear.items():
            if model.basis.size or case.params is not None:  # positions, or its weights
                preds[("MoMoPRT", material)] = model.predict(data)
        preds |= unseen_scores.baselines(data, mean_split, n_bands, coeffs, light)
        values = unseen_scores.frame_scores(data, preds, light, params)
        rows += unseen_scores.case_rows(name, case, values)
    table = pd.DataFrame(rows)
    io.write_csv(outputs["csv"], table)
    figures.unseen_figure(name, table, outputs["figure"])


def prt_unseen_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every object's unseen-deformation rows in one table (what the targets read:
    :func:`neurender.prt.unseen_scores.targets`)."""
    tables = [io.read_csv(p) for p in inputs["csvs"]]
    io.write_csv(outputs["csv"], pd.concat(tables, ignore_index=True))


# ---------------------------------------------------------------- report


def prt_viewer(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The report's interactive view of one object (:mod:`neurender.prt.viewer`): test
    frame 0 as a mesh with the diffuse transfer of the ground truth, DeepPRT and MoMoPRT,
    and every probe (``probes``: ``<name>_sh.csv`` files) turned about +y."""
    from neurender import viewer_data
    from neurender.prt.model import DeepPRT
    from neurender.prt.viewer import prt_view

    n_bands, name = params["n_bands"], params["object"]
    seq = io.load_npz(inputs["seq"])
    data = split_frames(inputs, seq, "test", n_bands)
    first = frames.Split(*(getattr(data, f.name)[:1] for f in dataclasses.fields(data)))
    predictions = {
        "DeepPRT": DeepPRT(inputs["deepprt"], inputs["onnx"], params["device"], threads).predict(
            first
        ),
        "MoMoPRT": MoMoPRT.load(inputs["momoprt"]).predict(first),
    }
    probes = {
        Path(p).name.removesuffix("_sh.csv"): frames.read_sh_light(p, n_bands)
        for p in inputs["probes"]
    }
    viewer_data.write(
        outputs["viewer"],
        "prt",
        f"DeepPRT {name}: test frame 0, diffuse, relit in the page",
        prt_view(first, 0, predictions, probes, n_bands),
    )
