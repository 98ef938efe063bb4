"""DeepPRT (Li et al. 2019): SH transfer of deforming surfaces predicted from geometry images.

This module names what the workflow's rules refer to; it imports nothing heavy, so the
Snakefile can read it when it builds the DAG.
"""

import glob
import hashlib
import re
from collections.abc import Callable, Iterator
from pathlib import Path

from neurender.mesh_header import vertex_count
from neurender.user_paths import file_problem, files_of, with_suffix

#: Built-in animated objects (:mod:`neurender.prt.objects`).
OBJECTS = ("head", "cloth", "creature")
#: Frame splits of every object: one smooth training sequence (train, val) and test frames
#: outside it.
SPLITS = ("train", "val", "test")
#: Transfer kinds, one network each: diffuse (K coefficients) and glossy (3 K).
MATERIALS = ("diffuse", "glossy")
#: Network variants (``prt_model.variants``), each trained per object and material at the
#: same epochs, and their names in the tables: ``paper``, the paper's U-Net from P and N
#: (:mod:`neurender.prt.model`); ``shadowing``, the analytic unshadowed transfer plus a
#: local network for what shadowing removes (:mod:`neurender.prt.local_model`).
VARIANTS = {"paper": "DeepPRT", "shadowing": "DeepPRT shadowing"}


#: Training frames whose activation ranges calibrate a network's int8 graph, and val
#: frames on which an exported graph is checked against PyTorch (``prt_deploy``).
CALIBRATION_FRAMES = 32
CHECK_FRAMES = 2


def int8_name(model: str) -> str:
    """The tables' name of a variant's int8 graph (its convolutions in int8, scored and
    timed as a network of its own) from the variant's name ``model``."""
    return f"{model} int8"


#: Datasets of paper section 4.2.2 (Fig. 6), built on the head's geometry image: a linear
#: shape space with a plane, and the head without one expression in training.
EXPERIMENTS = ("head_linear", "head_excluded")
#: Dataset names a user object cannot take.
RESERVED = (*OBJECTS, "plane", *EXPERIMENTS)
#: Mesh files of user meshes and animation frames: read by trimesh (``MESH_SUFFIXES``) or
#: by PyVista with VTK's readers (``VTK_SUFFIXES``).
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
VTK_SUFFIXES = (".vtk", ".vtp", ".vtu")
#: The fewest vertices a mesh the geometry image maps can have: the boundary loop of its
#: disk is pinned to the square's four corners (:mod:`neurender.prt.geometry_image`).
MIN_VERTICES = 4
#: What a user mesh (or an animation's rest frame) must be, for messages.
DISK_EXPECTED = (
    "expected one connected surface (a disk, or cut to one) with a boundary loop of at "
    f"least {MIN_VERTICES} vertices, which the geometry image pins to the square's corners"
)


def _natural_key(path: Path) -> tuple:
    """``frame_9`` before ``frame_10``: digit runs compare as numbers."""
    parts = re.split(r"(\d+)", path.name)
    return [(0, int(t)) if t.isdigit() else (1, t.lower()) for t in parts], str(path)


def mesh_files(paths: str | list[str]) -> list[Path]:
    """The mesh files behind user paths (a folder, a glob or files;
    :func:`neurender.user_paths.files_of`: hidden files such as macOS's ``._frame.obj``
    left out of folders), sorted by name with numbers in order (``frame_2`` before
    ``frame_10``); files of other suffixes and paths that are not files are left out."""
    found = set()
    for path in [paths] if isinstance(paths, str) else paths:
        found.update(p for p in files_of(str(path)) if p.is_file())
    return sorted(with_suffix(found, MESH_SUFFIXES + VTK_SUFFIXES), key=_natural_key)


