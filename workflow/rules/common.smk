# Config validation, helpers and input functions shared by every stage.
from snakemake.utils import validate

# Validate (and fill defaults) before any job runs: unknown keys and wrong types fail here.
validate(config, schema="../schemas/config.schema.yaml")

BUILTIN_OBJECTS = ("head", "cloth", "creature")
BUILTIN_PROBES = ("sky", "sunset", "studio")
PRT_SPLITS = ("train", "val", "test")
PRT_MATERIALS = ("diffuse", "glossy")


def _check_names(kind, names, builtins, user):
    for name in names:
        if name not in builtins and name not in user:
            raise ValueError(
                f"config: {kind} {name!r} is neither built in ({', '.join(builtins)}) "
                f"nor listed under the user entries ({', '.join(user) or 'none'})"
            )


_check_names("prt.objects entry", config["prt"]["objects"], BUILTIN_OBJECTS, config["prt"]["user_meshes"])
_check_names("prt.probes entry", config["prt"]["probes"], BUILTIN_PROBES, config["prt"]["user_probes"])
if config["prt"]["light"] not in config["prt"]["probes"]:
    raise ValueError(f"config: prt.light {config['prt']['light']!r} must be one of prt.probes {config['prt']['probes']}")


wildcard_constraints:
    object="[A-Za-z0-9_]+",
    probe="[A-Za-z0-9_]+",
    split="train|val|test",
    material="diffuse|glossy",
    case="head|metaballs",


def prt_params():
    """The PRT data subtree plus the seed: what every PRT data rule depends on."""
    return {"seed": config["seed"], **config["prt"]}


def prt_object_source(wildcards):
    """A user mesh file is an input of its geometry-image job, so editing it reruns the job."""
    path = config["prt"]["user_meshes"].get(wildcards.object)
    return [path] if path else []


def prt_probe_source(wildcards):
    path = config["prt"]["user_probes"].get(wildcards.probe)
    return [path] if path else []


def prt_all_objects():
    return list(config["prt"]["objects"]) + ["plane"]


def report_tables():
    tables = ("targets", "metrics", "compression", "data", "noise_floor", "benchmark")
    return expand("results/prt/{table}.csv", table=tables) + prt_experiment_tables() + ndr_tables() + metaballs_tables() + simplify_tables()


def report_figures():
    objects = config["prt"]["objects"]
    frames = expand("results/prt/figures/{object}_{kind}.png", object=objects, kind=("prediction", "frames"))
    experiments = expand("results/prt/figures/{experiment}.png", experiment=PRT_EXPERIMENTS)
    fixed = [
        "results/prt/figures/loss_curves.png",
        "results/prt/figures/equal_quality.png",
        "results/prt/figures/light_probes.png",
    ]
    if len(config["prt"]["probes"]) >= 2:
        fixed.append(f"results/prt/figures/{objects[0]}_relight.png")
    return frames + experiments + fixed + ndr_figures() + metaballs_figures() + simplify_figures()


def prt_subset(*keys):
    """Only the PRT config keys a rule uses, so unrelated edits never rerun it."""
    return {"seed": config["seed"], **{k: config["prt"][k] for k in keys}}


def prt_directions(wildcards):
    """Test frames get the clean reference's direction count (paper scale: >= 4x)."""
    key = "reference_directions" if wildcards.split == "test" else "directions"
    return config["prt"][key]


def prt_split_inputs(wildcards):
    """Sequence file, frame folders and manifests of every split of one object."""
    base = f"results/prt/{wildcards.object}"
    inputs = {"seq": f"{base}/sequence.npz"}
    for split in PRT_SPLITS:
        inputs[f"{split}_dir"] = f"{base}/{split}"
        inputs[f"{split}_manifest"] = f"{base}/{split}_manifest.csv"
    return inputs


PRT_TRAIN_KEYS = ("widths", "blocks", "epochs", "batch_size", "lr", "lr_schedule", "residual_targets")


