"""What each of the metaballs' rules' jobs read of the config
(:attr:`neurender.method.Rule.params`), in the order of their params;
:mod:`neurender.metaballs.method` gives them to its rules. Read at DAG
time: imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from neurender.metaballs import GAN_VARIANTS
from neurender.method import Group, Value, When, wildcard

#: The keys of the metaballs' sections no job's params hold: the user's scenes and
#: structures and the variants trained pick input files or add and remove jobs (which
#: other rerun triggers rerun); the threads are a resource.
UNREAD = (
    "metaballs.user_scenes",
    "metaballs_model.variants",
    "metaballs_scale.user_structures",
    "metaballs_model.threads",
)


def _finite_kernel(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return cfg["metaballs"]["kernel"]["name"] != "inverse_square"


def _cluster(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return cfg["metaballs"]["family"] == "cluster"


def _gan(cfg: Mapping[str, Any], wildcards: Mapping[str, str]) -> bool:
    return wildcards["variant"] in GAN_VARIANTS


#: The field's kernel, ``kernel``: its name, and its support and sharpness for a kernel of
#: finite support (so that editing an unused one reruns nothing).
KERNEL = Group(
    "kernel",
    (
        "metaballs.kernel.name",
        When(_finite_kernel, ("metaballs.kernel.support", "metaballs.kernel.sharpness")),
    ),
)
#: The keys an example's scene reads: ``balls``, ``family``, ``radius`` (family
#: ``thesis``) or ``packing`` (``cluster``) and the kernel's.
SCENE = (
    "metaballs.balls",
    "metaballs.family",
    When(lambda cfg, wildcards: not _cluster(cfg, wildcards), ("metaballs.radius",)),
    When(_cluster, ("metaballs.packing",)),
    KERNEL,
)

EXAMPLES = (
    "seed",
    "metaballs.width",
    wildcard("split"),
    Value(
        "examples",
        lambda cfg, wildcards: cfg["metaballs"]["examples"][wildcards["split"]],
        ("metaballs.examples",),
    ),
    *SCENE,
)
#: A variant's training keys (the GAN's only for the GAN variants, the others train with
#: ``gan_weight`` 0) and the image width.
TRAIN = (
    "seed",
    "device",
    "metaballs_model.ngf",
    "metaballs_model.l1_weight",
    "metaballs_model.flips",
    "metaballs_model.epochs",
    "metaballs_model.batch_size",
    "metaballs_model.lr",
    "metaballs_model.lr_schedule",
    When(_gan, ("metaballs_model.ndf", "metaballs_model.gan_weight")),
    wildcard("variant"),
    "metaballs.width",
    When(
        lambda cfg, wildcards: not _gan(cfg, wildcards),
        (Value("gan_weight", lambda cfg, wildcards: 0.0),),
    ),
)
#: The scenes' renders: the width and the kernel (also the user's scenes').
EVALUATE = ("device", "metaballs.width", KERNEL)
EQUAL_QUALITY = ("device", "metaballs_model.equal_quality_examples", "metaballs.width", KERNEL)
DEMO = (
    "seed",
    "device",
    "metaballs_model.demo_frames",
    "metaballs_model.demo_balls",
    "metaballs_model.timing_balls",
    "metaballs.width",
    "metaballs.radius",
    KERNEL,
)
DEPLOY = (KERNEL,)
TARGETS = ("metaballs.width",)
#: The demo's scene and length (not its timing keys) and the image width.
VIEWER = (
    "seed",
    "device",
    "metaballs_model.demo_frames",
    "metaballs_model.demo_balls",
    "metaballs.width",
    "metaballs.radius",
    KERNEL,
)
#: The measurement's keys, the cluster family's and the kernel's, and the trained width.
SCALE = (
    "seed",
    "device",
    "metaballs.width",
    "metaballs.packing",
    KERNEL,
    Group(
        "scale",
        (
            "metaballs_scale.balls",
            "metaballs_scale.widths",
            "metaballs_scale.scenes",
            "metaballs_scale.repeats",
        ),
    ),
)
#: The real scenes' keys, the kernel's and the trained width.
REAL_SCENES = (
    "device",
    "metaballs.width",
    KERNEL,
    Group(
        "scale",
        (
            "metaballs_scale.structures",
            "metaballs_scale.ball_scale",
            "metaballs_scale.trajectory_frames",
            "metaballs_scale.repeats",
        ),
    ),
)
