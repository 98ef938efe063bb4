# Helpers of workflow/rules/simplification.smk: the names, config keys and input files its rules use.

from neurender.simplify import CASE_FILES as SIMPLIFY_CASE_FILES

SIMPLIFY_CASES = tuple(config["simplify"]["cases"])
SIMPLIFY_RENDER_KEYS = ("resolution", "intensity")
SIMPLIFY_PREPARE_KEYS = SIMPLIFY_RENDER_KEYS + (
    "texture_size",
    "train_views",
    "test_views",
    "reference_spp",
    "test_spp",
    "supersample",
    "camera_distance",
    "fov",
    "light_distance",
    "light_cone",
)
SIMPLIFY_OPTIMISE_KEYS = SIMPLIFY_RENDER_KEYS + (
    "texture_size",
    "steps",
    "batch",
    "spp",
    "lr_positions",
    "lr_textures",
    "lr_final_fraction",
    "laplacian_scale",
    "laplacian_min_fraction",
)
#: Keys only one use case reads.
SIMPLIFY_CASE_KEYS = {
    "head": ("head_vertices", "head_triangles"),
    "metaballs": ("metaball_count", "metaball_grid", "metaball_triangles"),
}


def simplify_prepare_params(wildcards):
    keys = SIMPLIFY_PREPARE_KEYS + SIMPLIFY_CASE_KEYS[wildcards.case]
    return section_keys("simplify", keys, ("seed", "device"), case=wildcards.case)


def simplify_optimise_params(wildcards):
    return section_keys(
        "simplify", SIMPLIFY_OPTIMISE_KEYS, ("seed", "device"), case=wildcards.case
    )


def simplify_evaluate_params():
    keys = SIMPLIFY_RENDER_KEYS + ("eval_spp", "threads", "cases")
    return section_keys("simplify", keys, ("seed", "device"))


def simplify_evaluate_inputs(wildcards):
    """Every case's files, keyed ``<case>_<kind>`` as the evaluation reads them."""
    return {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFY_CASES
        for kind, name in SIMPLIFY_CASE_FILES.items()
    }


def simplify_report_tables():
    tables = ("targets", "metrics", "stats")
    return (
        expand("results/simplification/{table}.csv", table=tables)
        if SIMPLIFY_CASES
        else []
    )


def simplify_report_figures():
    names = ("comparison", "loss_curves")
    return (
        expand("results/simplification/figures/{name}.png", name=names)
        if SIMPLIFY_CASES
        else []
    )


wildcard_constraints:
    case="|".join(SIMPLIFY_CASES) or "-",
