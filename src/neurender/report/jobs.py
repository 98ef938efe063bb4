"""The report stage's jobs, for the rules of ``workflow/rules/report.smk`` and
``workflow/rules/provenance.smk``."""

from __future__ import annotations

from neurender import provenance as provenance_record
from neurender.report.build import build_report, commit_label


def report(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every table, figure and viewer of the run in one self-contained HTML file, headed by
    the commit and with the run's ``provenance`` in a collapsed section; each method's
    committed studies (``inputs["studies"]``, their CSVs and sidecars) after its tables."""
    record = provenance_record.read(inputs["provenance"])
    run_info = {
        "config": ", ".join(params["configfiles"]),
        "seed": str(params["seed"]),
        "commit": commit_label(record["git"]),
    }
    build_report(
        inputs["tables"],
        inputs["figures"],
        outputs["html"],
        params["title"],
        run_info,
        viewers=inputs.get("viewers", []),
        provenance=record,
        root=".",  # the workflow's working directory, the repository root
    )


def provenance(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """``results/provenance.json`` (:mod:`neurender.provenance`); ``inputs`` (the report's
    results) are not read: they order this job after every one of them."""
    record = provenance_record.collect(
        params["config"],
        params["configfiles"],
        params["root"],
        params["start_marker"],
    )
    provenance_record.write(outputs["json"], record)
