# neurender: one DAG from procedural data to results/report.html.
# Run: snakemake --cores 2 results/report.html   (other configs: --configfile config/smoke.yaml)
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/examples.smk"
include: "workflow/rules/helpers/prt.smk"
include: "workflow/rules/helpers/ndr.smk"
include: "workflow/rules/helpers/metaballs.smk"
include: "workflow/rules/helpers/simplification.smk"
include: "workflow/rules/prt.smk"
include: "workflow/rules/ndr.smk"
include: "workflow/rules/metaballs.smk"
include: "workflow/rules/simplification.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/provenance.smk"


rule all:
    default_target: True
    input:
        "results/report.html",
