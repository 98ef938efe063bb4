"""requirements.lock, requirements.in, pyproject.toml and the rules' conda env agree."""

import re
import tomllib
from pathlib import Path

import pytest
import yaml
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
# The lock is compiled for CI's interpreter and platform (scripts/update-lock.sh).
TARGET = default_environment() | {
    "python_version": "3.11",
    "python_full_version": "3.11.0",
    "platform_system": "Linux",
    "sys_platform": "linux",
    "platform_machine": "x86_64",
    "implementation_name": "cpython",
}


def _lock() -> dict[str, tuple[Version, list[str]]]:
    """Name -> (version, sha256 hashes) of every requirement in requirements.lock."""
    text = (ROOT / "requirements.lock").read_text()
    pins = {}
    for block in re.split(r"\n(?=\S)", text):
        if block.startswith("#") or not block.strip():
            continue
        match = re.match(r"([A-Za-z0-9._-]+)==(\S+)", block)
        assert match, f"requirements.lock: not an exact pin: {block.splitlines()[0]!r}"
        pins[canonicalize_name(match[1])] = (
            Version(match[2]),
            re.findall(r"--hash=sha256:([0-9a-f]{64})", block),
        )
    return pins


def _project_requirements() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    names = project["dependencies"] + extras["dev"] + extras["slurm"]
    return [r for r in map(Requirement, names) if not r.marker or r.marker.evaluate(TARGET)]


def _env_pins() -> dict[str, Version]:
    env = yaml.safe_load((ROOT / "workflow/envs/neurender.yaml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    pins = {}
    for line in pip:
        name, sep, version = line.partition("==")
        assert sep, f"workflow/envs/neurender.yaml: not an exact pin: {line!r}"
        pins[canonicalize_name(name)] = Version(version)
    return pins


def test_every_locked_package_has_an_exact_version_and_hashes():
    lock = _lock()
    assert len(lock) > 50
    assert all(hashes for _, hashes in lock.values()), "a pin without --hash"


@pytest.mark.parametrize("req", _project_requirements(), ids=str)
def test_the_lock_satisfies_every_project_requirement(req):
    lock = _lock()
    name = canonicalize_name(req.name)
    assert name in lock, f"{req} (pyproject.toml) is not in requirements.lock"
    assert req.specifier.contains(lock[name][0], prereleases=True), (
        f"requirements.lock pins {name}=={lock[name][0]}, outside pyproject.toml's {req}: "
        "run scripts/update-lock.sh"
    )


def test_the_lock_pins_what_requirements_in_names_torch_as_the_cpu_wheel():
    lock = _lock()
    pins = [
        Requirement(line)
        for line in (ROOT / "requirements.in").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    for req in pins:
        (version,) = req.specifier
        assert lock[canonicalize_name(req.name)][0] == Version(version.version)
    assert lock["torch"][0].local == "cpu"


def test_the_rules_env_pins_the_locked_runtime_versions():
    lock, env = _lock(), _env_pins()
    runtime = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    for req in map(Requirement, runtime):
        assert canonicalize_name(req.name) in env, f"{req} is not in the rules' env"
    for name, version in env.items():
        assert name in lock, f"workflow/envs/neurender.yaml pins {name}, not in the lock"
        locked = lock[name][0]
        # torch: the same release, PyPI's build (CUDA) rather than the CPU wheel.
        assert version == (Version(locked.public) if name == "torch" else locked), name
    assert not env["torch"].local
