# Image-space metaballs (thesis 4.1, 5.2): circle inputs and ray-marched G-buffers as AB PNGs.


rule metaballs_examples:
    output:
        examples=directory("results/metaballs/{split}"),
        manifest="results/metaballs/{split}_manifest.csv",
    params:
        cfg=metaballs_params(),
    log:
        "results/logs/metaballs_examples/{split}.log",
    benchmark:
        "results/benchmarks/metaballs_examples/{split}.tsv"
    threads: 1
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
