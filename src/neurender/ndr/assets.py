"""The files behind a user's mesh path: the mesh and the material and texture files it names.

Plain text parsing only (no mesh library), so the Snakefile can make every one of them an
input of the jobs that read the mesh, and the config check can name a missing texture
before any job runs. OBJ files name MTL files (``mtllib``), which name textures
(``map_Kd``, ``map_Ks``, ``bump`` ...); ``.gltf`` files name buffers and images (``uri``,
data URIs aside); every other format is one file.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

#: Mesh suffixes NDR reads: through trimesh, and the VTK formats through PyVista.
TRIMESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
VTK_SUFFIXES = (".vtk", ".vtp")
MESH_SUFFIXES = TRIMESH_SUFFIXES + VTK_SUFFIXES


def _last_token(rest: str) -> str:
    """The file name of an MTL map statement (options such as ``-s 1 1 1`` come first)."""
    try:
        tokens = shlex.split(rest)
    except ValueError:
        tokens = rest.split()
    return tokens[-1] if tokens else ""


def _statements(path: Path, keys: tuple[str, ...]) -> list[str]:
    """The arguments of the lines of a text file starting with one of ``keys``."""
    found = []
    for line in path.read_text(errors="replace").splitlines():
        parts = line.strip().split(maxsplit=1)
        if len(parts) == 2 and parts[0] in keys:
            found.append(parts[1])
    return found


def _obj_files(path: Path) -> list[Path]:
    files = []
    for names in _statements(path, ("mtllib",)):
        for name in names.split():
            mtl = path.parent / name
            files.append(mtl)
            if mtl.is_file():
                maps = _statements(mtl, ("map_Kd", "map_Ka", "map_Ks", "map_d", "map_Bump", "bump"))
                files += [mtl.parent / _last_token(m) for m in maps if _last_token(m)]
    return files


def _gltf_files(path: Path) -> list[Path]:
    try:
        doc = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:
        raise ValueError(f"mesh {path}: not a readable glTF JSON file ({err})") from err
    uris = [item.get("uri", "") for key in ("buffers", "images") for item in doc.get(key, [])]
    return [path.parent / u for u in uris if u and not u.startswith("data:")]


def mesh_files(path: str | Path) -> list[str]:
    """``path`` and the files it names, each once, in order; named files need not exist
    (:func:`missing_files` says which do not)."""
    p = Path(path)
    files = [p]
    if p.is_file() and p.suffix.lower() == ".obj":
        files += _obj_files(p)
    elif p.is_file() and p.suffix.lower() == ".gltf":
        files += _gltf_files(p)
    return list(dict.fromkeys(str(f) for f in files))


def missing_files(path: str | Path) -> list[str]:
    """The files of :func:`mesh_files` that do not exist."""
    return [f for f in mesh_files(path) if not Path(f).is_file()]
