"""User animations: per-frame mesh files with one shared topology (``prt.user_sequences``).

A sequence is what DCC tools write with "export as mesh sequence" (Blender, Maya,
Houdini): one file per frame, frames in the order of their names
(:func:`neurender.prt.mesh_files`), every frame with the same vertices in the same order
and the same triangles. Files are read as they are, without merging or reordering
vertices (:func:`neurender.prt.objects.read_mesh`), so vertex ``i``
is the same surface point in every frame; polygons are split into triangles the same way
in every frame. Positions are in the files' units.

The first frame is the rest pose that is parametrised (:mod:`neurender.prt.disk`,
:mod:`neurender.prt.geometry_image`); without separate test frames the last
``test_fraction`` of the sequence is held out (extrapolation in time).

A frame whose vertices were written in another order has the same counts and triangles
but joins other surface points: its edges (each pair of vertices a triangle joins) run
across the shape. Every frame's edge lengths are compared with the rest frame's
(:func:`edge_changes`), and a frame where many changed by a large factor is refused
(:data:`EDGE_FACTOR`, :data:`EDGE_SHARE`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from neurender.prt import mesh_files
from neurender.prt.disk import bbox_diagonal, edges_of
from neurender.prt.objects import read_mesh

#: An edge changed implausibly when its length in a frame is more than this factor longer
#: or shorter than in the rest frame, taken as is and relative to the change of the
#: frame's size (bounding-box diagonal), so a frame scaled as a whole or crumpled is not
#: counted. The built-in animations and the example sequences (results/examples) change
#: none by 4 (at most 2.8 x), the unseen-deformation families at strength 1 at most 0.3 %
#: of the edges of a geometry image's grid; vertices in another order change about 90 %.
EDGE_FACTOR = 4.0
#: A frame with more than this share of its edges changed by :data:`EDGE_FACTOR` is refused
#: (a mesh with a tenth of its vertices reordered changes about 18 %).
EDGE_SHARE = 0.1


@dataclasses.dataclass
class Frames:
    """Frames of one animation with their shared topology.

    Attributes:
        files: the frame files in order.
        positions: ``(F, V, 3)`` float64 vertex positions per frame.
        faces: ``(T, 3)`` int64 triangles of every frame.
    """

    files: list[Path]
    positions: np.ndarray
    faces: np.ndarray


def load_frames(
    files: list[Path], what: str, reference: tuple[Path, np.ndarray, np.ndarray] | None = None
) -> Frames:
    """Read frame files and check they share one topology, up front.

    Args:
        files: frame files in order (at least one).
        what: the config entry they come from, for messages.
        reference: ``(file, positions, faces)`` of the rest frame when ``files`` are
            other frames of the same animation (its test frames).

    Raises:
        ValueError naming the first file whose vertex or triangle count, or triangles,
        differ from the rest frame's, with both counts, or whose edges changed length
        implausibly (:func:`edge_changes`: vertices in another order), with its position
        in ``files``.
    """
    if not files:
        raise ValueError(f"{what}: no mesh files found")
    positions = []
    ref_file, ref_vertices, ref_faces = reference or (files[0], *read_mesh(files[0]))
    edges = np.unique(np.sort(edges_of(ref_faces), axis=1), axis=0)
    for index, path in enumerate(files):
        vertices, faces = (ref_vertices, ref_faces) if path == ref_file else read_mesh(path)
        if len(vertices) != len(ref_vertices) or len(faces) != len(ref_faces):
            raise ValueError(
                f"{what}: frame {path} has {len(vertices)} vertices and {len(faces)} "
                f"triangles, but the rest frame {ref_file} has {len(ref_vertices)} vertices "
                f"and {len(ref_faces)} triangles; every frame needs the same vertices and "
                "triangles (export the animation as a mesh sequence, without modifiers that "
                "change the topology)"
            )
        differ = np.nonzero((faces != ref_faces).any(axis=1))[0]
        if len(differ):
            raise ValueError(
                f"{what}: frame {path} has {len(vertices)} vertices and {len(faces)} triangles "
                f"like the rest frame {ref_file}, but {len(differ)} triangles join other "
                f"vertices (the first is triangle {differ[0]}); every frame needs the same "
                "triangles"
            )
        changes = np.abs(edge_changes(ref_vertices, vertices, edges))
        share = float(np.mean(changes > np.log(EDGE_FACTOR))) if len(changes) else 0.0
        if share > EDGE_SHARE:
            raise ValueError(
                f"{what}: frame {index + 1} of {len(files)}, {path}, has the triangles of the "
                f"rest frame {ref_file}, but {share:.0%} of its {len(changes)} edges are more "
                f"than {EDGE_FACTOR:g} times longer or shorter than there (median factor "
                f"{np.exp(np.median(changes)):.1f}); expected the same vertices in the same "
                "order as the rest frame, deformed (vertices written in another order join "
                "other surface points: export every frame from one mesh as a mesh sequence, "
                "keeping the vertex order)"
            )
        positions.append(vertices)
    return Frames(list(files), np.stack(positions), ref_faces)


def edge_changes(rest: np.ndarray, frame: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """How much each edge's length changed from ``rest`` to ``frame`` (``(V, 3)`` positions
    of the same vertices), as ``(E,)`` natural logs of the length ratio for ``edges``
    ``(E, 2)``: of the two readings, as is and relative to the change of the bounding-box
    diagonal, the one nearer 0 (a frame scaled as a whole changes no edge). Edges of zero
    length in the rest frame are left out; one collapsed in ``frame`` counts as a change
    by a factor 1e12."""
    size = bbox_diagonal(rest)
    before = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    after = np.linalg.norm(frame[edges[:, 0]] - frame[edges[:, 1]], axis=1)
    kept = before > 1e-12 * size
    raw = np.log(np.maximum(after[kept], 1e-12 * before[kept]) / before[kept])
    scaled = raw - np.log(max(bbox_diagonal(frame), 1e-12 * size) / size)
    return np.where(np.abs(raw) < np.abs(scaled), raw, scaled)


def load_sequence(
    frames: list[str], test_frames: list[str], what: str
) -> tuple[Frames, Frames | None]:
    """The frames (and the separate test frames, if any) of one user sequence, checked
    against the rest frame (the first of ``frames``).

    Args:
        frames, test_frames: folders, globs or files (:func:`neurender.prt.mesh_files`).
        what: the config entry, for messages.

    Raises:
        ValueError: as :func:`load_frames`, and for a test frame whose vertex positions
            equal a training frame's, naming both files.
    """
    sequence = load_frames(mesh_files(frames), f"{what}.frames")
    if not test_frames:
        return sequence, None
    rest = (sequence.files[0], sequence.positions[0], sequence.faces)
    tests = load_frames(mesh_files(test_frames), f"{what}.test_frames", rest)
    # The config check compares files; this compares what was read (the same pose
    # exported again, or in another format), so no test score is one on training data.
    for positions, file in zip(tests.positions, tests.files, strict=True):
        twin = same_pose(positions, sequence)
        if twin is not None:
            raise ValueError(
                f"{what}.test_frames: frame {file} has the same vertex positions as the "
                f"training frame {twin}; test frames must be other poses than those of frames"
            )
    return sequence, tests


#: Positions closer than this fraction of the rest frame's bounding-box diagonal are the
#: same pose: above the rounding of a text export (10 digits: 1e-10), far below motion.
SAME_POSE = 1e-6


def same_pose(positions: np.ndarray, frames: Frames) -> Path | None:
    """The first of ``frames`` whose ``(V, 3)`` positions equal ``positions`` to within
    :data:`SAME_POSE` of the rest frame's size, or ``None``."""
    rest = frames.positions[0]
    tolerance = SAME_POSE * float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    for other, file in zip(frames.positions, frames.files, strict=True):
        if np.abs(other - positions).max() <= tolerance:
            return file
    return None


def held_out(frames: int, test_fraction: float) -> int:
    """Frames at the end of a sequence held out for testing: ``round(fraction x frames)``,
    at least one."""
    return max(1, round(test_fraction * frames))
