# NDR (Suppan et al. 2021): procedural scenes, Mitsuba ground truth, two-decoder U-Net,
# ablations and baselines.
# Helpers (params and input functions): workflow/rules/helpers/ndr.smk.


rule ndr_data:
    input:
        unpack(ndr_user_probe_files),
    output:
        samples=directory("results/ndr/{split}"),
        manifest="results/ndr/{split}_manifest.csv",
        lighting="results/ndr/{split}_lighting.csv",
    log:
        "results/logs/ndr_data/{split}.log",
    benchmark:
        "results/benchmarks/ndr_data/{split}.tsv"
    wildcard_constraints:
        split="|".join(NDR_SPLITS),
    # NDR's training is the second-longest chain of one-thread jobs.
    priority: 15
    conda:
        "../envs/neurender.yaml"
    # One thread: the splits' jobs run side by side, which keeps both cores busier than one
    # two-thread job at a time (those used 1.2 to 1.5 of the 2 cores in the default run).
    threads: 1
    resources:
        **scheduler_resources("ndr_data"),
    params:
        cfg=rule_params("ndr_data"),
    script:
        "../scripts/ndr_data.py"


rule ndr_summary:
    input:
        manifests=expand("results/ndr/{split}_manifest.csv", split=ndr_splits()),
        example="results/ndr/test",
    output:
        csv=report(
            "results/ndr/data.csv",
            category="NDR",
            labels={"table": "data"},
        ),
        furnace=report(
            "results/ndr/furnace.csv",
            category="NDR",
            labels={"table": "furnace"},
        ),
        figure=report(
            "results/ndr/figures/buffers.png",
            category="NDR",
            labels={"figure": "buffers"},
        ),
    log:
        "results/logs/ndr_summary/ndr_summary.log",
    benchmark:
        "results/benchmarks/ndr_summary/ndr_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("ndr_summary"),
    params:
        cfg=rule_params("ndr_summary"),
    script:
        "../scripts/ndr_summary.py"


rule ndr_train:
    input:
        unpack(ndr_train_inputs),
    output:
        checkpoint="results/ndr/models/{variant}.pt",
        loss="results/ndr/models/{variant}_loss.csv",
        tensorboard="results/tensorboard/ndr/{variant}/run.json",
    log:
        "results/logs/ndr_train/{variant}.log",
    benchmark:
        "results/benchmarks/ndr_train/{variant}.tsv"
    wildcard_constraints:
        variant="|".join(NDR_VARIANT_TABLE),
    # The longest one-thread jobs first, so none runs alone at the end of the DAG.
    priority: 15
    conda:
        "../envs/neurender.yaml"
    threads: config["ndr_model"]["threads"]
    resources:
        **scheduler_resources("ndr_train"),
    params:
        cfg=rule_params("ndr_train"),
    script:
        "../scripts/ndr_train.py"


rule ndr_evaluate:
    input:
        unpack(ndr_evaluate_inputs),
    output:
        metrics=report(
            "results/ndr/metrics.csv",
            category="NDR",
            labels={"table": "metrics"},
        ),
        samples="results/ndr/metrics_samples.csv",
        timing=report(
            "results/ndr/timing.csv",
            category="NDR",
            labels={"table": "timing"},
        ),
        figure=report(
            "results/ndr/figures/comparison.png",
            category="NDR",
            labels={"figure": "comparison"},
        ),
        curves=report(
            "results/ndr/figures/training_curves.png",
            category="NDR",
            labels={"figure": "training curves"},
        ),
    log:
        "results/logs/ndr_evaluate/ndr_evaluate.log",
    benchmark:
        "results/benchmarks/ndr_evaluate/ndr_evaluate.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("ndr_evaluate"),
    params:
        cfg=rule_params("ndr_evaluate"),
    script:
        "../scripts/ndr_evaluate.py"


