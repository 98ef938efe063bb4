"""The simplification stage's jobs, one per rule of ``workflow/rules/simplification.smk``.

Each job is named after its rule and has the signature of :data:`neurender.jobs.Job`:
``(inputs, outputs, params, threads)``; each imports the modules it drives when it runs,
so a job loads only the libraries it uses (torch, Mitsuba, PyVista). Use cases: ``head``
(normal-map baking and joint simplification of the detailed head, grey Lambertian),
``metaballs`` (a ray-marched implicit surface converted to a textured mesh: albedo and
normal maps) and each user asset (a mesh file with its material, ``params["asset"]``, also
a textured mesh); see :mod:`neurender.simplification.assets`.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from neurender import io
from neurender.simplification import CASE_FILES, EXPORT_FILES

if TYPE_CHECKING:
    from neurender.simplification import views


def case_views(cfg: dict, case: str, split: str, kind: str) -> list[views.View]:
    """Training or test views of a use case, over the asset's camera range ``kind``."""
    from neurender.simplification import assets, views

    count = cfg["train_views"] if split == "train" else cfg["test_views"]
    return views.sample_views(
        count,
        cfg["seed"],
        f"{case}-{split}",
        cfg["camera_distance"],
        cfg["fov"],
        *assets.VIEW_RANGES[kind],
        cfg["light_distance"],
        cfg["light_cone"],
    )


