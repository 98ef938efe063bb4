import numpy as np

from neurender.prt import noise


def test_the_reference_quality_label_is_the_estimate_with_the_most_directions():
    models = ["DeepPRT", "ground truth 256 dirs", "ground truth 1024 dirs", "MoMoPRT"]
    assert noise.reference_quality_label(models) == "ground truth 1024 dirs"
    assert noise.reference_quality_label(["DeepPRT", "ground truth"]) is None
    assert noise.ground_truth_label(64) == "ground truth 64 dirs"


def test_the_reference_quality_estimate_is_closer_to_a_clean_one_than_the_training_one(
    bowl_positions,
):
    cfg = {"seed": 3, "n_bands": 2, "direction_sets": 2, "ray_offset": 1e-3}
    cfg |= {"directions": 16, "reference_directions": 256}
    positions = bowl_positions()
    light = np.full((4, 3), 0.5, np.float32)  # 2 bands of SH light
    preds = noise.noise_floor_predictions("bowl", positions, light, cfg, 1)
    assert set(preds) == {
        (label, material)
        for label in ("ground truth 16 dirs", "ground truth 256 dirs")
        for material in ("diffuse", "glossy")
    }
    assert preds["ground truth 256 dirs", "diffuse"].shape == (2, 4, 6, 6)
    assert preds["ground truth 256 dirs", "glossy"].shape == (2, 12, 6, 6)
    clean = noise.noise_floor_predictions("bowl", positions, light, cfg | {"directions": 4096}, 1)
    truth = clean["ground truth 4096 dirs", "diffuse"]
    error = {
        n: np.abs(preds[f"ground truth {n} dirs", "diffuse"] - truth).mean() for n in (16, 256)
    }
    assert error[256] < 0.5 * error[16]
