"""The report's job, for the rule of ``workflow/rules/report.smk``."""

from __future__ import annotations

from neurender.report.build import build_report


def report(inputs: dict, outputs: dict, params: dict, threads: int) -> None:
    """Every table, figure and viewer of the run in one self-contained HTML file."""
    run_info = {"config": ", ".join(params["configfiles"]), "seed": str(params["seed"])}
    build_report(
        inputs["tables"],
        inputs["figures"],
        outputs["html"],
        params["title"],
        run_info,
        viewers=inputs.get("viewers", []),
    )
