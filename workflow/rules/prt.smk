# DeepPRT (Li et al. 2019): meshes -> geometry images -> deformation sequences ->
# ray-traced SH transfer per frame -> a network per variant (prt_model.variants), object and
# material, the shipped variant copied to deepprt_{material}, MoMoPRT baseline,
# rendered-appearance evaluation, compression, timing and the paper's experiments.
# Helpers (params and input functions): workflow/rules/helpers/prt.smk.


# ---------------------------------------------------------------- data (paper 3.1, 3.2.2)
rule prt_probe:
    input:
        unpack(prt_probe_source),
    output:
        exr="results/prt/probes/{probe}.exr",
        sh="results/prt/probes/{probe}_sh.csv",
    log:
        "results/logs/prt_probe/{probe}.log",
    benchmark:
        "results/benchmarks/prt_probe/{probe}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_probe"),
    params:
        cfg=rule_params("prt_probe"),
    script:
        "../scripts/prt_probe.py"


rule prt_geometry_image:
    input:
        unpack(prt_object_source),
    output:
        gim="results/prt/{object}/geometry_image.npz",
        stats="results/prt/{object}/geometry_image.csv",
    log:
        "results/logs/prt_geometry_image/{object}.log",
    benchmark:
        "results/benchmarks/prt_geometry_image/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_geometry_image"),
    params:
        cfg=rule_params("prt_geometry_image"),
    script:
        "../scripts/prt_geometry_image.py"


rule prt_sequence:
    input:
        unpack(prt_sequence_files),
    output:
        seq="results/prt/{object}/sequence.npz",
    log:
        "results/logs/prt_sequence/{object}.log",
    benchmark:
        "results/benchmarks/prt_sequence/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_sequence"),
    params:
        cfg=rule_params("prt_sequence"),
    script:
        "../scripts/prt_sequence.py"


rule prt_transfer:
    input:
        seq="results/prt/{object}/sequence.npz",
        light=PRT_LIGHT,
    output:
        frames=directory("results/prt/{object}/{split}"),
        manifest="results/prt/{object}/{split}_manifest.csv",
    log:
        "results/logs/prt_transfer/{object}_{split}.log",
    benchmark:
        "results/benchmarks/prt_transfer/{object}_{split}.tsv"
    # DeepPRT's ground truth before the short jobs that fill the gaps.
    priority: 10
    conda:
        "../envs/neurender.yaml"
    # One thread: the objects' and splits' jobs run side by side, which keeps both cores
    # busier than one two-thread job at a time (those used 1.2 to 1.5 of 2 in the default run).
    threads: 1
    resources:
        **scheduler_resources("prt_transfer"),
        embree=1,
    params:
        cfg=rule_params("prt_transfer"),
    script:
        "../scripts/prt_transfer.py"


rule prt_noise_floor:
    input:
        seq="results/prt/{object}/sequence.npz",
        reference="results/prt/{object}/test",
        light=PRT_LIGHT,
    output:
        csv="results/prt/{object}/noise_floor.csv",
    log:
        "results/logs/prt_noise_floor/{object}.log",
    benchmark:
        "results/benchmarks/prt_noise_floor/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("prt_noise_floor"),
        embree=1,
    params:
        cfg=rule_params("prt_noise_floor"),
    script:
        "../scripts/prt_noise_floor.py"


rule prt_figure:
    input:
        frames="results/prt/{object}/test",
        light=PRT_LIGHT,
    output:
        png=report(
            "results/prt/figures/{object}_frames.png",
            category="DeepPRT",
            subcategory="data",
            labels={"object": "{object}", "figure": "test frames"},
        ),
    log:
        "results/logs/prt_figure/{object}.log",
    benchmark:
        "results/benchmarks/prt_figure/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_figure"),
    params:
        cfg=rule_params("prt_figure"),
    script:
        "../scripts/prt_figure.py"


rule prt_summary:
    input:
        gim=expand(
            "results/prt/{object}/geometry_image.csv", object=PRT_OBJECTS + ["plane"]
        ),
        manifests=expand(
            "results/prt/{object}/{split}_manifest.csv",
            object=PRT_OBJECTS,
            split=PRT_SPLITS,
        ),
        noise=expand("results/prt/{object}/noise_floor.csv", object=PRT_OBJECTS),
    output:
        data=report(
            "results/prt/data.csv",
            category="DeepPRT",
            subcategory="data",
            labels={"table": "data"},
        ),
        noise=report(
            "results/prt/noise_floor.csv",
            category="DeepPRT",
            subcategory="data",
            labels={"table": "noise floor"},
        ),
    log:
        "results/logs/prt_summary/prt_summary.log",
    benchmark:
        "results/benchmarks/prt_summary/prt_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_summary"),
    params:
        cfg=rule_params("prt_summary"),
    script:
        "../scripts/prt_summary.py"


