# Image-space metaballs (thesis 4.1, 5.2): circle inputs and ray-marched G-buffers as AB PNGs.


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


def metaballs_report_tables():
    return expand("results/metaballs/{table}.csv", table=("targets", "metrics", "timing", "data"))


def metaballs_report_figures():
    names = ("comparison", "accuracy_by_scene", "demo_network_vs_raymarch", "temporal_stability")
    names += ("frame_time_vs_balls", "examples")
    return expand("results/metaballs/figures/{name}.png", name=names) + ["results/metaballs/figures/demo.gif"]




rule metaballs_examples:
    output:
        examples=directory("results/metaballs/{split}"),
        manifest="results/metaballs/{split}_manifest.csv",
        balls="results/metaballs/{split}_balls.csv",
    params:
        cfg=metaballs_params(),
    log:
        "results/logs/metaballs_examples/{split}.log",
    benchmark:
        "results/benchmarks/metaballs_examples/{split}.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_examples.py"


rule metaballs_summary:
    input:
        manifests=expand("results/metaballs/{split}_manifest.csv", split=METABALL_SPLITS),
        examples=expand("results/metaballs/{split}", split=METABALL_SPLITS),
    output:
        csv="results/metaballs/data.csv",
        figure=report("results/metaballs/figures/examples.png", category="Metaballs"),
    log:
        "results/logs/metaballs_summary/metaballs_summary.log",
    benchmark:
        "results/benchmarks/metaballs_summary/metaballs_summary.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_summary.py"


rule metaballs_train:
    input:
        train_dir="results/metaballs/train",
        train_manifest="results/metaballs/train_manifest.csv",
        train_balls="results/metaballs/train_balls.csv",
        val_dir="results/metaballs/val",
        val_manifest="results/metaballs/val_manifest.csv",
        val_balls="results/metaballs/val_balls.csv",
    output:
        checkpoint="results/metaballs/{variant}.pt",
        loss="results/metaballs/{variant}_loss.csv",
    params:
        cfg=metaballs_model_params,
    log:
        "results/logs/metaballs_train/{variant}.log",
    benchmark:
        "results/benchmarks/metaballs_train/{variant}.tsv"
    threads: config["metaballs_model"]["threads"]
    resources:
        gpu=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_train.py"


rule metaballs_evaluate:
    input:
        test_dir="results/metaballs/test",
        test_manifest="results/metaballs/test_manifest.csv",
        test_balls="results/metaballs/test_balls.csv",
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALL_VARIANTS),
    output:
        metrics="results/metaballs/metrics.csv",
        examples="results/metaballs/metrics_examples.csv",
        by_scene="results/metaballs/accuracy_by_scene.csv",
        figure=report("results/metaballs/figures/comparison.png", category="Metaballs"),
        scene_figure=report("results/metaballs/figures/accuracy_by_scene.png", category="Metaballs"),
    params:
        cfg=metaballs_model_params,
        variants=METABALL_VARIANTS,
    log:
        "results/logs/metaballs_evaluate/metaballs_evaluate.log",
    benchmark:
        "results/benchmarks/metaballs_evaluate/metaballs_evaluate.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_evaluate.py"


rule metaballs_demo:
    input:
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALL_DEMO_VARIANTS),
    output:
        frames="results/metaballs/demo_frames.csv",
        timing="results/metaballs/timing.csv",
        balls="results/metaballs/frame_time_vs_balls.csv",
        balls_png=report("results/metaballs/figures/frame_time_vs_balls.png", category="Metaballs"),
        gif=report("results/metaballs/figures/demo.gif", category="Metaballs"),
        strip=report("results/metaballs/figures/demo_network_vs_raymarch.png", category="Metaballs"),
        stability=report("results/metaballs/figures/temporal_stability.png", category="Metaballs"),
    params:
        cfg=metaballs_model_params,
        variants=METABALL_DEMO_VARIANTS,
    log:
        "results/logs/metaballs_demo/metaballs_demo.log",
    benchmark:
        "results/benchmarks/metaballs_demo/metaballs_demo.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_demo.py"


rule metaballs_targets:
    input:
        metrics="results/metaballs/metrics.csv",
        timing="results/metaballs/timing.csv",
    output:
        targets="results/metaballs/targets.csv",
    params:
        paper_scale=config["metaballs"]["width"] >= 512,
    log:
        "results/logs/metaballs_targets/metaballs_targets.log",
    benchmark:
        "results/benchmarks/metaballs_targets/metaballs_targets.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/metaballs_targets.py"
