import numpy as np
import pandas as pd
import pytest

from neurender import equal_quality as shared
from neurender.simplification import evaluate, figures, summary


def test_coverage_error_counts_extra_and_missing_pixels():
    ref = np.zeros((10, 10))
    ref[2:6, 2:6] = 1  # 16 covered pixels
    cand = np.zeros((10, 10))
    cand[2:6, 3:7] = 1  # shifted one column: 4 extra, 4 missing
    extra, missing = evaluate.coverage_error(cand, ref)
    assert extra == missing == 4 / 16
    assert evaluate.coverage_error(ref, ref) == (0.0, 0.0)


def test_image_metrics_of_identical_and_perturbed_images():
    rng = np.random.default_rng(0)
    ref = np.concatenate([rng.uniform(0, 0.8, (32, 32, 3)), np.ones((32, 32, 1))], -1)
    same = evaluate.image_metrics(ref.astype(np.float32), ref.astype(np.float32))
    assert same["ssim"] > 0.999 and same["flip"] < 1e-6 and same["coverage_error"] == 0
    noisy = ref.copy()
    noisy[..., :3] += rng.normal(0, 0.02, (32, 32, 3))
    m = evaluate.image_metrics(noisy.astype(np.float32), ref.astype(np.float32))
    assert 20 < m["psnr"] < 45 and m["flip"] > 0


def test_object_crop_frames_the_covered_pixels():
    alpha = np.zeros((20, 20))
    alpha[5:8, 10:12] = 1
    rows, cols = figures.object_crop(alpha, margin=1)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (4, 9, 9, 13)


def test_targets_compare_ours_with_both_baselines_and_read_no_time():
    rows = []
    for model, psnr, cov in (("qem", 30.0, 0.02), ("baked", 31.0, 0.02), ("ours", 33.5, 0.01)):
        rows += [
            {"dataset": "head", "model": model, "metric": "psnr", "value": psnr},
            {"dataset": "head", "model": model, "metric": "coverage_error", "value": cov},
        ]
    rows.append({"dataset": "head", "model": "ours_glb", "metric": "psnr", "value": 33.45})
    sweep = pd.DataFrame(
        {"setting": ["100 triangles", "200 triangles"], "triangles": [100, 200], "psnr": [31, 34]}
    )
    ours = {"ours": shared.Network({"psnr": 33.5}, 100.0)}
    equal = shared.table(
        "simplification", "head", "classic", sweep, ours, {"psnr": True}, shared.TRIANGLES
    )
    targets = summary.targets(pd.DataFrame(rows), equal)
    assert set(targets.subject) == {"head"}  # no stage row: a target reads no time
    measured = targets.set_index("check")["measured"]
    assert measured["PSNR gain over QEM >= 3 dB (measured: dB)"] == 3.5
    assert measured["PSNR above the classic baked normal map (measured: ours - baked, dB)"] == 2.5
    assert measured["coverage error below QEM's (measured: ours - QEM)"] == pytest.approx(-0.01)
    glb = "exported GLB re-renders within 0.1 dB of ours (measured: |PSNR difference|, dB)"
    assert measured[glb] == pytest.approx(0.05)
    triangles = (
        "ours at least 1.5x fewer triangles than the cheapest classic QEM + bake of its "
        "quality (against 200 triangles, within the sweep)"
    )
    assert measured[triangles] == 2.0
    assert len(targets) == 5 and targets["met"].all()  # no OBJ row: none was rendered


def test_statistics_add_each_cases_optimisation_seconds_to_its_own():
    stats = [
        pd.DataFrame(
            {"case": case, "quantity": ["lowpoly_triangles", "prepare_seconds"], "value": [n, 60.0]}
        )
        for case, n in (("head", 1199.0), ("metaballs", 600.0))
    ]
    losses = [
        pd.DataFrame(
            {
                "case": case,
                "step": [0, 0, 1, 1],
                "metric": ["loss", "seconds"] * 2,
                "value": [0.5, s, 0.4, s],
            }
        )
        for case, s in (("head", 30.0), ("metaballs", 20.0))
    ]
    table = summary.statistics(stats, losses)
    assert list(table.columns) == ["case", "quantity", "value"]
    value = table.set_index(["case", "quantity"])["value"]
    assert value["head", "optimise_seconds"] == 60.0
    assert value["metaballs", "optimise_seconds"] == 40.0
    assert value["metaballs", "lowpoly_triangles"] == 600.0
    assert not table.quantity.isin(["stage_seconds", "evaluate_seconds"]).any()
