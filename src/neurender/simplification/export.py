"""The simplified asset as files other tools read, and read back: glTF 2.0 binary (GLB)
and OBJ + MTL + PNG textures, in the asset file's own units (the stage's normalisation
undone, :attr:`neurender.simplification.assets.Asset.to_asset`).

GLB (written here, one mesh of one primitive): ``POSITION``, ``NORMAL`` (the welded
mesh's area-weighted vertex normals, as the stage renders it), ``TANGENT``,
``TEXCOORD_0``, 16-bit indices (32-bit from 65536 vertices on); one material
(:mod:`neurender.gltf`): ``baseColorTexture`` (8-bit PNG,
sRGB-encoded as glTF requires), ``normalTexture`` (8-bit PNG, linear ``(n + 1) / 2``),
``metallicFactor`` 0, ``roughnessFactor`` 1 and ``KHR_materials_specular`` with
``specularFactor`` 0, which makes glTF's BRDF the stage's Lambertian (a viewer without the
extension shows a rough dielectric with a faint sheen); one sampler, linear, clamped.

Tangent frames. Mitsuba's normal map (:mod:`neurender.simplification.render`) is expressed in
``(s, t, n)`` with ``s`` the per-triangle ``dp/du`` made orthogonal to the interpolated
normal ``n`` and ``t = n x s``. glTF's frame is per vertex: ``TANGENT = (T, w)``, the
bitangent ``B = cross(N, T) w``, and a viewer interpolates ``T``, ``B`` and ``N`` over the
triangle and shades with ``normalize(T x + B y + N z)`` (glTF Sample Viewer, three.js). The
exported tangents are MikkTSpace-style: ``T`` the corner-angle weighted mean of the
adjacent triangles' ``dp/du`` in the vertex's tangent plane, ``w = +1`` where the bitangent
points up the image (``-dp/dv``, glTF's "+Y is up") and ``-1`` on mirrored charts. The
normal map is re-expressed texel by texel from Mitsuba's frame into that interpolated glTF
frame (:func:`to_gltf_normals`), so a viewer that uses the file's ``TANGENT`` (as glTF
requires when it is present) shades with the optimised normals at every texel centre;
tools that recompute MikkTSpace tangents themselves (Blender's importer) agree up to the
small difference between this averaging and MikkTSpace's. Texels outside every chart take
the frame of the nearest covered texel, so the conversion is exactly invertible
(:func:`to_mitsuba_normals`) and a re-import reproduces the map up to 8-bit quantisation.

Placement. Both files hold the asset where the asset file had it. The GLB's node
``translation`` (float64 in the JSON) carries a round point near the asset's centre and
``POSITION`` the float32 offsets from it (:mod:`neurender.gltf`), and the OBJ's ``v`` have
as many significant digits as the distance from the origin needs (:func:`position_digits`),
so an asset in georeferenced coordinates (x ~ 5e5 m, y ~ 5e6 m) reads back to about 1e-7
of its size, like one about the origin.

OBJ + MTL: the same vertices, ``vt = (u, 1 - v)`` (OBJ counts ``v`` up), ``vn``;
``map_Kd`` the same sRGB base-colour PNG, ``norm`` the same normal map (OBJ has no
tangents: a reader computes its own, MikkTSpace in most tools).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from neurender import asset_files, gltf, io
from neurender.asset_files import AssetFileError
from neurender.display import srgb
from neurender.geometry import vertex_normals
from neurender.simplification import user_mesh
from neurender.simplification.bake import dilate, rasterise_uvs, tangent_frames
from neurender.simplification.mesh_ops import LowPolyMesh

GENERATOR = "neurender appearance-driven simplification"


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-20)


def _perpendicular(n: np.ndarray) -> np.ndarray:
    """Some unit vector orthogonal to each unit ``n (K, 3)``."""
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    return _unit(np.cross(n, helper))


def vertex_tangents(
    positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, faces: np.ndarray
) -> np.ndarray:
    """glTF ``TANGENT`` ``(A, 4)`` of a mesh with per-vertex ``positions``, unit
    ``normals (A, 3)`` and ``uvs (A, 2)`` (``v`` down the image), see the module docstring.
    ``xyz`` is a unit vector orthogonal to the normal and ``w`` is +1 or -1."""
    p, uv = positions[faces], uvs[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    mapped = np.abs(det) > 1e-20  # triangles without UV area give no direction
    det = np.where(mapped, det, 1.0)[:, None]
    dp_du = (d2[:, 1:] * e1 - d1[:, 1:] * e2) / det
    dp_dv = (d1[:, :1] * e2 - d2[:, :1] * e1) / det
    tangent = np.zeros_like(positions)
    up = np.zeros_like(positions)
    for k in range(3):  # corner k: weight by its angle, as MikkTSpace does
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        cos = (_unit(a) * _unit(b)).sum(1).clip(-1, 1)
        angle = (np.arccos(cos) * mapped)[:, None]
        n = normals[faces[:, k]]
        t = _unit(dp_du - n * (n * dp_du).sum(1, keepdims=True))
        for c in range(3):
            tangent[:, c] += np.bincount(faces[:, k], (angle * t)[:, c], len(positions))
            up[:, c] += np.bincount(faces[:, k], (-angle * dp_dv)[:, c], len(positions))
    tangent -= normals * (normals * tangent).sum(1, keepdims=True)
    short = np.linalg.norm(tangent, axis=1) < 1e-12
    tangent[short] = _perpendicular(normals[short])
    tangent = _unit(tangent)
    w = np.where((np.cross(normals, tangent) * up).sum(1) >= 0, 1.0, -1.0)
    return np.column_stack([tangent, w])


def frame_change(
    positions: np.ndarray,
    normals: np.ndarray,
    tangents: np.ndarray,
    uvs: np.ndarray,
    faces: np.ndarray,
    size: int,
) -> np.ndarray:
    """Per texel of a ``size^2`` map, the ``(size, size, 3, 3)`` matrix taking a normal in
    Mitsuba's frame to glTF's (up to length), for an atlas mesh with per-vertex
    ``positions``, unit ``normals``, ``tangents (A, 4)`` and ``uvs``; uncovered texels
    take the nearest covered texel's matrix."""
    samples = rasterise_uvs(uvs, faces, size)
    _, s, t, n = tangent_frames(positions, normals, uvs, faces, samples)
    mitsuba = np.stack([s, t, n], -1)  # columns: Mitsuba's frame in world space
    corners, bary = faces[samples.face], samples.bary
    bitangents = np.cross(normals, tangents[:, :3]) * tangents[:, 3:]

    def interpolate(x):
        return _unit(np.einsum("kj,kjc->kc", bary, x[corners]))

    gltf_frame = np.stack(
        [interpolate(tangents[:, :3]), interpolate(bitangents), interpolate(normals)], -1
    )  # columns: glTF's frame (T, B, N) in world space
    change = np.zeros((size, size, 3, 3))
    change[samples.rows, samples.cols] = np.linalg.solve(gltf_frame, mitsuba)
    covered = np.zeros((size, size), dtype=bool)
    covered[samples.rows, samples.cols] = True
    return dilate(change, covered)


