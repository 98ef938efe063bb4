# Helpers of workflow/rules/metaballs.smk: the names, config keys and input files its rules use.

from neurender.metaballs import (
    DEMO_VARIANTS as METABALLS_DEMO_VARIANTS,
    GAN_VARIANTS as METABALLS_GAN_VARIANTS,
    SPLITS as METABALLS_SPLITS,
    trained_variants as metaballs_trained_variants,
)

from neurender.metaballs.method import kernel_keys as metaballs_kernel_keys
from neurender.metaballs.method import scene_keys as metaballs_scene_keys

#: The networks this run trains (``metaballs_model.variants`` and always the demo's).
METABALLS_VARIANTS = metaballs_trained_variants(config["metaballs_model"]["variants"])

#: The keys of ``metaballs_model`` every training job reads; the GAN variants also ``ndf``
#: and ``gan_weight`` (the others train with ``gan_weight`` 0).
METABALLS_TRAIN_KEYS = (
    "ngf",
    "l1_weight",
    "flips",
    "epochs",
    "batch_size",
    "lr",
    "lr_schedule",
)
METABALLS_GAN_KEYS = ("ndf", "gan_weight")
METABALLS_DEMO_KEYS = ("demo_frames", "demo_balls", "timing_balls")


def metaballs_examples_params(wildcards):
    split = wildcards.split
    examples = config["metaballs"]["examples"][split]
    return section_keys(
        "metaballs",
        ("width",),
        ("seed",),
        split=split,
        examples=examples,
        **metaballs_scene_keys(config["metaballs"]),
    )


def metaballs_train_params(wildcards):
    """A variant's training keys (the GAN's only for pix2pix) and the image width."""
    variant = wildcards.variant
    gan = variant in METABALLS_GAN_VARIANTS
    keys = METABALLS_TRAIN_KEYS + (METABALLS_GAN_KEYS if gan else ())
    cfg = section_keys("metaballs_model", keys, ("seed", "device"), variant=variant)
    cfg["width"] = config["metaballs"]["width"]
    return cfg if gan else {**cfg, "gan_weight": 0.0}


def metaballs_evaluate_params():
    return section_keys(
        "metaballs",
        ("width",),
        ("device",),
        kernel=metaballs_kernel_keys(config["metaballs"]),
    )


def metaballs_equal_quality_params():
    cfg = section_keys("metaballs_model", ("equal_quality_examples",), ("device",))
    kernel = metaballs_kernel_keys(config["metaballs"])
    return {**cfg, **section_keys("metaballs", ("width",), kernel=kernel)}


def metaballs_demo_params():
    cfg = section_keys("metaballs_model", METABALLS_DEMO_KEYS, ("seed", "device"))
    kernel = metaballs_kernel_keys(config["metaballs"])
    return {**cfg, **section_keys("metaballs", ("width", "radius"), kernel=kernel)}


def metaballs_viewer_params():
    """The demo's scene and length (not its timing keys) and the image width."""
    keys = ("demo_frames", "demo_balls")
    cfg = section_keys("metaballs_model", keys, ("seed", "device"))
    kernel = metaballs_kernel_keys(config["metaballs"])
    return {**cfg, **section_keys("metaballs", ("width", "radius"), kernel=kernel)}


def metaballs_user_scenes_file():
    """The user's scenes CSV (its job is only asked for when one is set)."""
    return (
        as_input(config["metaballs"]["user_scenes"])
        or "metaballs.user_scenes is not set"
    )


def metaballs_user_structure_files():
    """Your structure files (``metaballs_scale.user_structures``), as inputs."""
    return [as_input(path) for path in config["metaballs_scale"]["user_structures"]]


def metaballs_scale_params():
    """The measurement's keys, the cluster family's and the kernel's, and the trained width."""
    keys = ("balls", "widths", "scenes", "repeats")
    mb = config["metaballs"]
    return {
        **section_keys("metaballs", ("width", "packing"), ("seed", "device")),
        "kernel": metaballs_kernel_keys(mb),
        "scale": {k: config["metaballs_scale"][k] for k in keys},
    }


def metaballs_real_scenes_params():
    """The real scenes' keys, the kernel's and the trained width."""
    keys = ("structures", "ball_scale", "trajectory_frames", "repeats")
    return {
        **section_keys("metaballs", ("width",), ("device",)),
        "kernel": metaballs_kernel_keys(config["metaballs"]),
        "scale": {k: config["metaballs_scale"][k] for k in keys},
    }
