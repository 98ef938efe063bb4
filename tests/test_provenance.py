import importlib.metadata
import json
import os
import subprocess

import pytest

from neurender import provenance

FIELDS = {"config", "configfiles", "git", "packages", "python", "executable", "machine"}
FIELDS |= {"gpus", "started", "finished"}


def test_package_versions_are_importlib_metadata_s_and_none_when_not_installed():
    versions = provenance.package_versions()
    assert list(versions) == list(provenance.PACKAGES)
    for name, version in versions.items():
        try:
            assert version == importlib.metadata.version(name), name
        except importlib.metadata.PackageNotFoundError:
            assert version is None, name
    assert versions["torch"] is not None and versions["numpy"] is not None
    assert provenance.package_versions(["no-such-distribution-x"]) == {
        "no-such-distribution-x": None
    }


def _git(repo, *args):
    command = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t", *args]
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def repo(tmp_path):
    pytest.importorskip("shutil").which("git") or pytest.skip("git is not installed")
    _git(tmp_path, "init", "-q")
    (tmp_path / "code.py").write_text("x = 1\n")
    (tmp_path / ".gitignore").write_text("results/\n")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-q", "-m", "first")
    return tmp_path


def test_git_state_names_the_commit_and_sees_every_kind_of_dirt(repo):
    state = provenance.git_state(repo)
    assert state == {"commit": _git(repo, "rev-parse", "HEAD"), "dirty": False}
    assert len(state["commit"]) == 40
    (repo / "results").mkdir()
    (repo / "results" / "out.csv").write_text("a\n")  # ignored: still clean
    assert provenance.git_state(repo)["dirty"] is False
    (repo / "new.py").write_text("y = 2\n")  # untracked
    assert provenance.git_state(repo)["dirty"] is True
    (repo / "new.py").unlink()
    (repo / "code.py").write_text("x = 2\n")  # tracked and edited
    assert provenance.git_state(repo)["dirty"] is True
    _git(repo, "commit", "-q", "-am", "second")
    after = provenance.git_state(repo)
    assert after["dirty"] is False and after["commit"] != state["commit"]


def test_git_state_outside_a_checkout_or_without_git_is_null(tmp_path, monkeypatch):
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    (tmp_path / "plain").mkdir()
    assert provenance.git_state(tmp_path / "plain") == {"commit": None, "dirty": None}
    monkeypatch.setattr(provenance.shutil, "which", lambda name: None)
    assert provenance.git_state(tmp_path) == {"commit": None, "dirty": None}


def test_gpus_are_none_without_nvidia_smi_and_parsed_from_it(tmp_path, monkeypatch):
    monkeypatch.setattr(provenance.shutil, "which", lambda name: None)
    assert provenance.gpus() == []
    monkeypatch.undo()
    fake = tmp_path / "nvidia-smi"
    fake.write_text(
        "#!/bin/sh\necho 'NVIDIA H200, 143771 MiB, 570.86'\necho 'Tesla T4, 15360 MiB, 570.86'\n"
    )
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    assert provenance.gpus() == [
        {"name": "NVIDIA H200", "memory": "143771 MiB", "driver": "570.86"},
        {"name": "Tesla T4", "memory": "15360 MiB", "driver": "570.86"},
    ]
    fake.write_text("#!/bin/sh\nexit 9\n")  # a failing nvidia-smi (no driver): none
    assert provenance.gpus() == []


