# DeepPRT data (paper 3.1, 3.2.2): meshes -> geometry images -> deformation sequences ->
# ray-traced SH transfer per frame, plus light probes, noise floor and ray benchmark.


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




rule prt_probe:
    input:
        prt_probe_source,
    output:
        exr="results/prt/probes/{probe}.exr",
        sh="results/prt/probes/{probe}_sh.csv",
    params:
        cfg=prt_subset("probe_height", "n_bands"),
    log:
        "results/logs/prt_probe/{probe}.log",
    benchmark:
        "results/benchmarks/prt_probe/{probe}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_probe.py"


rule prt_geometry_image:
    input:
        prt_object_source,
    output:
        gim="results/prt/{object}/geometry_image.npz",
        stats="results/prt/{object}/geometry_image.csv",
    params:
        cfg=prt_subset("resolution", "source_vertices"),
    log:
        "results/logs/prt_geometry_image/{object}.log",
    benchmark:
        "results/benchmarks/prt_geometry_image/{object}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_geometry_image.py"


rule prt_sequence:
    input:
        gim=prt_sequence_gim,
    output:
        seq="results/prt/{object}/sequence.npz",
    params:
        cfg=prt_subset(
            "frames", "experiment_points", "experiment_train_frames", "linear_range", "excluded_expression"
        ),
    log:
        "results/logs/prt_sequence/{object}.log",
    benchmark:
        "results/benchmarks/prt_sequence/{object}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_sequence.py"


rule prt_transfer:
    input:
        seq="results/prt/{object}/sequence.npz",
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        frames=directory("results/prt/{object}/{split}"),
        manifest="results/prt/{object}/{split}_manifest.csv",
    params:
        cfg=prt_subset("n_bands", "direction_sets", "ray_offset"),
        directions=prt_directions,
    log:
        "results/logs/prt_transfer/{object}_{split}.log",
    benchmark:
        "results/benchmarks/prt_transfer/{object}_{split}.tsv"
    threads: workflow.cores
    resources:
        embree=1,
    # Finish the ground truth first: a 2-thread transfer cannot share the cores with the
    # 1-thread training jobs, which then run two at a time.
    priority: 10
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_transfer.py"


rule prt_noise_floor:
    input:
        seq="results/prt/{object}/sequence.npz",
        reference="results/prt/{object}/test",
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        csv="results/prt/{object}/noise_floor.csv",
    params:
        cfg=prt_subset("n_bands", "direction_sets", "ray_offset", "directions", "noise_floor_frames"),
    log:
        "results/logs/prt_noise_floor/{object}.log",
    benchmark:
        "results/benchmarks/prt_noise_floor/{object}.tsv"
    threads: workflow.cores
    resources:
        embree=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_noise_floor.py"


rule prt_figure:
    input:
        frames="results/prt/{object}/test",
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        png=report("results/prt/figures/{object}_frames.png", category="DeepPRT", labels={"object": "{object}"}),
    params:
        n_bands=config["prt"]["n_bands"],
    log:
        "results/logs/prt_figure/{object}.log",
    benchmark:
        "results/benchmarks/prt_figure/{object}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_figure.py"


rule prt_summary:
    input:
        gim=expand("results/prt/{object}/geometry_image.csv", object=prt_all_objects()),
        manifests=expand(
            "results/prt/{object}/{split}_manifest.csv", object=config["prt"]["objects"], split=PRT_SPLITS
        ),
        noise=expand("results/prt/{object}/noise_floor.csv", object=config["prt"]["objects"]),
    output:
        data="results/prt/data.csv",
        noise="results/prt/noise_floor.csv",
    log:
        "results/logs/prt_summary/prt_summary.log",
    benchmark:
        "results/benchmarks/prt_summary/prt_summary.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_summary.py"


rule prt_benchmark:
    input:
        seq=expand("results/prt/{object}/sequence.npz", object=config["prt"]["objects"][0]),
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        csv="results/prt/benchmark.csv",
    params:
        cfg=prt_subset("n_bands", "direction_sets", "ray_offset", "directions", "benchmark_paper_scale"),
    log:
        "results/logs/prt_benchmark/prt_benchmark.log",
    benchmark:
        "results/benchmarks/prt_benchmark/prt_benchmark.tsv"
    threads: workflow.cores
    resources:
        embree=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_benchmark.py"


rule prt_probes_figure:
    input:
        exrs=expand("results/prt/probes/{probe}.exr", probe=config["prt"]["probes"]),
        sh=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["probes"]),
    output:
        png=report("results/prt/figures/light_probes.png", category="DeepPRT"),
    log:
        "results/logs/prt_probes_figure/prt_probes_figure.log",
    benchmark:
        "results/benchmarks/prt_probes_figure/prt_probes_figure.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_probes_figure.py"
