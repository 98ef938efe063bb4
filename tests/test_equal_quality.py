"""The shared equal-quality rule: the pick, its bounds, the table, the targets and the
report's summary of every method's table."""

import dataclasses
import math

import pandas as pd
import pytest

from neurender import equal_quality as eq
from neurender import io, methods, tables
from neurender.method import Method
from neurender.report import build

#: Two metrics, one better higher, one better lower.
QUALITY = {"iou": True, "error": False}


def _sweep(rows):
    """``(setting, ms_per_frame, iou, error)`` per row."""
    return pd.DataFrame(rows, columns=["setting", "ms_per_frame", "iou", "error"])


SWEEP = _sweep(
    [
        ("coarse", 2.0, 0.80, 9.0),
        ("medium", 5.0, 0.90, 5.0),
        ("fine", 17.0, 0.95, 2.0),
        ("finest", 65.0, 0.99, 1.0),
    ]
)


def test_the_pick_is_the_fastest_setting_reaching_the_network_on_every_metric():
    assert eq.pick(SWEEP, {"iou": 0.92, "error": 6.0}, QUALITY) == eq.Pick("fine", 17.0, eq.WITHIN)
    # Equal to the network's quality reaches it.
    assert eq.pick(SWEEP, {"iou": 0.90, "error": 5.0}, QUALITY) == eq.Pick("medium", 5.0, eq.WITHIN)
    # One metric short is not reaching: medium's IoU reaches 0.85, its error misses 4.
    assert eq.pick(SWEEP, {"iou": 0.85, "error": 4.0}, QUALITY).setting == "fine"


def test_the_pick_goes_by_measured_time_not_by_the_order_of_the_settings():
    noisy = SWEEP.assign(ms_per_frame=[2.0, 5.0, 17.0, 16.0])
    assert eq.pick(noisy, {"iou": 0.92, "error": 6.0}, QUALITY) == eq.Pick(
        "finest", 16.0, eq.WITHIN
    )


def test_equal_times_pick_the_first_listed():
    tied = SWEEP.assign(ms_per_frame=[2.0, 9.0, 9.0, 20.0])
    assert eq.pick(tied, {"iou": 0.9, "error": 5.0}, QUALITY).setting == "medium"


def test_no_setting_reaching_is_a_lower_bound_against_the_slowest():
    assert eq.pick(SWEEP, {"iou": 1.0, "error": 0.5}, QUALITY) == eq.Pick("finest", 65.0, eq.LOWER)


def test_a_nan_score_reaches_nothing():
    unscored = SWEEP.assign(iou=math.nan)
    assert eq.pick(unscored, {"iou": 0.5, "error": 10.0}, QUALITY).bound == eq.LOWER


def test_the_fastest_setting_reaching_is_an_upper_bound():
    assert eq.pick(SWEEP, {"iou": 0.5, "error": 10.0}, QUALITY) == eq.Pick("coarse", 2.0, eq.UPPER)


def test_scores_without_a_metric_or_a_row_are_refused():
    with pytest.raises(ValueError, match=r"no column \['error'\]"):
        eq.pick(SWEEP.drop(columns="error"), {"iou": 0.9, "error": 1.0}, QUALITY)
    with pytest.raises(ValueError, match="no row"):
        eq.pick(SWEEP.iloc[:0], {"iou": 0.9, "error": 1.0}, QUALITY)


def _table():
    networks = {
        "net": eq.Network({"iou": 0.92, "error": 6.0}, 4.0, {"network_ms": 3.0}),
        "perfect": eq.Network({"iou": 1.0, "error": 0.5}, 2.0),
    }
    return eq.table("toy", "scenes", "tracer", SWEEP, networks, QUALITY)


def test_the_table_holds_every_setting_and_each_networks_pick():
    table = _table()
    assert set(table.columns) == {
        "method",
        "dataset",
        "model",
        "split",
        "setting",
        "bound",
        "metric",
        "value",
    }
    assert set(table.split) == {eq.SPLIT} and set(table.method) == {"toy"}
    tracer = table[table.model == "tracer"]
    assert set(tracer.bound) == {eq.MEASURED}
    assert len(tracer) == 4 * 3  # ms_per_frame, iou, error per setting
    value = table.set_index(["model", "setting", "bound", "metric"])["value"]
    assert value["tracer", "fine", eq.MEASURED, "ms_per_frame"] == 17.0
    assert value["net", "fine", eq.WITHIN, eq.SPEEDUP] == pytest.approx(17.0 / 4.0)
    assert value["net", "fine", eq.WITHIN, eq.REFERENCE_MS] == 17.0
    assert value["net", "fine", eq.WITHIN, "network_ms"] == 3.0
    assert value["net", "fine", eq.WITHIN, "iou"] == 0.92
    assert value["perfect", "finest", eq.LOWER, eq.SPEEDUP] == pytest.approx(65.0 / 2.0)


