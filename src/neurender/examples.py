"""Small example assets of the kinds users bring, written by third-party tools (PyVista,
trimesh, OpenEXR), for ``config/examples/own_assets.yaml``, the smoke config and the tests.

Everything lands in one folder (``results/examples`` in the workflow); deterministic from
the seed. World units, y up.

* ``wave/frame_NNN.obj``: an animated open surface (a PyVista plane, disk topology) with
  a travelling wave, as DCC tools export mesh sequences (VTK's OBJ writer);
* ``blob/frame_NNN.obj``: a closed genus-0 surface (PyVista ellipsoid) breathing;
* ``torus/frame_NNN.ply``: a closed genus-1 surface (PyVista torus) twisting;
* ``rock.glb``: a detailed displaced sphere (about 80k triangles) with a base-colour
  texture and glTF PBR factors, written by trimesh;
* ``crate.obj`` (+ ``crate.mtl``, ``crate.png``): a subdivided, textured box as OBJ with MTL;
* ``vase.ply``: a surface of revolution with vertex colours;
* ``maps/*.exr``: lat-long HDR maps as downloaded: a small sun of realistic radiance, sky
  and ground, resampled with a cubic filter (so they carry the small negative pixels of
  real maps next to the sun);
* ``balls.csv``: metaball scenes, one row per ball (``scene, x, y, z, radius, r, g, b``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pyvista as pv
import scipy.ndimage
import trimesh
from PIL import Image

from neurender import io, sh
from neurender.rng import stable_seed

SEQUENCE_FRAMES = 24


def _save_vtk(mesh: pv.PolyData, path: Path) -> None:
    """Save through VTK's own writers (the format from the suffix), atomically."""
    with io.atomic_path(path) as tmp:
        mesh.save(str(tmp))


def _sequence(base: pv.PolyData, folder: Path, suffix: str, move) -> None:
    """Write ``SEQUENCE_FRAMES`` frames of ``base`` with points ``move(points, t)``."""
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(SEQUENCE_FRAMES):
        frame = base.copy()
        frame.points = move(np.asarray(base.points, np.float64), f / SEQUENCE_FRAMES)
        _save_vtk(frame, folder / f"frame_{f:03d}{suffix}")


def wave_sequence(folder: Path) -> None:
    """An open 2 x 2 sheet (disk topology) with a travelling, decaying wave."""
    plane = pv.Plane(i_size=2.0, j_size=2.0, i_resolution=40, j_resolution=40).triangulate()

    def move(p, t):
        r = np.hypot(p[:, 0] + 0.3, p[:, 1])
        p[:, 2] = 0.18 * np.sin(5.0 * r - 2 * math.pi * t) * np.exp(-0.8 * r)
        return p

    _sequence(plane, folder, ".obj", move)


def blob_sequence(folder: Path) -> None:
    """A closed ellipsoid (genus 0) breathing with three lobes."""
    blob = pv.ParametricEllipsoid(1.0, 0.8, 0.7, u_res=36, v_res=36).triangulate().clean()

    def move(p, t):
        angle = np.arctan2(p[:, 1], p[:, 0])
        bulge = 1 + 0.15 * np.sin(3 * angle + 2 * math.pi * t) * np.cos(math.pi * p[:, 2])
        return p * bulge[:, None]

    _sequence(blob, folder, ".obj", move)


def torus_sequence(folder: Path) -> None:
    """A closed torus (genus 1) twisting about its axis."""
    torus = pv.ParametricTorus(1.0, 0.35, u_res=48, v_res=20).triangulate().clean()

    def move(p, t):
        twist = 0.6 * math.sin(2 * math.pi * t) * p[:, 0]
        c, s = np.cos(twist), np.sin(twist)
        return np.column_stack([p[:, 0], c * p[:, 1] - s * p[:, 2], s * p[:, 1] + c * p[:, 2]])

    _sequence(torus, folder, ".ply", move)


def _texture(size: int, rng: np.random.Generator) -> np.ndarray:
    """An 8-bit RGB texture ``(size, size, 3)``: blotches of two colours and fine grain."""
    noise = scipy.ndimage.gaussian_filter(rng.normal(size=(size, size)), size / 24, mode="wrap")
    noise = (noise - noise.min()) / np.ptp(noise)
    grain = rng.uniform(0.85, 1.0, (size, size))
    a, b = np.array([0.55, 0.42, 0.3]), np.array([0.25, 0.3, 0.22])
    rgb = (a * noise[..., None] + b * (1 - noise[..., None])) * grain[..., None]
    return io.to_uint8(rgb)