def prt_train_params():
    """What a DeepPRT training job reads, so an edit of an evaluation key never retrains."""
    model = config["prt_model"]
    return {"device": config["device"], **prt_subset("n_bands"), **{k: model[k] for k in PRT_TRAIN_KEYS}}


def prt_train_priority(wildcards):
    """The object networks first, the shorter experiment networks after them and the
    seconds-long MoMoPRT fits (priority 0) in the gaps, so the two single-thread training
    jobs keep both cores busy until the last one ends."""
    return 1 if wildcards.object in PRT_EXPERIMENTS else 2


def prt_momoprt_params():
    """What a MoMoPRT fit reads."""
    model = config["prt_model"]
    return {**prt_subset("n_bands"), **{k: model[k] for k in ("pca_components", "ridges")}}


def prt_model_params():
    """What the evaluation rules depend on: the model subtree and the data keys they read."""
    data_keys = ("n_bands", "directions", "reference_directions", "direction_sets", "ray_offset")
    data_keys += ("noise_floor_frames", "resolution", "frames")
    return {"device": config["device"], **prt_subset(*data_keys), **config["prt_model"]}


PRT_EXPERIMENTS = ("head_linear", "head_excluded") if config["prt"]["experiments"] else ()


def prt_sequence_gim(wildcards):
    """The section 4.2.2 experiments deform the head's geometry image."""
    source = "head" if wildcards.object in ("head_linear", "head_excluded") else wildcards.object
    return f"results/prt/{source}/geometry_image.npz"


def prt_experiment_tables():
    return expand("results/prt/{experiment}/experiment.csv", experiment=PRT_EXPERIMENTS)


METABALL_SPLITS = ("train", "val", "test")


METABALL_VARIANTS = ("pix2pix", "l1only", "sphere_residual")


# The thesis's network and ours: the demo animates and times both.
METABALL_DEMO_VARIANTS = ("pix2pix", "sphere_residual")


def metaballs_params():
    return {"seed": config["seed"], **config["metaballs"]}


def metaballs_model_params(wildcards):
    """Data and model keys. A training job gets its own variant's epochs only, so tuning one
    variant never retrains another; only the thesis's pix2pix has a GAN term."""
    cfg = {"device": config["device"], **metaballs_params(), **config["metaballs_model"]}
    variant = wildcards.get("variant")
    if variant is not None:
        cfg["variant"] = variant
        cfg["epochs"] = cfg["epochs"][variant]
        if variant != "pix2pix":
            cfg["gan_weight"] = 0.0
    return cfg


def metaballs_tables():
    return expand("results/metaballs/{table}.csv", table=("targets", "metrics", "timing", "data"))


def metaballs_figures():
    names = ("comparison", "accuracy_by_scene", "demo_network_vs_raymarch", "temporal_stability")
    names += ("frame_time_vs_balls", "examples")
    return expand("results/metaballs/figures/{name}.png", name=names) + ["results/metaballs/figures/demo.gif"]


SIMPLIFY_CASES = tuple(config["simplify"]["cases"])


def simplify_params(wildcards):
    """The simplify subtree; a use case's jobs skip the other case's keys, so tuning one
    case never reruns the other."""
    cfg = {"seed": config["seed"], "device": config["device"], **config["simplify"]}
    other = {"head": "metaball_", "metaballs": "head_"}.get(wildcards.get("case"))
    if other is None:
        return cfg
    return {k: v for k, v in cfg.items() if k != "cases" and not k.startswith(other)}


SIMPLIFY_CASE_FILES = {
    "lowpoly": "lowpoly.npz",
    "baked_normal": "baked_normal.png",
    "baked_albedo": "baked_albedo.png",
    "stats": "stats.csv",
    "test_views": "views_test.csv",
    "test_images": "reference_test.exr",
    "mesh": "optimised.npz",
    "normal": "optimised_normal.png",
    "albedo": "optimised_albedo.png",
    "loss": "loss.csv",
}