def test_speedups_list_the_networks_only():
    frame = eq.speedups(_table())
    assert frame.to_dict("records") == [
        {
            "method": "toy",
            "dataset": "scenes",
            "model": "net",
            "setting": "fine",
            "bound": eq.WITHIN,
            "speedup": pytest.approx(4.25),
        },
        {
            "method": "toy",
            "dataset": "scenes",
            "model": "perfect",
            "setting": "finest",
            "bound": eq.LOWER,
            "speedup": pytest.approx(32.5),
        },
    ]


def test_a_bound_is_stated_with_its_word():
    assert eq.stated(4.25, eq.WITHIN) == "4.25x"
    assert eq.stated(32.5, eq.LOWER) == ">= 32.5x (lower bound)"
    assert eq.stated(32.5, eq.UPPER) == "<= 32.5x (upper bound)"


def test_a_target_is_met_by_a_pick_or_a_lower_bound_never_by_an_upper_bound():
    assert eq.met(5.0, eq.WITHIN, 5.0) and not eq.met(4.9, eq.WITHIN, 5.0)
    assert eq.met(5.0, eq.LOWER, 5.0)
    assert not eq.met(50.0, eq.UPPER, 5.0)
    met = {t.check.split()[0]: (t.met, t.measured) for t in eq.targets(_table(), 10.0, "tracer")}
    assert met == {"net": (False, pytest.approx(4.25)), "perfect": (True, pytest.approx(32.5))}
    (net, _) = eq.targets(_table(), 10.0, "tracer")
    assert net.subject == "scenes"
    assert "against fine, within the sweep" in net.check


def _renamed(method: Method, key: str, title: str) -> Method:
    """A built-in method's record under another key and title, its stages' rules kept."""
    return dataclasses.replace(method, key=key, title=title, stage_rules=method.stages)


def test_a_registered_method_gets_the_reports_equal_quality_table(tmp_path, monkeypatch):
    toy = _renamed(methods.METHODS[0], "toy", "Toy: a registered method")
    monkeypatch.setattr(methods, "METHODS", (*methods.METHODS, toy))
    path = tmp_path / "results" / "toy" / "equal_quality.csv"
    io.write_csv(path, _table())
    html = build.equal_quality_summary([path])
    for cell in ("Toy", "scenes", "net", "4.25x", "fine", "&gt;= 32.5x (lower bound)", "finest"):
        assert f"<td>{cell}</td>" in html
    assert build.equal_quality_summary([tmp_path / "results" / "toy" / "metrics.csv"]) == ""
    # Its targets, by the shared rule, as the report's summary counts them.
    targets = tables.target_table("toy", eq.targets(_table(), 10.0, "tracer"))
    summary = build._targets(targets)
    assert summary["met"] == 1
    assert summary["missed"] == [
        "scenes: net at least 10x faster than the cheapest tracer of its quality "
        "(against fine, within the sweep) (measured 4.25)"
    ]


# Triangles as the cost (the appearance-driven simplification against the classic QEM +
# bake): budgets of a mesh of 100 triangles, PSNR better higher, FLIP better lower.
TRIANGLE_QUALITY = {"psnr": True, "flip": False}
BUDGETS = pd.DataFrame(
    [("1x", 100, 30.0, 0.05), ("2x", 199, 33.0, 0.03), ("4x", 401, 35.0, 0.02)],
    columns=["setting", "triangles", "psnr", "flip"],
)


def test_a_networks_time_row_keeps_its_metrics_in_order():
    """Time is the default cost: the columns of the NDR, DeepPRT and metaballs tables."""
    table = _table()
    assert table.equals(
        eq.table(
            "toy",
            "scenes",
            "tracer",
            SWEEP,
            {
                "net": eq.Network({"iou": 0.92, "error": 6.0}, 4.0, {"network_ms": 3.0}),
                "perfect": eq.Network({"iou": 1.0, "error": 0.5}, 2.0),
            },
            QUALITY,
            eq.TIME,
        )
    )
    net = table[table.model == "net"]
    assert list(net.metric) == [
        "ms_per_frame",
        "iou",
        "error",
        "network_ms",
        "equal_quality_reference_ms",
        "equal_quality_speedup",
    ]


