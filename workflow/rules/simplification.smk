# Appearance-driven simplification (Hasselgren et al. 2021) through Mitsuba 3:
# reference renders, QEM and classic bakes, optimisation, held-out evaluation.

from neurender.simplify import CASE_FILES as SIMPLIFY_CASE_FILES

SIMPLIFY_CASES = tuple(config["simplify"]["cases"])
SIMPLIFY_RENDER_KEYS = ("resolution", "intensity")
SIMPLIFY_PREPARE_KEYS = SIMPLIFY_RENDER_KEYS + (
    "texture_size",
    "train_views",
    "test_views",
    "reference_spp",
    "test_spp",
    "supersample",
    "camera_distance",
    "fov",
    "light_distance",
    "light_cone",
)
SIMPLIFY_OPTIMISE_KEYS = SIMPLIFY_RENDER_KEYS + (
    "texture_size",
    "steps",
    "batch",
    "spp",
    "lr_positions",
    "lr_textures",
    "lr_final_fraction",
    "laplacian_scale",
    "laplacian_min_fraction",
)
#: Keys only one use case reads.
SIMPLIFY_CASE_KEYS = {
    "head": ("head_vertices", "head_triangles"),
    "metaballs": ("metaball_count", "metaball_grid", "metaball_triangles"),
}


def simplify_prepare_params(wildcards):
    keys = SIMPLIFY_PREPARE_KEYS + SIMPLIFY_CASE_KEYS[wildcards.case]
    return section_keys("simplify", keys, ("seed", "device"), case=wildcards.case)


def simplify_optimise_params(wildcards):
    return section_keys(
        "simplify", SIMPLIFY_OPTIMISE_KEYS, ("seed", "device"), case=wildcards.case
    )


def simplify_evaluate_params():
    keys = SIMPLIFY_RENDER_KEYS + ("eval_spp", "threads", "cases")
    return section_keys("simplify", keys, ("seed", "device"))


def simplify_evaluate_inputs(wildcards):
    """Every case's files, keyed ``<case>_<kind>`` as the evaluation reads them."""
    return {
        f"{case}_{kind}": f"results/simplification/{case}/{name}"
        for case in SIMPLIFY_CASES
        for kind, name in SIMPLIFY_CASE_FILES.items()
    }


def simplify_report_tables():
    tables = ("targets", "metrics", "stats")
    return (
        expand("results/simplification/{table}.csv", table=tables)
        if SIMPLIFY_CASES
        else []
    )


def simplify_report_figures():
    names = ("comparison", "loss_curves")
    return (
        expand("results/simplification/figures/{name}.png", name=names)
        if SIMPLIFY_CASES
        else []
    )


wildcard_constraints:
    case="|".join(SIMPLIFY_CASES) or "-",


rule simplify_prepare:
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
        "results/logs/simplify_prepare/{case}.log",
    benchmark:
        "results/benchmarks/simplify_prepare/{case}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    params:
        cfg=simplify_prepare_params,
    script:
        "../scripts/simplify_prepare.py"


rule simplify_optimise:
    input:
        lowpoly="results/simplification/{case}/lowpoly.npz",
        train_images="results/simplification/{case}/reference_train.exr",
        train_views="results/simplification/{case}/views_train.csv",
    output:
        mesh="results/simplification/{case}/optimised.npz",
        obj="results/simplification/{case}/optimised.obj",
        mtl="results/simplification/{case}/optimised.mtl",
        texture="results/simplification/{case}/optimised_texture.png",
        normal="results/simplification/{case}/optimised_normal.png",
        albedo="results/simplification/{case}/optimised_albedo.png",
        loss="results/simplification/{case}/loss.csv",
    log:
        "results/logs/simplify_optimise/{case}.log",
    benchmark:
        "results/benchmarks/simplify_optimise/{case}.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: config["simplify"]["threads"]
    resources:
        gpu=1,
    params:
        cfg=simplify_optimise_params,
    script:
        "../scripts/simplify_optimise.py"


rule simplify_evaluate:
    input:
        unpack(simplify_evaluate_inputs),
    output:
        metrics="results/simplification/metrics.csv",
        metrics_views="results/simplification/metrics_views.csv",
        targets="results/simplification/targets.csv",
        stats="results/simplification/stats.csv",
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
        "results/logs/simplify_evaluate/simplify_evaluate.log",
    benchmark:
        "results/benchmarks/simplify_evaluate/simplify_evaluate.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: workflow.cores
    params:
        cfg=simplify_evaluate_params(),
    script:
        "../scripts/simplify_evaluate.py"
