# The HTML report: every measured table and figure beside the papers' numbers.
import neurender.methods


def report_inputs(kind):
    """Every registered method's report files of one ``kind`` (``tables``, ``figures``,
    ``viewers``), methods in report order (:mod:`neurender.methods`)."""
    return [
        path
        for method in neurender.methods.METHODS
        for path in getattr(method.report_inputs(config), kind)
    ]


rule report:
    input:
        tables=report_inputs("tables"),
        figures=report_inputs("figures"),
        viewers=report_inputs("viewers"),
    output:
        html="results/report.html",
    log:
        "results/logs/report/report.log",
    benchmark:
        "results/benchmarks/report/report.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("report"),
    params:
        cfg={
            "title": config["report"]["title"],
            "configfiles": [str(f) for f in workflow.configfiles],
            "seed": config["seed"],
        },
    script:
        "../scripts/report.py"
