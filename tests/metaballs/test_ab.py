import numpy as np
import pytest
import torch

from neurender.metaballs import ab, inputs, raymarch, scenes


def test_ab_round_trip(tmp_path):
    gen = torch.Generator().manual_seed(1)
    scene = scenes.sample_scene(5, (1.0, 2.0), gen).to(torch.float32)
    target = raymarch.render_gbuffers(scene, 16).stack()
    x = inputs.draw_inputs(scene, 16)
    packed = ab.pack(x, target)
    assert packed.shape == (16, 48, 4) and packed.dtype == np.uint8
    ab.write_ab(tmp_path / "a.png", packed)
    back = ab.read_ab(tmp_path / "a.png")
    for key, ref in (("inputs", x), ("target", target)):
        assert back[key].shape == ref.shape
        np.testing.assert_allclose(back[key], ref, atol=0.5 / 255 + 1e-6)


def test_malformed_ab_images_are_refused_with_their_name(tmp_path):
    packed = np.zeros((16, 48, 4), np.uint8)
    with pytest.raises(ValueError, match="expected \\(W, 3W, 4\\)"):
        ab.unpack(packed[:, :40])
    ab.write_ab(tmp_path / "narrow.png", packed[:, :40])
    with pytest.raises(ValueError, match="narrow.png"):
        ab.read_ab(tmp_path / "narrow.png")
