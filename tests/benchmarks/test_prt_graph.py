"""The parts of the shipped shadowing graph that benchmarks/prt_graph.py times."""

import pytest
import torch

from neurender.prt.local_model import correction_gate

from . import scripts

graph_script = scripts.load("prt_graph")


def test_frame_normals_are_unit_and_orthogonal_to_the_surface():
    x = graph_script.frame(16)[0]
    p, n = x[:3], x[3:]
    torch.testing.assert_close(n.norm(dim=0), torch.ones(16, 16))
    du = p[:, :, 1:] - p[:, :, :-1]  # along u (columns)
    mid = 0.5 * (n[:, :, 1:] + n[:, :, :-1])
    assert (mid * du).sum(0).abs().max() < 0.02 * du.norm(dim=0).max()


@pytest.mark.parametrize("material", ["diffuse", "glossy"])
def test_the_timed_parts_compose_the_whole_graph(material):
    """The whole graph is the unshadowed transfer minus the disks' occlusion plus the core's
    gated correction of the local features and the normalised occlusion: the parts timed
    are the graph's own computations."""
    model = graph_script.shadowing_model(material, seed=1)
    x = graph_script.frame(32)
    part = {name: graph_script.Part(model, name) for name in graph_script.PARTS}
    with torch.inference_mode():
        occlusion = part["disks' occlusion"](x)
        normalised = occlusion / model.o_scale
        features = torch.cat([part["local features"](x), normalised], 1)
        correction = part["core network"](features) * correction_gate(normalised, model.cfg.colours)
        expected = part["unshadowed transfer"](x) - occlusion
        expected = expected + correction * model.t_scale + model.t_offset
        got = model(x)
    assert correction.abs().max() > 0  # the head is not zero: the core's term is tested
    torch.testing.assert_close(got, expected)
