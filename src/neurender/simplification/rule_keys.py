"""What each of the simplification's rules' jobs read of the config
(:attr:`neurender.method.Rule.params`), in the order of their params;
:mod:`neurender.simplification.method` gives them to its rules. Every key of the
``simplification`` section is some job's. Read at DAG time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from neurender.method import OfJob, Value, When, wildcard


def _case(name: str) -> OfJob:
    """The condition of the jobs of the built-in use case ``name``."""
    return lambda cfg, wildcards: wildcards["case"] == name


def _runs(name: str) -> OfJob:
    """The condition of a job of all cases that the built-in case ``name`` runs in."""
    return lambda cfg, wildcards: name in cfg["simplification"]["cases"]


def _user_asset(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return wildcards["case"] in cfg["simplification"]["user_assets"]


#: The keys the renders of every stage read.
RENDER = ("simplification.resolution", "simplification.intensity")
#: A case's reference: a built-in case's own keys, a user asset's entry.
REFERENCE = (
    When(_case("head"), ("simplification.head_vertices", "simplification.head_triangles")),
    When(
        _case("metaballs"),
        (
            "simplification.metaball_count",
            "simplification.metaball_grid",
            "simplification.metaball_triangles",
        ),
    ),
    wildcard("case"),
    When(
        _user_asset,
        (
            Value(
                "asset",
                lambda cfg, wc: cfg["simplification"]["user_assets"][wc["case"]],
                ("simplification.user_assets",),
            ),
        ),
    ),
)
PREPARE = (
    "seed",
    "device",
    *RENDER,
    "simplification.texture_size",
    "simplification.train_views",
    "simplification.test_views",
    "simplification.reference_spp",
    "simplification.test_spp",
    "simplification.supersample",
    "simplification.camera_distance",
    "simplification.fov",
    "simplification.light_distance",
    "simplification.light_cone",
    *REFERENCE,
)
OPTIMISE = (
    "seed",
    "device",
    *RENDER,
    "simplification.texture_size",
    "simplification.steps",
    "simplification.batch",
    "simplification.spp",
    "simplification.lr_positions",
    "simplification.lr_textures",
    "simplification.lr_final_fraction",
    "simplification.laplacian_scale",
    "simplification.laplacian_min_fraction",
    wildcard("case"),
)
#: The case (the deployment table's rows name it); the export reads no config key.
DEPLOY = (wildcard("case"),)
#: The render keys and the cases (the user assets' names: which cases there are, a shape
#: of the DAG).
EVALUATE = (
    "seed",
    "device",
    *RENDER,
    "simplification.eval_spp",
    Value(
        "cases",
        lambda cfg, wc: [*cfg["simplification"]["cases"], *cfg["simplification"]["user_assets"]],
        ("simplification.cases",),
    ),
)
#: Every case's reference (as the preparation rebuilds it: a built-in case's keys where it
#: runs, the user assets' entries), the bake's texture size, the evaluation's render keys
#: and the budgets swept.
EQUAL_QUALITY = (
    "seed",
    "device",
    *RENDER,
    "simplification.texture_size",
    "simplification.eval_spp",
    "simplification.equal_quality_multiples",
    Value(
        "cases",
        lambda cfg, wc: [*cfg["simplification"]["cases"], *cfg["simplification"]["user_assets"]],
        ("simplification.cases",),
    ),
    When(_runs("head"), ("simplification.head_vertices", "simplification.head_triangles")),
    When(
        _runs("metaballs"),
        (
            "simplification.metaball_count",
            "simplification.metaball_grid",
            "simplification.metaball_triangles",
        ),
    ),
    "simplification.user_assets",
)
#: Keys no job's params hold: the optimisation's Dr.Jit threads are its rule's threads, a
#: resource, so a change reruns no job (with one thread the result is deterministic).
UNREAD = ("simplification.threads",)
#: The keys that rebuild a case's reference (a user asset: its entry), not those that
#: render it (the viewer and the mesh figure).
VIEWER = ("seed", *REFERENCE)
