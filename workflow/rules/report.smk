# The HTML report: every measured table and figure beside the papers' numbers.
from neurender.user_paths import workdir_relative


rule report:
    input:
        unpack(report_results),
        studies=report_studies,
        provenance="results/provenance.json",
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
        # Relative paths: a checkout moved with its results reruns nothing.
        cfg=rule_params(
            "report", configfiles=[workdir_relative(f) for f in workflow.configfiles]
        ),
    script:
        "../scripts/report.py"