def _apply(change: np.ndarray, normal_map: np.ndarray) -> np.ndarray:
    """Normal map ``(T, T, 3)`` in [0, 1] through per-texel matrices, re-normalised."""
    m = normal_map * 2.0 - 1.0
    out = _unit(np.einsum("rcij,rcj->rci", change, m))
    return (out + 1.0) / 2.0


def to_gltf_normals(change: np.ndarray, normal_map: np.ndarray) -> np.ndarray:
    """A normal map in Mitsuba's frame re-expressed in glTF's (see :func:`frame_change`)."""
    return _apply(change, normal_map)


def to_mitsuba_normals(change: np.ndarray, normal_map: np.ndarray) -> np.ndarray:
    """The inverse of :func:`to_gltf_normals` (a unit-length Mitsuba normal map)."""
    return _apply(np.linalg.inv(change), normal_map)


def atlas_primitive(
    low: LowPolyMesh,
    positions: np.ndarray,
    albedo: np.ndarray | float,
    normal_map: np.ndarray | None,
    to_asset: np.ndarray,
) -> gltf.Primitive:
    """The glTF primitive of the atlas mesh at welded ``positions (V, 3)`` (stage frame),
    moved by ``to_asset (4, 4)`` (float64, in the asset's units and place; the GLB writer
    stores them relative to its node's translation): welded-mesh normals, and with a
    ``(T, T, 3)`` linear ``albedo`` map (sRGB base-colour texture; a number is a uniform
    ``baseColorFactor``) and a ``normal_map`` in Mitsuba's tangent frame (re-expressed in
    glTF's, with the tangents; None: no normal texture); maps in [0, 1], row 0 at ``v = 0``."""
    atlas = low.atlas_positions(positions)
    normals = low.atlas_normals(positions)
    world = atlas @ to_asset[:3, :3].T + to_asset[:3, 3]
    primitive = gltf.Primitive(world, low.uv_faces, normals, uvs=low.uvs)
    if np.ndim(albedo) == 0:
        primitive.base_colour = (float(albedo),) * 3
    else:
        primitive.base_colour_png = gltf.png_bytes(srgb(albedo))
    if normal_map is not None:
        primitive.tangents = vertex_tangents(atlas, normals, low.uvs, low.uv_faces)
        change = frame_change(
            atlas, normals, primitive.tangents, low.uvs, low.uv_faces, len(normal_map)
        )
        primitive.normal_png = gltf.png_bytes(to_gltf_normals(change, normal_map))
    return primitive