def test_machine_counts_cpus_and_reports_the_thread_variables_that_are_set(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    info = provenance.machine(cores=2)
    assert info["cpus"] == os.cpu_count() and 1 <= info["cpus_usable"] <= info["cpus"]
    assert info["snakemake_cores"] == 2 and info["thread_variables"]["OMP_NUM_THREADS"] == "3"
    assert "MKL_NUM_THREADS" not in info["thread_variables"]
    assert info["cpu_model"] == provenance.cpu_model() and info["cpu_model"]


def test_collect_holds_every_field_and_the_marked_start(repo):
    marker = repo / "results" / "logs" / "started.json"  # ignored by git: the tree stays clean
    assert provenance.read_start(marker) == {"started": None, "snakemake_cores": None}
    provenance.mark_start(marker, 6)
    config = {"seed": 3, "prt": {"resolution": 32}}
    record = provenance.collect(config, ["config/smoke.yaml"], repo, marker)
    assert set(record) == FIELDS and set(provenance.TIME_FIELDS) <= FIELDS
    assert record["started"] == json.loads(marker.read_text())["started"]
    assert record["machine"]["snakemake_cores"] == 6
    assert record["started"] <= record["finished"]  # ISO 8601 in UTC sorts as time
    assert record["config"] == config and record["git"]["dirty"] is False
    out = repo / "results" / "provenance.json"
    provenance.write(out, record)
    assert provenance.read(out) == json.loads(json.dumps(record))


def test_the_job_writes_what_collect_gathers_for_the_rules_params(repo):
    from neurender.report import jobs

    marker = repo / "results" / "logs" / "started.json"
    provenance.mark_start(marker, 2)
    params = {"config": {"seed": 7}, "configfiles": ["config/config.yaml"], "root": str(repo)}
    params["start_marker"] = str(marker)
    out = repo / "results" / "provenance.json"
    jobs.provenance({"tables": ["ignored.csv"]}, {"json": str(out)}, params, 1)
    written = provenance.read(out)
    gathered = provenance.collect(params["config"], params["configfiles"], repo, marker)
    assert {k: v for k, v in written.items() if k != "finished"} == {
        k: v for k, v in json.loads(json.dumps(gathered)).items() if k != "finished"
    }
    assert written["machine"]["snakemake_cores"] == 2 and written["config"] == {"seed": 7}


def test_read_names_a_missing_or_broken_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="provenance file .*gone.json"):
        provenance.read(tmp_path / "gone.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="bad.json is not JSON"):
        provenance.read(tmp_path / "bad.json")


def _record(**changes):
    record = {
        "git": {"commit": "a" * 40, "dirty": False},
        "python": "3.11.9",
        "machine": {"cpu_model": "CPU X", "cpus": 2},
        "gpus": [],
        "packages": {"torch": "2.13.0", "numpy": "2.3.0"},
        "config": {"seed": 0, "prt": {"epochs": 3, "widths": [4, 8]}},
        "started": "2026-01-01T00:00:00+00:00",
        "finished": "2026-01-01T01:00:00+00:00",
    }
    for key, value in changes.items():
        record[key] = value if not isinstance(value, dict) else {**record[key], **value}
    return record


def test_differences_name_commit_dirt_packages_and_config_keys_never_the_times():
    same = _record(started="2027-05-05T00:00:00+00:00", finished="2027-05-05T02:00:00+00:00")
    assert provenance.differences(_record(), same) == []
    other = _record(
        git={"commit": "b" * 40, "dirty": True},
        packages={"torch": "2.14.0", "onnx": "1.20"},
        config={"prt": {"epochs": 4, "widths": [4, 8]}},
    )
    assert provenance.differences(_record(), other) == [
        f"git.commit: {'a' * 40} -> {'b' * 40}",
        "git.dirty: False -> True",
        "packages.onnx: (absent) -> 1.20",
        "packages.torch: 2.13.0 -> 2.14.0",
        "config.prt.epochs: 3 -> 4",
    ]
    gpu = _record(gpus=[{"name": "NVIDIA H200"}], machine={"cpu_model": "CPU Y"})
    assert provenance.differences(_record(), gpu) == [
        "machine.cpu_model: CPU X -> CPU Y",
        "gpus: none -> NVIDIA H200",
    ]


def test_study_sidecar_names_its_command_script_commit_machine_and_extra_keys(tmp_path):
    path = tmp_path / "study.json"
    provenance.write_study_sidecar(
        path, "snakemake x", "benchmarks/s.py", ["a", "b"], tmp_path, 2, note="n"
    )
    sidecar = json.loads(path.read_text())
    assert sidecar["command"] == "snakemake x"
    assert sidecar["profile_command"] == "python benchmarks/s.py a b"
    assert sidecar["commit"] is None  # tmp_path is no git checkout
    assert sidecar["machine"]["snakemake_cores"] == 2 and sidecar["note"] == "n"
    assert [p.name for p in tmp_path.iterdir()] == ["study.json"]  # no temporary file left
