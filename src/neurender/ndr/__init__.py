"""Neural Direct-illumination Renderer (Suppan et al. 2021): procedural data, model, evaluation.

This module names what the workflow's rules refer to (variants, splits); it imports
nothing heavy, so the Snakefile can read it when it builds the DAG.

Modules: ``objects``, ``environments``, ``render``, ``shading`` and ``prefiltered`` (one
scene and its buffers; the coarse shading importance-sampled or prefiltered), ``data``
and ``pool`` (a split's samples), ``buffers`` (their file format and loading),
``variants`` and ``model`` (the networks), ``training``, ``evaluate`` (scores),
``deploy`` and ``shipped`` (the ONNX files: the networks; shading and network in one
graph, in float32 and int8), ``graph_scores`` (that graph's inputs and scores),
``equal_quality`` (NDR against Mitsuba's sample counts), ``relight``,
``furnace``, ``summary`` (statistics, timings, targets),
``user_objects`` (your meshes; :mod:`neurender.asset_files` finds the files they name),
``figures`` and ``jobs`` (one function per rule of ``workflow/rules/ndr.smk``).
"""

from pathlib import Path

from neurender.asset_files import TRIMESH_SUFFIXES, VTK_SUFFIXES
from neurender.ndr.variants import VARIANTS
from neurender.user_paths import files_of, is_note, with_suffix

#: Mesh files ``ndr.user_objects`` may name: trimesh's formats and PyVista's VTK ones.
MESH_SUFFIXES = TRIMESH_SUFFIXES + VTK_SUFFIXES

#: The parts of a dataset; a split is a part of the ``complex`` data (``train``), of the
#: ``diffuse`` data (``diffuse_train``) or the ``sunlit`` test set (real-world-like maps).
PARTS = ("train", "val", "test")
KINDS = ("complex", "diffuse", "sunlit")
DIFFUSE_SPLITS = tuple(f"diffuse_{part}" for part in PARTS)
SUNLIT_SPLIT = "sunlit_test"
SPLITS = PARTS + DIFFUSE_SPLITS + (SUNLIT_SPLIT,)

#: The ``dataset`` label of each kind's rows in the tables.
DATASETS = {"complex": "complex", "diffuse": "diffuse", "sunlit": "real-world-like maps"}

#: The data each kind's test set is rendered by the networks trained on.
TRAINED_ON = {"complex": "complex", "diffuse": "diffuse", "sunlit": "complex"}

#: Timed calls per render of the equal-quality sweep and per part of NDR's frame (each
#: after one uncounted call; :mod:`neurender.ndr.equal_quality`).
EQUAL_QUALITY_REPEATS = 3

#: Training samples whose activations set the int8 shipped graph's ranges (fewer where the
#: split has fewer; :mod:`neurender.ndr.deploy`).
CALIBRATION_SAMPLES = 16

#: The variants trained and tested on the diffuse, fixed-illumination data.
DIFFUSE_VARIANTS = tuple(name for name, v in VARIANTS.items() if v.data == "diffuse")


#: HDR maps as downloaded that Mitsuba (installed with neurender) converts to OpenEXR:
#: Radiance RGBE and PFM (``mitsuba.Bitmap(path).write(...)``); the example command of
#: :func:`user_probes_problem` names the first such file found.
_MITSUBA_CONVERTS = (".hdr", ".rgbe", ".pic", ".pfm")


def user_probe_files(folder: str | Path) -> list[Path]:
    """The lat-long maps of ``ndr.user_probes_dir``: the folder's visible ``.exr`` files,
    the suffix in any case (``B.EXR``), sorted by name; none when it is not a folder."""
    if not Path(folder).is_dir():
        return []
    return with_suffix(files_of(str(folder)), (".exr",))


def user_probe_strays(folder: str | Path) -> list[Path]:
    """The visible files of ``ndr.user_probes_dir`` that are neither maps
    (:func:`user_probe_files`) nor notes (:func:`neurender.user_paths.is_note`), sorted
    by name: maps in other formats (``.hdr``, ``.jpg`` previews) that would be left out
    unsaid; none when it is not a folder."""
    if not Path(folder).is_dir():
        return []
    maps = set(user_probe_files(folder))
    return [p for p in files_of(str(folder)) if p not in maps and not is_note(p)]


def user_probes_problem(folder: str | Path) -> str | None:
    """Why ``ndr.user_probes_dir = folder`` cannot be used, as a message naming the key,
    the folder and the files at fault; ``None`` for a folder holding ``.exr`` maps and at
    most hidden files and notes besides (:func:`user_probe_strays`)."""
    strays = user_probe_strays(folder)
    if strays:
        shown = ", ".join(p.name for p in strays[:10])
        more = f" and {len(strays) - 10} more" if len(strays) > 10 else ""
        none = "" if user_probe_files(folder) else " and no .exr map"
        what = (
            f"{len(strays)} files that are not OpenEXR maps"
            if len(strays) > 1
            else "a file that is not an OpenEXR map"
        )
        hdr = [p for p in strays if p.suffix.lower() in _MITSUBA_CONVERTS]
        example = hdr[0].name if hdr else "map.hdr"
        return (
            f"ndr.user_probes_dir = {str(folder)!r}: holds {what} ({shown}{more}){none}; "
            "the workflow reads only *.exr lat-long maps and would leave them out. Convert "
            'HDR maps (.hdr, .pfm, .tif) to OpenEXR lat-long, e.g. python -c "import '
            f"mitsuba; mitsuba.Bitmap('{example}').write('{Path(example).stem}.exr')\" "
            "(Mitsuba reads .hdr and .pfm), and move other files (LDR previews such as .jpg "
            "or .png are no radiance maps) out of the "
            "folder; beside the maps it may hold only hidden files and notes (README, "
            "LICENSE, *.txt, *.md)"
        )
    if not user_probe_files(folder):
        return (
            f"ndr.user_probes_dir = {str(folder)!r}: expected a folder holding *.exr lat-long maps"
        )
    return None


def split_kind(split: str) -> tuple[str, str]:
    """``"diffuse_test"`` -> ``("diffuse", "test")``; ``"train"`` -> ``("complex", "train")``;
    ``"sunlit_test"`` -> ``("sunlit", "test")`` (the sunlit kind has a test part only)."""
    kind, _, part = split.rpartition("_")
    if split == SUNLIT_SPLIT:
        return "sunlit", "test"
    if part not in PARTS or kind not in ("", "diffuse"):
        raise ValueError(
            f"NDR split {split!r}: expected [diffuse_]train|val|test or {SUNLIT_SPLIT}"
        )
    return kind or "complex", part


def split_name(kind: str, part: str) -> str:
    """The inverse of :func:`split_kind`."""
    return part if kind == "complex" else f"{kind}_{part}"