def rock(path: Path, rng: np.random.Generator) -> None:
    """A detailed textured rock: an icosphere displaced by multi-scale noise, spherical UVs,
    a base-colour texture and PBR factors, as GLB."""
    sphere = trimesh.creation.icosphere(subdivisions=6)
    v = np.asarray(sphere.vertices)
    bumps = sum(
        a * np.sin(v @ rng.normal(size=3) * f + rng.uniform(0, 2 * math.pi))
        for a, f in ((0.08, 3.0), (0.03, 9.0), (0.012, 27.0), (0.006, 61.0))
    )
    vertices = v * (1.0 + bumps)[:, None]
    uv = np.column_stack(
        [
            0.5 + np.arctan2(v[:, 0], v[:, 2]) / (2 * math.pi),
            np.arccos(np.clip(v[:, 1], -1, 1)) / math.pi,
        ]
    )
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(_texture(256, rng)),
        metallicFactor=0.0,
        roughnessFactor=0.7,
    )
    mesh = trimesh.Trimesh(vertices, sphere.faces, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    with io.atomic_path(path) as tmp:
        mesh.export(tmp)


def crate(folder: Path, rng: np.random.Generator) -> None:
    """A subdivided box with a texture, as ``crate.obj`` + ``crate.mtl`` + ``crate.png`` in
    ``folder`` (trimesh's exporter)."""
    box = trimesh.creation.box(extents=(1.6, 1.2, 1.2))
    for _ in range(3):
        box = box.subdivide()
    uv = np.column_stack([box.vertices[:, 0] / 1.6 + 0.5, box.vertices[:, 1] / 1.2 + 0.5])
    material = trimesh.visual.material.SimpleMaterial(
        image=Image.fromarray(_texture(128, rng)), name="crate"
    )
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    text, files = trimesh.exchange.obj.export_obj(
        box, include_texture=True, mtl_name="crate.mtl", return_texture=True
    )
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in [("crate.obj", text.encode()), *files.items()]:
        with io.atomic_path(folder / name) as tmp:
            tmp.write_bytes(data)


def vase(path: Path) -> None:
    """A surface of revolution (a closed vase) with vertex colours, as PLY."""
    profile = pv.Spline(
        np.column_stack(
            [[0.05, 0.5, 0.35, 0.45, 0.2, 0.05], [0] * 6, [-1, -0.8, -0.1, 0.4, 0.9, 1]]
        ),
        60,
    )
    vase = profile.extrude_rotate(resolution=64, capping=True).triangulate().clean()
    height = (vase.points[:, 2] + 1) / 2
    colours = np.column_stack([0.2 + 0.6 * height, 0.35 + 0.2 * height, 0.6 - 0.4 * height])
    vase.point_data["RGB"] = io.to_uint8(colours)
    with io.atomic_path(path) as tmp:
        vase.save(str(tmp), texture="RGB")


def downloaded_map(
    height: int, sun: np.ndarray, power: float, rng: np.random.Generator
) -> np.ndarray:
    """A lat-long map ``(height, 2 height, 3)``: sky, ground and a half-degree sun of
    ``power`` times the sky's radiance, rendered at 4x the resolution and resampled with a
    cubic filter, as map sites do (which leaves small negative pixels near the sun)."""
    fine = 4 * height
    dirs, _ = sh.latlong_directions(fine, 2 * fine)
    up = dirs[..., 1:2]
    sky = np.where(up > 0, 0.6 * (1 - up) + np.array([0.25, 0.45, 0.9]) * up, 0.0)
    ground = np.where(up <= 0, np.array([0.12, 0.1, 0.08]), 0.0)
    sun_dir = sun / np.linalg.norm(sun)
    disk = (dirs @ sun_dir > math.cos(math.radians(0.5 * 4))).astype(np.float64)[..., None]
    image = sky + ground + disk * power * np.array([1.0, 0.95, 0.85])
    image *= rng.uniform(0.8, 1.2)
    return np.stack(
        [scipy.ndimage.zoom(image[..., c], 0.25, order=3, mode="grid-wrap") for c in range(3)], -1
    ).astype(np.float32)


def balls(path: Path, rng: np.random.Generator, scenes: int = 3) -> None:
    """Metaball scenes in the thesis's view space (camera at the origin looking along +z)."""
    rows = []
    for scene in range(scenes):
        count = int(rng.integers(4, 10))
        centre = np.array([0.0, 0.0, 15.0])
        for _ in range(count):
            x, y, z = centre + rng.normal(scale=[1.5, 1.5, 1.5])
            r, g, b = rng.uniform(0.1, 0.9, 3)
            rows.append(
                {
                    "scene": scene,
                    "x": x,
                    "y": y,
                    "z": z,
                    "radius": rng.uniform(0.6, 1.3),
                    "r": r,
                    "g": g,
                    "b": b,
                }
            )
    io.write_csv(path, pd.DataFrame(rows))


def write_examples(folder: str | Path, seed: int = 0) -> None:
    """Every example asset into ``folder`` (see the module docstring)."""
    out = Path(folder)
    rng = np.random.default_rng(stable_seed(seed, "examples"))
    wave_sequence(out / "wave")
    blob_sequence(out / "blob")
    torus_sequence(out / "torus")
    rock(out / "rock.glb", rng)
    crate(out, rng)
    vase(out / "vase.ply")
    for k, (sun, power) in enumerate((([0.4, 0.5, 0.3], 4.0e4), ([-0.6, 0.15, 0.2], 1.5e4))):
        image = downloaded_map(64, np.array(sun), power, rng)
        io.write_exr(
            out / "maps" / f"outdoor_{k}.exr", {c: image[..., i] for i, c in enumerate("RGB")}
        )
    balls(out / "balls.csv", rng)


def example_assets(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """The ``example_assets`` job: every example into the folder of ``outputs["balls"]``."""
    write_examples(Path(outputs["balls"]).parent, params["seed"])
