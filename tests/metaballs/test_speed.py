import pandas as pd

from neurender.metaballs import speed


def test_timing_table_speedup_is_at_the_most_balls():
    timings = pd.DataFrame(
        [
            {
                "frame": 0,
                "model": "net",
                "input_ms": 1.0,
                "network_ms": 2.0,
                "shading_ms": 3.0,
                "raymarch_ms": 4.0,
            }
        ]
    )
    flips = pd.DataFrame({"frame": [1], "net": [0.1], "ray marching": [0.05]})
    balls = pd.DataFrame(
        {
            "balls": [3, 3, 20, 20],
            "model": [speed.RAY_MARCHER, "net", speed.RAY_MARCHER, "net"],
            "ms_per_frame": [10.0, 5.0, 100.0, 4.0],
        }
    )
    table = speed.timing_table(timings, flips, balls)
    demo = table[table.dataset == "demo"].set_index("metric")["value"]
    assert demo["speedup_at_20_balls"] == 25.0
    assert demo["silhouette_flips"] == 0.1 and demo["silhouette_flips_raymarch"] == 0.05
    assert demo["network_ms_per_frame"] == 2.0
    per_balls = table[table.metric == "ms_per_frame"]
    assert per_balls.dataset.tolist() == ["3 balls"] * 2 + ["20 balls"] * 2
