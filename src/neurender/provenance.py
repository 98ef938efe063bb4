"""What produced a run's results: ``results/provenance.json``.

Fields (all JSON): ``config`` (the resolved config, schema defaults filled in),
``configfiles``, ``git`` (``commit`` and ``dirty``, both null outside a git checkout),
``packages`` (distribution name -> version, null when not installed; read with
:mod:`importlib.metadata`, nothing is imported), ``python``, ``machine`` (platform, CPU
model, CPUs, the cores Snakemake was given, thread variables), ``gpus`` (as ``nvidia-smi``
lists them; none without it) and the run's times ``started`` and ``finished`` (ISO 8601,
UTC; :data:`TIME_FIELDS`).

The times: ``started`` is when the Snakemake invocation that computed the results began
(the workflow's ``onstart`` hook writes it, with the invocation's ``--cores``, by
:func:`mark_start`: in the main process of a real run only, never in a dry run or a
cluster job); ``finished`` is when the provenance job ran, once every table, figure and
viewer of the report was done. The rule depends on exactly what the report shows, so it
is rewritten by every invocation that recomputes any result and makes nothing but the
report rerun (the start and the cores are not its params: a rerun with other ``--cores``
has nothing to do). Without a start marker (``--no-hooks``) both are null.
"""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import shutil
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from neurender import io

#: Distributions whose versions can change a result (PyPI names).
PACKAGES = (
    "torch",
    "mitsuba",
    "drjit",
    "embreex",
    "trimesh",
    "numpy",
    "onnxruntime",
    "onnx",
    "snakemake",
    "pandas",
    "scipy",
    "libigl",
    "OpenEXR",
    "kornia",
    "pyvista",
    "vtk",
    "tensorboard",
)
#: Fields that differ between any two runs (left out of comparisons).
TIME_FIELDS = ("started", "finished")
#: Environment variables that set library thread pools.
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "DRJIT_NUM_THREADS",
)


def now() -> str:
    """The current time, ISO 8601 in UTC to the second."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def package_versions(names: Sequence[str] = PACKAGES) -> dict[str, str | None]:
    """Installed version of each distribution in ``names`` (None where not installed)."""
    versions: dict[str, str | None] = {}
    for name in names:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def git_state(root: str | Path) -> dict[str, Any]:
    """``{"commit": full hash, "dirty": bool}`` of the checkout at ``root``: dirty when a
    tracked file differs from the commit or a file git does not ignore is untracked.
    Both are None when ``root`` is not in a git checkout or git is not installed."""
    git = shutil.which("git")
    if git is None:
        return {"commit": None, "dirty": None}

    def output(*args: str) -> str | None:
        done = subprocess.run(
            [git, "-C", str(root), *args], capture_output=True, text=True, check=False
        )
        return done.stdout if done.returncode == 0 else None

    commit = output("rev-parse", "--verify", "HEAD")
    status = output("status", "--porcelain")
    if commit is None or status is None:
        return {"commit": None, "dirty": None}
    return {"commit": commit.strip(), "dirty": bool(status.strip())}


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's processor string elsewhere)."""
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        return platform.processor() or "CPU"


