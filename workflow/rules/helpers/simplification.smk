# Helpers of workflow/rules/simplification.smk: the names, config keys and input files its rules use.

from neurender.simplify import CASE_FILES as SIMPLIFY_CASE_FILES
from neurender.simplify import EXPORT_FILES as SIMPLIFY_EXPORT_FILES
from neurender.asset_files import asset_inputs

#: name -> entry (path, ratio, triangles, views); each runs as a use case of its own.
SIMPLIFY_USER_ASSETS = config["simplify"]["user_assets"]
SIMPLIFY_CASES = tuple(config["simplify"]["cases"]) + tuple(SIMPLIFY_USER_ASSETS)
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
    case = wildcards.case
    if case in SIMPLIFY_USER_ASSETS:
        return section_keys(
            "simplify",
            SIMPLIFY_PREPARE_KEYS,
            ("seed", "device"),
            case=case,
            asset=SIMPLIFY_USER_ASSETS[case],
        )
    keys = SIMPLIFY_PREPARE_KEYS + SIMPLIFY_CASE_KEYS[case]
    return section_keys("simplify", keys, ("seed", "device"), case=case)


def simplify_prepare_inputs(wildcards):
    """A user asset's file and the files it names (MTL, textures, glTF buffers and
    images), so that editing any of them reruns its jobs; nothing for a built-in case.
    An asset the workflow makes (under results/) is made with its files by one job."""
    entry = SIMPLIFY_USER_ASSETS.get(wildcards.case)
    if entry is None:
        return {}
    path = entry["path"]
    if made_by_the_workflow(path):
        return {"asset": as_input(path), "asset_files": []}
    return {"asset": path, "asset_files": asset_inputs(path)}


def simplify_viewer_params(wildcards):
    """The keys that rebuild a case's reference (a user asset: its entry), not those
    that render it (the viewer and the mesh figure)."""
    case = wildcards.case
    if case in SIMPLIFY_USER_ASSETS:
        return section_keys(
            "simplify", (), ("seed",), case=case, asset=SIMPLIFY_USER_ASSETS[case]
        )
    return section_keys("simplify", SIMPLIFY_CASE_KEYS[case], ("seed",), case=case)


def simplify_optimise_params(wildcards):
    return section_keys(
        "simplify", SIMPLIFY_OPTIMISE_KEYS, ("seed", "device"), case=wildcards.case
    )


def simplify_optimise_inputs(wildcards):
    """A user asset's albedo map starts from its classic bake (its own texture moved to
    the new atlas); a built-in case's from grey."""
    if wildcards.case in SIMPLIFY_USER_ASSETS:
        return {
            "initial_albedo": f"results/simplification/{wildcards.case}/baked_albedo.png"
        }
    return {}


def simplify_evaluate_params():
    """The render keys, the cases, and the optimisation jobs' threads (the evaluation's
    own are the workflow's cores): the stage's time counts each optimisation by its
    share of the cores."""
    return section_keys(
        "simplify",
        SIMPLIFY_RENDER_KEYS + ("eval_spp",),
        ("seed", "device"),
        cases=list(SIMPLIFY_CASES),
        user_assets=list(SIMPLIFY_USER_ASSETS),
        optimise_threads=config["simplify"]["threads"],
    )


def simplify_evaluate_inputs(wildcards):
    """Every case's files, and the user assets' exported files (read back and rendered),
    keyed ``<case>_<kind>`` as the evaluation reads them."""
    files = {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFY_CASES
        for kind, name in SIMPLIFY_CASE_FILES.items()
    }
    files.update(
        {
            f"{case}_{kind}": f"results/simplification/{case}/{name}"
            for case in SIMPLIFY_USER_ASSETS
            for kind, name in SIMPLIFY_EXPORT_FILES.items()
        }
    )
    return files


wildcard_constraints:
    case="|".join(SIMPLIFY_CASES) or "-",
