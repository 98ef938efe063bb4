# What produced the results: results/provenance.json (neurender.provenance). It depends on
# exactly what the report shows, so every invocation that recomputes a result rewrites it
# and nothing but the report reruns because of it. A local rule: on a cluster (SLURM) it
# runs where the workflow runs, so the record describes the machine that ran the
# invocation, not a compute node.
import neurender.provenance
from neurender.user_paths import workdir_relative

#: When the invocation began and its --cores (written by the onstart hook of a real run
#: only; not params, so that a rerun with other --cores has nothing to do).
PROVENANCE_START = "results/logs/provenance/started.json"


onstart:
    neurender.provenance.mark_start(PROVENANCE_START, workflow.cores)


localrules:
    provenance,


rule provenance:
    input:
        unpack(report_results),
    output:
        json="results/provenance.json",
    log:
        "results/logs/provenance/provenance.log",
    benchmark:
        "results/benchmarks/provenance/provenance.tsv"
    conda:
        "../envs/neurender.yaml"
    threads: 1
    resources:
        **scheduler_resources("provenance"),
    params:
        cfg={
            "config": config,
            # Relative paths: a checkout moved with its results reruns nothing.
            "configfiles": [workdir_relative(f) for f in workflow.configfiles],
            "root": workdir_relative(workflow.basedir),
            "start_marker": PROVENANCE_START,
        },
    script:
        "../scripts/provenance.py"
