"""DeepPRT's jobs, one per rule of ``workflow/rules/prt.smk`` (whose params and input
functions are in ``workflow/rules/helpers/prt.smk``).

Each job is named after its rule and has the signature of :data:`neurender.jobs.Job`:
``(inputs, outputs, params, threads)``. Their files are under ``results/prt/``:
``probes/`` (the light probes and their SH), ``<object>/`` (geometry image, sequence,
one folder of frames and a manifest per split, scores, deployment rows, the shipped
networks ``deepprt_<material>``, every variant's networks in ``variants/``) and
``figures/``. Formats of the probes' SH, the sequences and the frames:
:mod:`neurender.prt.frames`; of the deployment rows: :mod:`neurender.deployment`.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from neurender import io, lights, sh, train, viewer_data
from neurender.deployment import deployment_table, read_deployment
from neurender.prt import (
    MATERIALS,
    SPLITS,
    VARIANTS,
    animations,
    figures,
    frames,
    noise,
    objects,
    summary,
    transfer,
    unseen,
    unseen_scores,
    unshadowed,
)
from neurender.prt.equal_quality import deployment_rows, inference_seconds, timing_rows
from neurender.prt.experiments import path_coordinate, path_rows, relight_rows
from neurender.prt.geometry_image import parametrise, reconstruction_error, resample
from neurender.prt.local_model import LocalConfig
from neurender.prt.model import DeepPRT, export_deepprt
from neurender.prt.momoprt import MoMoPRT, fit_momoprt
from neurender.prt.scores import aggregate, score_frames
from neurender.prt.sequences import build_sequences, user_sequences
from neurender.prt.training import train_deepprt, train_local
from neurender.prt.viewer import prt_view
from neurender.shapes import BLENDSHAPES, SourceMesh
from neurender.tables import tidy_rows

log = logging.getLogger(__name__)

#: What :func:`prt_geometry_image` may change in a mesh to map it (counted in its table).
REPAIRS = ("welded_vertices", "dropped_faces", "reoriented_faces", "seam_edges", "split_edges")


def _light(path: str, n_bands: int) -> np.ndarray:
    return frames.read_sh_light(path)[: n_bands**2]


def _split(inputs: dict, seq: dict, split: str, n_bands: int) -> frames.Split:
    return frames.load_split(
        inputs[f"{split}_dir"], inputs[f"{split}_manifest"], seq[f"{split}_params"], n_bands
    )


# ---------------------------------------------------------------- data


def prt_probe(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """A light probe (built in, or the user's EXR ``source``) and its SH projection."""
    source = inputs.get("source")
    image = (
        lights.load_probe(source)
        if source
        else lights.procedural_probe(params["probe"], params["probe_height"])
    )
    lights.write_probe(outputs["exr"], image)
    io.write_csv(outputs["sh"], frames.sh_light_table(sh.project_latlong(image, params["n_bands"])))


def _user_sequence(inputs: dict, name: str) -> tuple[animations.Frames, animations.Frames | None]:
    """A user animation's frames and separate test frames, checked up front."""
    return animations.load_sequence(
        inputs["frames"], inputs.get("test_frames", []), f"prt.user_sequences.{name}"
    )


def prt_geometry_image(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The object's rest shape (built in, the user's mesh ``source``, or the first of the
    user's animation ``frames``) made a disk, parametrised on the square and resampled,
    with its blendshapes, on the ``resolution^2`` grid; the grid's lookup (``face``,
    ``bary`` in the source triangles) resamples every other frame the same way."""
    start = time.perf_counter()
    name, n, seed = params["object"], params["resolution"], params["seed"]
    counts = {}
    if "frames" in inputs:
        sequence, test = _user_sequence(inputs, name)
        mesh, kind = SourceMesh(sequence.positions[0], sequence.faces), "user_sequence"
        label = str(sequence.files[0])
        counts = {"frames": len(sequence.files), "test_frames": len(test.files) if test else 0}
    elif "source" in inputs:
        mesh, label, kind = objects.load_user_mesh(inputs["source"]), inputs["source"], "user"
    else:
        mesh, label, kind = objects.source_mesh(name, params["source_vertices"], seed), name, name
    # The plane shares the head's map so S_lin = a S_head + (1 - a) S_plane keeps pixels aligned.
    mapped = (
        objects.source_mesh("head", params["source_vertices"], seed) if name == "plane" else mesh
    )
    gim, disk = parametrise(mapped.vertices, mapped.faces, n, label)
    if gim.flipped:
        raise RuntimeError(f"object {name}: harmonic map still has {gim.flipped} flipped triangles")
    rest = gim.resample(mesh.faces, mesh.vertices)
    names = sorted(mesh.blendshapes, key=BLENDSHAPES.index) if mesh.blendshapes else []
    deltas = (
        np.stack([gim.resample(mesh.faces, mesh.blendshapes[b]) for b in names])
        if names
        else np.zeros((0, n, n, 3))
    )
    error = reconstruction_error(mesh.vertices, mesh.faces, rest)
    io.save_npz(
        outputs["gim"],
        rest=rest.astype(np.float32),
        deltas=deltas.astype(np.float32),
        blendshapes=np.array(names, dtype=str),
        uv=gim.uv,
        face=gim.face,
        bary=gim.bary,
        source_vertices=mesh.vertices,
        source_faces=mesh.faces,
        kind=np.array(kind),
    )
    stats = {
        "source_vertices": len(mesh.vertices),
        "source_faces": len(mesh.faces),
        "flipped_triangles": gim.flipped,
        "cotangent_weights": int(gim.method == "cotangent"),
        "recon_error_mean": error["mean"],
        "recon_error_max": error["max"],
        "seconds": time.perf_counter() - start,
        **counts,
        **{k: disk.changes[k] for k in ("boundary_loops", "genus", "seam_edges", "seam_length")},
        "stretch_l2": gim.stretch_l2,
        "stretch_max": gim.stretch_max,
        **{k: disk.changes[k] for k in ("welded_vertices", "dropped_faces", "reoriented_faces")},
        "split_edges": gim.split_edges,
    }
    repaired = {k: stats[k] for k in REPAIRS if stats[k]}
    if repaired:
        log.info("%s: changed to map %s without flipped triangles: %s", name, label, repaired)
    log.info("%s: %s", name, stats)
    rows = tidy_rows("prt", name, "geometry image", "all", stats)
    io.write_csv(outputs["stats"], pd.DataFrame(rows))


def prt_sequence(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Deformation frames of every split (:mod:`neurender.prt.sequences`); a user
    animation's frames resampled through its geometry image's lookup."""
    gim = io.load_npz(inputs["gim"])
    name = params["object"]
    if "frames" in inputs:
        sequence, test = _user_sequence(inputs, name)
        n = gim["rest"].shape[0]

        def grids(animation: animations.Frames) -> np.ndarray:
            return np.stack(
                [
                    resample(gim["face"], gim["bary"], n, animation.faces, p)
                    for p in animation.positions
                ]
            )

        arrays = user_sequences(name, grids(sequence), grids(test) if test else None, params)
    else:
        arrays = build_sequences(name, gim, params)
    io.save_npz(outputs["seq"], **arrays)


def prt_transfer(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Ray-traced diffuse and glossy transfer of every frame of a split, one EXR per frame,
    and the split's manifest."""
    name, split, directions = params["object"], params["split"], params["directions"]
    seq = io.load_npz(inputs["seq"])
    positions = seq[f"{split}_positions"]
    light = _light(inputs["light"], params["n_bands"])
    offset = frames.ray_offset(positions[0], params["ray_offset"])
    Path(outputs["frames"]).mkdir(parents=True, exist_ok=True)
    rows = []
    for f in tqdm(range(len(positions)), desc=f"{name} {split}", mininterval=2.0):
        start = time.perf_counter()
        normals, diffuse, glossy, rays = transfer.sample_frame(
            positions[f], directions, params, offset, light, threads, name, split, f, directions
        )
        seconds = time.perf_counter() - start
        file = Path(outputs["frames"]) / f"frame_{f:04d}.exr"
        frames.write_frame(file, positions[f], normals, diffuse, glossy, params["n_bands"])
        rows.append(
            {
                "frame": f,
                "split": split,
                "file": file.name,
                "directions": directions,
                "rays": rays,
                "seconds": seconds,
                "rays_per_s": rays / seconds,
                "extrapolated": bool(seq["test_extrapolated"][f]) if split == "test" else False,
            }
        )
    io.write_csv(outputs["manifest"], pd.DataFrame(rows))


def prt_noise_floor(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The noise floor of the training-quality ground truth (:mod:`neurender.prt.noise`)."""
    positions = io.load_npz(inputs["seq"])["test_positions"]
    light = _light(inputs["light"], params["n_bands"])
    rows = noise.noise_floor_rows(
        params["object"], positions, inputs["reference"], light, params, threads
    )
    io.write_csv(outputs["csv"], pd.DataFrame(rows))


def prt_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    figures.frames_figure(
        params["object"], inputs["frames"], inputs["light"], params["n_bands"], outputs["png"]
    )


def prt_mesh_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The object's geometry-image mesh and deformation frames in 3D (PyVista)."""
    gim, seq = io.load_npz(inputs["gim"]), io.load_npz(inputs["seq"])
    figures.meshes_figure(
        params["object"], gim["rest"], seq["train_positions"], seq["test_positions"], outputs["png"]
    )


def prt_probes_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    figures.probes_figure(inputs["exrs"], inputs["sh"], outputs["png"])


def prt_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Per-object data statistics and the noise floor of every object in two tables."""
    io.write_csv(outputs["data"], summary.data_table(inputs["gim"], inputs["manifests"]))
    noise_rows = pd.concat([io.read_csv(p) for p in inputs["noise"]], ignore_index=True)
    io.write_csv(outputs["noise"], noise_rows.drop(columns="frame"))


def prt_benchmark(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    from neurender.prt.benchmark import run_benchmark

    light = frames.read_sh_light(inputs["light"])
    run_benchmark(inputs["seq"], light, params, threads, outputs["csv"])


# ---------------------------------------------------------------- models


def prt_train(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """One network of one variant (``params["variant"]``, :data:`neurender.prt.VARIANTS`)
    trained on an object's train split (val for model selection), and the selected
    network exported as its ONNX file: ``paper``, the paper's U-Net
    (:func:`~neurender.prt.training.train_deepprt`); ``shadowing``, the unshadowed
    transfer plus a local network (:func:`~neurender.prt.training.train_local`; glossy
    reads the SH ``light``)."""
    seq = io.load_npz(inputs["seq"])
    train_split, val_split = (_split(inputs, seq, s, params["n_bands"]) for s in ("train", "val"))
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
        light = _light(inputs["light"], params["n_bands"]) if "light" in inputs else None
        train_local(
            train_split, val_split, local_cfg, params, *common, light, data_key, tensorboard
        )
    else:
        raise ValueError(
            f"prt_train: variant {params['variant']!r}; expected one of {list(VARIANTS)}"
        )
    export_deepprt(outputs["checkpoint"], val_split, outputs["onnx"])


def prt_momoprt(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """MoMoPRT fitted on the train split, on blendshape weights where the object has them."""
    seq = io.load_npz(inputs["seq"])
    train_split, val_split = (_split(inputs, seq, s, params["n_bands"]) for s in ("train", "val"))
    use_params = str(seq["kind"]) in ("head", "head_linear", "head_excluded")
    model = fit_momoprt(
        train_split,
        val_split,
        params["material"],
        use_params,
        params["pca_components"],
        params["ridges"],
    )
    model.save(outputs["model"])


def _variant_files(
    variants: list[str], files: list[str], materials: tuple[str, ...] = MATERIALS
) -> dict:
    """``(variant, material) -> file`` of a rule's per-variant files (expanded in the
    order variant, material)."""
    keys = [(v, m) for v in variants for m in materials]
    return dict(zip(keys, files, strict=True))


def _evaluation_scores(
    inputs: dict, params: dict, seq: dict, light: np.ndarray, nets: dict, threads: int
) -> tuple[pd.DataFrame, dict, frames.Split]:
    """Per-frame scores of every network (keys ``(model name, material)``), MoMoPRT and
    the noise floor on val and test, Fig. 7's panels and the test split."""
    name, n_bands = params["object"], params["n_bands"]
    linear = {m: MoMoPRT.load(p) for m, p in zip(MATERIALS, inputs["momoprt"], strict=True)}
    rows, panels = [], {}
    for split in ("val", "test"):
        data = _split(inputs, seq, split, n_bands)
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


def prt_evaluate(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant's networks (``params["variants"]``, named by
    :data:`neurender.prt.VARIANTS`), MoMoPRT and the noise floor scored on the val and
    test frames of one object (:mod:`neurender.prt.scores`), each variant timed
    (:mod:`neurender.prt.equal_quality`; each network's times and ONNX file are its
    ``deployment`` rows) with its training budget (``epochs_<material>``), and Fig. 7."""
    name, variants = params["object"], params["variants"]
    seq = io.load_npz(inputs["seq"])
    light = _light(inputs["light"], params["n_bands"])
    checkpoints = _variant_files(variants, inputs["deepprt"])
    onnx_files = _variant_files(variants, inputs["onnx"])
    nets = {
        (VARIANTS[v], m): DeepPRT(path, onnx_files[v, m], params["device"], threads)
        for (v, m), path in checkpoints.items()
    }
    scores, panels, test = _evaluation_scores(inputs, params, seq, light, nets, threads)
    io.write_csv(outputs["frames"], scores)
    engine_s = {key: inference_seconds(net, test) for key, net in nets.items()}
    models = [VARIANTS[v] for v in variants]
    timing = timing_rows(
        name,
        {model: nets[model, "diffuse"] for model in models},
        {model: engine_s[model, "diffuse"] for model in models},
        test,
        light,
        params,
        threads,
        scores,
    )
    deployment, budget = [], []
    for v, model in zip(variants, models, strict=True):
        deployment += deployment_rows(
            name,
            {m: nets[model, m] for m in MATERIALS},
            {m: onnx_files[v, m] for m in MATERIALS},
            {m: engine_s[model, m] for m in MATERIALS},
            test,
            threads,
            model,
        )
        epochs = {f"epochs_{m}": train.epochs_trained(checkpoints[v, m]) for m in MATERIALS}
        budget += tidy_rows("prt", name, model, "test", epochs)
    io.write_csv(outputs["deployment"], deployment_table(deployment))
    table = pd.concat([aggregate(scores), timing, pd.DataFrame(budget)], ignore_index=True)
    io.write_csv(outputs["metrics"], table)
    figures.prediction_figure(name, panels, outputs["figure"])


def prt_model_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every object's results in the report's DeepPRT tables (its ``deployment`` rows
    too), every variant's compression rows and loss curves, the shipped files' sizes, the
    equal-quality figure, and the targets of the shipped variant (``params["shipped"]``),
    the unseen-deformation benchmark's (``unseen``, :mod:`neurender.prt.unseen_scores`)
    too."""
    names, variants = params["objects"], params["variants"]
    table = pd.concat([io.read_csv(p) for p in inputs["metrics"]], ignore_index=True)
    io.write_csv(outputs["metrics"], table)
    deployment = [read_deployment(p) for p in inputs["deployment"]]
    io.write_csv(outputs["deployment"], pd.concat(deployment, ignore_index=True))
    splits = len(SPLITS)
    frame_dirs = {o: inputs["frames"][splits * i : splits * (i + 1)] for i, o in enumerate(names)}
    keys = [(o, VARIANTS[v], m) for o in names for v in variants for m in MATERIALS]
    compression = summary.compression_rows(
        names,
        dict(zip(keys, inputs["checkpoints"], strict=True)),
        dict(zip(keys, inputs["onnx"], strict=True)),
        frame_dirs,
        params["resolution"],
        params["n_bands"],
    )
    shipped = VARIANTS[params["shipped"]]
    shipped_files = dict(
        zip([(o, m) for o in names for m in MATERIALS], inputs["shipped"], strict=True)
    )
    compression = pd.concat([compression, summary.shipped_rows(shipped_files, shipped)])
    io.write_csv(outputs["compression"], compression.reset_index(drop=True))
    experiments = [io.read_csv(p) for p in inputs["experiments"]]
    unseen = io.read_csv(inputs["unseen"])
    io.write_csv(outputs["targets"], summary.target_frame(table, experiments, shipped, unseen))
    figures.loss_figure(dict(zip(keys, inputs["losses"], strict=True)), outputs["loss"])
    models = [VARIANTS[v] for v in variants]
    figures.equal_quality_figure(
        table, params["equal_quality_directions"], models, outputs["equal_quality"]
    )


def prt_experiment(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Paper section 4.2.2 / Fig. 6: diffuse L2-RGB along the experiment's test path for
    every variant's diffuse network (``params["variants"]``) and MoMoPRT; each network's
    ``deployment`` row (timed as in :func:`prt_evaluate`)."""
    name = params["object"]
    seq = io.load_npz(inputs["seq"])
    light = _light(inputs["light"], params["n_bands"])
    data = _split(inputs, seq, "test", params["n_bands"])
    x, label = path_coordinate(name, data)
    files = zip(params["variants"], inputs["deepprt"], inputs["onnx"], strict=True)
    nets = {
        VARIANTS[v]: (DeepPRT(ckpt, onnx, params["device"], threads), onnx)
        for v, ckpt, onnx in files
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
    if len(inputs["probes"]) < 2:
        raise ValueError(f"dynamic lighting needs two light probes, got {inputs['probes']}")
    seq = io.load_npz(inputs["seq"])
    probes = [_light(p, params["n_bands"]) for p in inputs["probes"][:2]]
    data = _split(inputs, seq, "test", params["n_bands"])
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
    and the unshadowed and static baselines; the table and the error-against-strength
    figure (paper Fig. 6 generalised)."""
    name, n_bands = params["object"], params["n_bands"]
    gim, seq = io.load_npz(inputs["gim"]), io.load_npz(inputs["seq"])
    light = _light(inputs["light"], n_bands)
    variant_files = [(v, m) for v in params["variants"] for m in MATERIALS]  # expand()'s order
    nets = {
        (VARIANTS[v], m): DeepPRT(ckpt, onnx, params["device"], threads)
        for (v, m), ckpt, onnx in zip(variant_files, inputs["deepprt"], inputs["onnx"], strict=True)
    }
    linear = {m: MoMoPRT.load(p) for m, p in zip(MATERIALS, inputs["momoprt"], strict=True)}
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
        preds |= unseen_scores.baselines(data, mean_split, n_bands, coeffs)
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
    n_bands, name = params["n_bands"], params["object"]
    seq = io.load_npz(inputs["seq"])
    data = _split(inputs, seq, "test", n_bands)
    first = frames.Split(*(getattr(data, f.name)[:1] for f in dataclasses.fields(data)))
    predictions = {
        "DeepPRT": DeepPRT(inputs["deepprt"], inputs["onnx"], params["device"], threads).predict(
            first
        ),
        "MoMoPRT": MoMoPRT.load(inputs["momoprt"]).predict(first),
    }
    probes = {Path(p).name.removesuffix("_sh.csv"): _light(p, n_bands) for p in inputs["probes"]}
    viewer_data.write(
        outputs["viewer"],
        "prt",
        f"DeepPRT {name}: test frame 0, diffuse, relit in the page",
        prt_view(first, 0, predictions, probes, n_bands),
    )
