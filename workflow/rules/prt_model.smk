# DeepPRT model (paper 3.2, 4): ResNet U-Net per object and material, MoMoPRT baseline,
# rendered-appearance evaluation against the clean test reference, compression and timing.


def prt_report_tables():
    tables = ("targets", "metrics", "compression", "data", "noise_floor", "benchmark")
    return expand("results/prt/{table}.csv", table=tables) + prt_experiment_tables()


def prt_report_figures():
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
    return frames + experiments + fixed




rule prt_train:
    input:
        unpack(prt_split_inputs),
    output:
        checkpoint="results/prt/{object}/deepprt_{material}.pt",
        onnx="results/prt/{object}/deepprt_{material}.onnx",
        loss="results/prt/{object}/deepprt_{material}_loss.csv",
    params:
        cfg=prt_train_params(),
    log:
        "results/logs/prt_train/{object}_{material}.log",
    benchmark:
        "results/benchmarks/prt_train/{object}_{material}.tsv"
    threads: config["prt_model"]["threads"]
    priority: prt_train_priority
    resources:
        gpu=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_train.py"


rule prt_momoprt:
    input:
        unpack(prt_split_inputs),
    output:
        model="results/prt/{object}/momoprt_{material}.npz",
    params:
        cfg=prt_momoprt_params(),
    log:
        "results/logs/prt_momoprt/{object}_{material}.log",
    benchmark:
        "results/benchmarks/prt_momoprt/{object}_{material}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_momoprt.py"


rule prt_evaluate:
    input:
        unpack(prt_split_inputs),
        deepprt=expand("results/prt/{{object}}/deepprt_{material}.pt", material=PRT_MATERIALS),
        onnx=expand("results/prt/{{object}}/deepprt_{material}.onnx", material=PRT_MATERIALS),
        momoprt=expand("results/prt/{{object}}/momoprt_{material}.npz", material=PRT_MATERIALS),
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        metrics="results/prt/{object}/metrics.csv",
        frames="results/prt/{object}/metrics_frames.csv",
        figure=report("results/prt/figures/{object}_prediction.png", category="DeepPRT"),
    params:
        cfg=prt_model_params(),
    log:
        "results/logs/prt_evaluate/{object}.log",
    benchmark:
        "results/benchmarks/prt_evaluate/{object}.tsv"
    threads: workflow.cores
    resources:
        embree=1,
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_evaluate.py"


rule prt_model_summary:
    input:
        metrics=expand("results/prt/{object}/metrics.csv", object=config["prt"]["objects"]),
        checkpoints=expand(
            "results/prt/{object}/deepprt_{material}.pt", object=config["prt"]["objects"], material=PRT_MATERIALS
        ),
        onnx=expand(
            "results/prt/{object}/deepprt_{material}.onnx",
            object=config["prt"]["objects"],
            material=PRT_MATERIALS,
        ),
        losses=expand(
            "results/prt/{object}/deepprt_{material}_loss.csv",
            object=config["prt"]["objects"],
            material=PRT_MATERIALS,
        ),
        frames=expand("results/prt/{object}/{split}", object=config["prt"]["objects"], split=PRT_SPLITS),
        experiments=prt_experiment_tables(),
    output:
        metrics="results/prt/metrics.csv",
        compression="results/prt/compression.csv",
        targets="results/prt/targets.csv",
        loss=report("results/prt/figures/loss_curves.png", category="DeepPRT"),
        equal_quality=report("results/prt/figures/equal_quality.png", category="DeepPRT"),
    params:
        cfg=prt_model_params(),
        objects=config["prt"]["objects"],
    log:
        "results/logs/prt_model_summary/prt_model_summary.log",
    benchmark:
        "results/benchmarks/prt_model_summary/prt_model_summary.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_model_summary.py"


rule prt_experiment:
    input:
        unpack(prt_split_inputs),
        deepprt="results/prt/{object}/deepprt_diffuse.pt",
        onnx="results/prt/{object}/deepprt_diffuse.onnx",
        momoprt="results/prt/{object}/momoprt_diffuse.npz",
        light=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["light"]),
    output:
        csv="results/prt/{object}/experiment.csv",
        figure=report("results/prt/figures/{object}.png", category="DeepPRT"),
    params:
        cfg=prt_model_params(),
    wildcard_constraints:
        object="head_linear|head_excluded",
    log:
        "results/logs/prt_experiment/{object}.log",
    benchmark:
        "results/benchmarks/prt_experiment/{object}.tsv"
    threads: workflow.cores
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_experiment.py"


rule prt_relight:
    input:
        unpack(prt_split_inputs),
        deepprt="results/prt/{object}/deepprt_diffuse.pt",
        onnx="results/prt/{object}/deepprt_diffuse.onnx",
        probes=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["probes"]),
    output:
        csv="results/prt/{object}/relight.csv",
        figure=report("results/prt/figures/{object}_relight.png", category="DeepPRT"),
    params:
        cfg=prt_model_params(),
    log:
        "results/logs/prt_relight/{object}.log",
    benchmark:
        "results/benchmarks/prt_relight/{object}.tsv"
    threads: 1
    conda:
        "../envs/neurender.yaml"
    script:
        "../scripts/prt_relight.py"