def test_with_triangles_the_pick_is_the_fewest_triangles_reaching_on_every_metric():
    cost = eq.TRIANGLES
    assert eq.pick(BUDGETS, {"psnr": 32.0, "flip": 0.04}, TRIANGLE_QUALITY, cost) == eq.Pick(
        "2x", 199.0, eq.WITHIN
    )
    # PSNR reached at 2x, FLIP only at 4x.
    assert eq.pick(BUDGETS, {"psnr": 32.0, "flip": 0.025}, TRIANGLE_QUALITY, cost).setting == "4x"
    # The same bounds: none reaching is at least the ratio to the most triangles...
    assert eq.pick(BUDGETS, {"psnr": 40.0, "flip": 0.01}, TRIANGLE_QUALITY, cost) == eq.Pick(
        "4x", 401.0, eq.LOWER
    )
    # ... and the fewest reaching already is at most the ratio to them.
    assert eq.pick(BUDGETS, {"psnr": 29.0, "flip": 0.06}, TRIANGLE_QUALITY, cost) == eq.Pick(
        "1x", 100.0, eq.UPPER
    )
    # Not the order listed, the count: a reordered sweep picks the same.
    assert eq.pick(BUDGETS[::-1], {"psnr": 32.0, "flip": 0.04}, TRIANGLE_QUALITY, cost).setting == (
        "2x"
    )
    with pytest.raises(ValueError, match=r"no column \['triangles'\]"):
        eq.pick(SWEEP, {"iou": 0.9, "error": 1.0}, QUALITY, cost)


def _triangle_table():
    ours = {
        "ours": eq.Network({"psnr": 32.0, "flip": 0.04}, 100.0),
        "sharper": eq.Network({"psnr": 36.0, "flip": 0.01}, 100.0),
    }
    return eq.table("simplify", "head", "classic", BUDGETS, ours, TRIANGLE_QUALITY, eq.TRIANGLES)


def test_the_triangle_table_names_its_cost_ratio_and_reference():
    table = _triangle_table()
    value = table.set_index(["model", "setting", "bound", "metric"])["value"]
    assert value["classic", "2x", eq.MEASURED, "triangles"] == 199.0
    assert list(table[table.model == "ours"].metric) == [
        "triangles",
        "psnr",
        "flip",
        "equal_quality_reference_triangles",
        "equal_quality_triangle_ratio",
    ]
    assert value["ours", "2x", eq.WITHIN, "equal_quality_triangle_ratio"] == pytest.approx(1.99)
    assert value["ours", "2x", eq.WITHIN, "equal_quality_reference_triangles"] == 199.0
    assert value["sharper", "4x", eq.LOWER, "equal_quality_triangle_ratio"] == pytest.approx(4.01)
    assert not set(table.metric) & {eq.SPEEDUP, eq.REFERENCE_MS, "ms_per_frame"}


def test_ratios_are_those_of_the_tables_cost_only():
    triangles, time = _triangle_table(), _table()
    assert eq.speedups(triangles).empty and eq.ratios(time, eq.TRIANGLES).empty
    assert list(eq.ratios(triangles, eq.TRIANGLES).ratio) == pytest.approx([1.99, 4.01])
    both = pd.concat([time, triangles])
    assert list(eq.ratios(both).ratio) == list(eq.speedups(time).speedup)


def test_a_triangle_target_says_fewer_triangles_and_keeps_the_bounds_meaning():
    found = eq.targets(_triangle_table(), 2.0, "classic QEM + bake", eq.TRIANGLES)
    assert [(t.subject, t.met) for t in found] == [("head", False), ("head", True)]
    assert found[0].check == (
        "ours at least 2x fewer triangles than the cheapest classic QEM + bake of its "
        "quality (against 2x, within the sweep)"
    )
    assert found[1].measured == pytest.approx(4.01) and "4x, lower bound" in found[1].check
    # An upper bound never meets a target, whatever its ratio.
    worse = eq.table(
        "simplify",
        "head",
        "classic",
        BUDGETS,
        {"ours": eq.Network({"psnr": 29.0, "flip": 0.06}, 50.0)},
        TRIANGLE_QUALITY,
        eq.TRIANGLES,
    )
    (upper,) = eq.targets(worse, 1.5, "classic", eq.TRIANGLES)
    assert upper.measured == pytest.approx(2.0) and not upper.met
    assert "(against 1x, upper bound)" in upper.check


def test_the_reports_summary_has_a_table_per_cost(tmp_path, monkeypatch):
    toy = _renamed(methods.METHODS[0], "toy", "Toy: a registered method")
    mesh = _renamed(methods.METHODS[0], "mesh", "Mesh: triangles")
    monkeypatch.setattr(methods, "METHODS", (*methods.METHODS, toy, mesh))
    paths = [tmp_path / "results" / key / "equal_quality.csv" for key in ("mesh", "toy")]
    io.write_csv(paths[0], _triangle_table().assign(method="mesh"))
    io.write_csv(paths[1], _table())
    html = build.equal_quality_summary(paths)
    time, triangles = html.split("</table>")[:2]
    assert "<th>x faster at equal quality</th>" in time and "<th>network</th>" in time
    assert "<td>4.25x</td>" in time and "<td>Toy</td>" in time
    assert "<th>x fewer triangles at equal quality</th>" in triangles
    assert "<th>model</th>" in triangles and "<td>Mesh</td>" in triangles
    for cell in ("ours", "1.99x", "2x", "&gt;= 4.01x (lower bound)", "4x"):
        assert f"<td>{cell}</td>" in triangles
