import pandas as pd

from neurender.metaballs import speed

from .keys import KERNEL


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
            "engine": ["pytorch", "onnxruntime"] * 2,
            "ms_per_frame": [10.0, 5.0, 100.0, 4.0],
        }
    )
    table = speed.timing_table(timings, flips, balls)
    demo = table[table.dataset == "demo"].set_index("metric")["value"]
    assert demo["speedup_at_20_balls"] == 25.0
    assert demo["silhouette_flips"] == 0.1 and demo["silhouette_flips_raymarch"] == 0.05
    assert demo["network_ms_per_frame"] == 2.0
    assert set(table[table.model == "net"].engine) == {"onnxruntime"}
    assert set(table[table.model == speed.RAY_MARCHER].engine) == {"pytorch"}
    per_balls = table[table.metric == "ms_per_frame"]
    assert per_balls.dataset.tolist() == ["3 balls"] * 2 + ["20 balls"] * 2


def test_timing_table_speedup_skips_frames_the_near_plane_walls_off():
    row = {"frame": 0, "model": "net", "input_ms": 1.0, "network_ms": 2.0}
    timings = pd.DataFrame([row | {"shading_ms": 3.0, "raymarch_ms": 4.0}])
    flips = pd.DataFrame({"frame": [1], "net": [0.1], "ray marching": [0.05]})
    balls = pd.DataFrame(
        {
            "balls": [3, 3, 20, 20, 145, 145],
            "model": [speed.RAY_MARCHER, "net"] * 3,
            "engine": ["pytorch", "onnxruntime"] * 3,
            "ms_per_frame": [10.0, 5.0, 100.0, 4.0, 900.0, 4.0],
            "near_plane": [0.0, 0.0, 0.04, 0.04, 0.99, 0.99],
        }
    )
    table = speed.timing_table(timings, flips, balls)
    demo = table[table.dataset == "demo"].set_index("metric")["value"]
    assert demo["speedup_at_20_balls"] == 25.0 and "speedup_at_145_balls" not in demo
    walled = table[(table.dataset == "145 balls") & (table.metric == "near_plane")]
    assert walled.value.tolist() == [0.99, 0.99]


class _FakeRenderer:
    """Inputs and network of a renderer that runs its network through ONNX Runtime."""

    engine = "onnxruntime"

    def inputs(self, scene):
        return scene.centres.new_zeros(4, 8, 8)

    def __call__(self, x):
        return x[:, :3]


def test_frame_times_name_every_model_and_its_engine_per_ball_count():
    cfg = {"timing_balls": [2, 5], "seed": 0, "radius": [1.0, 2.0], "width": 8, **KERNEL}
    balls = speed.frame_time_vs_balls({"net": _FakeRenderer()}, cfg, repeats=1)
    assert balls.balls.tolist() == [2, 2, 5, 5]
    assert balls.model.tolist() == [speed.RAY_MARCHER, "net"] * 2
    assert balls.engine.tolist() == ["pytorch", "onnxruntime"] * 2
    assert (balls.ms_per_frame > 0).all()
    assert balls.near_plane.between(0, 1).all()
