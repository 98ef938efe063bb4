# Image-space metaballs (thesis 4.1, 5.2): circle inputs and ray-marched G-buffers as AB
# PNGs, three networks, their evaluation on held-out scenes and an animated, timed demo.
# Helpers (params and input functions): workflow/rules/helpers/metaballs.smk.


rule metaballs_examples:
    output:
        examples=directory("results/metaballs/{split}"),
        manifest="results/metaballs/{split}_manifest.csv",
        balls="results/metaballs/{split}_balls.csv",
    log:
        "results/logs/metaballs_examples/{split}.log",
    benchmark:
        "results/benchmarks/metaballs_examples/{split}.tsv"
    wildcard_constraints:
        split="|".join(METABALLS_SPLITS),
    # The metaballs' training is the longest chain of one-thread jobs: start it first.
    priority: 20
    conda:
        "../envs/neurender.yaml"
    # One thread: the splits' jobs run side by side, which keeps both cores busier than one
    # two-thread job at a time (those used 1.2 to 1.5 of the 2 cores in the default run).
    threads: 1
    resources:
        **scheduler_resources("metaballs_examples"),
    params:
        cfg=rule_params("metaballs_examples"),
    script:
        "../scripts/metaballs_examples.py"


rule metaballs_summary:
    input:
        manifests=expand(
            "results/metaballs/{split}_manifest.csv", split=METABALLS_SPLITS
        ),
        examples=expand("results/metaballs/{split}", split=METABALLS_SPLITS),
    output:
        csv=report(
            "results/metaballs/data.csv",
            category="Metaballs",
            labels={"table": "data"},
        ),
        figure=report(
            "results/metaballs/figures/examples.png",
            category="Metaballs",
            labels={"figure": "AB examples"},
        ),
    log:
        "results/logs/metaballs_summary/metaballs_summary.log",
    benchmark:
        "results/benchmarks/metaballs_summary/metaballs_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("metaballs_summary"),
    params:
        cfg=rule_params("metaballs_summary"),
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
        tensorboard="results/tensorboard/metaballs/{variant}/run.json",
    log:
        "results/logs/metaballs_train/{variant}.log",
    benchmark:
        "results/benchmarks/metaballs_train/{variant}.tsv"
    wildcard_constraints:
        variant="|".join(METABALLS_VARIANTS),
    # The longest one-thread jobs first, so none runs alone at the end of the DAG.
    priority: 20
    conda:
        "../envs/neurender.yaml"
    threads: config["metaballs_model"]["threads"]
    resources:
        **scheduler_resources("metaballs_train"),
    params:
        cfg=rule_params("metaballs_train"),
    script:
        "../scripts/metaballs_train.py"


rule metaballs_evaluate:
    input:
        test_dir="results/metaballs/test",
        test_manifest="results/metaballs/test_manifest.csv",
        test_balls="results/metaballs/test_balls.csv",
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
    output:
        metrics=report(
            "results/metaballs/metrics.csv",
            category="Metaballs",
            labels={"table": "metrics"},
        ),
        examples="results/metaballs/metrics_examples.csv",
        by_scene="results/metaballs/accuracy_by_scene.csv",
        figure=report(
            "results/metaballs/figures/comparison.png",
            category="Metaballs",
            labels={"figure": "held-out comparison"},
        ),
        scene_figure=report(
            "results/metaballs/figures/accuracy_by_scene.png",
            category="Metaballs",
            labels={"figure": "accuracy by scene"},
        ),
    log:
        "results/logs/metaballs_evaluate/metaballs_evaluate.log",
    benchmark:
        "results/benchmarks/metaballs_evaluate/metaballs_evaluate.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("metaballs_evaluate"),
    params:
        cfg=rule_params("metaballs_evaluate"),
    script:
        "../scripts/metaballs_evaluate.py"


rule metaballs_equal_quality:
    input:
        test_dir="results/metaballs/test",
        test_manifest="results/metaballs/test_manifest.csv",
        test_balls="results/metaballs/test_balls.csv",
        examples="results/metaballs/metrics_examples.csv",
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
        onnx=expand("results/metaballs/onnx/{variant}.onnx", variant=METABALLS_VARIANTS),
    output:
        table=report(
            "results/metaballs/equal_quality.csv",
            category="Metaballs",
            labels={"table": "equal quality"},
        ),
        figure=report(
            "results/metaballs/figures/equal_quality.png",
            category="Metaballs",
            labels={"figure": "equal quality"},
        ),
    log:
        "results/logs/metaballs_equal_quality/metaballs_equal_quality.log",
    benchmark:
        "results/benchmarks/metaballs_equal_quality/metaballs_equal_quality.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("metaballs_equal_quality"),
    params:
        cfg=rule_params("metaballs_equal_quality"),
    script:
        "../scripts/metaballs_equal_quality.py"


rule metaballs_demo:
    input:
        checkpoints=expand(
            "results/metaballs/{variant}.pt", variant=METABALLS_DEMO_VARIANTS
        ),
        onnx=expand(
            "results/metaballs/onnx/{variant}.onnx", variant=METABALLS_DEMO_VARIANTS
        ),
    output:
        frames="results/metaballs/demo_frames.csv",
        timing=report(
            "results/metaballs/timing.csv",
            category="Metaballs",
            labels={"table": "timing"},
        ),
        balls="results/metaballs/frame_time_vs_balls.csv",
        balls_png=report(
            "results/metaballs/figures/frame_time_vs_balls.png",
            category="Metaballs",
            labels={"figure": "frame time vs balls"},
        ),
        gif=report(
            "results/metaballs/figures/demo.gif",
            category="Metaballs",
            labels={"figure": "demo animation"},
        ),
        strip=report(
            "results/metaballs/figures/demo_network_vs_raymarch.png",
            category="Metaballs",
            labels={"figure": "demo frames"},
        ),
        stability=report(
            "results/metaballs/figures/temporal_stability.png",
            category="Metaballs",
            labels={"figure": "temporal stability"},
        ),
    log:
        "results/logs/metaballs_demo/metaballs_demo.log",
    benchmark:
        "results/benchmarks/metaballs_demo/metaballs_demo.tsv"
    conda:
        "../envs/neurender.yaml"
    # one thread: frames are timed as the equal-quality sweep's, marcher and networks alike
    threads: 1
    resources:
        **scheduler_resources("metaballs_demo"),
    params:
        cfg=rule_params("metaballs_demo"),
    script:
        "../scripts/metaballs_demo.py"


