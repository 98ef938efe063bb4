"""Neural Direct-illumination Renderer (Suppan et al. 2021): procedural data, model, evaluation.

This module names what the workflow's rules refer to (variants, splits); it imports
nothing heavy, so the Snakefile can read it when it builds the DAG.

Modules: ``objects``, ``environments``, ``render``, ``shading`` (one scene and its
buffers), ``data`` and ``pool`` (a split's samples), ``buffers`` (their file format and
loading), ``variants`` and ``model`` (the networks), ``training``, ``evaluate`` (scores),
``relight``, ``furnace``, ``summary`` (statistics, timings, targets), ``figures`` and
``jobs`` (one function per rule of ``workflow/rules/ndr.smk``).
"""

from neurender.ndr.variants import VARIANTS

#: The parts of a dataset; a split is a part of the ``complex`` data (``train``) or of
#: the ``diffuse`` data (``diffuse_train``).
PARTS = ("train", "val", "test")
KINDS = ("complex", "diffuse")
DIFFUSE_SPLITS = tuple(f"diffuse_{part}" for part in PARTS)
SPLITS = PARTS + DIFFUSE_SPLITS

#: The variants trained and tested on the diffuse, fixed-illumination data.
DIFFUSE_VARIANTS = tuple(name for name, v in VARIANTS.items() if v.data == "diffuse")


def split_kind(split: str) -> tuple[str, str]:
    """``"diffuse_test"`` -> ``("diffuse", "test")``; ``"train"`` -> ``("complex", "train")``."""
    kind, _, part = split.rpartition("_")
    if part not in PARTS or kind not in ("", "diffuse"):
        raise ValueError(f"NDR split {split!r}: expected [diffuse_]train|val|test")
    return kind or "complex", part


def split_name(kind: str, part: str) -> str:
    """The inverse of :func:`split_kind`."""
    return part if kind == "complex" else f"{kind}_{part}"
