# DeepPRT data (paper 3.1, 3.2.2): meshes -> geometry images -> deformation sequences ->
# ray-traced SH transfer per frame, plus light probes, noise floor and ray benchmark.


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
