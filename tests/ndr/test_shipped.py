"""The shipped NDR graph: prefiltered coarse shading and the network in one ONNX file."""

import numpy as np
import pytest
import torch

from neurender import lights
from neurender.camera import pixel_rays
from neurender.ndr import environments
from neurender.ndr import prefiltered as pf
from neurender.ndr.buffers import light_features
from neurender.ndr.model import NDRModel
from neurender.ndr.render import camera
from neurender.ndr.shipped import (
    DYNAMIC_AXES,
    INPUTS,
    ShadingPart,
    ShippedNDR,
    gbuffer_groups,
)
from neurender.ndr.variants import VARIANTS
from neurender.nn.inference import OnnxNetwork, export_onnx

WIDTH, DISTANCE, FOV = 16, 3.9, 30.0


def _inputs(batch: int, seed: int):
    """Random G-buffers (unit normals facing the camera, a mask), the lighting of a
    real-world-like map (a sun: lights) and built-in probes."""
    g = torch.Generator().manual_seed(seed)
    n = torch.randn(batch, 3, WIDTH, WIDTH, generator=g)
    n[:, 2] = n[:, 2].abs() + 0.3
    n = torch.nn.functional.normalize(n, dim=1)
    r = 0.05 + 0.95 * torch.rand(batch, 1, WIDTH, WIDTH, generator=g)
    d = torch.rand(batch, 1, WIDTH, WIDTH, generator=g)
    a_d, a_s = (torch.rand(batch, 3, WIDTH, WIDTH, generator=g) for _ in range(2))
    mask = (torch.rand(batch, 1, WIDTH, WIDTH, generator=g) > 0.3).float()
    sunlit = environments.sunlit_environment(np.random.default_rng(seed), 32)
    envs = [sunlit, lights.procedural_probe("studio", 32), lights.procedural_probe("sky", 32)]
    lighting = [pf.lighting(e, environments.resize_latlong(e, 16)) for e in envs]
    lighting = [lighting[i % 3] for i in range(batch)]
    sh = torch.stack([x.coefficients.reshape(-1) for x in lighting]).float()
    irradiance = torch.stack([x.irradiance for x in lighting]).float()
    cells = torch.stack([x.cells for x in lighting]).float()
    bright = pf.stack_lights([x.lights for x in lighting]).float()
    buffers = {"N": n, "R": r, "D": d, "A_D": a_d, "A_S": a_s, "mask": mask}
    return buffers, (sh, irradiance, cells, bright), lighting


@pytest.fixture(scope="module")
def graph():
    torch.manual_seed(0)
    model = NDRModel(VARIANTS["ndr"], widths=[4, 8], sh_hidden=8).eval()
    return ShippedNDR(model, DISTANCE, FOV, WIDTH)


def _stack(graph, buffers):
    return torch.cat([buffers[k] for k in gbuffer_groups(graph.model)], 1)


def test_the_graph_is_the_shading_then_the_network(graph):
    """Per pixel, the graph's shading is :func:`prefiltered_shading` with the camera's view
    directions (0 off the mask), and ``I_R`` is the model's on that batch."""
    buffers, light, per_map = _inputs(2, 1)
    sh = light[0]
    assert light[-1][0, :, 3:6].sum() > 0  # the sunlit map has lights
    x = _stack(graph, buffers)
    with torch.inference_mode():
        got = graph.batch(x, *light)
        i_r = graph(x, *light)
        expected_i_r = graph.model({**buffers, **got})["I_R"]
    np.testing.assert_allclose(i_r.numpy(), expected_i_r.numpy(), rtol=1e-6)
    np.testing.assert_allclose(got["light"].numpy(), light_features(sh.numpy()).numpy())
    view = torch.from_numpy(-pixel_rays(camera(DISTANCE, FOV), WIDTH).reshape(-1, 3))
    for b in range(2):
        normals = buffers["N"][b].flatten(1).T.double()
        alpha = buffers["R"][b].flatten().double() ** 2
        s_d, s_s = pf.prefiltered_shading(normals, view, alpha, per_map[b])
        m = buffers["mask"][b].flatten()[:, None].double()
        for name, ref in (("S_D", s_d), ("S_S", s_s)):
            mine = got[name][b].flatten(1).T.double()
            np.testing.assert_allclose(mine.numpy(), (ref * m).numpy(), rtol=1e-4, atol=1e-5)


def test_onnx_file_renders_what_pytorch_renders(graph, tmp_path):
    """Exported on a batch of 2, the file renders a batch of 3 unseen inputs (with another
    number of lights) as PyTorch does, and so does the shading part alone."""
    buffers, light, _ = _inputs(2, 2)
    example = (_stack(graph, buffers), *light)
    kwargs = {"atol": 1e-3, "rtol": 1e-4, "input_names": INPUTS, "dynamic_axes": DYNAMIC_AXES}
    export_onnx(graph, example, tmp_path / "ndr.onnx", **kwargs)
    part = ShadingPart(graph.shading)
    export_onnx(part, example, tmp_path / "shading.onnx", **kwargs)
    buffers, light, _ = _inputs(3, 3)
    padded = pf.stack_lights([*light[-1], pf.no_lights(example[-1].shape[1] + 3)])[:3]
    fresh = (_stack(graph, buffers), *light[:-1], padded.float())
    for module, name in ((graph, "ndr"), (part, "shading")):
        with torch.inference_mode():
            expected = module(*fresh).numpy()
        got = OnnxNetwork(tmp_path / f"{name}.onnx")(*(t.numpy() for t in fresh))
        assert got.shape == expected.shape
        np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4 * np.abs(expected).max())