rule ndr_deploy:
    input:
        unpack(ndr_deploy_inputs),
    output:
        onnx=expand("results/ndr/onnx/{variant}.onnx", variant=NDR_VARIANTS),
        table="results/ndr/deployment.csv",
        shipped="results/ndr/onnx/ndr_shipped.onnx",
        shipped_int8="results/ndr/onnx/ndr_shipped_int8.onnx",
    log:
        "results/logs/ndr_deploy/ndr_deploy.log",
    benchmark:
        "results/benchmarks/ndr_deploy/ndr_deploy.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("ndr_deploy"),
    params:
        cfg=rule_params("ndr_deploy"),
    script:
        "../scripts/ndr_deploy.py"


rule ndr_equal_quality:
    input:
        unpack(ndr_equal_quality_inputs),
        checkpoint="results/ndr/models/ndr.pt",
        samples="results/ndr/metrics_samples.csv",
        graph="results/ndr/onnx/ndr_shipped.onnx",
        graph_int8="results/ndr/onnx/ndr_shipped_int8.onnx",
    output:
        table=report(
            "results/ndr/equal_quality.csv",
            category="NDR",
            labels={"table": "equal quality"},
        ),
        figure=report(
            "results/ndr/figures/equal_quality.png",
            category="NDR",
            labels={"figure": "equal quality"},
        ),
    log:
        "results/logs/ndr_equal_quality/ndr_equal_quality.log",
    benchmark:
        "results/benchmarks/ndr_equal_quality/ndr_equal_quality.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("ndr_equal_quality"),
    params:
        cfg=rule_params("ndr_equal_quality"),
    script:
        "../scripts/ndr_equal_quality.py"


rule ndr_targets:
    input:
        metrics="results/ndr/metrics.csv",
        equal_quality="results/ndr/equal_quality.csv",
    output:
        targets=report(
            "results/ndr/targets.csv",
            category="NDR",
            labels={"table": "targets"},
        ),
    log:
        "results/logs/ndr_targets/ndr_targets.log",
    benchmark:
        "results/benchmarks/ndr_targets/ndr_targets.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("ndr_targets"),
    params:
        cfg=rule_params("ndr_targets"),
    script:
        "../scripts/ndr_targets.py"


rule ndr_relight:
    input:
        unpack(ndr_user_probe_files),
        checkpoint="results/ndr/models/ndr.pt",
    output:
        csv=report(
            "results/ndr/relighting.csv",
            category="NDR",
            labels={"table": "relighting"},
        ),
        figure=report(
            "results/ndr/figures/relighting.png",
            category="NDR",
            labels={"figure": "relighting"},
        ),
    log:
        "results/logs/ndr_relight/ndr_relight.log",
    benchmark:
        "results/benchmarks/ndr_relight/ndr_relight.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("ndr_relight"),
    params:
        cfg=rule_params("ndr_relight"),
    script:
        "../scripts/ndr_relight.py"


rule ndr_user_objects:
    input:
        unpack(ndr_user_object_files),
        checkpoint="results/ndr/models/ndr.pt",
    output:
        table=report(
            "results/ndr/user_objects.csv",
            category="NDR",
            labels={"table": "your objects"},
        ),
        maps="results/ndr/user_objects_maps.csv",
        figure=report(
            "results/ndr/figures/your_objects.png",
            category="NDR",
            labels={"figure": "your objects"},
        ),
    log:
        "results/logs/ndr_user_objects/ndr_user_objects.log",
    benchmark:
        "results/benchmarks/ndr_user_objects/ndr_user_objects.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("ndr_user_objects"),
    params:
        cfg=rule_params("ndr_user_objects"),
    script:
        "../scripts/ndr_user_objects.py"


rule ndr_viewer:
    input:
        unpack(ndr_user_probe_files),
        checkpoint="results/ndr/models/ndr.pt",
    output:
        viewer="results/ndr/viewers/relight.json",
    log:
        "results/logs/ndr_viewer/ndr_viewer.log",
    benchmark:
        "results/benchmarks/ndr_viewer/ndr_viewer.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("ndr_viewer"),
    params:
        cfg=rule_params("ndr_viewer"),
    script:
        "../scripts/ndr_viewer.py"
