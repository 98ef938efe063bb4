import pandas as pd
import pytest
import torch

from neurender.ndr import equal_quality as eq
from neurender.ndr import summary
from neurender.tables import TARGET_COLUMNS, tidy_rows


def _metrics(rows: list[tuple[str, str, float]]) -> pd.DataFrame:
    """Test DSSIM(I_R) rows ``(dataset, model, value)`` as the evaluation writes them."""
    return pd.DataFrame(
        [r for d, m, v in rows for r in tidy_rows("ndr", d, m, "test", {"dssim_I_R": v})]
    )


def _equal(int8_dssim: float = 0.041) -> pd.DataFrame:
    """An equal-quality table: NDR 40x faster than the training 64 spp, 4x at equal DSSIM;
    its int8 graph 80x and 8x, and the shipped graphs' scores on the whole test split
    (int8 ``int8_dssim`` against float32 0.040)."""
    scores = {"spp": [4, 16, 64], "ms_per_frame": [2.0, 8.0, 80.0], eq.METRIC: [0.06, 0.03, 0.01]}
    scores = pd.DataFrame(scores).assign(scene_ms=1.0)
    network = {"coarse_shading_ms": 1.0, "network_ms": 1.0, "ms_per_frame": 2.0}
    networks = {eq.NETWORK: network | {eq.METRIC: 0.04}}
    networks[eq.NETWORK_INT8] = {"ms_per_frame": 1.0, eq.METRIC: 0.04}
    whole = {("complex", eq.NETWORK): 0.040, ("complex", eq.NETWORK_INT8): int8_dssim}
    graphs = eq.graph_table({k: {eq.METRIC: torch.tensor([v])} for k, v in whole.items()})
    return pd.concat([eq.table(scores, networks, 64), graphs])


def test_targets_state_met_and_missed():
    metrics = _metrics(
        [
            ("complex", "ndr", 0.05),
            ("complex", "shading_input", 0.06),
            ("complex", "no_intrinsic", 0.08),
            ("complex", "pix2pix", 0.03),
            ("complex", "noise floor", 0.01),
        ]
    )
    table = summary.targets(metrics, _equal())
    assert list(table.columns) == list(TARGET_COLUMNS)
    met = table.set_index("subject")["met"]
    assert not met["ndr"]  # 0.05 > 0.75 * 0.06
    assert met["no_intrinsic"].tolist() == [True, True]  # beaten by NDR, and >= 1.2 x NDR
    assert not met["pix2pix"]
    assert met["noise floor"]
    assert met["Mitsuba at the training 64 spp"]
    by_check = table.set_index("check")["met"]
    equal = by_check[by_check.index.str.startswith("ndr at least 3x faster than the cheapest")]
    assert equal.tolist() == [True]
    assert met["Mitsuba at the training 64 spp (int8 graph)"]
    assert met["int8 graph (complex)"]  # 0.041 <= 1.05 x 0.040
    # Variants that did not run, and the diffuse comparison without its data, are not rows.
    assert "single_decoder" not in met and "real_shading" not in met


def test_an_int8_graph_that_costs_quality_misses():
    metrics = _metrics([("complex", "ndr", 0.05), ("complex", "shading_input", 0.1)])
    table = summary.targets(metrics, _equal(0.045)).set_index("subject")
    assert not table.loc["int8 graph (complex)", "met"]
    assert table.loc["int8 graph (complex)", "measured"] == pytest.approx(0.045 / 0.040)


def test_half_the_shading_inputs_dssim_meets_the_target_and_no_stage_time_is_one():
    metrics = _metrics([("complex", "ndr", 0.05), ("complex", "shading_input", 0.1)])
    table = summary.targets(metrics, _equal()).set_index("subject")
    assert table.loc["ndr", "met"]  # 50 % below the shading input
    assert table.loc["ndr", "measured"] == 0.5
    # The stage's time is a run's profile (benchmarks/run_profile.py), not a target.
    assert "stage" not in table.index


def test_timing_table_names_the_coarse_shading_of_the_training_data(tmp_path):
    """The rows carry the manifest's estimator (``importance`` for a manifest from before
    the column existed) and its lighting's once-per-map seconds where it has them; the
    speed-up is Mitsuba's time over network + shading per image."""
    columns = {"render_seconds": [0.3, 0.5], "train_spp_render_seconds": [0.3, 0.5]}
    columns |= {"coarse_seconds": [0.01, 0.03], "spp": [64, 64]}
    test = tmp_path / "test.csv"
    pd.DataFrame({**columns, "spp": [512, 512]}).to_csv(test, index=False)
    for shading in ("prefiltered", None):
        train = tmp_path / f"{shading}.csv"
        frame = pd.DataFrame(columns)
        if shading:
            frame["coarse_shading"] = shading
            frame["coarse_lighting_seconds"] = [0.03, 0.05]
        frame.to_csv(train, index=False)
        table = summary.timing_table(0.02, str(train), str(test), "cpu, 1 thread")
        assert set(table.coarse_shading) == {shading or "importance"}
        speedup = table.set_index("metric").value["speedup_vs_training_spp_render"]
        assert speedup == 0.4 / (0.02 + 0.02)
        per_map = table.set_index("metric").value.get("coarse_lighting_seconds_per_map")
        assert per_map == (0.04 if shading else None)
