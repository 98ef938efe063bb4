import numpy as np
import pandas as pd
import pytest

from neurender import io
from neurender.jobs import input_name
from neurender.prt import MATERIALS, VARIANTS, data_jobs, jobs, unseen, unseen_scores, unshadowed
from neurender.prt.frames import Split, ray_offset
from neurender.prt.local_model import LocalConfig
from neurender.prt.model import export_deepprt
from neurender.prt.momoprt import fit_momoprt
from neurender.prt.training import shadowing_training, train_deepprt, train_local
from neurender.tables import tidy_rows

#: The reference directions of the benchmark's ground truth here (the workflow's config
#: asks for at least 4 x the training frames' directions; a test needs fewer).
REFERENCE_DIRECTIONS = 16


@pytest.fixture(scope="module")
def unseen_params(prt_params) -> dict:
    """The params of the head's unseen-deformation job, as the workflow gives them, with
    :data:`REFERENCE_DIRECTIONS`; its render keys are also what the scores render with."""
    return prt_params("prt_unseen", object="head") | {"reference_directions": REFERENCE_DIRECTIONS}


def _random_split(frames, rng, n=8, k=16, params=7):
    return Split(
        rng.normal(size=(frames, n, n, 3)).astype(np.float32),
        rng.normal(size=(frames, n, n, 3)).astype(np.float32),
        rng.uniform(0, 1, (frames, n, n, k)).astype(np.float32),
        rng.uniform(0, 1, (frames, n, n, 3, k)).astype(np.float32),
        rng.uniform(0, 1, (frames, params)).astype(np.float32),
    )


@pytest.fixture(scope="module")
def head(tmp_path_factory, prt_params, unseen_params):
    """The head's data at 8^2, tiny networks of both variants and MoMoPRT on its blendshape
    weights (trained on random frames: the job's rows, not their values, are tested)."""
    d = tmp_path_factory.mktemp("unseen")
    probe = {"exr": d / "sky.exr", "sh": d / "sky_sh.csv"}
    data_jobs.prt_probe({}, probe, prt_params("prt_probe", probe="sky"), 1)
    gim = {"gim": d / "gim.npz", "stats": d / "g.csv"}
    data_jobs.prt_geometry_image({}, gim, prt_params("prt_geometry_image", object="head"), 1)
    seq = {"seq": d / "seq.npz"}
    data_jobs.prt_sequence(
        {"gim": d / "gim.npz"}, seq, prt_params("prt_sequence", object="head"), 1
    )
    rng = np.random.default_rng(0)
    train, val = _random_split(4, rng), _random_split(2, rng)
    light = rng.normal(size=(16, 3))
    files = {}
    for variant in VARIANTS:
        for material in MATERIALS:
            ckpt, onnx = d / f"{variant}_{material}.pt", d / f"{variant}_{material}.onnx"
            params = prt_params("prt_train", material=material, variant=variant)
            if variant == "paper":
                train_deepprt(train, val, material, params, 1, str(ckpt), str(d / "l.csv"))
            else:
                local = LocalConfig(
                    n_bands=params["n_bands"],
                    material=material,
                    widths=tuple(params["widths"]),
                    blocks=params["blocks"],
                    width=4,
                    dilations=(1,),
                    window=3,
                )
                cfg = shadowing_training(params)
                train_local(train, val, local, cfg, 1, str(ckpt), str(d / "l.csv"), light=light)
            export_deepprt(ckpt, val, onnx)
            files[input_name("pt", variant, material)] = str(ckpt)
            files[input_name("onnx", variant, material)] = str(onnx)
    for material in MATERIALS:
        path = d / f"momoprt_{material}.npz"
        fit_momoprt(train, val, material, True, 4, [1e-3]).save(path)
        files[input_name("momoprt", material)] = str(path)
    inputs = {**files, "gim": d / "gim.npz", "seq": d / "seq.npz", "light": d / "sky_sh.csv"}
    outputs = {"csv": d / "unseen.csv", "figure": d / "unseen.png"}
    jobs.prt_unseen(inputs, outputs, unseen_params, 1)
    return d


