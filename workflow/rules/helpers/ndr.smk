# Helpers of workflow/rules/ndr.smk: the names and input files its rules use (their params:
# neurender.ndr.rule_keys).

from neurender.ndr import DIFFUSE_VARIANTS as NDR_DIFFUSE_VARIANTS
from neurender.ndr import SPLITS as NDR_SPLITS
from neurender.ndr import SUNLIT_SPLIT as NDR_SUNLIT_SPLIT
from neurender.ndr import VARIANTS as NDR_VARIANT_TABLE
from neurender.ndr import split_kind as ndr_split_kind
from neurender.ndr import rule_keys as ndr_rule_keys
from neurender.asset_files import asset_inputs

NDR_VARIANTS = tuple(ndr_rule_keys.variants(config))


def ndr_splits():
    """The splits made (:func:`neurender.ndr.rule_keys.splits`)."""
    return ndr_rule_keys.splits(config)


def ndr_user_probe_files(wildcards):
    """The user's maps are inputs of every job that renders complex samples (a split of
    them, or the relit test sample), so editing a map reruns exactly those jobs."""
    folder = config["ndr"]["user_probes_dir"]
    if not folder or ndr_split_kind(wildcards.get("split", "test"))[0] != "complex":
        return {}
    return {"user_probes": user_files(folder)}


def ndr_user_object_files(wildcards):
    """Each user object's files (an OBJ's MTL and textures, a glTF's buffers and images;
    a path under results/ is the workflow's output) and the user's maps."""
    files = {
        f"object_{name}": (
            [as_input(path)]
            if made_by_the_workflow(path)
            else [path, *asset_inputs(path)]
        )
        for name, path in config["ndr"]["user_objects"].items()
    }
    folder = config["ndr"]["user_probes_dir"]
    if folder:
        files["user_probes"] = user_files(folder)
    return files


def ndr_split_files(split):
    return {
        "dir": f"results/ndr/{split}",
        "manifest": f"results/ndr/{split}_manifest.csv",
        "lighting": f"results/ndr/{split}_lighting.csv",
    }


def ndr_train_inputs(wildcards):
    prefix = "diffuse_" if wildcards.variant in NDR_DIFFUSE_VARIANTS else ""
    return {
        f"{part}_{key}": path
        for part in ("train", "val")
        for key, path in ndr_split_files(prefix + part).items()
    }


def ndr_evaluate_inputs(wildcards):
    inputs = {f"checkpoint_{v}": f"results/ndr/models/{v}.pt" for v in NDR_VARIANTS}
    inputs.update(
        {f"loss_{v}": f"results/ndr/models/{v}_loss.csv" for v in NDR_VARIANTS}
    )
    for split in ndr_splits():
        if split.endswith("test"):
            inputs.update(
                {f"{split}_{k}": p for k, p in ndr_split_files(split).items()}
            )
    inputs["train_manifest"] = "results/ndr/train_manifest.csv"
    return inputs


def ndr_deploy_inputs(wildcards):
    """Every variant's checkpoint and the test split of each kind of data they train on
    (an export is checked on its first samples); the training split (the int8 shipped
    graph's calibration) and the user's maps (they light some of the samples whose
    graph inputs are remade)."""
    inputs = {f"checkpoint_{v}": f"results/ndr/models/{v}.pt" for v in NDR_VARIANTS}
    for v in NDR_VARIANTS:
        split = "diffuse_test" if v in NDR_DIFFUSE_VARIANTS else "test"
        inputs.update({f"{split}_{k}": p for k, p in ndr_split_files(split).items()})
    inputs.update({f"train_{k}": p for k, p in ndr_split_files("train").items()})
    return {**ndr_user_probe_files(wildcards), **inputs}


def ndr_equal_quality_inputs(wildcards):
    """The test split (its samples are rendered again), the real-world-like test split
    where it is made (the shipped graphs are scored on both) and the user's maps (they
    light some of them)."""
    splits = ["test"] + [s for s in ndr_splits() if s == NDR_SUNLIT_SPLIT]
    files = {
        f"{split}_{k}": p for split in splits for k, p in ndr_split_files(split).items()
    }
    return {**ndr_user_probe_files(wildcards), **files}
