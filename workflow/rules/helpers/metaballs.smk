# Helpers of workflow/rules/metaballs.smk: the names and input files its rules use (their
# params: neurender.metaballs.rule_keys).

from neurender.metaballs import (
    DEMO_VARIANTS as METABALLS_DEMO_VARIANTS,
    SPLITS as METABALLS_SPLITS,
    trained_variants as metaballs_trained_variants,
)

#: The networks this run trains (``metaballs_model.variants`` and always the demo's).
METABALLS_VARIANTS = metaballs_trained_variants(config["metaballs_model"]["variants"])


def metaballs_user_scenes_file():
    """The user's scenes CSV (its job is only asked for when one is set)."""
    return (
        as_input(config["metaballs"]["user_scenes"])
        or "metaballs.user_scenes is not set"
    )


def metaballs_user_structure_files():
    """Your structure files (``metaballs_scale.user_structures``), as inputs."""
    return [as_input(path) for path in config["metaballs_scale"]["user_structures"]]
