"""DeepPRT (Li et al. 2019): SH transfer of deforming surfaces predicted from geometry images.

This module names what the workflow's rules refer to; it imports nothing heavy, so the
Snakefile can read it when it builds the DAG.
"""

import glob
import re
from collections.abc import Callable, Iterator
from pathlib import Path

#: Built-in animated objects (:mod:`neurender.prt.objects`).
OBJECTS = ("head", "cloth", "creature")
#: Frame splits of every object: one smooth training sequence (train, val) and test frames
#: outside it.
SPLITS = ("train", "val", "test")
#: Transfer kinds, one network each: diffuse (K coefficients) and glossy (3 K).
MATERIALS = ("diffuse", "glossy")
#: Datasets of paper section 4.2.2 (Fig. 6), built on the head's geometry image: a linear
#: shape space with a plane, and the head without one expression in training.
EXPERIMENTS = ("head_linear", "head_excluded")
#: Dataset names a user object cannot take.
RESERVED = (*OBJECTS, "plane", *EXPERIMENTS)
#: Mesh files of user meshes and animation frames: read by trimesh (``MESH_SUFFIXES``) or
#: by PyVista with VTK's readers (``VTK_SUFFIXES``).
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
VTK_SUFFIXES = (".vtk", ".vtp", ".vtu")


def _natural_key(path: Path) -> tuple:
    """``frame_9`` before ``frame_10``: digit runs compare as numbers."""
    parts = re.split(r"(\d+)", path.name)
    return [(0, int(t)) if t.isdigit() else (1, t.lower()) for t in parts], str(path)


def mesh_files(paths: str | list[str]) -> list[Path]:
    """The mesh files behind user paths (a folder, a glob or files), sorted by name with
    numbers in order (``frame_2`` before ``frame_10``); other files are left out."""
    found = set()
    for path in [paths] if isinstance(paths, str) else paths:
        p = Path(path)
        if p.is_dir():
            found.update(q for q in p.iterdir() if q.is_file())
        elif glob.has_magic(str(path)):
            found.update(Path(q) for q in glob.glob(str(path)))
        elif p.is_file():
            found.add(p)
    suffixes = MESH_SUFFIXES + VTK_SUFFIXES
    return sorted((p for p in found if p.suffix.lower() in suffixes), key=_natural_key)


def held_out_frames(frames: int, test_fraction: float) -> int:
    """Frames at the end of a user sequence held out for testing when it has no separate
    test frames: ``round(test_fraction x frames)``, at least one."""
    return max(1, round(test_fraction * frames))


def user_sequence_problems(
    name: str, entry: dict, made_by_the_workflow: Callable[[str], bool]
) -> Iterator[str]:
    """Config problems of one ``prt.user_sequences`` entry: no mesh files behind ``frames``
    or ``test_frames``, or too few frames for training, validation and testing. Paths the
    workflow makes are checked by the jobs that read them."""
    key = f"prt.user_sequences.{name}"
    counts = {}
    for field in ("frames", "test_frames"):
        if entry[field] and not made_by_the_workflow(entry[field]):
            counts[field] = len(mesh_files(entry[field]))
            if not counts[field]:
                yield (
                    f"{key}.{field} = {entry[field]!r}: no mesh files found (expected a folder "
                    f"or glob of {', '.join(MESH_SUFFIXES + VTK_SUFFIXES)} files)"
                )
    frames = counts.get("frames", 0)
    if frames and not entry["test_frames"]:
        held = held_out_frames(frames, entry["test_fraction"])
        if frames - held < 2:
            yield (
                f"{key}: {frames} frames, {held} held out for testing (test_fraction = "
                f"{entry['test_fraction']}); expected at least 2 more for training and validation"
            )
    elif frames == 1:
        yield f"{key}: 1 frame; expected at least 2 for training and validation"
