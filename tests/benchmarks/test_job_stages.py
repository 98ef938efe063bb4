"""benchmarks/job_stages.py: profiles of jobs by stage, beside their benchmark's wall time."""

import cProfile
import time

import pytest

from . import scripts

job_stages = scripts.load("job_stages")

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _job():
    time.sleep(0.05)


def test_each_profile_by_stage_and_the_process_start_its_benchmark_adds(tmp_path):
    profiles, results = tmp_path / "profiles", tmp_path / "results"
    (profiles / "ndr_train").mkdir(parents=True)
    profiler = cProfile.Profile()
    profiler.runcall(_job)
    profiler.dump_stats(str(profiles / "ndr_train" / "ndr.pstats"))
    bench = results / "benchmarks" / "ndr_train" / "ndr.tsv"
    bench.parent.mkdir(parents=True)
    bench.write_text(HEADER + "5.0\t0:00:05\t1\t0\t0\t0\t0\t0\t90\t4\n")
    table = job_stages.job_stages(results, profiles).set_index("stage")
    assert set(table.rule) == {"ndr_train"} and set(table.job) == {"ndr"}
    total = table.loc["total", "seconds"]
    assert total >= 0.05
    assert table.loc["process start and imports", "seconds"] == pytest.approx(5.0 - total)


def test_no_profiles_is_an_error_naming_the_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path)):
        job_stages.job_stages(tmp_path, tmp_path)
