"""What each of NDR's rules' jobs read of the config (:attr:`neurender.method.Rule.params`),
in the order of their params; :mod:`neurender.ndr.method` gives them to its rules. Read at DAG
time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from neurender.method import Entry, OfJob, Value, When, wildcard
from neurender.ndr import (
    DIFFUSE_SPLITS,
    DIFFUSE_VARIANTS,
    PARTS,
    SUNLIT_SPLIT,
    VARIANTS,
    split_kind,
)

#: The keys of NDR's sections no job's params hold: the threads, a resource.
UNREAD = ("ndr_model.threads",)


def variants(cfg: Mapping[str, Any]) -> list[str]:
    """The variants trained: ``ndr`` (the shipped one) and ``ndr_model.variants``."""
    return list(dict.fromkeys(["ndr", *cfg["ndr_model"]["variants"]]))


def splits(cfg: Mapping[str, Any]) -> list[str]:
    """The splits made: the complex data, the diffuse data when a variant trains on it,
    and the real-world-like test set unless ``ndr.sunlit_samples`` is 0."""
    diffuse = any(v in DIFFUSE_VARIANTS for v in variants(cfg))
    sunlit = (SUNLIT_SPLIT,) if cfg["ndr"]["sunlit_samples"] else ()
    return list(PARTS + (DIFFUSE_SPLITS if diffuse else ()) + sunlit)


def _split_is(kind: str | None = None, part: str | None = None) -> OfJob:
    """The condition of the jobs whose split (wildcard ``split``) is of ``kind`` and
    ``part`` (either: any)."""

    def applies(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
        found = split_kind(wildcards["split"])
        return kind in (None, found[0]) and part in (None, found[1])

    return applies


def _importance(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return cfg["ndr"]["coarse_shading"] == "importance"


def _architecture(arch: str) -> OfJob:
    """The condition of the jobs that train a variant of architecture ``arch``."""
    return lambda cfg, wildcards: VARIANTS[wildcards["variant"]].arch == arch


def _uses_prior(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return VARIANTS[wildcards["variant"]].uses_prior


def _count(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> int:
    """The sample count of the split."""
    kind, part = split_kind(wildcards["split"])
    if kind == "sunlit":
        return cfg["ndr"]["sunlit_samples"]
    return cfg["ndr"]["samples" if kind == "complex" else "diffuse_samples"][part]


#: The keys of a complex sample's object and map, the small sun's included.
COMPLEX = ("ndr.user_probes_dir", "ndr.user_probe_fraction", "ndr.small_sun_fraction")
#: The ndr keys of a sample's scene and its coarse shading: every sample's, and a user
#: object's render's.
SCENE = (
    "ndr.width",
    "ndr.primitives",
    "ndr.edge_length",
    "ndr.camera_distance",
    "ndr.fov",
    "ndr.environment_height",
    "ndr.coarse_height",
    "ndr.coarse_shading",
)
#: The keys of the importance-sampled coarse shading (``ndr.coarse_shading``).
IMPORTANCE = When(_importance, ("ndr.coarse_samples", "ndr.bright_texels"))
#: The ndr keys every sample reads.
SAMPLE: tuple[Entry, ...] = (*SCENE, "ndr.spp", IMPORTANCE)
#: The keys that make a sample of the job's split: every sample's, its kind's and a test
#: part's reference.
SPLIT_SAMPLE = (
    *SAMPLE,
    When(_split_is("complex"), COMPLEX),
    When(_split_is("diffuse"), ("ndr.fixed_probe",)),
    When(_split_is(part="test"), ("ndr.reference_spp",)),
)
#: The keys that make a sample of the (complex) test set.
TEST_SAMPLE = (*SAMPLE, *COMPLEX, "ndr.reference_spp")
VARIANTS_TRAINED = Value("variants", lambda cfg, wildcards: variants(cfg), ("ndr_model.variants",))

#: A split's sample keys, its name and its sample count.
DATA = (
    "seed",
    "device",
    *SPLIT_SAMPLE,
    wildcard("split"),
    Value("count", _count, ("ndr.samples", "ndr.diffuse_samples", "ndr.sunlit_samples")),
)
#: The furnace and sun checks' keys and the splits whose manifests are summarised (that
#: ``ndr.sunlit_samples`` is not 0 adds the sunlit split's jobs: a shape of the DAG).
SUMMARY = (
    "seed",
    "device",
    "ndr.width",
    "ndr.furnace_spp",
    "ndr.coarse_samples",
    "ndr.coarse_height",
    Value("splits", lambda cfg, wildcards: splits(cfg), ("ndr_model.variants",)),
)
#: One variant's training keys: the shared ones, its architecture's (ndr.width too for
#: pix2pix; shading_residual where the variant can use it).
TRAIN = (
    "seed",
    "device",
    "ndr_model.mask_erosion",
    "ndr_model.epochs",
    "ndr_model.batch_size",
    "ndr_model.lr",
    "ndr_model.lr_schedule",
    When(_architecture("ndr"), ("ndr_model.widths", "ndr_model.sh_hidden")),
    When(
        _architecture("pix2pix"),
        ("ndr_model.ngf", "ndr_model.ndf", "ndr_model.l1_weight", "ndr_model.gan_weight"),
    ),
    When(_uses_prior, ("ndr_model.shading_residual",)),
    wildcard("variant"),
    When(_architecture("pix2pix"), ("ndr.width",)),
)
EVALUATE = ("device", "ndr_model.mask_erosion", VARIANTS_TRAINED)
#: The keys that regenerate a test sample, plus the relighting's own.
RELIGHT = (
    "seed",
    "device",
    "ndr_model.mask_erosion",
    "ndr_model.relight_sample",
    "ndr_model.relight_turns",
    *TEST_SAMPLE,
)
#: The keys that regenerate a test sample, and which sample is relit (the turns are the
#: viewer's own, :data:`neurender.viewer_data.TURNS`).
VIEWER = ("seed", "device", "ndr_model.mask_erosion", "ndr_model.relight_sample", *TEST_SAMPLE)
#: The keys that replay the test maps (objects drawn first: primitives, edge_length) and
#: render a test sample, the user objects' own, the test split's size and the mask
#: erosion of the scores.
USER_OBJECTS = (
    "seed",
    "device",
    *SCENE,
    "ndr.reference_spp",
    *COMPLEX,
    "ndr.sunlit_samples",
    "ndr.user_objects",
    "ndr.user_object_defaults",
    "ndr.user_object_maps",
    IMPORTANCE,
    Value("test_samples", lambda cfg, wc: cfg["ndr"]["samples"]["test"], ("ndr.samples.test",)),
    "ndr_model.mask_erosion",
)
#: The keys that redraw a test sample (its object and map) and render it, the sweep's own
#: and the mask erosion of the scores.
EQUAL_QUALITY = (
    "seed",
    "device",
    *SAMPLE,
    *COMPLEX,
    "ndr.equal_quality_spp",
    "ndr.equal_quality_samples",
    "ndr_model.mask_erosion",
)
#: The keys of NDR's shipped graph: those that draw a complex sample's object and map
#: again (the seed too), the coarse map's height, the camera and the width; and the
#: variants exported.
DEPLOY = (
    "seed",
    "ndr.primitives",
    "ndr.edge_length",
    "ndr.environment_height",
    *COMPLEX,
    "ndr.coarse_height",
    "ndr.camera_distance",
    "ndr.fov",
    "ndr.width",
    VARIANTS_TRAINED,
)