def position_digits(positions: np.ndarray) -> int:
    """Significant digits that write every coordinate of ``positions (N, 3)`` to 1e-9 of
    their bounding box's longest side: 9 (float32's round trip, enough about the origin)
    plus the decimal orders by which the farthest coordinate exceeds that side, at most 17
    (float64's round trip)."""
    side = float(np.ptp(positions, axis=0).max())
    far = float(np.abs(positions).max())
    if not side > 0:
        return 17
    return int(min(17, 9 + max(0, np.ceil(np.log10(far / side)))))


def obj_text(
    positions: np.ndarray,
    normals: np.ndarray,
    uvs: np.ndarray,
    faces: np.ndarray,
    mtl: str,
    name: str,
) -> str:
    """OBJ text of a textured mesh (one index per corner for ``v``, ``vt`` and ``vn``),
    positions with :func:`position_digits` significant digits."""
    lines = [
        "# neurender appearance-driven simplification",
        f"mtllib {mtl}",
        f"o {name}",
    ]
    d = position_digits(positions)
    lines += [f"v {x:.{d}g} {y:.{d}g} {z:.{d}g}" for x, y, z in positions]
    lines += [f"vt {u:.9g} {1.0 - v:.9g}" for u, v in uvs]
    lines += [f"vn {x:.9g} {y:.9g} {z:.9g}" for x, y, z in normals]
    lines.append(f"usemtl {name}")
    lines += [f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}" for a, b, c in faces + 1]
    return "\n".join(lines) + "\n"


def mtl_text(name: str, base_colour: str, normal: str) -> str:
    """MTL text of the Lambertian material: white ``Kd`` times the ``map_Kd`` texture, and
    the tangent-space normal map as ``norm`` (glTF's convention, see the module docstring)."""
    return "\n".join(
        [
            "# neurender appearance-driven simplification: Lambertian albedo (sRGB PNG) and",
            "# a tangent-space normal map (+X along +u, +Y up the image, MikkTSpace-style",
            "# tangents; the GLB beside this file carries the exact tangents).",
            f"newmtl {name}",
            "Ka 0 0 0",
            "Kd 1 1 1",
            "Ks 0 0 0",
            "illum 1",
            f"map_Kd {base_colour}",
            f"norm {normal}",
            "",
        ]
    )


