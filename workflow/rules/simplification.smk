# Appearance-driven simplification (Hasselgren et al. 2021) through Mitsuba 3:
# reference renders, QEM and classic bakes, optimisation, its GLB/OBJ export (deploy),
# held-out evaluation; built-in cases and the user's assets (simplification.user_assets).
# Helpers (params and input functions): workflow/rules/helpers/simplification.smk.


rule simplification_prepare:
    input:
        unpack(simplification_prepare_inputs),
    output:
        train_images="results/simplification/{case}/reference_train.exr",
        test_images="results/simplification/{case}/reference_test.exr",
        train_views="results/simplification/{case}/views_train.csv",
        test_views="results/simplification/{case}/views_test.csv",
        lowpoly="results/simplification/{case}/lowpoly.npz",
        baked_normal="results/simplification/{case}/baked_normal.png",
        baked_albedo="results/simplification/{case}/baked_albedo.png",
        stats="results/simplification/{case}/stats.csv",
    log:
        "results/logs/simplification_prepare/{case}.log",
    benchmark:
        "results/benchmarks/simplification_prepare/{case}.tsv"
    # Before DeepPRT's short training jobs, which then fill the gaps.
    priority: 12
    conda:
        "../envs/neurender.yaml"
    # One thread: the cases' jobs run side by side, which keeps both cores busier than one
    # two-thread job at a time (those used 1.2 to 1.5 of the 2 cores in the default run).
    threads: 1
    resources:
        **scheduler_resources("simplification_prepare"),
    params:
        cfg=rule_params("simplification_prepare"),
    script:
        "../scripts/simplification_prepare.py"


rule simplification_summary:
    input:
        stats=expand(
            "results/simplification/{case}/stats.csv", case=SIMPLIFICATION_CASES
        ),
        losses=expand(
            "results/simplification/{case}/loss.csv", case=SIMPLIFICATION_CASES
        ),
    output:
        stats=report(
            "results/simplification/stats.csv",
            category="Simplification",
            labels={"table": "statistics"},
        ),
    log:
        "results/logs/simplification_summary/simplification_summary.log",
    benchmark:
        "results/benchmarks/simplification_summary/simplification_summary.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("simplification_summary"),
    params:
        cfg=rule_params("simplification_summary"),
    script:
        "../scripts/simplification_summary.py"


rule simplification_optimise:
    input:
        unpack(simplification_optimise_inputs),
        lowpoly="results/simplification/{case}/lowpoly.npz",
        train_images="results/simplification/{case}/reference_train.exr",
        train_views="results/simplification/{case}/views_train.csv",
    output:
        mesh="results/simplification/{case}/optimised.npz",
        normal="results/simplification/{case}/optimised_normal.png",
        albedo="results/simplification/{case}/optimised_albedo.png",
        loss="results/simplification/{case}/loss.csv",
    log:
        "results/logs/simplification_optimise/{case}.log",
    benchmark:
        "results/benchmarks/simplification_optimise/{case}.tsv"
    # Before DeepPRT's short training jobs, which then fill the gaps.
    priority: 12
    conda:
        "../envs/neurender.yaml"
    threads: config["simplification"]["threads"]
    resources:
        **scheduler_resources("simplification_optimise"),
    params:
        cfg=rule_params("simplification_optimise"),
    script:
        "../scripts/simplification_optimise.py"


rule simplification_deploy:
    input:
        lowpoly="results/simplification/{case}/lowpoly.npz",
        mesh="results/simplification/{case}/optimised.npz",
        normal="results/simplification/{case}/optimised_normal.png",
        albedo="results/simplification/{case}/optimised_albedo.png",
    output:
        glb="results/simplification/{case}/optimised.glb",
        obj="results/simplification/{case}/optimised.obj",
        mtl="results/simplification/{case}/optimised.mtl",
        texture="results/simplification/{case}/optimised_texture.png",
        normal_texture="results/simplification/{case}/optimised_texture_normal.png",
        table=report(
            "results/simplification/{case}/deployment.csv",
            category="Simplification",
            labels={"case": "{case}", "table": "deployment"},
        ),
    log:
        "results/logs/simplification_deploy/{case}.log",
    benchmark:
        "results/benchmarks/simplification_deploy/{case}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("simplification_deploy"),
    params:
        cfg=rule_params("simplification_deploy"),
    script:
        "../scripts/simplification_deploy.py"