def machine(cores: int | None) -> dict[str, Any]:
    """Platform, CPU model, the machine's CPUs and those this process may use, the cores
    Snakemake was given (``cores``) and the thread variables that are set."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "platform": platform.platform(),
        "cpu_model": cpu_model(),
        "cpus": os.cpu_count(),
        "cpus_usable": usable,
        "snakemake_cores": cores,
        "thread_variables": {k: os.environ[k] for k in THREAD_VARIABLES if k in os.environ},
    }


def write_study_sidecar(
    path: str | Path,
    command: str,
    script: str,
    argv: Sequence[str],
    checkout: str | Path,
    cores: int | None,
    **extra: Any,
) -> None:
    """A committed study's JSON sidecar, written atomically: the ``command`` that made its
    inputs, the ``script`` and ``argv`` that made the file, the commit of the ``checkout``
    they came from, the machine (:func:`machine`) and ``extra`` keys."""
    sidecar = {
        "command": command,
        "profile_command": " ".join(["python", script, *argv]),
        **git_state(checkout),
        "machine": machine(cores),
        **extra,
    }
    io.write_json(path, sidecar)


def gpus() -> list[dict[str, str]]:
    """Every GPU ``nvidia-smi`` lists (name, memory, driver); none without ``nvidia-smi``
    or when it fails. CUDA is never initialised here."""
    smi = shutil.which("nvidia-smi")
    if smi is None:
        return []
    query = "--query-gpu=name,memory.total,driver_version"
    done = subprocess.run(
        [smi, query, "--format=csv,noheader"], capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        return []
    rows = [line.split(", ") for line in done.stdout.splitlines() if line.strip()]
    return [dict(zip(("name", "memory", "driver"), row, strict=False)) for row in rows]


def mark_start(path: str | Path, cores: int | None) -> None:
    """Write the start of a run (:func:`now`) and its Snakemake ``cores`` to ``path`` as
    JSON (the ``onstart`` hook)."""
    io.write_json(path, {"started": now(), "snakemake_cores": cores}, indent=None)


def read_start(path: str | Path) -> dict[str, Any]:
    """``{"started", "snakemake_cores"}`` as :func:`mark_start` wrote them at ``path``,
    both None when there is no such file."""
    p = Path(path)
    marked = json.loads(p.read_text()) if p.is_file() else {}
    return {k: marked.get(k) for k in ("started", "snakemake_cores")}


def collect(
    config: Mapping[str, Any],
    configfiles: Sequence[str],
    root: str | Path,
    start_marker: str | Path,
) -> dict[str, Any]:
    """Every field of the module doc (the checkout at ``root``, the start and the cores
    from ``start_marker``), ``finished`` being now."""
    start = read_start(start_marker)
    return {
        "config": dict(config),
        "configfiles": list(configfiles),
        "git": git_state(root),
        "packages": package_versions(),
        "python": platform.python_version(),
        "executable": sys.executable,
        "machine": machine(start["snakemake_cores"]),
        "gpus": gpus(),
        "started": start["started"],
        "finished": now(),
    }


def write(path: str | Path, record: Mapping[str, Any]) -> None:
    """``record`` as indented JSON at ``path`` (atomically)."""
    io.write_json(path, record, indent=1, sort_keys=True)


def read(path: str | Path) -> dict[str, Any]:
    """A provenance file, naming it when it is missing or not JSON."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"provenance file {p} does not exist")
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"provenance file {p} is not JSON: {err}") from err


def _flat(tree: Any, prefix: str = "") -> dict[str, Any]:
    """Nested mappings as ``{"a.b.c": leaf}``."""
    if not isinstance(tree, Mapping):
        return {prefix: tree}
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        flat |= _flat(value, f"{prefix}.{key}" if prefix else str(key))
    return flat


def differences(first: Mapping[str, Any], second: Mapping[str, Any]) -> list[str]:
    """One line per field in which two provenance records differ (``name: a -> b``, a
    field one of them lacks shown as ``(absent)``): git commit and dirty flag, Python,
    CPU model, GPUs, package versions and config keys (dotted). The times
    (:data:`TIME_FIELDS`) always differ and are left out."""
    a, b = _flat(_compared(first)), _flat(_compared(second))
    return [
        f"{key}: {a.get(key, ABSENT)} -> {b.get(key, ABSENT)}"
        for key in sorted(set(a) | set(b), key=_order)
        if a.get(key, ABSENT) != b.get(key, ABSENT)
    ]


ABSENT = "(absent)"
_GROUPS = ("git", "python", "machine", "gpus", "packages", "config")


def _compared(record: Mapping[str, Any]) -> dict[str, Any]:
    """The fields :func:`differences` compares, grouped in its order."""
    machine_ = record.get("machine", {})
    return {
        "git": record.get("git", {}),
        "python": record.get("python"),
        "machine": {"cpu_model": machine_.get("cpu_model")} if machine_ else {},
        "gpus": ", ".join(g.get("name", "?") for g in record.get("gpus", [])) or "none",
        "packages": record.get("packages", {}),
        "config": record.get("config", {}),
    }


def _order(key: str) -> tuple[int, str]:
    return _GROUPS.index(key.split(".", 1)[0]), key