def export(
    paths: dict[str, str | Path],
    low: LowPolyMesh,
    positions: np.ndarray,
    albedo: np.ndarray,
    normal_map: np.ndarray,
    to_asset: np.ndarray,
) -> None:
    """Write the optimised asset: ``paths["glb"]``, and ``paths["obj"]`` with
    ``paths["mtl"]``, ``paths["texture"]`` (base colour) and ``paths["normal_texture"]``,
    the last four in one folder; each file atomically.

    Args:
        low, positions: the atlas mesh at welded ``positions (V, 3)`` (stage frame).
        albedo: linear ``(T, T, 3)`` albedo map; normal_map: ``(T, T, 3)`` in Mitsuba's
            tangent frame; both in [0, 1], row 0 at ``v = 0``.
        to_asset: ``(4, 4)`` uniform scale and translation from the stage's frame to the
            asset file's.
    """
    obj_paths = [Path(paths[k]) for k in ("obj", "mtl", "texture", "normal_texture")]
    if len({p.parent for p in obj_paths}) != 1:
        raise ValueError(f"OBJ, MTL and textures must share a folder; got {paths}")
    primitive = atlas_primitive(low, positions, albedo, normal_map, to_asset)
    name = Path(paths["glb"]).stem
    glb = gltf.glb([primitive], name, GENERATOR)
    obj, mtl, texture, normal_texture = obj_paths
    files = {
        Path(paths["glb"]): glb,
        obj: obj_text(
            primitive.positions, primitive.normals, low.uvs, low.uv_faces, mtl.name, name
        ).encode(),
        mtl: mtl_text(name, texture.name, normal_texture.name).encode(),
        texture: primitive.base_colour_png,
        normal_texture: primitive.normal_png,
    }
    for path, data in files.items():
        with io.atomic_path(path) as tmp:
            tmp.write_bytes(data)


def reimport(path: str | Path, to_asset: np.ndarray) -> tuple[LowPolyMesh, np.ndarray, np.ndarray]:
    """Read an exported GLB or OBJ back (trimesh, through :func:`user_mesh.load`) into the
    stage's frame, as a renderer that follows glTF's conventions sees it.

    Returns:
        the atlas mesh (its own welded positions and faces), the linear albedo map and the
        normal map in Mitsuba's tangent frame (both ``(T, T, 3)``, row 0 at ``v = 0``).
    """
    mesh = user_mesh.load(path)
    if len(mesh.parts) != 1 or mesh.parts[0].kind != "texture":
        raise AssetFileError(
            f"{path}: expected one textured mesh, found {len(mesh.parts)} part(s) of kinds "
            f"{[p.kind for p in mesh.parts]}"
        )
    part = mesh.parts[0]
    normal_values = part.normal_texture
    if normal_values is None and Path(path).suffix.lower() == ".obj":
        maps = asset_files.obj_maps(path, "norm")
        if maps:
            normal_values = user_mesh.image_values(Image.open(maps[0]))
    if normal_values is None:
        raise AssetFileError(f"{path}: no normal map (normalTexture or MTL norm)")
    inverse = np.linalg.inv(to_asset)
    positions = part.vertices @ inverse[:3, :3].T + inverse[:3, 3]
    welded = mesh.vertices @ inverse[:3, :3].T + inverse[:3, 3]
    low = LowPolyMesh(welded, mesh.faces, mesh.weld, part.uvs, part.faces)
    normals = vertex_normals(welded, mesh.faces)[mesh.weld]
    tangents = vertex_tangents(positions, normals, part.uvs, part.faces)
    change = frame_change(positions, normals, tangents, part.uvs, part.faces, len(normal_values))
    albedo = part.texture * part.albedo
    return low, albedo, to_mitsuba_normals(change, normal_values)