rule prt_benchmark:
    input:
        seq=f"results/prt/{PRT_OBJECTS[0]}/sequence.npz",
        light=PRT_LIGHT,
    output:
        csv=report(
            "results/prt/benchmark.csv",
            category="DeepPRT",
            subcategory="data",
            labels={"table": "ray-tracing benchmark"},
        ),
    log:
        "results/logs/prt_benchmark/prt_benchmark.log",
    benchmark:
        "results/benchmarks/prt_benchmark/prt_benchmark.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("prt_benchmark"),
        embree=1,
    params:
        cfg=rule_params("prt_benchmark"),
    script:
        "../scripts/prt_benchmark.py"


rule prt_probes_figure:
    input:
        exrs=expand("results/prt/probes/{probe}.exr", probe=config["prt"]["probes"]),
        sh=expand("results/prt/probes/{probe}_sh.csv", probe=config["prt"]["probes"]),
    output:
        png=report(
            "results/prt/figures/light_probes.png",
            category="DeepPRT",
            subcategory="data",
            labels={"figure": "light probes"},
        ),
    log:
        "results/logs/prt_probes_figure/prt_probes_figure.log",
    benchmark:
        "results/benchmarks/prt_probes_figure/prt_probes_figure.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_probes_figure"),
    params:
        cfg=rule_params("prt_probes_figure"),
    script:
        "../scripts/prt_probes_figure.py"


# ---------------------------------------------------------------- models (paper 3.2, 4)


rule prt_train:
    input:
        unpack(prt_variant_training_files),
    output:
        checkpoint="results/prt/{object}/variants/{variant}_{material}.pt",
        loss="results/prt/{object}/variants/{variant}_{material}_loss.csv",
        tensorboard="results/tensorboard/prt/{object}_{variant}_{material}/run.json",
    log:
        "results/logs/prt_train/{object}_{variant}_{material}.log",
    benchmark:
        "results/benchmarks/prt_train/{object}_{variant}_{material}.tsv"
    priority: prt_train_priority
    conda:
        "../envs/neurender.yaml"
    threads: config["prt_model"]["threads"]
    resources:
        **scheduler_resources("prt_train"),
    params:
        cfg=rule_params("prt_train"),
    script:
        "../scripts/prt_train.py"


# One trained network as the graphs a renderer ships (ONNX, int8 ONNX): its own job, so that
# a change to the export reruns it and what reads the graphs, not the training.
rule prt_deploy:
    input:
        unpack(prt_deploy_files),
    output:
        onnx="results/prt/{object}/variants/{variant}_{material}.onnx",
        int8="results/prt/{object}/variants/{variant}_{material}_int8.onnx",
    log:
        "results/logs/prt_deploy/{object}_{variant}_{material}.log",
    benchmark:
        "results/benchmarks/prt_deploy/{object}_{variant}_{material}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_deploy"),
    params:
        cfg=rule_params("prt_deploy"),
    script:
        "../scripts/prt_deploy.py"


# The shipped network (prt_model.shipped): what relighting, the viewer and a renderer use.
# A file copy: local, so that a cluster run does not queue a job for it.
localrules:
    prt_ship,


rule prt_ship:
    input:
        unpack(prt_shipped_files),
    output:
        checkpoint="results/prt/{object}/deepprt_{material}.pt",
        onnx="results/prt/{object}/deepprt_{material}.onnx",
        int8="results/prt/{object}/deepprt_{material}_int8.onnx",
    log:
        "results/logs/prt_ship/{object}_{material}.log",
    benchmark:
        "results/benchmarks/prt_ship/{object}_{material}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_ship"),
    params:
        cfg=rule_params("prt_ship"),
    script:
        "../scripts/prt_ship.py"


rule prt_momoprt:
    input:
        unpack(prt_training_files),
    output:
        model="results/prt/{object}/momoprt_{material}.npz",
    log:
        "results/logs/prt_momoprt/{object}_{material}.log",
    benchmark:
        "results/benchmarks/prt_momoprt/{object}_{material}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_momoprt"),
    params:
        cfg=rule_params("prt_momoprt"),
    script:
        "../scripts/prt_momoprt.py"


