"""The files behind a user's mesh path, found without loading the mesh (read at DAG time):
the mesh files every method reads (:mod:`neurender.mesh_file` loads them), and the
material files and textures they name.

An OBJ names its material files (``mtllib``), and a material file names its textures
(``map_Kd`` for the base colour, ``norm`` for a tangent-space normal map); a ``.gltf``
(and, rarely, a ``.glb``) names external buffers and images by ``uri``; a PLY may name a
texture in its header (``comment TextureFile``). Every such file is an input of the jobs
that read the asset, so editing a texture reruns them, and a missing one is refused by
name before any job starts (:mod:`neurender.config`) and again when the asset is loaded.

One rule finds a named file, here and in the loader (:func:`named_file`): relative to the
folder of the file that names it (as that file was found, not where a symbolic link to it
points), opened as the operating system opens it (symbolic links followed, ``..`` allowed).
Standard library and :mod:`neurender.unique_keys` only: the Snakefile imports this module.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path
from urllib.parse import unquote

from neurender.unique_keys import DuplicateKeyError, load_json
from neurender.user_paths import UserPath, file_problem, files_of

#: Mesh files trimesh loads with a material or vertex colours.
TRIMESH_SUFFIXES = (".obj", ".glb", ".gltf", ".ply", ".off", ".stl")
#: Mesh files PyVista loads (VTK legacy, XML poly data with point colours, and XML
#: unstructured grids, of which the surface is read).
VTK_SUFFIXES = (".vtk", ".vtp", ".vtu")
#: MTL statements whose files the stages read: the base colour and the normal map.
MTL_MAPS = ("map_kd", "norm")

_MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+(.+?)[ \t]*\r?$", re.MULTILINE)
_TEXTURE_FILE = re.compile(rb"^comment[ \t]+TextureFile[ \t]+(.+?)[ \t]*\r?$", re.M | re.I)
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class AssetFileError(ValueError):
    """A user's asset that cannot be read; the message names the file and what was found."""


def named_file(referrer: str | Path, name: str) -> Path:
    """The file that ``name``, written in ``referrer`` (an OBJ, MTL, glTF or PLY), means:
    ``name`` relative to ``referrer``'s folder (absolute names as they are), ``\\`` read
    as ``/``. The path is not resolved: opening it follows symbolic links and ``..`` as the
    operating system does, so files that are symbolic links into other folders, and names
    such as ``../textures/wood.png``, find the files their author meant."""
    return Path(referrer).parent / name.strip().replace("\\", "/")


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


def mtl_materials(mtl: Path) -> dict[str, dict[str, Path]]:
    """The maps of every material an MTL file defines (``newmtl`` name, as trimesh names
    materials), by statement (lower case: ``map_kd``, ``norm``), found by
    :func:`named_file`; a material without maps maps to ``{}``. A map before any
    ``newmtl`` belongs to the material ``""``."""
    found: dict[str, dict[str, Path]] = {}
    material = ""
    for line in mtl.read_text(errors="replace").splitlines():
        parts = line.strip().split(None, 1)
        if len(parts) == 2 and parts[0].lower() == "newmtl":
            material = " ".join(parts[1].split())
            found.setdefault(material, {})
        elif len(parts) == 2 and parts[0].lower() in MTL_MAPS:
            found.setdefault(material, {})[parts[0].lower()] = named_file(mtl, _file_name(parts[1]))
    return found


def mtl_maps(mtl: Path) -> dict[str, list[Path]]:
    """The maps an MTL file names, by statement (lower case: ``map_kd``, ``norm``), each
    found by :func:`named_file`."""
    found: dict[str, list[Path]] = {}
    for maps in mtl_materials(mtl).values():
        for statement, path in maps.items():
            found.setdefault(statement, []).append(path)
    return found


def obj_mtl_files(obj: str | Path) -> list[Path]:
    """The MTL files an OBJ names (``mtllib a.mtl [b.mtl ...]``), found by :func:`named_file`."""
    obj = Path(obj)
    names = []
    for match in _MTLLIB.finditer(obj.read_bytes()):
        text = match.group(1).decode(errors="replace")
        # A name may hold spaces; if the whole text is no file, read it as several names.
        whole = named_file(obj, text)
        names += [whole] if whole.is_file() else [named_file(obj, n) for n in text.split()]
    return names


def obj_maps(obj: str | Path, statement: str) -> list[Path]:
    """The files an OBJ's material files name in ``statement`` (``map_kd`` or ``norm``)."""
    return [
        m for mtl in obj_mtl_files(obj) if mtl.is_file() for m in mtl_maps(mtl).get(statement, [])
    ]


def ply_texture(ply: str | Path) -> Path | None:
    """The texture a PLY's header names (``comment TextureFile wood.png``), found by
    :func:`named_file`, or ``None``."""
    with Path(ply).open("rb") as f:
        head = f.read(1 << 16)
    match = _TEXTURE_FILE.search(head.split(b"end_header", 1)[0])
    return named_file(ply, match.group(1).decode(errors="replace")) if match else None