def test_the_job_writes_a_row_per_family_strength_model_and_metric(head, unseen_params):
    table = io.read_csv(head / "unseen.csv")
    assert (head / "unseen.png").stat().st_size > 0
    assert np.isfinite(table.value).all()
    metrics = {f"{s}_{m}" for s in ("ssim", "rel_l1_radiance") for m in MATERIALS}
    models = {
        *VARIANTS.values(),
        unseen_scores.UNSHADOWED,
        unseen_scores.STATIC,
        unseen_scores.DISKS,
    }
    for family in unseen.FAMILIES:  # the head has blendshapes: every family
        for strength in unseen_params["unseen_strengths"]:
            sel = table[(table.family == family) & (table.strength == strength)]
            # MoMoPRT on the head's blendshape weights predicts only where they are known.
            expected = models | ({"MoMoPRT"} if family == "extrapolation" else set())
            assert set(sel.model) == expected, (family, strength)
            for model in expected:
                assert set(sel[sel.model == model].metric) == metrics
    assert len(table) == len(table.drop_duplicates(["model", "family", "strength", "metric"]))
    assert set(table.split) == {"unseen"} and set(table.dataset) == {"head"}


def test_extrapolation_weights_are_the_mean_weights_plus_the_frames_step():
    rng = np.random.default_rng(1)
    rest, deltas = rng.normal(size=(6, 6, 3)), rng.normal(size=(3, 6, 6, 3))
    weights = rng.uniform(0, 1, (5, 3))
    mean = rest + np.einsum("fk,kijc->fijc", weights, deltas).mean(0)
    (case,) = unseen_scores.cases(mean, ("extrapolation",), [0.8], 1, 3, deltas, weights.mean(0))
    # The blendshape model is linear: the frame is the rest shape at its weights.
    expected = rest + np.einsum("k,kijc->ijc", case.params[0], deltas)
    assert np.allclose(case.positions[0], expected)
    assert np.isclose(np.abs(case.params[0] - weights.mean(0)).max(), 1.5 * 0.8)


def _dome(n=12):
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    return np.stack([xx, yy, 0.8 * np.exp(-(xx**2 + yy**2) / 0.2)], -1)


def _traced(positions, directions, light):
    cfg = {"seed": 0, "direction_sets": 4, "n_bands": 4}
    offset = ray_offset(positions[0], 1e-3)
    return unseen_scores.traced(positions, directions, cfg, offset, light, 1, "t", "unseen_t")


def _sky():
    """SH light from +z mostly: positive radiance (the scores clamp predictions at 0)."""
    light = np.zeros((16, 3))
    light[0], light[2] = 3.0, 1.5
    return light


def test_a_model_equal_to_the_ground_truth_scores_zero_error_and_ssim_one(unseen_params):
    light = _sky()
    data = _traced(_dome()[None], 64, light)
    preds = {("truth", m): data.targets(m) for m in MATERIALS}
    values = unseen_scores.frame_scores(data, preds, light, unseen_params)["truth"]
    for m in MATERIALS:
        assert values[f"rel_l1_radiance_{m}"][0] == 0.0
        assert values[f"ssim_{m}"][0] == pytest.approx(1.0, abs=1e-9)


def test_the_unshadowed_baseline_is_exact_on_a_plane_even_rotated(unseen_params):
    """Nothing occludes a plane, so the traced transfer is the unshadowed one up to Monte
    Carlo noise; on the dome, which shadows itself, it is far off."""
    n = 12
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    plane = np.stack([xx, yy, np.zeros_like(xx)], -1)
    tilted = unseen.deform(plane, "rotation", 1.0, 0)
    sky = _sky()
    coeffs = unshadowed.glossy_polynomial(sky)
    errors = {}
    for label, shape in {"plane": plane, "tilted": tilted, "dome": _dome()}.items():
        data = _traced(shape[None], 1024, sky)
        mean = _traced(shape[None], 64, sky)
        preds = unseen_scores.baselines(data, mean, 4, coeffs, sky)
        preds = {k: v for k, v in preds.items() if k[0] == unseen_scores.UNSHADOWED}
        values = unseen_scores.frame_scores(data, preds, sky, unseen_params)[
            unseen_scores.UNSHADOWED
        ]
        errors[label] = {m: values[f"rel_l1_radiance_{m}"][0] for m in MATERIALS}
    for m in MATERIALS:
        assert errors["plane"][m] < 0.02 and errors["tilted"][m] < 0.02, errors
        assert errors["dome"][m] > 5 * max(errors["plane"][m], errors["tilted"][m]), errors


def _trough(n=16):
    """A deep V-shaped trough along y: each wall hides much of the sky from the other."""
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    return np.stack([xx, yy, 1.5 * np.abs(xx)], -1)