def simplify_evaluate_inputs(wildcards):
    """Every case's files, keyed ``<case>_<kind>`` as the evaluation reads them."""
    return {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFY_CASES
        for kind, name in SIMPLIFY_CASE_FILES.items()
    }


def simplify_tables():
    if not SIMPLIFY_CASES:
        return []
    return expand("results/simplification/{table}.csv", table=("targets", "metrics", "stats"))


def simplify_figures():
    if not SIMPLIFY_CASES:
        return []
    return expand("results/simplification/figures/{name}.png", name=("comparison", "loss_curves"))


NDR_VARIANTS = tuple(dict.fromkeys(["ndr", *config["ndr_model"]["variants"]]))
if config["ndr_model"]["relight_sample"] >= config["ndr"]["samples"]["test"]:
    raise ValueError(
        f"config: ndr_model.relight_sample {config['ndr_model']['relight_sample']} must be below "
        f"ndr.samples.test ({config['ndr']['samples']['test']})"
    )
NDR_DIFFUSE_VARIANTS = ("ndr_diffuse", "real_shading")


def ndr_splits():
    splits = ["train", "val", "test"]
    if any(v in NDR_DIFFUSE_VARIANTS for v in NDR_VARIANTS):
        splits += ["diffuse_train", "diffuse_val", "diffuse_test"]
    return splits


def ndr_data_params(wildcards):
    """The NDR data subtree plus seed and device; a split's job also gets its sample count."""
    cfg = {"seed": config["seed"], "device": config["device"], **config["ndr"]}
    split = wildcards.get("split")
    if split:
        kind, _, part = split.rpartition("_")
        cfg["count"] = config["ndr"]["diffuse_samples" if kind else "samples"][part]
    return cfg


def ndr_model_params(wildcards):
    """Model keys (not the relighting figure's) plus the data keys the networks need."""
    model = {k: v for k, v in config["ndr_model"].items() if not k.startswith("relight_")}
    return {"seed": config["seed"], "device": config["device"], "width": config["ndr"]["width"],
            **model}


def ndr_relight_params(wildcards):
    """The data keys that regenerate a test sample, plus the model keys relighting reads."""
    return {**ndr_data_params(wildcards), "mask_erosion": config["ndr_model"]["mask_erosion"],
            "relight_sample": config["ndr_model"]["relight_sample"],
            "relight_turns": config["ndr_model"]["relight_turns"]}


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
    inputs.update({f"loss_{v}": f"results/ndr/models/{v}_loss.csv" for v in NDR_VARIANTS})
    for split in ndr_splits():
        if split.endswith("test"):
            inputs.update({f"{split}_{k}": p for k, p in ndr_split_files(split).items()})
    inputs["train_manifest"] = "results/ndr/train_manifest.csv"
    return inputs


def ndr_benchmarks():
    """Every NDR job's benchmark file and its threads: the stage's measured time."""
    train_threads = config["ndr_model"]["threads"]
    return (
        [(f"results/benchmarks/ndr_data/{s}.tsv", workflow.cores) for s in ndr_splits()]
        + [(f"results/benchmarks/ndr_train/{v}.tsv", train_threads) for v in NDR_VARIANTS]
        + [("results/benchmarks/ndr_summary/ndr_summary.tsv", 1)]
        + [("results/benchmarks/ndr_evaluate/ndr_evaluate.tsv", workflow.cores)]
        + [("results/benchmarks/ndr_relight/ndr_relight.tsv", workflow.cores)]
    )


def ndr_tables():
    tables = ("targets", "metrics", "timing", "relighting", "furnace", "data")
    return expand("results/ndr/{table}.csv", table=tables)


def ndr_figures():
    names = ("buffers", "comparison", "relighting", "training_curves")
    return expand("results/ndr/figures/{name}.png", name=names)
