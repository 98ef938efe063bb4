"""Jobs killed with SIGKILL (with Snakemake itself, as a power cut would) are never taken as
complete: a rerun redoes a data job and resumes a training job from its last finished
epoch, ending with exactly what an uninterrupted run gives.

Runs the real workflow at smoke scale in a copy of the checkout (about a minute).
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
TRAIN = "results/prt/head/variants/paper_diffuse.pt"
TEST_FRAMES = "results/prt/head/test"
#: Smoke scale, one object, with enough epochs and test frames to be caught mid-way (the
#: training is killed once its first epoch's resume file exists: 60 epochs leave it tens
#: of seconds to go).
FAULT_CONFIG = {
    "prt": {
        "objects": ["head"],
        "experiments": False,
        "frames": {"train": 6, "val": 2, "test": 40},
        "resolution": 32,
    },
    "prt_model": {"epochs": 60},
}


def _copy_checkout(dest: Path) -> None:
    files = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\0")
    for name in filter(None, files):
        source = ROOT / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def _snakemake(work: Path, *args: str, background: bool = False):
    command = [
        sys.executable,
        "-m",
        "snakemake",
        *args,
        "--cores",
        "2",
        "--configfile",
        "config/smoke.yaml",
        "fault.yaml",
    ]
    if background:
        return subprocess.Popen(
            command,
            cwd=work,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
    result = subprocess.run(command, cwd=work, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return result.stdout + result.stderr


def _kill_when(process: subprocess.Popen, ready, timeout: float = 120.0) -> None:
    """SIGKILL Snakemake and its jobs (one process group) once ``ready()`` holds."""
    deadline = time.monotonic() + timeout
    while not ready():
        if process.poll() is not None or time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail("the job finished or stalled before it could be killed mid-way")
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    if not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout to copy")
    work = tmp_path_factory.mktemp("checkout")
    _copy_checkout(work)
    (work / "fault.yaml").write_text(yaml.safe_dump(FAULT_CONFIG))
    _snakemake(
        work,
        "results/prt/head/train_manifest.csv",
        "results/prt/head/val_manifest.csv",
        "results/prt/head/test_manifest.csv",
    )
    return work


def test_a_killed_training_job_resumes_and_ends_as_an_uninterrupted_run(work):
    resume = work / (TRAIN + ".resume")
    process = _snakemake(work, TRAIN, background=True)
    _kill_when(process, resume.exists)
    _snakemake(work, "--unlock")  # Snakemake died holding its lock (docs/troubleshooting.md)
    assert not (work / TRAIN).exists()  # the checkpoint is written only at the end
    dry = _snakemake(work, TRAIN, "-n")
    assert "prt_train" in dry  # not taken as complete
    log = work / "results/logs/prt_train/head_paper_diffuse.log"
    _snakemake(work, TRAIN)
    assert "resuming from" in log.read_text()
    resumed = (work / "results/prt/head/variants/paper_diffuse_loss.csv").read_text()
    _snakemake(work, TRAIN, "--forcerun", "prt_train")
    assert "resuming from" not in log.read_text()
    uninterrupted = (work / "results/prt/head/variants/paper_diffuse_loss.csv").read_text()
    assert resumed == uninterrupted
    curve = pd.read_csv(io.StringIO(resumed))
    assert not curve.duplicated(["epoch", "split", "metric"]).any()  # every epoch logged once
    assert set(curve["epoch"]) == set(range(1, FAULT_CONFIG["prt_model"]["epochs"] + 1))


def test_a_killed_data_job_is_redone_and_gives_the_same_frames(work):
    frames = work / TEST_FRAMES
    before = {p.name: p.read_bytes() for p in frames.glob("frame_*.exr")}
    assert len(before) == 40
    process = _snakemake(
        work,
        "results/prt/head/test_manifest.csv",
        "--forcerun",
        "prt_transfer",
        background=True,
    )
    started = time.time()

    def some_frames_rewritten() -> bool:
        rewritten = 0
        for p in frames.glob("frame_*.exr"):
            try:
                rewritten += p.stat().st_mtime > started
            except FileNotFoundError:  # Snakemake removes the old outputs as the job starts
                pass
        return rewritten >= 2

    _kill_when(process, some_frames_rewritten)
    _snakemake(work, "--unlock")
    dry = _snakemake(work, "results/prt/head/test_manifest.csv", "-n")
    assert "prt_transfer" in dry  # the half-rewritten folder is not taken as complete
    _snakemake(work, "results/prt/head/test_manifest.csv")
    after = {p.name: p.read_bytes() for p in frames.glob("frame_*.exr")}
    assert after == before
    # No temporary file left behind (Snakemake marks a finished directory output with
    # its own .snakemake_timestamp).
    assert [p.name for p in frames.glob(".*")] == [".snakemake_timestamp"]