def test_the_disk_occlusion_baseline_is_exact_on_a_plane_and_sees_a_trough_shadow_itself(
    unseen_params,
):
    """No rays, no learning: on a plane it is the unshadowed transfer; in a trough, whose
    walls occlude each other, it is far closer to the traced transfer than unshadowed."""
    t = np.linspace(-1.0, 1.0, 16)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    plane = np.stack([xx, yy, np.zeros_like(xx)], -1)[None]
    assert np.allclose(
        unseen.disk_occlusion_baseline(plane, 4), unseen.unshadowed_baseline(plane, 4), atol=1e-6
    )
    sky = _sky()
    coeffs = unshadowed.glossy_polynomial(sky)
    data = _traced(_trough()[None], 1024, sky)
    preds = unseen_scores.baselines(data, data, 4, coeffs, sky)
    values = unseen_scores.frame_scores(data, preds, sky, unseen_params)
    for m in MATERIALS:
        disks = values[unseen_scores.DISKS][f"rel_l1_radiance_{m}"][0]
        unshadowed_err = values[unseen_scores.UNSHADOWED][f"rel_l1_radiance_{m}"][0]
        assert disks < 0.25 * unshadowed_err, (m, disks, unshadowed_err)


def _table(shipped, unshadowed_err, static_err, paper=None):
    """Hand-made rows: ``{family: [error per strength]}`` per model, strengths 0.5 and 1."""
    rows = []
    models = {"ours": shipped, "unshadowed": unshadowed_err, "static": static_err}
    if paper is not None:
        models["paper"] = paper
    for model, families in models.items():
        for family, errors in families.items():
            for strength, err in zip((0.5, 1.0), errors, strict=True):
                for material in MATERIALS:
                    values = {f"rel_l1_radiance_{material}": err, f"ssim_{material}": 0.9}
                    rows += tidy_rows(
                        "prt", "obj", model, "unseen", values, family=family, strength=strength
                    )
    return pd.DataFrame(rows)


BASE = {"bend": [0.10, 0.20], "twist": [0.10, 0.20]}
WORSE = {"bend": [0.30, 0.40], "twist": [0.30, 0.40]}


def test_targets_met_when_below_both_baselines_everywhere():
    table = _table({"bend": [0.05, 0.1], "twist": [0.05, 0.1]}, BASE, WORSE, paper=WORSE)
    targets = unseen_scores.targets(table, "ours", "paper")
    assert len(targets) == 2 * 4  # per material: mean, strongest, any strength, paper
    assert all(t.met for t in targets)
    # Measured: the worst family's ratio to the better baseline (0.05/0.1 = 0.1/0.2 = 0.5).
    assert {t.subject for t in targets} == {"obj"}
    assert all(np.isclose(t.measured, 0.5) for t in targets if "paper" not in t.check)


def test_targets_missed_on_one_family_name_it():
    # Below both on bend; on twist above the better baseline on average and at the strongest.
    table = _table({"bend": [0.05, 0.1], "twist": [0.12, 0.25]}, BASE, WORSE)
    targets = unseen_scores.targets(table, "ours")
    assert len(targets) == 2 * 3  # no paper model: no paper check
    for t in targets:
        assert not t.met and "twist" in t.check
    strongest = [t for t in targets if "strongest" in t.check]
    assert np.isclose(strongest[0].measured, 0.25 / 0.20)


def test_ten_percent_above_the_better_baseline_at_one_strength_is_allowed_but_not_more():
    # Mild strength 5% above the better baseline, strong one well below: the mean and the
    # strongest pass, the any-strength check passes at 1.05 and fails at 1.2.
    for over, expect in ((1.05, True), (1.2, False)):
        shipped = {"bend": [0.1 * over, 0.1], "twist": [0.05, 0.1]}
        targets = unseen_scores.targets(_table(shipped, BASE, WORSE), "ours")
        by_kind = {("every unseen strength" in t.check, "strongest" in t.check): t for t in targets}
        assert by_kind[(True, False)].met is expect
        assert np.isclose(by_kind[(True, False)].measured, over)
        assert by_kind[(False, True)].met and by_kind[(False, False)].met


def test_the_summary_holds_every_objects_rows(head, tmp_path):
    table = io.read_csv(head / "unseen.csv")
    other = tmp_path / "other.csv"
    io.write_csv(other, table.assign(dataset="other"))
    out = tmp_path / "all.csv"
    jobs.prt_unseen_summary({"csvs": [str(head / "unseen.csv"), str(other)]}, {"csv": out}, {}, 1)
    merged = io.read_csv(out)
    assert len(merged) == 2 * len(table) and set(merged.dataset) == {"head", "other"}