def simplification_prepare(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Reference images (train/test EXR + view CSVs), the QEM atlas
    mesh and the classic bakes of one use case."""
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.simplification import assets, bake, formats, mesh_ops, views

    started = time.perf_counter()
    case = params["case"]
    mi, _ = require_mitsuba(params["device"])
    asset = assets.load(case, params)
    for split in ("train", "test"):
        split_views = case_views(params, case, split, asset.views)
        formats.write_images(outputs[f"{split}_images"], asset.references(mi, split_views, split))
        io.write_csv(outputs[f"{split}_views"], views.views_frame(split_views))
    v, f = mesh_ops.decimate(asset.vertices, asset.faces, asset.triangles)
    low = mesh_ops.uv_atlas(v, f, params["texture_size"])
    formats.save_lowpoly(outputs["lowpoly"], low, asset.albedo, asset.to_asset)
    normal_map, colour_map = bake.bake(
        low, asset.vertices, asset.faces, params["texture_size"], asset.colour_fn, asset.normal_fn
    )
    formats.write_texture(outputs["baked_normal"], normal_map)
    formats.write_texture(
        outputs["baked_albedo"],
        np.full_like(normal_map, asset.albedo) if colour_map is None else colour_map,
    )
    stats = {
        "reference_triangles": len(asset.faces),
        "lowpoly_triangles": len(f),
        "triangle_fraction": len(f) / len(asset.faces),
        "texture_size": params["texture_size"],
        "prepare_seconds": time.perf_counter() - started,
    }
    io.write_csv(
        outputs["stats"],
        pd.DataFrame([{"case": case, "quantity": k, "value": v} for k, v in stats.items()]),
    )


def simplification_optimise(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The QEM mesh's vertices and normal map (and, where the colour
    varies, its albedo map) optimised through Mitsuba against the training references:
    the optimised positions (``mesh``), maps and loss (its files as shipped:
    :func:`simplification_deploy`). The albedo map
    starts from ``inputs["initial_albedo"]`` where given (user assets: the classic bake
    of their own albedo), else from grey; an asset of uniform albedo (stored with its
    ``lowpoly`` file) keeps it."""
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.simplification import formats, optimise, views

    case = params["case"]
    mi, dr = require_mitsuba(params["device"])
    # One Dr.Jit thread makes the gradient scatter-adds, and so the result, deterministic.
    dr.set_thread_count(threads)
    low = formats.load_lowpoly(inputs["lowpoly"])
    references = optimise.References(
        views.views_from_frame(io.read_csv(inputs["train_views"])),
        formats.read_images(inputs["train_images"]),
    )
    size = params["texture_size"]
    flat = np.broadcast_to([0.5, 0.5, 1.0], (size, size, 3)).copy()
    constant = formats.load_albedo(inputs["lowpoly"])
    if "initial_albedo" in inputs:
        # A user asset's own texture (or colours), transferred to the atlas by the classic
        # bake, is the initial guess (paper 3: "texture maps from the reference scene").
        albedo = formats.read_texture(inputs["initial_albedo"])
    else:
        albedo = constant if constant is not None else np.full((size, size, 3), 0.5)
    settings = optimise.OptimiseConfig.from_stage(params, optimise_albedo=constant is None)
    positions, normal_map, albedo_map, loss = optimise.optimise(
        mi, dr, optimise.Start(low, flat, albedo), references, settings
    )
    if albedo_map is None:
        albedo_map = np.full_like(normal_map, constant)
    io.save_npz(outputs["mesh"], positions=positions)
    formats.write_texture(outputs["normal"], normal_map)
    formats.write_texture(outputs["albedo"], albedo_map)
    loss.insert(0, "case", case)
    io.write_csv(outputs["loss"], loss)


def simplification_deploy(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The optimised result of one case (``lowpoly``, ``mesh``, ``normal``, ``albedo``) as
    its shipped files, GLB and OBJ + MTL + PNGs in the asset's own units (the outputs of
    :data:`neurender.simplification.EXPORT_FILES`), each read back and checked against
    the optimised mesh, and the export timed: ``table``
    (:mod:`neurender.simplification.deploy`)."""
    from neurender.simplification import deploy, formats

    files = {kind: outputs[kind] for kind in EXPORT_FILES}
    table = deploy.deploy(
        params["case"],
        files,
        formats.load_lowpoly(inputs["lowpoly"]),
        io.load_npz(inputs["mesh"])["positions"],
        formats.read_texture(inputs["albedo"]),
        formats.read_texture(inputs["normal"]),
        formats.load_to_asset(inputs["lowpoly"]),
    )
    io.write_csv(outputs["table"], table)


def simplification_evaluate(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every variant of every case rendered from its held-out views, and ours as shipped
    (the GLB and OBJ of :func:`simplification_deploy`, read back): the metrics (means over
    the views, and per view) and the figures (the held-out comparison, the loss curves)."""
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.simplification import evaluate, figures

    mi, dr = require_mitsuba(params["device"])
    rows, crops = [], {}
    for case in params["cases"]:
        files = {kind: inputs[f"{case}_{kind}"] for kind in CASE_FILES}
        exports = {kind: inputs[f"{case}_{kind}"] for kind in EXPORT_FILES}
        case_rows, crops[case] = evaluate.evaluate_case(mi, dr, case, files, params, exports)
        rows += case_rows
    frame = pd.DataFrame(rows)
    io.write_csv(outputs["metrics_views"], frame)
    keys = ["method", "dataset", "model", "split", "metric"]
    io.write_csv(outputs["metrics"], frame.groupby(keys, sort=False)["value"].mean().reset_index())
    figures.comparison_figure(crops, outputs["figure"])
    losses = [io.read_csv(inputs[f"{case}_loss"]) for case in params["cases"]]
    figures.loss_figure(losses, outputs["loss_figure"])


def simplification_equal_quality(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Ours against the classic QEM + bake at equal quality, in triangles, for every case
    (:mod:`neurender.simplification.equal_quality`): each case's asset rebuilt from its
    keys (a user asset from ``params["user_assets"]``), the classic pipeline at
    ``equal_quality_multiples`` of its budget rendered from its held-out views
    (``<case>_test_views``, ``<case>_test_images``) and scored; ours' quality from
    ``metrics`` and its triangles from ``<case>_lowpoly``. The table (``table``, every
    case's) and the figure (``figure``)."""
    from neurender.mitsuba_setup import require_mitsuba
    from neurender.simplification import assets, formats, views
    from neurender.simplification import equal_quality as eq

    mi, dr = require_mitsuba(params["device"])
    metrics = io.read_csv(inputs["metrics"], ["dataset", "model", "metric", "value"])
    tables, sweeps, quality, triangles = [], {}, {}, {}
    for case in params["cases"]:
        cfg = {**params, "case": case}
        if case in params["user_assets"]:
            cfg["asset"] = params["user_assets"][case]
        asset = assets.load(case, cfg)
        test_views = views.views_from_frame(io.read_csv(inputs[f"{case}_test_views"]))
        references = formats.read_images(inputs[f"{case}_test_images"])
        sweeps[case] = eq.score_sweep(mi, dr, case, asset, test_views, references, cfg)
        quality[case] = eq.ours(metrics, case)
        triangles[case] = len(formats.load_lowpoly(inputs[f"{case}_lowpoly"]).faces)
        tables.append(eq.table(case, sweeps[case], quality[case], triangles[case]))
    table = pd.concat(tables, ignore_index=True)
    io.write_csv(outputs["table"], table)
    eq.quality_figure(sweeps, quality, triangles, outputs["figure"])


def simplification_summary(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every case's statistics (``stats``, each case's preparation's) with its
    optimisation's seconds (``losses``, the same cases in order) in one table, ``stats``
    (:func:`neurender.simplification.summary.statistics`)."""
    from neurender.simplification import summary

    stats = [io.read_csv(path) for path in inputs["stats"]]
    losses = [io.read_csv(path) for path in inputs["losses"]]
    io.write_csv(outputs["stats"], summary.statistics(stats, losses))


def simplification_targets(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The targets of the held-out ``metrics`` and of the ``equal_quality`` table
    (:func:`neurender.simplification.summary.targets`): results only, no time."""
    from neurender.simplification import summary

    metrics = io.read_csv(inputs["metrics"], ["dataset", "model", "metric", "value"])
    columns = ["method", "dataset", "model", "setting", "bound", "metric", "value"]
    equal = io.read_csv(inputs["equal_quality"], columns)
    io.write_csv(outputs["targets"], summary.targets(metrics, equal))


def simplification_viewer(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The report's interactive view of one use case (:mod:`neurender.simplification.viewer`):
    the reference (rebuilt from the case's keys, or read from the user's file) and the
    QEM, classic-bake and optimised meshes with their triangle counts and held-out PSNR
    (``metrics``)."""
    from neurender import viewer_data
    from neurender.simplification import assets
    from neurender.simplification.viewer import simplification_view

    case = params["case"]
    asset = assets.load(case, params)
    metrics = io.read_csv(inputs["metrics"], ["dataset", "model", "split", "metric", "value"])
    view = simplification_view(case, asset, inputs, metrics)
    viewer_data.write(
        outputs["viewer"],
        "meshes",
        f"Simplification {case}: reference, QEM, classic bake and ours (one camera)",
        view,
    )


def simplification_mesh_figure(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The case's reference, QEM and optimised meshes in 3D with wireframes (PyVista)."""
    from neurender.simplification import assets, figures, formats

    asset = assets.load(params["case"], params)
    low = formats.load_lowpoly(inputs["lowpoly"])
    ours = io.load_npz(inputs["mesh"])["positions"]
    figures.meshes_figure(
        params["case"],
        (asset.vertices, asset.faces),
        (low.positions, low.faces),
        (ours, low.faces),
        outputs["png"],
    )
