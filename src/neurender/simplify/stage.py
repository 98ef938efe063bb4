"""The simplification stage's jobs: prepare a use case (reference renders, QEM mesh,
classic bakes), optimise it, and evaluate every variant on held-out views.

Use cases (issue / paper 4.1, 4.5): ``head`` (normal-map baking and joint simplification
of the detailed DeepPRT head, grey Lambertian) and ``metaballs`` (a ray-marched implicit
surface converted to a textured mesh: albedo and normal maps). Variants compared at the
same triangle count and texture size: ``qem`` (decimated mesh with the reference's material,
baked classically for the metaballs' colours), ``baked`` (plus a classically baked normal
map) and ``ours`` (vertices and textures optimised through Mitsuba).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import trimesh
from PIL import Image

from neurender import io
from neurender.metaballs.raymarch import field, surface_attributes
from neurender.simplify import assets, bake, cameras, implicit, mesh_ops, render
from neurender.simplify.optimise import OptimiseConfig, optimise

CASES = assets.ASSETS
HEAD_ALBEDO = 0.8
CHANNELS = ("R", "G", "B", "A")


def case_views(cfg: dict, case: str, split: str) -> list[cameras.View]:
    """Training or test views of a use case: the head is an open relief seen from the
    front half-space; the metaballs from all around."""
    count = cfg["train_views"] if split == "train" else cfg["test_views"]
    ranges = ((-80.0, 80.0), (-35.0, 45.0)) if case == "head" else ((-180.0, 180.0), (-60.0, 70.0))
    return cameras.sample_views(
        count,
        cfg["seed"],
        f"{case}-{split}",
        cfg["camera_distance"],
        cfg["fov"],
        *ranges,
        cfg["light_distance"],
        cfg["light_cone"],
    )


def write_images(path: str | Path, images: np.ndarray) -> None:
    """``(N, H, W, 4)`` RGBA stack -> one EXR with channels ``v000.R`` ... ``vNNN.A``."""
    io.write_exr(
        path,
        {
            f"v{i:03d}.{c}": img[..., k]
            for i, img in enumerate(images)
            for k, c in enumerate(CHANNELS)
        },
    )


def read_images(path: str | Path) -> np.ndarray:
    """Inverse of :func:`write_images`: ``(N, H, W, 4)`` float32."""
    data = io.read_exr(path)
    n = len(data) // 4
    return np.stack([np.stack([data[f"v{i:03d}.{c}"] for c in CHANNELS], -1) for i in range(n)])


def save_lowpoly(path: str | Path, low: mesh_ops.LowPolyMesh) -> None:
    io.save_npz(
        path,
        positions=low.positions,
        faces=low.faces,
        vmap=low.vmap,
        uvs=low.uvs,
        uv_faces=low.uv_faces,
    )


def load_lowpoly(path: str | Path) -> mesh_ops.LowPolyMesh:
    d = io.load_npz(path)
    return mesh_ops.LowPolyMesh(d["positions"], d["faces"], d["vmap"], d["uvs"], d["uv_faces"])


def to_png16(texture: np.ndarray) -> np.ndarray:
    return np.round(np.clip(texture, 0, 1) * 65535).astype(np.uint16)


def read_texture(path: str | Path) -> np.ndarray:
    """A texture written by :func:`to_png16` as ``(T, T, 3)`` float64 in [0, 1]."""
    return io.read_png(path)[..., :3].astype(np.float64) / 65535.0


def prepare_case(case: str, cfg: dict, mi, out: dict[str, str]) -> None:
    """Reference images (train/test EXR + view CSVs), the QEM atlas mesh and classic bakes."""
    started = time.perf_counter()
    width, intensity = cfg["resolution"], cfg["intensity"]
    views = {s: case_views(cfg, case, s) for s in ("train", "test")}
    spp = {"train": cfg["reference_spp"], "test": cfg["test_spp"]}
    colour_fn = None
    if case == "head":
        detail = assets.detailed_head(cfg["head_vertices"], cfg["seed"])
        dv, df = detail.vertices, detail.faces
        shape = render.mesh_shape(mi, dv, df, render.material(mi, HEAD_ALBEDO))
        images = {
            s: render.render_views(
                mi,
                shape,
                views[s],
                width,
                spp[s],
                intensity,
                cfg["seed"] + 7919 * (s == "test"),
                f"{case} {s}",
            )
            for s in views
        }
        target = cfg["head_triangles"]
        normal_fn = None
    else:
        balls = assets.metaball_creature(cfg["metaball_count"], cfg["seed"])
        # Held-out references get 4x the sub-pixel rays: their coverage is then close to
        # continuous, like Mitsuba's, and the silhouette metric is not quantised.
        ss = {"train": cfg["supersample"], "test": 2 * cfg["supersample"]}
        images = {
            s: np.stack(
                [implicit.render_implicit(balls, v, width, ss[s], intensity) for v in views[s]]
            )
            for s in views
        }
        margin = float(balls.radii.max()) * 2.5
        lo = balls.centres.min(0).values.numpy() - margin
        hi = balls.centres.max(0).values.numpy() + margin
        dv, df = mesh_ops.implicit_mesh(
            lambda p: field(torch.from_numpy(p), balls)[0].numpy(),
            (lo, hi),
            cfg["metaball_grid"],
            1.0,
        )
        target = cfg["metaball_triangles"]

        def colour_fn(points, face, bary):
            return surface_attributes(torch.from_numpy(points), balls)[0].numpy()

        def normal_fn(points, face, bary):
            return surface_attributes(torch.from_numpy(points), balls)[1].numpy()

    for s in views:
        write_images(out[f"{s}_images"], images[s])
        io.write_csv(out[f"{s}_views"], cameras.views_frame(views[s]))
    v, f = mesh_ops.decimate(dv, df, target)
    low = mesh_ops.uv_atlas(v, f, cfg["texture_size"])
    save_lowpoly(out["lowpoly"], low)
    normal_map, colour_map = bake.bake(low, dv, df, cfg["texture_size"], colour_fn, normal_fn)
    io.write_png(out["baked_normal"], to_png16(normal_map))
    albedo = np.full_like(normal_map, HEAD_ALBEDO) if colour_map is None else colour_map
    io.write_png(out["baked_albedo"], to_png16(albedo))
    stats = pd.DataFrame(
        [
            {"case": case, "quantity": "reference_triangles", "value": len(df)},
            {"case": case, "quantity": "lowpoly_triangles", "value": len(f)},
            {"case": case, "quantity": "triangle_fraction", "value": len(f) / len(df)},
            {"case": case, "quantity": "texture_size", "value": cfg["texture_size"]},
            {"case": case, "quantity": "prepare_seconds", "value": time.perf_counter() - started},
        ]
    )
    io.write_csv(out["stats"], stats)


def optimise_case(case: str, cfg: dict, mi, dr, inputs: dict, out: dict) -> None:
    """Optimise the QEM mesh's vertices and normal map (and, for the metaballs, albedo)."""
    low = load_lowpoly(inputs["lowpoly"])
    views = cameras.views_from_frame(io.read_csv(inputs["train_views"]))
    references = read_images(inputs["train_images"])
    size = cfg["texture_size"]
    flat = np.broadcast_to([0.5, 0.5, 1.0], (size, size, 3)).copy()
    albedo = HEAD_ALBEDO if case == "head" else np.full((size, size, 3), 0.5)
    settings = OptimiseConfig(
        steps=cfg["steps"],
        batch=cfg["batch"],
        spp=cfg["spp"],
        width=cfg["resolution"],
        lr_positions=cfg["lr_positions"],
        lr_textures=cfg["lr_textures"],
        lr_final_fraction=cfg["lr_final_fraction"],
        intensity=cfg["intensity"],
        seed=cfg["seed"],
        optimise_albedo=case != "head",
        laplacian_scale=cfg["laplacian_scale"],
        laplacian_min_fraction=cfg["laplacian_min_fraction"],
    )
    positions, normal_map, albedo_map, loss = optimise(
        mi, dr, low, flat, albedo, references, views, settings
    )
    if albedo_map is None:
        albedo_map = np.full_like(normal_map, HEAD_ALBEDO)
    io.save_npz(out["mesh"], positions=positions)
    io.write_png(out["normal"], to_png16(normal_map))
    io.write_png(out["albedo"], to_png16(albedo_map))
    loss.insert(0, "case", case)
    io.write_csv(out["loss"], loss)
    # A portable copy: OBJ + MTL + albedo PNG (the normal map PNG sits beside it).
    textured = trimesh.Trimesh(
        positions[low.vmap],
        low.uv_faces,
        process=False,
        visual=trimesh.visual.TextureVisuals(
            uv=low.uvs, image=Image.fromarray(io.to_uint8(albedo_map))
        ),
    )
    with io.atomic_path(out["obj"]) as tmp:
        textured.export(tmp, include_texture=True, mtl_name=f"{case}.mtl")
