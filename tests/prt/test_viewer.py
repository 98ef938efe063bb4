"""The DeepPRT viewer: its file decodes to the frame's arrays, the page's shading with a
turned probe equals relighting with the turned map, and the job and the mesh figure run on
a tiny object as the workflow calls them."""

import numpy as np
import pytest
from PIL import Image

from neurender import sh, viewer_data
from neurender.geometry import grid_faces
from neurender.prt import data_jobs, frames, jobs, transfer
from neurender.prt.viewer import TURNS, prt_view

N, K = 6, 16


def _split(frames_=3, seed=0):
    rng = np.random.default_rng(seed)
    f = lambda *shape: rng.normal(size=shape).astype(np.float32)  # noqa: E731
    return frames.Split(
        f(frames_, N, N, 3),
        f(frames_, N, N, 3),
        f(frames_, N, N, K),
        f(frames_, N, N, 3, K),
        f(frames_, 2),
    )


def test_the_viewer_data_decode_to_the_frame_and_the_predictions():
    data = _split()
    predictions = {"DeepPRT": np.random.default_rng(1).normal(size=(3, K, N, N))}
    view = prt_view(data, 1, predictions, {"sky": np.ones((K, 3))}, 4)
    decode = viewer_data.decode_array
    np.testing.assert_array_equal(
        decode(view["positions"], "f4", (N * N, 3)), data.positions[1].reshape(-1, 3)
    )
    np.testing.assert_array_equal(decode(view["indices"], "u4", (-1, 3)), grid_faces(N))
    assert list(view["transfer"]) == ["ground truth", "DeepPRT"] and view["coefficients"] == K
    truth = decode(view["transfer"]["ground truth"], "f4", (N, N, K))
    np.testing.assert_array_equal(truth, data.diffuse[1])
    predicted = decode(view["transfer"]["DeepPRT"], "f4", (N, N, K))
    np.testing.assert_allclose(predicted, np.moveaxis(predictions["DeepPRT"][1], 0, -1))
    assert view["probes"]["sky"]["turns"] == [360.0 * t / TURNS for t in range(TURNS)]


@pytest.mark.parametrize("turn", [0, 1, 5, 12, 23])
def test_shading_under_a_turned_probe_equals_relighting_with_the_turned_map(turn):
    """Turn ``t`` is ``360 t / 24`` degrees about +y: on a 48-column map, the map rolled by
    ``-2 t`` columns (a right-handed turn moves content to smaller u)."""
    coeffs = np.random.default_rng(2).normal(size=(K, 3))
    image = sh.reconstruct_latlong(coeffs, 24, 48)
    data = _split()
    view = prt_view(data, 0, {}, {"probe": sh.project_latlong(image, 4)}, 4)
    lights = viewer_data.decode_array(view["probes"]["probe"]["lights"], "f4", (TURNS, K, 3))
    t = viewer_data.decode_array(view["transfer"]["ground truth"], "f4", (N * N, K))
    in_page = np.einsum("vj,jc->vc", t, lights[turn]) / np.pi  # what viewers.js computes
    direct = transfer.relight_diffuse(
        data.diffuse[0].reshape(-1, K), sh.project_latlong(np.roll(image, -2 * turn, axis=1), 4)
    )
    np.testing.assert_allclose(in_page, direct, atol=2e-3 * np.abs(direct).max())


@pytest.fixture(scope="module")
def trained(tmp_path_factory, prt_params):
    """A tiny head through the DeepPRT jobs: probes, frames of every split, a one-epoch
    network and MoMoPRT."""
    d = tmp_path_factory.mktemp("viewer")
    for probe in ("sky", "sunset"):
        files = {"exr": d / f"{probe}.exr", "sh": d / f"{probe}_sh.csv"}
        data_jobs.prt_probe({}, files, prt_params("prt_probe", probe=probe), 1)
    gim = {"gim": d / "gim.npz", "stats": d / "gim.csv"}
    data_jobs.prt_geometry_image({}, gim, prt_params("prt_geometry_image", object="head"), 1)
    seq = {"seq": d / "seq.npz"}
    data_jobs.prt_sequence(
        {"gim": d / "gim.npz"}, seq, prt_params("prt_sequence", object="head"), 1
    )
    files = {"seq": str(d / "seq.npz")}
    for split in ("train", "val", "test"):
        data_jobs.prt_transfer(
            {"seq": d / "seq.npz", "light": d / "sky_sh.csv"},
            {"frames": d / split, "manifest": d / f"{split}.csv"},
            prt_params("prt_transfer", object="head", split=split),
            1,
        )
        files |= {f"{split}_dir": str(d / split), f"{split}_manifest": str(d / f"{split}.csv")}
    network = {"variant": "paper", "material": "diffuse"}
    trained = {"checkpoint": d / "net.pt", "loss": d / "loss.csv"}
    jobs.prt_train(files, trained, prt_params("prt_train", **network), 1)
    graphs = {"onnx": d / "net.onnx", "int8": d / "net_int8.onnx"}
    deploy = prt_params("prt_deploy", object="head", **network)
    jobs.prt_deploy({**files, "checkpoint": d / "net.pt"}, graphs, deploy, 1)
    momoprt = prt_params("prt_momoprt", material="diffuse")
    data_jobs.prt_momoprt(files, {"model": d / "momo.npz"}, momoprt, 1)
    return d, files


def test_the_viewer_job_writes_every_model_and_probe(trained, prt_params):
    d, files = trained
    inputs = files | {"deepprt": str(d / "net.pt"), "onnx": str(d / "net.onnx")}
    inputs |= {
        "momoprt": str(d / "momo.npz"),
        "probes": [str(d / "sky_sh.csv"), str(d / "sunset_sh.csv")],
    }
    params = prt_params("prt_viewer", object="head")
    jobs.prt_viewer(inputs, {"viewer": d / "viewer.json"}, params, 1)
    viewer = viewer_data.read(d / "viewer.json")
    assert viewer["kind"] == "prt" and "head" in viewer["title"]
    data = viewer["data"]
    assert list(data["transfer"]) == ["ground truth", "DeepPRT", "MoMoPRT"]
    assert list(data["probes"]) == ["sky", "sunset"]
    test = frames.read_frame(d / "test" / "frame_0000.exr", 4)
    truth = viewer_data.decode_array(data["transfer"]["ground truth"], "f4", test["T"].shape)
    np.testing.assert_array_equal(truth, test["T"])
    light = viewer_data.decode_array(data["probes"]["sunset"]["lights"], "f4", (TURNS, K, 3))
    np.testing.assert_allclose(light[0], frames.read_sh_light(d / "sunset_sh.csv"), atol=1e-6)


def test_the_mesh_figure_job_draws_the_geometry_image_and_frames(trained, prt_params):
    d, files = trained
    out = d / "figures" / "head_meshes.png"
    params = prt_params("prt_mesh_figure", object="head")
    jobs.prt_mesh_figure({"gim": str(d / "gim.npz"), "seq": files["seq"]}, {"png": out}, params, 1)
    image = np.asarray(Image.open(out).convert("RGB"))
    assert image.shape == (550, 1100, 3)
    assert (image.sum(-1) < 600).mean() > 0.05  # meshes drawn on the white background
