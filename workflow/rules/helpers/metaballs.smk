# Helpers of workflow/rules/metaballs.smk: the names, config keys and input files its rules use.

from neurender.metaballs import (
    DEMO_VARIANTS as METABALLS_DEMO_VARIANTS,
    GAN_VARIANTS as METABALLS_GAN_VARIANTS,
    SPLITS as METABALLS_SPLITS,
    VARIANTS as METABALLS_VARIANTS,
)

METABALLS_SCENE_KEYS = ("width", "balls", "radius")
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
        "metaballs", METABALLS_SCENE_KEYS, ("seed",), split=split, examples=examples
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
    return section_keys("metaballs", ("width",), ("device",))


def metaballs_equal_quality_params():
    cfg = section_keys("metaballs_model", ("equal_quality_examples",), ("device",))
    return {**cfg, **section_keys("metaballs", ("width",))}


def metaballs_demo_params():
    cfg = section_keys("metaballs_model", METABALLS_DEMO_KEYS, ("seed", "device"))
    return {**cfg, **section_keys("metaballs", ("width", "radius"))}


def metaballs_viewer_params():
    """The demo's scene and length (not its timing keys) and the image width."""
    keys = ("demo_frames", "demo_balls")
    cfg = section_keys("metaballs_model", keys, ("seed", "device"))
    return {**cfg, **section_keys("metaballs", ("width", "radius"))}


def metaballs_user_scenes_file():
    """The user's scenes CSV (its job is only asked for when one is set)."""
    return (
        as_input(config["metaballs"]["user_scenes"])
        or "metaballs.user_scenes is not set"
    )
