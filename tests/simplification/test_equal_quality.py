"""The simplification's equal-quality sweep: its budgets and ours' side of the table."""

import pandas as pd
import pytest

from neurender import equal_quality as shared
from neurender.simplification import equal_quality as eq


def test_budgets_are_the_multiples_below_the_reference_in_increasing_order():
    assert eq.budgets([1, 2, 4, 8, 16], 600, 71564) == [
        (1, 600),
        (2, 1200),
        (4, 2400),
        (8, 4800),
        (16, 9600),
    ]
    # Capped below the reference's triangles, sorted, a rounded budget once.
    assert eq.budgets([16, 1, 4, 1.001], 200, 3000) == [(1, 200), (4, 800)]
    with pytest.raises(ValueError, match=r"equal_quality_multiples = \[16\].*none is below"):
        eq.budgets([16], 200, 3000)


def test_ours_is_read_from_the_evaluations_means_and_compared_in_triangles():
    metrics = pd.DataFrame(
        [
            ("head", model, metric, value)
            for model, values in (
                ("ours", (40.0, 0.99, 0.01, 0.005)),
                ("baked", (36, 0.98, 0.02, 0.01)),
            )
            for metric, value in zip(eq.QUALITY, values, strict=True)
        ],
        columns=["dataset", "model", "metric", "value"],
    )
    ours = eq.ours(metrics, "head")
    assert ours == {"psnr": 40.0, "ssim": 0.99, "flip": 0.01, "coverage_error": 0.005}
    with pytest.raises(ValueError, match="no \\['psnr', 'ssim', 'flip', 'coverage_error'\\]"):
        eq.ours(metrics, "metaballs")
    sweep = pd.DataFrame(
        [
            ("1199 triangles", 1.0, 1199, 36.0, 0.98, 0.02, 0.010),
            ("2398 triangles", 2.0, 2398, 39.0, 0.99, 0.012, 0.006),
            # PSNR, SSIM and FLIP reach ours at 4x; the coverage error only at 8x.
            ("4796 triangles", 4.0, 4796, 41.0, 0.995, 0.008, 0.0051),
            ("9592 triangles", 8.0, 9592, 42.0, 0.996, 0.007, 0.004),
        ],
        columns=["setting", "multiple", "triangles", *eq.QUALITY],
    )
    table = eq.table("head", sweep, ours, 1199)
    row = table[table.model == "ours"].set_index("metric")
    assert set(row.setting) == {"9592 triangles"} and set(row.bound) == {shared.WITHIN}
    assert row.value["equal_quality_triangle_ratio"] == pytest.approx(8.0)
    assert row.value["triangles"] == 1199
    assert set(table[table.model == eq.CLASSIC].metric) == {"multiple", "triangles", *eq.QUALITY}
