"""DeepPRT's data jobs, one per rule of ``workflow/rules/prt.smk``: light probes, geometry
images, deformation sequences, ray-traced transfer, MoMoPRT and the ray-tracing benchmark.

They import neither torch nor the model code, and each imports the modules it drives when
it runs, so the many small jobs that build the data start in a fraction of a second; the
model and evaluation jobs are in :mod:`neurender.prt.jobs`. Signatures and files as there.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from tqdm import tqdm

from neurender import io
from neurender.prt import frames
from neurender.tables import tidy_rows

if TYPE_CHECKING:
    from neurender.prt import animations

log = logging.getLogger(__name__)

#: What :func:`prt_geometry_image` may change in a mesh to map it (counted in its table).
REPAIRS = ("welded_vertices", "dropped_faces", "reoriented_faces", "seam_edges", "split_edges")


def prt_probe(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """A light probe (built in, or the user's EXR ``source``, ``prt.user_probes.<probe>``)
    and its SH projection."""
    from neurender import lights, sh

    source = inputs.get("source")
    image = (
        lights.load_probe(source, f"prt.user_probes.{params['probe']}")
        if source
        else lights.procedural_probe(params["probe"], params["probe_height"])
    )
    lights.write_probe(outputs["exr"], image)
    io.write_csv(outputs["sh"], frames.sh_light_table(sh.project_latlong(image, params["n_bands"])))


def _user_sequence(inputs: dict, name: str) -> tuple[animations.Frames, animations.Frames | None]:
    """A user animation's frames and separate test frames, checked up front."""
    from neurender.prt import animations

    return animations.load_sequence(
        inputs["frames"], inputs.get("test_frames", []), f"prt.user_sequences.{name}"
    )


def prt_geometry_image(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The object's rest shape (built in, the user's mesh ``source``, or the first of the
    user's animation ``frames``) made a disk, parametrised on the square and resampled,
    with its blendshapes, on the ``resolution^2`` grid; the grid's lookup (``face``,
    ``bary`` in the source triangles) resamples every other frame the same way."""
    from neurender.prt import objects
    from neurender.prt.geometry_image import parametrise, reconstruction_error
    from neurender.shapes import BLENDSHAPES, SourceMesh

    start = time.perf_counter()
    name, n, seed = params["object"], params["resolution"], params["seed"]
    counts = {}
    if "frames" in inputs:
        sequence, test = _user_sequence(inputs, name)
        mesh, kind = SourceMesh(sequence.positions[0], sequence.faces), "user_sequence"
        label = str(sequence.files[0])
        counts = {"frames": len(sequence.files), "test_frames": len(test.files) if test else 0}
        objects.check_placement(mesh.vertices, f"{label} (prt.user_sequences.{name})")
    elif "source" in inputs:
        mesh, label, kind = objects.load_user_mesh(inputs["source"]), inputs["source"], "user"
        objects.check_placement(mesh.vertices, f"{label} (prt.user_meshes.{name})")
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
    from neurender.prt.geometry_image import resample
    from neurender.prt.sequences import build_sequences, user_sequences

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
    from neurender.prt import transfer

    name, split, directions = params["object"], params["split"], params["directions"]
    seq = io.load_npz(inputs["seq"])
    positions = seq[f"{split}_positions"]
    light = frames.read_sh_light(inputs["light"], params["n_bands"])
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


def prt_momoprt(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """MoMoPRT fitted on the train split, on blendshape weights where the object has them."""
    from neurender.prt.momoprt import fit_momoprt

    seq = io.load_npz(inputs["seq"])
    train_split, val_split = (
        frames.split_frames(inputs, seq, s, params["n_bands"]) for s in ("train", "val")
    )
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


def prt_benchmark(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    from neurender.prt.benchmark import run_benchmark

    light = frames.read_sh_light(inputs["light"])
    run_benchmark(inputs["seq"], light, params, threads, outputs["csv"])
