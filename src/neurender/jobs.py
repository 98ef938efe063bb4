"""The bridge from a Snakemake rule to its job function.

Every rule of ``workflow/rules/<method>.smk`` names its files (``input:``, ``output:``),
passes the config keys it reads as one ``params: cfg=...`` dict (wildcard values included;
built by the method's ``workflow/rules/helpers/<method>.smk``), and runs a one-line shim
``workflow/scripts/<rule>.py``, e.g. ``workflow/scripts/prt_train.py``::

    from neurender.jobs import run
    from neurender.prt import jobs

    run(snakemake, jobs.prt_train)

Each method's ``jobs.py`` holds one function per rule with the signature of :data:`Job`,
so a job can be called from Python (tests, notebooks) with plain dicts exactly as the
workflow calls it. A rule that only publishes files under a second name runs
:func:`copy_files` from here instead.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from neurender import io
from neurender.logs import log_to_file
from neurender.profiling import run_profiled

log = logging.getLogger(__name__)

#: ``job(inputs, outputs, params, threads)``: file names by role (a path, or a list of
#: paths for an ``expand``), the rule's config keys, and its thread count.
Job = Callable[[Mapping[str, Any], Mapping[str, Any], Mapping[str, Any], int], None]


def run(smk: Any, job: Job) -> None:
    """Run ``job`` for the ``snakemake`` object of a rule's script, logging to its log file
    (under cProfile when ``NEURENDER_PROFILE`` names a folder: :mod:`neurender.profiling`)."""
    log_to_file(smk.log[0])
    run_profiled(
        lambda: job(_files(smk.input), _files(smk.output), smk.params.cfg, smk.threads),
        smk.log[0],
    )


def input_name(kind: str, *key: str) -> str:
    """The name of one of a rule's many inputs of ``kind``, by what it is (object, variant,
    material, split): ``kind:part:part``, e.g. ``pt:paper:diffuse``. The workflow's input
    functions name such files by it and jobs look each up by it, never by its place in a
    list."""
    return ":".join((kind, *key))


def _files(named: Any) -> dict[str, str | list[str]]:
    """Snakemake's named file list as a plain dict (an ``expand`` entry as a list)."""
    return {k: v if isinstance(v, str) else list(v) for k, v in named.items()}


def copy_files(
    inputs: Mapping[str, Any], outputs: Mapping[str, Any], params: Mapping[str, Any], threads: int
) -> None:
    """Each input copied, atomically, to the output of the same name: the job of a rule
    that publishes files under a second name (``prt_ship``), kept here so that its shim
    imports no method's modules (torch, ONNX) for a copy."""
    for key, source in inputs.items():
        io.copy_file(source, outputs[key])
        log.info("copied %s to %s", source, outputs[key])
