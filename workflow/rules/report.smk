# The HTML report: every measured table and figure beside the papers' numbers.


rule report:
    input:
        tables=prt_report_tables()
        + ndr_report_tables()
        + metaballs_report_tables()
        + simplify_report_tables(),
        figures=prt_report_figures()
        + ndr_report_figures()
        + metaballs_report_figures()
        + simplify_report_figures(),
        viewers=prt_report_viewers()
        + ndr_report_viewers()
        + metaballs_report_viewers()
        + simplify_report_viewers(),
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
