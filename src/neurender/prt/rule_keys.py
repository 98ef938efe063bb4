"""What each of DeepPRT's rules' jobs read of the config (:attr:`neurender.method.Rule.params`),
in the order of their params; :mod:`neurender.prt.method` gives them to its rules. Read at DAG
time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from neurender.method import OfJob, Value, When, wildcard

#: The ray tracer's keys (every job that traces transfer).
TRANSFER = ("prt.n_bands", "prt.direction_sets", "prt.ray_offset")


#: The keys of DeepPRT's sections no job's params hold: the light, the probes, the user's
#: meshes and probes and the experiments pick input files or add and remove jobs (which
#: other rerun triggers rerun); the threads are a resource.
UNREAD = (
    "prt.light",
    "prt.probes",
    "prt.user_probes",
    "prt.user_meshes",
    "prt.experiments",
    "prt_model.threads",
)


def _procedural(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    """A built-in object, neither a user mesh nor a user animation."""
    prt = cfg["prt"]
    return wildcards["object"] not in {**prt["user_meshes"], **prt["user_sequences"]}


def _user_sequence(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return wildcards["object"] in cfg["prt"]["user_sequences"]


def _variant(name: str) -> OfJob:
    """The condition of the jobs that train the variant ``name``."""
    return lambda cfg, wildcards: wildcards["variant"] == name


def _directions(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> int:
    """Test frames get the clean reference's direction count (paper scale: >= 4x)."""
    key = "reference_directions" if wildcards["split"] == "test" else "directions"
    return cfg["prt"][key]


#: The section 4.2.2 experiments and the relighting figure: the test frames' keys.
TEST_FRAME = ("device", "prt.n_bands", "prt_model.render_resolution", wildcard("object"))

PROBE = ("prt.probe_height", "prt.n_bands", wildcard("probe"))
#: Procedural objects read their vertex count; user meshes and animations do not.
GEOMETRY_IMAGE = (
    "seed",
    "prt.resolution",
    When(_procedural, ("prt.source_vertices",)),
    wildcard("object"),
)
SEQUENCE = (
    "seed",
    "prt.frames",
    "prt.experiment_points",
    "prt.experiment_train_frames",
    "prt.linear_range",
    "prt.excluded_expression",
    wildcard("object"),
    When(
        _user_sequence,
        (
            Value(
                "test_fraction",
                lambda cfg, wc: cfg["prt"]["user_sequences"][wc["object"]]["test_fraction"],
                ("prt.user_sequences",),
            ),
        ),
    ),
)
TRANSFER_JOB = (
    "seed",
    *TRANSFER,
    wildcard("object"),
    wildcard("split"),
    Value("directions", _directions, ("prt.directions", "prt.reference_directions")),
)
NOISE_FLOOR = (
    "seed",
    *TRANSFER,
    "prt.directions",
    "prt.noise_floor_frames",
    wildcard("object"),
)
FIGURE = ("prt.n_bands", wildcard("object"))
MESH_FIGURE = (wildcard("object"),)
BENCHMARK = ("seed", *TRANSFER, "prt.directions", "prt.benchmark_paper_scale")
#: One variant's training keys, in one fixed order for both variants (Snakemake compares
#: params as text): an edit of an evaluation key, or of a key only the other variant reads
#: (the shadowing variant's architecture constants are in
#: neurender.prt.local_model.LocalConfig, not in the config), never retrains.
TRAIN = (
    "seed",
    "device",
    "prt.n_bands",
    "prt_model.widths",
    "prt_model.blocks",
    "prt_model.epochs",
    When(_variant("paper"), ("prt_model.batch_size", "prt_model.lr")),
    "prt_model.lr_schedule",
    When(_variant("paper"), ("prt_model.residual_targets",)),
    When(_variant("shadowing"), ("prt_model.shadowing_batch_size", "prt_model.shadowing_lr")),
    wildcard("material"),
    wildcard("variant"),
)
DEPLOY = ("prt.n_bands", wildcard("object"), wildcard("variant"), wildcard("material"))
SHIP = ("prt_model.shipped",)
MOMOPRT = ("prt.n_bands", "prt_model.pca_components", "prt_model.ridges", wildcard("material"))
#: The scores' keys: the noise floor's ground truth (traced at both direction counts) and
#: the renders.
EVALUATE = (
    "seed",
    "device",
    *TRANSFER,
    "prt.directions",
    "prt.reference_directions",
    "prt_model.render_resolution",
    "prt_model.glossy_exponent",
    "prt_model.variants",
    wildcard("object"),
)
#: The ray-traced estimates' keys (on the first noise_floor_frames test frames).
EQUAL_QUALITY = (
    "seed",
    "device",
    *TRANSFER,
    "prt.reference_directions",
    "prt.noise_floor_frames",
    "prt_model.render_resolution",
    "prt_model.equal_quality_directions",
    "prt_model.variants",
    wildcard("object"),
)
MODEL_SUMMARY = (
    "prt.resolution",
    "prt.n_bands",
    "prt_model.variants",
    "prt_model.shipped",
    "prt.objects",
)
#: The shipped variant, whose targets these are.
TARGETS = ("prt_model.shipped",)
#: The benchmark's sizes, its ground truth's keys and the scores' render keys.
UNSEEN = (
    "seed",
    "device",
    *TRANSFER,
    "prt.reference_directions",
    "prt_model.render_resolution",
    "prt_model.glossy_exponent",
    "prt_model.variants",
    "prt_model.unseen_strengths",
    "prt_model.unseen_frames",
    wildcard("object"),
)
#: Fig. 6: the test frames' keys and the variants drawn (their files are its inputs).
EXPERIMENT = (*TEST_FRAME, "prt_model.variants")
#: The report's view (the probes it turns are its input files).
VIEWER = ("device", "prt.n_bands", wildcard("object"))
