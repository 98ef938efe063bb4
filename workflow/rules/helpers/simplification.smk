# Helpers of workflow/rules/simplification.smk: the names and input files its rules use
# (their params: neurender.simplification.rule_keys).

from neurender.simplification import CASE_FILES as SIMPLIFICATION_CASE_FILES
from neurender.simplification import EXPORT_FILES as SIMPLIFICATION_EXPORT_FILES
from neurender.asset_files import asset_inputs

#: name -> entry (path, ratio, triangles, views); each runs as a use case of its own.
SIMPLIFICATION_USER_ASSETS = config["simplification"]["user_assets"]
SIMPLIFICATION_CASES = tuple(config["simplification"]["cases"]) + tuple(
    SIMPLIFICATION_USER_ASSETS
)


def simplification_prepare_inputs(wildcards):
    """A user asset's file and the files it names (MTL, textures, glTF buffers and
    images), so that editing any of them reruns its jobs; nothing for a built-in case.
    An asset the workflow makes (under results/) is made with its files by one job."""
    return simplification_asset_files(wildcards.case)


def simplification_asset_files(case):
    """The files of case ``case`` if it is a user asset (simplification_prepare_inputs)."""
    entry = SIMPLIFICATION_USER_ASSETS.get(case)
    if entry is None:
        return {}
    path = entry["path"]
    if made_by_the_workflow(path):
        return {"asset": as_input(path), "asset_files": []}
    return {"asset": path, "asset_files": asset_inputs(path)}


def simplification_optimise_inputs(wildcards):
    """A user asset's albedo map starts from its classic bake (its own texture moved to
    the new atlas); a built-in case's from grey."""
    if wildcards.case in SIMPLIFICATION_USER_ASSETS:
        return {
            "initial_albedo": f"results/simplification/{wildcards.case}/baked_albedo.png"
        }
    return {}


def simplification_evaluate_inputs(wildcards):
    """Every case's files and its exported files (simplification_deploy's, read back and
    rendered), keyed ``<case>_<kind>`` as the evaluation reads them."""
    return {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFICATION_CASES
        for kind, name in {
            **SIMPLIFICATION_CASE_FILES,
            **SIMPLIFICATION_EXPORT_FILES,
        }.items()
    }


def simplification_equal_quality_inputs(wildcards):
    """Every case's held-out views and references and its QEM mesh (ours' triangle count),
    keyed ``<case>_<kind>``, and the user assets' files (each rebuilt, as the preparation
    rebuilds it), keyed ``<case>_asset`` and ``<case>_asset_files``."""
    files = {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFICATION_CASES
        for kind, name in (
            ("test_views", "views_test.csv"),
            ("test_images", "reference_test.exr"),
            ("lowpoly", "lowpoly.npz"),
        )
    }
    for case in SIMPLIFICATION_USER_ASSETS:
        asset = simplification_asset_files(case)
        files.update({f"{case}_{kind}": path for kind, path in asset.items()})
    return files


wildcard_constraints:
    case="|".join(SIMPLIFICATION_CASES) or "-",
