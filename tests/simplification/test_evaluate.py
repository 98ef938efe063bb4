import numpy as np
import pandas as pd

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


def test_targets_compare_ours_with_both_baselines():
    rows = []
    for model, psnr, cov in (("qem", 30.0, 0.02), ("baked", 31.0, 0.02), ("ours", 33.5, 0.01)):
        rows += [
            {"dataset": "head", "model": model, "metric": "psnr", "value": psnr},
            {"dataset": "head", "model": model, "metric": "coverage_error", "value": cov},
        ]
    stats = pd.DataFrame([{"case": "head", "quantity": "prepare_seconds", "value": 60.0}])
    loss = pd.DataFrame(
        {"case": "head", "step": [0, 1], "metric": "seconds", "value": [30.0, 30.0]}
    )
    # The one-thread preparation holds half the cores: the other case's runs beside it.
    two = summary.with_timings(stats, [loss], 30.0, optimise_threads=2, cores=2)
    assert two.set_index("quantity")["value"]["stage_seconds"] == 60 / 2 + 60 + 30
    # So does a one-thread optimisation.
    stats = summary.with_timings(stats, [loss], 30.0, optimise_threads=1, cores=2)
    stats = stats.set_index("quantity")["value"]
    assert stats["optimise_seconds"] == 60 and stats["stage_seconds"] == 60 / 2 + 60 / 2 + 30
    targets = summary.targets(pd.DataFrame(rows), stats.reset_index()).set_index("check")
    assert targets.loc["PSNR gain over QEM >= 3 dB (measured: dB)", "measured"] == 3.5
    assert targets.loc["stage within 12 minutes (measured: minutes)", "measured"] == 1.5
    assert targets["met"].all()