rule prt_evaluate:
    input:
        unpack(prt_evaluation_files),
        **prt_variant_files("pt"),
        **prt_variant_files("onnx"),
        **prt_variant_files("int8.onnx"),
        **prt_momoprt_files(),
        light=PRT_LIGHT,
    output:
        metrics="results/prt/{object}/metrics.csv",
        frames="results/prt/{object}/metrics_frames.csv",
        figure=report(
            "results/prt/figures/{object}_prediction.png",
            category="DeepPRT",
            subcategory="models",
            labels={"object": "{object}", "figure": "prediction vs ground truth"},
        ),
    log:
        "results/logs/prt_evaluate/{object}.log",
    benchmark:
        "results/benchmarks/prt_evaluate/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing (prt_equal_quality times), so it runs beside another job.
    threads: 1
    resources:
        **scheduler_resources("prt_evaluate"),
        embree=1,
    params:
        cfg=rule_params("prt_evaluate"),
    script:
        "../scripts/prt_evaluate.py"


rule prt_equal_quality:
    input:
        unpack(prt_test_files),
        **prt_variant_files("pt"),
        **prt_variant_files("onnx"),
        **prt_variant_files("int8.onnx"),
        light=PRT_LIGHT,
        frames="results/prt/{object}/metrics_frames.csv",
    output:
        equal_quality="results/prt/{object}/equal_quality.csv",
        deployment="results/prt/{object}/deployment.csv",
    log:
        "results/logs/prt_equal_quality/{object}.log",
    benchmark:
        "results/benchmarks/prt_equal_quality/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    # Every core: the networks and the ray tracer are timed on the same threads, alone.
    threads: workflow.cores
    resources:
        **scheduler_resources("prt_equal_quality"),
        embree=1,
    params:
        cfg=rule_params("prt_equal_quality"),
    script:
        "../scripts/prt_equal_quality.py"


rule prt_model_summary:
    input:
        **prt_variant_files("pt", PRT_OBJECTS),
        **prt_variant_files("onnx", PRT_OBJECTS),
        **prt_variant_files("loss.csv", PRT_OBJECTS),
        **prt_shipped_summary_files(),
        metrics=expand("results/prt/{object}/metrics.csv", object=PRT_OBJECTS),
        equal_quality=expand(
            "results/prt/{object}/equal_quality.csv", object=PRT_OBJECTS
        ),
        deployment=expand("results/prt/{object}/deployment.csv", object=PRT_OBJECTS)
        + expand("results/prt/{x}/experiment_deployment.csv", x=PRT_EXPERIMENTS),
    output:
        metrics=report(
            "results/prt/metrics.csv",
            category="DeepPRT",
            subcategory="models",
            labels={"table": "metrics"},
        ),
        compression=report(
            "results/prt/compression.csv",
            category="DeepPRT",
            subcategory="models",
            labels={"table": "compression"},
        ),
        equal_quality=report(
            "results/prt/equal_quality.csv",
            category="DeepPRT",
            subcategory="models",
            labels={"table": "equal quality"},
        ),
        deployment="results/prt/deployment.csv",
        loss=report(
            "results/prt/figures/loss_curves.png",
            category="DeepPRT",
            subcategory="models",
            labels={"figure": "training curves"},
        ),
        equal_quality_figure=report(
            "results/prt/figures/equal_quality.png",
            category="DeepPRT",
            subcategory="models",
            labels={"figure": "equal quality"},
        ),
    log:
        "results/logs/prt_model_summary/prt_model_summary.log",
    benchmark:
        "results/benchmarks/prt_model_summary/prt_model_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_model_summary"),
    params:
        cfg=rule_params("prt_model_summary"),
    script:
        "../scripts/prt_model_summary.py"


rule prt_targets:
    input:
        metrics="results/prt/metrics.csv",
        equal_quality="results/prt/equal_quality.csv",
        experiments=expand("results/prt/{x}/experiment.csv", x=PRT_EXPERIMENTS),
        unseen="results/prt/unseen.csv",
    output:
        targets=report(
            "results/prt/targets.csv",
            category="DeepPRT",
            subcategory="models",
            labels={"table": "targets"},
        ),
    log:
        "results/logs/prt_targets/prt_targets.log",
    benchmark:
        "results/benchmarks/prt_targets/prt_targets.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_targets"),
    params:
        cfg=rule_params("prt_targets"),
    script:
        "../scripts/prt_targets.py"