def gltf_json(path: Path) -> dict:
    """The JSON of a ``.gltf`` file or of a ``.glb``'s first chunk ({} when unreadable).

    Raises:
        AssetFileError: naming the file and the key, for a key set twice in one object
            (trimesh would keep the last without a word).
    """
    try:
        if path.suffix.lower() == ".gltf":
            return load_json(path.read_text(), str(path))
        with path.open("rb") as f:
            magic, _, _ = struct.unpack("<4sII", f.read(12))
            length, kind = struct.unpack("<I4s", f.read(8))
            if magic != b"glTF" or kind != b"JSON":
                return {}
            return load_json(f.read(length), f"{path} (its JSON chunk)")
    except DuplicateKeyError as err:
        raise AssetFileError(str(err)) from err
    except (OSError, ValueError, struct.error):
        return {}  # the loader reports an unreadable file with its own message


def references(path: str | Path) -> list[tuple[Path, Path]]:
    """``(referring file, referenced file)`` for every file the asset at ``path`` names:
    an OBJ's MTL files and their base-colour and normal maps, a glTF's external buffers
    and images (``data:`` URIs are embedded, not files), a PLY's texture. Missing files
    are listed too; a ``path`` that is no regular file names none."""
    path = Path(path)
    found = []
    suffix = path.suffix.lower()
    if file_problem(path):
        return found  # nothing to read (and a FIFO must not be opened)
    if suffix == ".obj":
        for mtl in obj_mtl_files(path):
            found.append((path, mtl))
            if mtl.is_file():
                found += [(mtl, m) for maps in mtl_maps(mtl).values() for m in maps]
    elif suffix in (".gltf", ".glb"):
        found += [(path, named_file(path, uri)) for uri in gltf_file_uris(path)]
    elif suffix == ".ply":
        texture = ply_texture(path)
        found += [(path, texture)] if texture else []
    return found


def gltf_file_uris(path: str | Path) -> list[str]:
    """The ``uri`` of every external buffer and image of a glTF (percent-decoded; ``data:``
    URIs are embedded, not files), in the file's order: buffers, then images."""
    tree = gltf_json(Path(path))
    tree = tree if isinstance(tree, dict) else {}
    items = [
        item
        for key in ("buffers", "images")
        if isinstance(tree.get(key), list)
        for item in tree[key]
    ]
    return [
        unquote(item["uri"])
        for item in items
        if isinstance(item, dict)
        and isinstance(item.get("uri"), str)
        and not item["uri"].startswith("data:")
    ]


def missing(path: str | Path) -> list[str]:
    """One sentence per file the mesh at ``path`` names that is not a readable file (empty
    if none), e.g. ``a.obj names a.mtl (/data/a.mtl), which does not exist``; or the one
    sentence saying why its list of files cannot be trusted (a glTF key set twice)."""
    try:
        named = references(path)
    except AssetFileError as err:
        return [str(err)]
    return [
        f"{source} names {target.name} ({target}), which {problem}"
        for source, target in named
        if (problem := file_problem(target))
    ]


def asset_inputs(path: str) -> list[str]:
    """The files a job reading the asset depends on besides ``path`` itself."""
    return sorted({str(target) for _, target in references(path)})


def user_path_inputs(entry: UserPath) -> list[str]:
    """The files a user path brings into the DAG: the path, its folder's or glob's files
    (:func:`neurender.user_paths.files_of`) and, for an asset, the files the mesh names
    (:func:`asset_inputs`; none when it cannot be read: its method's check names it)."""
    files = [entry.path, *map(str, files_of(entry.path))]
    if entry.asset and file_problem(entry.path) is None:
        try:
            files += asset_inputs(entry.path)
        except (OSError, ValueError):
            pass
    return files


def check(path: str | Path, suffixes: tuple[str, ...], named: bool = True) -> Path:
    """``path`` once it has one of ``suffixes``, is a file, and (``named``) every file it
    names is one.

    Raises:
        AssetFileError: naming the file: an unknown suffix, no such file (or a folder, a
            FIFO ... where the file should be), a glTF key set twice, or the files it names
            that are missing.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in suffixes:
        raise AssetFileError(
            f"{path}: unknown mesh format {suffix or '(no suffix)'}; expected one of "
            f"{', '.join(suffixes)}"
        )
    problem = file_problem(path)
    if problem == "does not exist":
        raise AssetFileError(f"{path}: no such file")
    if problem:
        raise AssetFileError(f"{path}: {problem}; expected a mesh file")
    if suffix in (".gltf", ".glb"):
        gltf_json(path)  # refuses a key set twice, of which trimesh would keep the last
    absent = missing(path) if named else []
    if absent:
        raise AssetFileError(f"{path}: " + "; ".join(absent))
    return path
