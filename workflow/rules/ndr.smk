# NDR (Suppan et al. 2021): procedural scenes, Mitsuba ground truth, two-decoder U-Net,
# ablations and baselines.


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


def ndr_report_tables():
    tables = ("targets", "metrics", "timing", "relighting", "furnace", "data")
    return expand("results/ndr/{table}.csv", table=tables)


def ndr_report_figures():
    names = ("buffers", "comparison", "relighting", "training_curves")
    return expand("results/ndr/figures/{name}.png", name=names)


rule ndr_data:
    wildcard_constraints:
        split="(diffuse_)?(train|val|test)",
    output:
        samples=directory("results/ndr/{split}"),
        manifest="results/ndr/{split}_manifest.csv",
        lighting="results/ndr/{split}_lighting.csv",
    params:
        cfg=ndr_data_params,
    log:
        "results/logs/ndr_data/{split}.log",
    benchmark:
        "results/benchmarks/ndr_data/{split}.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_data.py"


rule ndr_summary:
    input:
        manifests=expand("results/ndr/{split}_manifest.csv", split=ndr_splits()),
        example="results/ndr/test",
    output:
        csv="results/ndr/data.csv",
        furnace="results/ndr/furnace.csv",
        figure=report("results/ndr/figures/buffers.png", category="NDR"),
    params:
        cfg=ndr_data_params,
        splits=ndr_splits(),
    log:
        "results/logs/ndr_summary/ndr_summary.log",
    benchmark:
        "results/benchmarks/ndr_summary/ndr_summary.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_summary.py"


rule ndr_train:
    input:
        unpack(ndr_train_inputs),
    output:
        checkpoint="results/ndr/models/{variant}.pt",
        loss="results/ndr/models/{variant}_loss.csv",
    params:
        cfg=ndr_model_params,
    log:
        "results/logs/ndr_train/{variant}.log",
    benchmark:
        "results/benchmarks/ndr_train/{variant}.tsv"
    threads: config["ndr_model"]["threads"]
    resources:
        gpu=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_train.py"


rule ndr_evaluate:
    input:
        unpack(ndr_evaluate_inputs),
    output:
        metrics="results/ndr/metrics.csv",
        samples="results/ndr/metrics_samples.csv",
        timing="results/ndr/timing.csv",
        figure=report("results/ndr/figures/comparison.png", category="NDR"),
        curves=report("results/ndr/figures/training_curves.png", category="NDR"),
    params:
        cfg=ndr_model_params,
        variants=NDR_VARIANTS,
    log:
        "results/logs/ndr_evaluate/ndr_evaluate.log",
    benchmark:
        "results/benchmarks/ndr_evaluate/ndr_evaluate.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_evaluate.py"


rule ndr_targets:
    input:
        metrics="results/ndr/metrics.csv",
        benchmarks=[path for path, _ in ndr_benchmarks()],
    output:
        targets="results/ndr/targets.csv",
    params:
        job_threads=[threads for _, threads in ndr_benchmarks()],
        cores=workflow.cores,
    log:
        "results/logs/ndr_targets/ndr_targets.log",
    benchmark:
        "results/benchmarks/ndr_targets/ndr_targets.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_targets.py"


rule ndr_relight:
    input:
        checkpoint="results/ndr/models/ndr.pt",
    output:
        csv="results/ndr/relighting.csv",
        figure=report("results/ndr/figures/relighting.png", category="NDR"),
    params:
        cfg=ndr_relight_params,
    log:
        "results/logs/ndr_relight/ndr_relight.log",
    benchmark:
        "results/benchmarks/ndr_relight/ndr_relight.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/ndr_relight.py"