rule prt_experiment:
    input:
        unpack(prt_test_files),
        **prt_variant_files("pt", materials=["diffuse"]),
        **prt_variant_files("onnx", materials=["diffuse"]),
        momoprt="results/prt/{object}/momoprt_diffuse.npz",
        light=PRT_LIGHT,
    output:
        csv=report(
            "results/prt/{object}/experiment.csv",
            category="DeepPRT",
            subcategory="experiments",
            labels={"experiment": "{object}", "table": "paper Fig. 6"},
        ),
        deployment="results/prt/{object}/experiment_deployment.csv",
        figure=report(
            "results/prt/figures/{object}.png",
            category="DeepPRT",
            subcategory="experiments",
            labels={"experiment": "{object}", "figure": "paper Fig. 6"},
        ),
    log:
        "results/logs/prt_experiment/{object}.log",
    benchmark:
        "results/benchmarks/prt_experiment/{object}.tsv"
    wildcard_constraints:
        object="|".join(EXPERIMENTS),
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("prt_experiment"),
    params:
        cfg=rule_params("prt_experiment"),
    script:
        "../scripts/prt_experiment.py"


rule prt_unseen:
    input:
        **prt_variant_files("pt"),
        **prt_variant_files("onnx"),
        **prt_momoprt_files(),
        gim="results/prt/{object}/geometry_image.npz",
        seq="results/prt/{object}/sequence.npz",
        light=PRT_LIGHT,
    output:
        csv=report(
            "results/prt/{object}/unseen.csv",
            category="DeepPRT",
            subcategory="unseen deformations",
            labels={"object": "{object}", "table": "unseen deformations"},
        ),
        figure=report(
            "results/prt/figures/{object}_unseen.png",
            category="DeepPRT",
            subcategory="unseen deformations",
            labels={
                "object": "{object}",
                "figure": "error against strength (Fig. 6 generalised)",
            },
        ),
    log:
        "results/logs/prt_unseen/{object}.log",
    benchmark:
        "results/benchmarks/prt_unseen/{object}.tsv"
    wildcard_constraints:
        object="|".join(PRT_OBJECTS),
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("prt_unseen"),
        embree=1,
    params:
        cfg=rule_params("prt_unseen"),
    script:
        "../scripts/prt_unseen.py"


rule prt_unseen_summary:
    input:
        csvs=expand("results/prt/{object}/unseen.csv", object=PRT_OBJECTS),
    output:
        csv=report(
            "results/prt/unseen.csv",
            category="DeepPRT",
            subcategory="unseen deformations",
            labels={"table": "unseen deformations"},
        ),
    log:
        "results/logs/prt_unseen_summary/prt_unseen_summary.log",
    benchmark:
        "results/benchmarks/prt_unseen_summary/prt_unseen_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_unseen_summary"),
    params:
        cfg=rule_params("prt_unseen_summary"),
    script:
        "../scripts/prt_unseen_summary.py"


rule prt_relight:
    input:
        unpack(prt_test_files),
        deepprt="results/prt/{object}/deepprt_diffuse.pt",
        onnx="results/prt/{object}/deepprt_diffuse.onnx",
        probes=expand(
            "results/prt/probes/{probe}_sh.csv", probe=config["prt"]["probes"]
        ),
    output:
        csv="results/prt/{object}/relight.csv",
        figure=report(
            "results/prt/figures/{object}_relight.png",
            category="DeepPRT",
            subcategory="models",
            labels={"object": "{object}", "figure": "relighting (paper Fig. 2)"},
        ),
    log:
        "results/logs/prt_relight/{object}.log",
    benchmark:
        "results/benchmarks/prt_relight/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_relight"),
    params:
        cfg=rule_params("prt_relight"),
    script:
        "../scripts/prt_relight.py"


# ---------------------------------------------------------------- report views


rule prt_viewer:
    input:
        unpack(prt_test_files),
        deepprt="results/prt/{object}/deepprt_diffuse.pt",
        onnx="results/prt/{object}/deepprt_diffuse.onnx",
        momoprt="results/prt/{object}/momoprt_diffuse.npz",
        probes=expand(
            "results/prt/probes/{probe}_sh.csv", probe=config["prt"]["probes"]
        ),
    output:
        viewer="results/prt/viewers/{object}.json",
    log:
        "results/logs/prt_viewer/{object}.log",
    benchmark:
        "results/benchmarks/prt_viewer/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_viewer"),
    params:
        cfg=rule_params("prt_viewer"),
    script:
        "../scripts/prt_viewer.py"


rule prt_mesh_figure:
    input:
        gim="results/prt/{object}/geometry_image.npz",
        seq="results/prt/{object}/sequence.npz",
    output:
        png=report(
            "results/prt/figures/{object}_meshes.png",
            category="DeepPRT",
            subcategory="data",
            labels={"object": "{object}", "figure": "geometry image and frames (3D)"},
        ),
    log:
        "results/logs/prt_mesh_figure/{object}.log",
    benchmark:
        "results/benchmarks/prt_mesh_figure/{object}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("prt_mesh_figure"),
    params:
        cfg=rule_params("prt_mesh_figure"),
    script:
        "../scripts/prt_mesh_figure.py"
