import math

import pandas as pd
import pytest
import torch

from neurender.metaball import Kernel
from neurender.metaballs import families, inputs, scale


def _mean_rows(values):
    """Mean rows of (renderer, setting, balls, width, ms, iou, normal error)."""
    rows = []
    for renderer, setting, balls, width, ms, iou, normal in values:
        head = {"renderer": renderer, "setting": setting, "engine": "x", "balls": balls}
        head["width"] = width
        for metric, value in (
            ("ms_per_frame", ms),
            ("iou_depth", iou),
            ("normal_error_mean_deg", normal),
        ):
            rows.append({**head, "metric": metric, "value": value})
    return pd.DataFrame(rows)


def test_equal_quality_picks_the_cheapest_setting_reaching_the_network_on_every_metric():
    mean = _mean_rows(
        [
            ("net", "trained", 100, 64, 10.0, 0.90, 5.0),
            ("marcher", "coarse", 100, 64, 20.0, 0.95, 6.0),  # misses the normal error
            ("marcher", "medium", 100, 64, 40.0, 0.91, 4.0),  # reaches both
            ("marcher", "fine", 100, 64, 80.0, 0.99, 1.0),  # reaches, dearer
            ("splats", "only", 100, 64, 5.0, 0.50, 30.0),  # reaches nothing
        ]
    )
    table = scale.equal_quality_rows(mean, ["net"]).set_index("renderer")
    assert table.loc["marcher", "setting"] == "medium"
    assert table.loc["marcher", "speedup"] == pytest.approx(4.0)
    assert table.loc["marcher", "bound"] == "within the sweep"
    # Splats' only setting reaches nothing: against it, a lower bound (5 ms over 10 ms).
    assert table.loc["splats", "bound"] == "lower bound"
    assert table.loc["splats", "speedup"] == pytest.approx(0.5)


def test_equal_quality_at_a_timed_only_width_takes_the_trained_widths_quality():
    mean = _mean_rows(
        [
            ("net", "trained", 100, 64, 10.0, 0.90, 5.0),
            ("net", "timed only", 100, 256, 30.0, math.nan, math.nan),
            ("marcher", "fine", 100, 256, 300.0, 0.95, 3.0),
        ]
    )
    table = scale.equal_quality_rows(mean, ["net"])
    row = table[table.width == 256].iloc[0]
    assert row.quality_from_width == 64 and row.speedup == pytest.approx(10.0)


def test_measure_scene_scores_the_exact_renderer_perfectly_and_every_renderer_once():
    scene = families.cluster(
        60, torch.Generator().manual_seed(0), packing=0.15, kernel=Kernel("wyvill", 2.0)
    ).to(torch.float32)

    def draw(s):
        return inputs.draw_spheres(s, 32).stack()

    def network(x):
        return x  # the spheres as the "network's" output

    measured = scale.measure_scene(scene, 32, {"spheres net": (draw, network, "x")}, True, 1)
    rows = pd.DataFrame(measured.rows)
    values = rows.pivot_table(index=["renderer", "setting"], columns="metric", values="value")
    spheres = values.loc[("isolated spheres", "spheres of radius r")]
    net = values.loc[("spheres net", "trained")]
    # The network that returns the sphere impostors scores exactly as the impostors do.
    for metric in ("iou_depth", "depth_error_world", "normal_error_mean_deg"):
        assert net[metric] == pytest.approx(spheres[metric])
    assert values.loc[("exact", "reference"), "covered"] > 0.05
    assert values.loc[("exact", "reference"), "near_plane"] == 0
    expected = {(s.renderer, s.setting) for s in scale.baselines()}
    assert expected <= set(values.index)
    assert (values["ms_per_frame"] > 0).all()
