"""The files behind a user's mesh path, found without loading the mesh (read at DAG time):
the mesh files NDR's objects and the simplification's assets read, and the material files
and textures they name.

An OBJ names its material files (``mtllib``), and a material file names its textures
(``map_Kd`` for the base colour, ``norm`` for a tangent-space normal map); a ``.gltf``
(and, rarely, a ``.glb``) names external buffers and images by ``uri``. Every such file is
an input of the jobs that read the asset, so editing a texture reruns them, and a missing
one is refused by name before any job starts (:mod:`neurender.config`) and again when the
asset is loaded. Standard library only: the Snakefile imports this module.
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path
from urllib.parse import unquote

#: Mesh files trimesh loads with a material or vertex colours.
TRIMESH_SUFFIXES = (".obj", ".glb", ".gltf", ".ply", ".off", ".stl")
#: Mesh files PyVista loads (VTK legacy and XML poly data, with point colours).
VTK_SUFFIXES = (".vtk", ".vtp")
#: MTL statements whose files the stages read: the base colour and the normal map.
MTL_MAPS = ("map_kd", "norm")

_MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+(.+?)[ \t]*\r?$", re.MULTILINE)
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class AssetFileError(ValueError):
    """A user's asset that cannot be read; the message names the file and what was found."""


def _file_name(text: str) -> str:
    """The file name at the end of an MTL map statement, after any ``-option value...``
    (``map_Kd -s 1 1 1 wood.png``); Windows separators become ``/``."""
    tokens = text.split()
    k = 0
    while k < len(tokens) and tokens[k].startswith("-") and not _NUMBER.match(tokens[k]):
        k += 1
        while k < len(tokens) - 1 and (_NUMBER.match(tokens[k]) or tokens[k] in ("on", "off")):
            k += 1
    return " ".join(tokens[k:]).replace("\\", "/")


def mtl_maps(mtl: Path) -> dict[str, list[Path]]:
    """The maps an MTL file names, by statement (lower case: ``map_kd``, ``norm``), each
    resolved against the MTL's folder."""
    found: dict[str, list[Path]] = {}
    for line in mtl.read_text(errors="replace").splitlines():
        parts = line.strip().split(None, 1)
        if len(parts) == 2 and parts[0].lower() in MTL_MAPS:
            found.setdefault(parts[0].lower(), []).append(mtl.parent / _file_name(parts[1]))
    return found


def _obj_materials(obj: Path) -> list[Path]:
    """The MTL files an OBJ names (``mtllib a.mtl [b.mtl ...]``), resolved against its folder."""
    names = []
    for match in _MTLLIB.finditer(obj.read_bytes()):
        text = match.group(1).decode(errors="replace").replace("\\", "/")
        # A name may hold spaces; if the whole text is no file, read it as several names.
        whole = obj.parent / text
        names += [whole] if whole.is_file() else [obj.parent / n for n in text.split()]
    return names


def obj_maps(obj: str | Path, statement: str) -> list[Path]:
    """The files an OBJ's material files name in ``statement`` (``map_kd`` or ``norm``)."""
    return [
        m
        for mtl in _obj_materials(Path(obj))
        if mtl.is_file()
        for m in mtl_maps(mtl).get(statement, [])
    ]


def _gltf_json(path: Path) -> dict:
    """The JSON of a ``.gltf`` file or of a ``.glb``'s first chunk ({} when unreadable)."""
    try:
        if path.suffix.lower() == ".gltf":
            return json.loads(path.read_text())
        with path.open("rb") as f:
            magic, _, _ = struct.unpack("<4sII", f.read(12))
            length, kind = struct.unpack("<I4s", f.read(8))
            if magic != b"glTF" or kind != b"JSON":
                return {}
            return json.loads(f.read(length))
    except (OSError, ValueError, struct.error):
        return {}  # the loader reports an unreadable file with its own message


def references(path: str | Path) -> list[tuple[Path, Path]]:
    """``(referring file, referenced file)`` for every file the asset at ``path`` names:
    an OBJ's MTL files and their base-colour and normal maps, a glTF's external buffers
    and images (``data:`` URIs are embedded, not files). Missing files are listed too."""
    path = Path(path)
    found = []
    suffix = path.suffix.lower()
    if suffix == ".obj":
        for mtl in _obj_materials(path):
            found.append((path, mtl))
            if mtl.is_file():
                found += [(mtl, m) for maps in mtl_maps(mtl).values() for m in maps]
    elif suffix in (".gltf", ".glb"):
        tree = _gltf_json(path)
        for item in tree.get("buffers", []) + tree.get("images", []):
            uri = item.get("uri")
            if isinstance(uri, str) and not uri.startswith("data:"):
                found.append((path, path.parent / unquote(uri)))
    return found


def missing(path: str | Path) -> list[str]:
    """One sentence per file the mesh at ``path`` names that does not exist (empty if
    none), e.g. ``a.obj names a.mtl (/data/a.mtl), which does not exist``."""
    return [
        f"{source} names {target.name} ({target}), which does not exist"
        for source, target in references(path)
        if not target.is_file()
    ]


def asset_inputs(path: str) -> list[str]:
    """The files a job reading the asset depends on besides ``path`` itself."""
    return sorted({str(target) for _, target in references(path)})


def check(path: str | Path, suffixes: tuple[str, ...]) -> Path:
    """``path`` once it has one of ``suffixes``, exists, and every file it names exists.

    Raises:
        AssetFileError: naming the file: an unknown suffix, no such file, or the files it
            names that are missing.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in suffixes:
        raise AssetFileError(
            f"{path}: unknown mesh format {suffix or '(no suffix)'}; expected one of "
            f"{', '.join(suffixes)}"
        )
    if not path.is_file():
        raise AssetFileError(f"{path}: no such file")
    absent = missing(path)
    if absent:
        raise AssetFileError(f"{path}: " + "; ".join(absent))
    return path