rule metaballs_deploy:
    input:
        test_balls="results/metaballs/test_balls.csv",
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
    output:
        onnx=expand("results/metaballs/onnx/{variant}.onnx", variant=METABALLS_VARIANTS),
        table="results/metaballs/deployment.csv",
    log:
        "results/logs/metaballs_deploy/metaballs_deploy.log",
    benchmark:
        "results/benchmarks/metaballs_deploy/metaballs_deploy.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: the graphs are timed as the metaballs' other timings (equal quality,
    # demo), and the jobs that read them need not wait for both cores to be free.
    threads: 1
    resources:
        **scheduler_resources("metaballs_deploy"),
    params:
        cfg=rule_params("metaballs_deploy"),
    script:
        "../scripts/metaballs_deploy.py"


rule metaballs_targets:
    input:
        metrics="results/metaballs/metrics.csv",
        timing="results/metaballs/timing.csv",
        equal_quality="results/metaballs/equal_quality.csv",
    output:
        targets=report(
            "results/metaballs/targets.csv",
            category="Metaballs",
            labels={"table": "targets"},
        ),
    log:
        "results/logs/metaballs_targets/metaballs_targets.log",
    benchmark:
        "results/benchmarks/metaballs_targets/metaballs_targets.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("metaballs_targets"),
    params:
        cfg=rule_params("metaballs_targets"),
    script:
        "../scripts/metaballs_targets.py"


rule metaballs_user_scenes:
    input:
        scenes=metaballs_user_scenes_file(),
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
    output:
        table=report(
            "results/metaballs/user_scenes.csv",
            category="Metaballs",
            labels={"table": "your scenes"},
        ),
        figure=report(
            "results/metaballs/figures/your_scenes.png",
            category="Metaballs",
            labels={"figure": "your scenes"},
        ),
    log:
        "results/logs/metaballs_user_scenes/metaballs_user_scenes.log",
    benchmark:
        "results/benchmarks/metaballs_user_scenes/metaballs_user_scenes.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("metaballs_user_scenes"),
    params:
        cfg=rule_params("metaballs_user_scenes"),
    script:
        "../scripts/metaballs_user_scenes.py"


rule metaballs_viewer:
    input:
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
    output:
        viewer="results/metaballs/viewers/demo.json",
    log:
        "results/logs/metaballs_viewer/metaballs_viewer.log",
    benchmark:
        "results/benchmarks/metaballs_viewer/metaballs_viewer.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread: it times nothing, so it runs beside another job instead of alone on
    # both cores (two threads used about 1.4 of them).
    threads: 1
    resources:
        **scheduler_resources("metaballs_viewer"),
    params:
        cfg=rule_params("metaballs_viewer"),
    script:
        "../scripts/metaballs_viewer.py"


rule metaballs_scale:
    input:
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
        onnx=expand("results/metaballs/onnx/{variant}.onnx", variant=METABALLS_VARIANTS),
    output:
        rows="results/metaballs/scale.csv",
        equal_quality=report(
            "results/metaballs/scale_equal_quality.csv",
            category="Metaballs",
            labels={"table": "equal quality at scale"},
        ),
        figure=report(
            "results/metaballs/figures/scale.png",
            category="Metaballs",
            labels={"figure": "cost and quality against the number of balls"},
        ),
    log:
        "results/logs/metaballs_scale/metaballs_scale.log",
    benchmark:
        "results/benchmarks/metaballs_scale/metaballs_scale.tsv"
    conda:
        "../envs/neurender.yaml"
    # One thread, as every other timing of the stage.
    threads: 1
    resources:
        **scheduler_resources("metaballs_scale"),
    params:
        cfg=rule_params("metaballs_scale"),
    script:
        "../scripts/metaballs_scale.py"


rule metaballs_real_scenes:
    input:
        checkpoints=expand("results/metaballs/{variant}.pt", variant=METABALLS_VARIANTS),
        onnx=expand("results/metaballs/onnx/{variant}.onnx", variant=METABALLS_VARIANTS),
        user_structures=metaballs_user_structure_files(),
    output:
        table=report(
            "results/metaballs/real_scenes.csv",
            category="Metaballs",
            labels={"table": "real scenes"},
        ),
        figure=report(
            "results/metaballs/figures/real_scenes.png",
            category="Metaballs",
            labels={"figure": "real scenes"},
        ),
        trajectory=report(
            "results/metaballs/figures/trajectory.gif",
            category="Metaballs",
            labels={"figure": "trajectory"},
        ),
    log:
        "results/logs/metaballs_real_scenes/metaballs_real_scenes.log",
    benchmark:
        "results/benchmarks/metaballs_real_scenes/metaballs_real_scenes.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("metaballs_real_scenes"),
    params:
        cfg=rule_params("metaballs_real_scenes"),
    script:
        "../scripts/metaballs_real_scenes.py"
