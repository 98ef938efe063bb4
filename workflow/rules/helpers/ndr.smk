# Helpers of workflow/rules/ndr.smk: the names, config keys and input files its rules use.

from neurender.ndr import DIFFUSE_SPLITS as NDR_DIFFUSE_SPLITS
from neurender.ndr import DIFFUSE_VARIANTS as NDR_DIFFUSE_VARIANTS
from neurender.ndr import PARTS as NDR_PARTS
from neurender.ndr import SPLITS as NDR_SPLITS
from neurender.ndr import SUNLIT_SPLIT as NDR_SUNLIT_SPLIT
from neurender.ndr import VARIANTS as NDR_VARIANT_TABLE
from neurender.ndr import split_kind as ndr_split_kind
from neurender.asset_files import asset_inputs

NDR_VARIANTS = tuple(dict.fromkeys(["ndr", *config["ndr_model"]["variants"]]))
#: ndr keys every sample reads; a kind's or the test part's own keys.
NDR_SAMPLE_KEYS = (
    "width",
    "primitives",
    "edge_length",
    "camera_distance",
    "fov",
    "environment_height",
    "coarse_height",
    "coarse_shading",
    "spp",
)
#: The keys of each coarse-shading estimator (``ndr.coarse_shading``).
NDR_SHADING_KEYS = {
    "importance": ("coarse_samples", "bright_texels"),
    "prefiltered": (),
}
NDR_KIND_KEYS = {
    "complex": ("user_probes_dir", "user_probe_fraction", "small_sun_fraction"),
    "diffuse": ("fixed_probe",),
    "sunlit": (),
}
NDR_TEST_KEYS = ("reference_spp",)
#: ndr keys of NDR's shipped graph (``ndr_deploy``): those that draw a complex sample's
#: object and map again, the coarse map's height, the camera and the width.
NDR_SHIPPED_KEYS = (
    "primitives",
    "edge_length",
    "environment_height",
    *NDR_KIND_KEYS["complex"],
    "coarse_height",
    "camera_distance",
    "fov",
    "width",
)
#: ndr_model keys every training reads; an architecture's own (the pix2pix GAN's too).
NDR_TRAIN_KEYS = ("mask_erosion", "epochs", "batch_size", "lr", "lr_schedule")
NDR_ARCH_KEYS = {
    "ndr": ("widths", "sh_hidden"),
    "pix2pix": ("ngf", "ndf", "l1_weight", "gan_weight"),
}
NDR_RELIGHT_KEYS = ("mask_erosion", "relight_sample", "relight_turns")
#: ndr keys the user objects' job reads: those that replay the test maps (objects drawn
#: first: primitives, edge_length), render a test sample, and its own.
NDR_USER_OBJECT_KEYS = (
    "width",
    "primitives",
    "edge_length",
    "camera_distance",
    "fov",
    "environment_height",
    "coarse_height",
    "coarse_shading",
    "reference_spp",
    "user_probes_dir",
    "user_probe_fraction",
    "small_sun_fraction",
    "sunlit_samples",
    "user_objects",
    "user_object_defaults",
    "user_object_maps",
)


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


def ndr_user_objects_params():
    """The keys of :data:`NDR_USER_OBJECT_KEYS`, the test split's size (its maps are
    replayed) and the mask erosion of the scores."""
    return section_keys(
        "ndr",
        NDR_USER_OBJECT_KEYS + NDR_SHADING_KEYS[config["ndr"]["coarse_shading"]],
        ("seed", "device"),
        test_samples=config["ndr"]["samples"]["test"],
        mask_erosion=config["ndr_model"]["mask_erosion"],
    )


def ndr_splits():
    """The splits made: the complex data, the diffuse data when a variant trains on it,
    and the real-world-like test set unless ``ndr.sunlit_samples`` is 0."""
    diffuse = any(v in NDR_DIFFUSE_VARIANTS for v in NDR_VARIANTS)
    sunlit = (NDR_SUNLIT_SPLIT,) if config["ndr"]["sunlit_samples"] else ()
    return list(NDR_PARTS + (NDR_DIFFUSE_SPLITS if diffuse else ()) + sunlit)


def ndr_sample_keys(split):
    """The ndr keys that make a sample of ``split``."""
    kind, part = ndr_split_kind(split)
    return (
        NDR_SAMPLE_KEYS
        + NDR_SHADING_KEYS[config["ndr"]["coarse_shading"]]
        + NDR_KIND_KEYS[kind]
        + (NDR_TEST_KEYS if part == "test" else ())
    )


def ndr_data_params(wildcards):
    """A split's sample keys, its sample count and its name."""
    kind, part = ndr_split_kind(wildcards.split)
    if kind == "sunlit":
        count = config["ndr"]["sunlit_samples"]
    else:
        count = config["ndr"]["samples" if kind == "complex" else "diffuse_samples"][
            part
        ]
    return section_keys(
        "ndr",
        ndr_sample_keys(wildcards.split),
        ("seed", "device"),
        split=wildcards.split,
        count=count,
    )


def ndr_summary_params():
    """The furnace and sun checks' keys and the splits whose manifests are summarised."""
    keys = ("width", "furnace_spp", "coarse_samples", "coarse_height")
    return section_keys("ndr", keys, ("seed", "device"), splits=ndr_splits())


def ndr_train_params(wildcards):
    """One variant's training keys: the shared epochs, its architecture (ndr.width too
    for pix2pix; shading_residual where the variant can use it)."""
    variant = NDR_VARIANT_TABLE[wildcards.variant]
    keys = NDR_TRAIN_KEYS + NDR_ARCH_KEYS[variant.arch]
    keys += ("shading_residual",) if variant.uses_prior else ()
    extra = {"width": config["ndr"]["width"]} if variant.arch == "pix2pix" else {}
    return section_keys(
        "ndr_model", keys, ("seed", "device"), variant=wildcards.variant, **extra
    )


def ndr_evaluate_params():
    return section_keys(
        "ndr_model", ("mask_erosion",), ("device",), variants=list(NDR_VARIANTS)
    )


def ndr_relight_params(wildcards):
    """The keys that regenerate a test sample, plus the relighting's own."""
    sample = {k: config["ndr"][k] for k in ndr_sample_keys("test")}
    return section_keys("ndr_model", NDR_RELIGHT_KEYS, ("seed", "device"), **sample)


def ndr_viewer_params(wildcards):
    """The keys that regenerate a test sample, and which sample is relit (the turns are
    the viewer's own, :data:`neurender.viewer_data.TURNS`)."""
    sample = {k: config["ndr"][k] for k in ndr_sample_keys("test")}
    keys = ("mask_erosion", "relight_sample")
    return section_keys("ndr_model", keys, ("seed", "device"), **sample)


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


def ndr_equal_quality_params():
    """The keys that redraw a test sample (its object and map) and render it, the sweep's
    own and the mask erosion of the scores."""
    keys = NDR_SAMPLE_KEYS + NDR_SHADING_KEYS[config["ndr"]["coarse_shading"]]
    keys += NDR_KIND_KEYS["complex"] + ("equal_quality_spp", "equal_quality_samples")
    return section_keys(
        "ndr",
        keys,
        ("seed", "device"),
        mask_erosion=config["ndr_model"]["mask_erosion"],
    )


def ndr_deploy_params():
    """The variants exported, and the keys of NDR's shipped graph
    (:data:`NDR_SHIPPED_KEYS`, the seed too: a sample's map is drawn again)."""
    return section_keys("ndr", NDR_SHIPPED_KEYS, ("seed",), variants=list(NDR_VARIANTS))
