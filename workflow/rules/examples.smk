# Example assets of the kinds users bring (src/neurender/examples.py), written by
# third-party tools; config/examples/own_assets.yaml and the smoke config run on them.


rule example_assets:
    output:
        wave=directory("results/examples/wave"),
        blob=directory("results/examples/blob"),
        torus=directory("results/examples/torus"),
        rock="results/examples/rock.glb",
        crate="results/examples/crate.obj",
        crate_mtl="results/examples/crate.mtl",
        crate_texture="results/examples/crate.png",
        vase="results/examples/vase.ply",
        maps=directory("results/examples/maps"),
        balls="results/examples/balls.csv",
    log:
        "results/logs/example_assets/example_assets.log",
    benchmark:
        "results/benchmarks/example_assets/example_assets.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("example_assets"),
    params:
        cfg=rule_params("example_assets"),
    script:
        "../scripts/example_assets.py"