def _digest(path: Path) -> str | None:
    """SHA-256 of the file's bytes; ``None`` when it cannot be read (the job that reads
    the frames names the file and why)."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def overlap_problems(key: str, frames: list[Path], test_frames: list[Path]) -> Iterator[str]:
    """Test frames that are also training frames: the same file (after resolving links
    and ``..``) or a file with the same bytes; the test score would be measured on
    training data. One message per test frame, naming both files."""
    by_path = {p.resolve(): p for p in frames}
    by_bytes = {}
    for p in frames:
        by_bytes.setdefault(_digest(p), p)
    by_bytes.pop(None, None)
    for p in test_frames:
        if p.resolve() in by_path:
            yield (
                f"{key}.test_frames: {p} is the training frame {by_path[p.resolve()]} "
                "(the same file); test frames must be other frames than those of frames"
            )
        elif (twin := by_bytes.get(_digest(p))) is not None:
            yield (
                f"{key}.test_frames: {p} has the same content as the training frame "
                f"{twin}; test frames must be other frames than those of frames"
            )


def too_small(path: str | Path) -> int | None:
    """The vertex count ``path``'s header declares when it is below :data:`MIN_VERTICES`
    (a single triangle), else ``None`` (:func:`neurender.mesh_header.vertex_count`: OBJ,
    PLY, OFF; other formats are checked when the mesh is mapped)."""
    count = vertex_count(path)
    return count if count is not None and count < MIN_VERTICES else None


def vertex_count_problems(key: str, files: list[Path]) -> Iterator[str]:
    """A rest frame (``files[0]``) with too few vertices to map (:func:`too_small`), or the
    first frame whose header declares another vertex count than the rest frame
    (:func:`neurender.mesh_header.vertex_count`: OBJ, PLY, OFF; other formats are checked
    when the frames are read)."""
    counts = [(p, vertex_count(p)) for p in files]
    known = [(p, n) for p, n in counts if n is not None]
    if not known or files[0] != known[0][0]:
        return
    rest, expected = known[0]
    if expected < MIN_VERTICES:
        yield f"{key}: the rest frame {rest} has {expected} vertices; {DISK_EXPECTED}"
        return
    for p, n in known[1:]:
        if n != expected:
            yield (
                f"{key}: frame {p} has {n} vertices but the rest frame {rest} has "
                f"{expected}; every frame needs the same vertices (export the animation as "
                "a mesh sequence, without modifiers that change the topology)"
            )
            return


def held_out_frames(frames: int, test_fraction: float) -> int:
    """Frames at the end of a user sequence held out for testing when it has no separate
    test frames: ``round(test_fraction x frames)``, at least one."""
    return max(1, round(test_fraction * frames))


def user_sequence_problems(
    name: str, entry: dict, made_by_the_workflow: Callable[[str], bool]
) -> Iterator[str]:
    """Config problems of one ``prt.user_sequences`` entry: no mesh files behind ``frames``
    or ``test_frames`` (or a path that is not a regular file), test frames that are also
    training frames, a frame whose header declares another vertex count, or too few
    frames for training, validation and testing. Paths the workflow makes are checked by
    the jobs that read them."""
    key = f"prt.user_sequences.{name}"
    found = {}
    for field in ("frames", "test_frames"):
        path = entry[field]
        if path and not made_by_the_workflow(path):
            found[field] = mesh_files(path)
            p = Path(path)
            if not found[field] and p.exists() and not p.is_dir() and not glob.has_magic(path):
                yield f"{key}.{field} = {path!r}: {file_problem(p) or 'is not a mesh file'}"
            elif not found[field]:
                yield (
                    f"{key}.{field} = {path!r}: no mesh files found (expected a folder "
                    f"or glob of {', '.join(MESH_SUFFIXES + VTK_SUFFIXES)} files)"
                )
    if found.get("frames") and found.get("test_frames"):
        yield from overlap_problems(key, found["frames"], found["test_frames"])
    if found.get("frames"):
        yield from vertex_count_problems(key, found["frames"] + found.get("test_frames", []))
    frames = len(found.get("frames", []))
    if frames and not entry["test_frames"]:
        held = held_out_frames(frames, entry["test_fraction"])
        if frames - held < 2:
            yield (
                f"{key}: {frames} frames, {held} held out for testing (test_fraction = "
                f"{entry['test_fraction']}); expected at least 2 more for training and validation"
            )
    elif frames == 1:
        yield f"{key}: 1 frame; expected at least 2 for training and validation"