rule simplification_evaluate:
    input:
        unpack(simplification_evaluate_inputs),
    output:
        metrics=report(
            "results/simplification/metrics.csv",
            category="Simplification",
            labels={"table": "metrics"},
        ),
        metrics_views="results/simplification/metrics_views.csv",
        figure=report(
            "results/simplification/figures/comparison.png",
            category="Simplification",
            labels={"figure": "held-out comparison"},
        ),
        loss_figure=report(
            "results/simplification/figures/loss_curves.png",
            category="Simplification",
            labels={"figure": "loss curves"},
        ),
    log:
        "results/logs/simplification_evaluate/simplification_evaluate.log",
    benchmark:
        "results/benchmarks/simplification_evaluate/simplification_evaluate.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    resources:
        **scheduler_resources("simplification_evaluate"),
    params:
        cfg=rule_params("simplification_evaluate"),
    script:
        "../scripts/simplification_evaluate.py"


rule simplification_equal_quality:
    input:
        unpack(simplification_equal_quality_inputs),
        metrics="results/simplification/metrics.csv",
    output:
        table=report(
            "results/simplification/equal_quality.csv",
            category="Simplification",
            labels={"table": "equal quality"},
        ),
        figure=report(
            "results/simplification/figures/equal_quality.png",
            category="Simplification",
            labels={"figure": "equal quality"},
        ),
    log:
        "results/logs/simplification_equal_quality/simplification_equal_quality.log",
    benchmark:
        "results/benchmarks/simplification_equal_quality/simplification_equal_quality.tsv"
    conda:
        "../envs/neurender.yaml"
    # Every core, as the evaluation, whose renders it repeats for each budget swept.
    threads: workflow.cores
    resources:
        **scheduler_resources("simplification_equal_quality"),
    params:
        cfg=rule_params("simplification_equal_quality"),
    script:
        "../scripts/simplification_equal_quality.py"


rule simplification_targets:
    input:
        metrics="results/simplification/metrics.csv",
        equal_quality="results/simplification/equal_quality.csv",
    output:
        targets=report(
            "results/simplification/targets.csv",
            category="Simplification",
            labels={"table": "targets"},
        ),
    log:
        "results/logs/simplification_targets/simplification_targets.log",
    benchmark:
        "results/benchmarks/simplification_targets/simplification_targets.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("simplification_targets"),
    params:
        cfg=rule_params("simplification_targets"),
    script:
        "../scripts/simplification_targets.py"


rule simplification_viewer:
    input:
        unpack(simplification_prepare_inputs),
        lowpoly="results/simplification/{case}/lowpoly.npz",
        baked_albedo="results/simplification/{case}/baked_albedo.png",
        baked_normal="results/simplification/{case}/baked_normal.png",
        mesh="results/simplification/{case}/optimised.npz",
        normal="results/simplification/{case}/optimised_normal.png",
        albedo="results/simplification/{case}/optimised_albedo.png",
        metrics="results/simplification/metrics.csv",
    output:
        viewer="results/simplification/viewers/{case}.json",
    log:
        "results/logs/simplification_viewer/{case}.log",
    benchmark:
        "results/benchmarks/simplification_viewer/{case}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("simplification_viewer"),
    params:
        cfg=rule_params("simplification_viewer"),
    script:
        "../scripts/simplification_viewer.py"


rule simplification_mesh_figure:
    input:
        unpack(simplification_prepare_inputs),
        lowpoly="results/simplification/{case}/lowpoly.npz",
        mesh="results/simplification/{case}/optimised.npz",
    output:
        png=report(
            "results/simplification/figures/{case}_meshes.png",
            category="Simplification",
            labels={"case": "{case}", "figure": "meshes (3D)"},
        ),
    log:
        "results/logs/simplification_mesh_figure/{case}.log",
    benchmark:
        "results/benchmarks/simplification_mesh_figure/{case}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("simplification_mesh_figure"),
    params:
        cfg=rule_params("simplification_mesh_figure"),
    script:
        "../scripts/simplification_mesh_figure.py"
