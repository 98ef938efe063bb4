# Helpers of workflow/rules/simplification.smk: the names, config keys and input files its rules use.

from neurender.simplification import CASE_FILES as SIMPLIFICATION_CASE_FILES
from neurender.simplification import EXPORT_FILES as SIMPLIFICATION_EXPORT_FILES
from neurender.asset_files import asset_inputs

#: name -> entry (path, ratio, triangles, views); each runs as a use case of its own.
SIMPLIFICATION_USER_ASSETS = config["simplification"]["user_assets"]
SIMPLIFICATION_CASES = tuple(config["simplification"]["cases"]) + tuple(
    SIMPLIFICATION_USER_ASSETS
)
SIMPLIFICATION_RENDER_KEYS = ("resolution", "intensity")
SIMPLIFICATION_PREPARE_KEYS = SIMPLIFICATION_RENDER_KEYS + (
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
SIMPLIFICATION_OPTIMISE_KEYS = SIMPLIFICATION_RENDER_KEYS + (
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
SIMPLIFICATION_CASE_KEYS = {
    "head": ("head_vertices", "head_triangles"),
    "metaballs": ("metaball_count", "metaball_grid", "metaball_triangles"),
}


def simplification_prepare_params(wildcards):
    case = wildcards.case
    if case in SIMPLIFICATION_USER_ASSETS:
        return section_keys(
            "simplification",
            SIMPLIFICATION_PREPARE_KEYS,
            ("seed", "device"),
            case=case,
            asset=SIMPLIFICATION_USER_ASSETS[case],
        )
    keys = SIMPLIFICATION_PREPARE_KEYS + SIMPLIFICATION_CASE_KEYS[case]
    return section_keys("simplification", keys, ("seed", "device"), case=case)


def simplification_prepare_inputs(wildcards):
    """A user asset's file and the files it names (MTL, textures, glTF buffers and
    images), so that editing any of them reruns its jobs; nothing for a built-in case.
    An asset the workflow makes (under results/) is made with its files by one job."""
    entry = SIMPLIFICATION_USER_ASSETS.get(wildcards.case)
    if entry is None:
        return {}
    path = entry["path"]
    if made_by_the_workflow(path):
        return {"asset": as_input(path), "asset_files": []}
    return {"asset": path, "asset_files": asset_inputs(path)}


def simplification_viewer_params(wildcards):
    """The keys that rebuild a case's reference (a user asset: its entry), not those
    that render it (the viewer and the mesh figure)."""
    case = wildcards.case
    if case in SIMPLIFICATION_USER_ASSETS:
        return section_keys(
            "simplification",
            (),
            ("seed",),
            case=case,
            asset=SIMPLIFICATION_USER_ASSETS[case],
        )
    return section_keys(
        "simplification", SIMPLIFICATION_CASE_KEYS[case], ("seed",), case=case
    )


def simplification_optimise_params(wildcards):
    return section_keys(
        "simplification",
        SIMPLIFICATION_OPTIMISE_KEYS,
        ("seed", "device"),
        case=wildcards.case,
    )


def simplification_optimise_inputs(wildcards):
    """A user asset's albedo map starts from its classic bake (its own texture moved to
    the new atlas); a built-in case's from grey."""
    if wildcards.case in SIMPLIFICATION_USER_ASSETS:
        return {
            "initial_albedo": f"results/simplification/{wildcards.case}/baked_albedo.png"
        }
    return {}


def simplification_evaluate_params():
    """The render keys, the cases, and the optimisation jobs' threads (the evaluation's
    own are the workflow's cores): the stage's time counts each optimisation by its
    share of the cores."""
    return section_keys(
        "simplification",
        SIMPLIFICATION_RENDER_KEYS + ("eval_spp",),
        ("seed", "device"),
        cases=list(SIMPLIFICATION_CASES),
        user_assets=list(SIMPLIFICATION_USER_ASSETS),
        optimise_threads=config["simplification"]["threads"],
    )


def simplification_evaluate_inputs(wildcards):
    """Every case's files, and the user assets' exported files (read back and rendered),
    keyed ``<case>_<kind>`` as the evaluation reads them."""
    files = {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFICATION_CASES
        for kind, name in SIMPLIFICATION_CASE_FILES.items()
    }
    files.update(
        {
            f"{case}_{kind}": f"results/simplification/{case}/{name}"
            for case in SIMPLIFICATION_USER_ASSETS
            for kind, name in SIMPLIFICATION_EXPORT_FILES.items()
        }
    )
    return files


wildcard_constraints:
    case="|".join(SIMPLIFICATION_CASES) or "-",
