import dataclasses
from dataclasses import replace

import numpy as np
import onnx as onnx_lib
import pytest
import torch

from neurender.geometry import grid_normals
from neurender.nn.inference import OnnxNetwork, export_onnx, prepare_for_inference
from neurender.prt import unshadowed
from neurender.prt.frames import Split
from neurender.prt.local_model import (
    DilatedNet,
    LocalConfig,
    ShadowingTransfer,
    correction_gate,
    load_local,
    local_features,
    local_mean,
    receptive_field,
)
from neurender.prt.model import DeepPRT, export_deepprt, export_int8
from neurender.prt.training import shadowing_training, train_local


def _local(**fields):
    """The variant with the schema's SH bands and a small U-Net, ``fields`` changed (the
    unet core and a core without the occlusion input ungated)."""
    ungated = fields.get("architecture") == "unet" or fields.get("occlusion_input") is False
    defaults = {"n_bands": 4, "widths": (8, 16), "blocks": 1, "gated": not ungated}
    return LocalConfig(**{**defaults, **fields})


def _bumpy(n=16, seed=0, shift=(0.0, 0.0, 0.0)):
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    rng = np.random.default_rng(seed)
    z = 0.3 * np.sin(3 * xx + rng.uniform(0, 6)) * np.cos(2 * yy + rng.uniform(0, 6))
    return np.stack([xx, yy, z], -1) + np.asarray(shift)


def _raw(positions):
    x = np.concatenate([positions, grid_normals(positions)], -1)
    return np.ascontiguousarray(np.moveaxis(x, -1, 0)[None], np.float32)


def _trained_like(cfg, seed=0):
    """A wrapper with random (non-zero) weights everywhere, as after training."""
    torch.manual_seed(seed)
    coeffs = light = None
    if cfg.material == "glossy":
        light = np.random.default_rng(seed).normal(size=(16, 3))
        coeffs = unshadowed.glossy_polynomial(light)
    model = ShadowingTransfer(cfg, coeffs, light)
    with torch.no_grad():
        for p in model.core.parameters():
            p.normal_(0, 0.2)
        model.t_scale.uniform_(0.5, 1.5)
        model.t_offset.uniform_(-0.1, 0.1)
    return model.eval()


def test_receptive_field_of_the_dilated_net():
    """An impulse at the centre reaches exactly 1 + 2 sum(dilations) pixels of the output."""
    net = DilatedNet(1, 1, 4, (1, 2, 4))
    with torch.no_grad():
        net.head.weight.fill_(1.0)
    x = torch.zeros(2, 1, 41, 41, requires_grad=True)
    net.eval()(x)[0, 0, 20, 20].backward()
    reached = (x.grad[0, 0].abs() > 0).any(0).nonzero()
    assert reached.max() - reached.min() + 1 == receptive_field((1, 2, 4)) == 15


def test_zero_network_on_a_flat_plane_returns_the_unshadowed_transfer():
    t = np.linspace(-1, 1, 16)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    x = _raw(np.stack([xx, yy, np.zeros_like(xx)], -1))
    model = ShadowingTransfer(_local()).eval()  # the head starts at zero
    out = model(torch.from_numpy(x)).detach().numpy()
    want = unshadowed.diffuse(np.array([0.0, 0.0, 1.0]), 4)
    assert np.allclose(out[0].reshape(16, -1).T, want, atol=1e-6)


@pytest.mark.parametrize("architecture", ["dilated", "unet"])
def test_output_does_not_change_when_the_shape_is_translated(architecture):
    cfg = _local(architecture=architecture)
    model = _trained_like(cfg)
    a = model(torch.from_numpy(_raw(_bumpy()))).detach()
    b = model(torch.from_numpy(_raw(_bumpy(shift=(5.0, -3.0, 12.0))))).detach()
    assert a.abs().max() > 0.1
    assert torch.allclose(a, b, atol=2e-5 * float(a.abs().max()))


def test_the_core_sees_an_occluder_beyond_its_receptive_field_only_through_the_disks():
    """A bump raised in one corner changes the core's output in the far corner (beyond
    its 7-px receptive field) when it reads the disks' occlusion; without, only through
    the frame's mean grid spacing (the local features' unit), far less."""
    cfg = _local(architecture="dilated", width=8, dilations=(1, 2), window=3, occlusion_grid=8)
    flat = _bumpy(n=32)
    raised = flat.copy()
    raised[:6, :6, 2] += 1.5 * np.exp(-((np.arange(6)[:, None] - 2.5) ** 2) / 4.0)
    far = (slice(None), slice(None), slice(12, 20), slice(0, 8))
    changed = {}
    for occlusion_input in (False, True):
        model = _trained_like(replace(cfg, occlusion_input=occlusion_input, gated=False))
        base, occlusion = model.estimates_of(_raw(flat))
        model.fit_normalisation(np.zeros_like(base), occlusion)  # the inputs' o_scale
        with torch.no_grad():
            a, b = (model.shadowing(torch.from_numpy(_raw(p))) for p in (flat, raised))
        changed[occlusion_input] = float((a[far] - b[far]).abs().max())
    assert changed[True] > 10 * changed[False]


def test_features_do_not_change_when_the_shape_is_scaled():
    p = _bumpy()
    a = local_features(torch.from_numpy(_raw(p)), 7)
    b = local_features(torch.from_numpy(_raw(4.0 * p)), 7)
    assert torch.allclose(a, b, atol=1e-5)


def test_local_mean_is_an_average_over_the_window():
    """Feature = (p - mean of the window inside the image) / (window/2 * mean edge length)."""
    p = _bumpy(n=12)
    feats = local_features(torch.from_numpy(_raw(p)), 5)[0, :3].numpy()
    edges = np.concatenate(
        [
            np.linalg.norm(np.diff(p, axis=1), axis=-1).ravel()[None],
            np.linalg.norm(np.diff(p, axis=0), axis=-1).ravel()[None],
        ]
    )
    spacing = 0.5 * (edges[0].mean() + edges[1].mean())
    i, j = 0, 7  # a border pixel: its window is cut to rows 0..2, columns 5..9
    mean = p[0:3, 5:10].reshape(-1, 3).mean(0)
    assert np.allclose(feats[:, i, j], (p[i, j] - mean) / (2.5 * spacing), atol=1e-5)


@pytest.mark.parametrize(
    ("material", "architecture"),
    [("diffuse", "dilated"), ("glossy", "dilated"), ("diffuse", "unet")],
)
def test_onnx_export_equals_pytorch(tmp_path, material, architecture):
    model = _trained_like(_local(material=material, architecture=architecture))
    x = np.concatenate([_raw(_bumpy(seed=s)) for s in range(3)])
    # As export_deepprt exports a checkpoint's graph: traced on two frames.
    export_onnx(prepare_for_inference(model), torch.from_numpy(x[:2]), tmp_path / "net.onnx")
    got = OnnxNetwork(tmp_path / "net.onnx")(x)  # a batch of 3: the batch axis is dynamic
    want = model(torch.from_numpy(x)).detach().numpy()
    assert got.shape == want.shape == (3, 16 if material == "diffuse" else 48, 16, 16)
    assert np.abs(got - want).max() <= 1e-4 * np.abs(want).max()


LIGHT = np.random.default_rng(9).normal(size=(16, 3))


def _split(seed, frames=4, n=16):
    pos = np.stack([_bumpy(n, seed * 100 + f) for f in range(frames)]).astype(np.float32)
    nrm = np.stack([grid_normals(p) for p in pos]).astype(np.float32)
    # A synthetic "shadowing": the unshadowed transfer darkened where z is low.
    dark = 1.0 - 0.5 * (pos[..., 2:3] < 0)
    diffuse = (unshadowed.diffuse(nrm.astype(np.float64), 4) * dark).astype(np.float32)
    coeffs = unshadowed.glossy_polynomial(LIGHT)
    glossy = unshadowed.glossy(nrm.astype(np.float64), coeffs).reshape(frames, n, n, 3, 16)
    glossy = (glossy * dark[..., None]).astype(np.float32)
    return Split(pos, nrm, diffuse, glossy, np.zeros((frames, 1), np.float32))


@pytest.mark.parametrize(
    ("material", "gated"), [("diffuse", True), ("glossy", True), ("glossy", False)]
)
def test_training_lowers_the_error_and_the_checkpoint_round_trips(tmp_path, material, gated):
    train, val = _split(0), _split(1)
    cfg = {"seed": 0, "epochs": 40, "batch_size": 2, "lr": 1e-2, "device": "cpu"}
    cfg["lr_schedule"] = "cosine"  # a config key: the schema's default, as the stage gets it
    local_cfg = _local(material=material, width=8, dilations=(1, 2), window=5, gated=gated)
    ckpt = tmp_path / "local.pt"
    model = train_local(
        train, val, local_cfg, cfg, 1, str(ckpt), str(tmp_path / "loss.csv"), light=LIGHT
    )
    x = torch.from_numpy(
        np.moveaxis(np.concatenate([val.positions, val.normals], -1), -1, 1).copy()
    )
    target = val.targets(material)
    with torch.no_grad():
        base = np.abs(model.base(x).numpy() - target).mean()
    with torch.no_grad():
        err = np.abs(model(x).numpy() - target).mean()
        loaded = load_local(ckpt)(x).numpy()
    # The synthetic darkening (z < 0) is not where the disks see occlusion everywhere, and
    # a gated correction acts only there: it gains less on it than an ungated one.
    bound = (0.75 if gated else 0.7) * base
    assert err < bound
    assert load_local(ckpt).cfg.gated == gated
    assert np.allclose(loaded, model(x).detach().numpy(), atol=1e-6)
    # The shared loader serves it as it serves the paper's form, by PyTorch and by the
    # exported file.
    onnx = tmp_path / "local.onnx"
    export_deepprt(ckpt, val, onnx)
    net = DeepPRT(ckpt, onnx, device="cpu")
    for engine in ("pytorch", "onnxruntime"):
        assert np.allclose(net.predict(val, engine=engine), loaded, rtol=1e-4, atol=1e-5)
    # Its int8 graph: convolutions quantized, served by ONNX Runtime alone, close to the
    # float32 graph and, like it, better than the estimate it corrects.
    int8_file = tmp_path / "local_int8.onnx"
    export_int8(onnx, train, int8_file)
    ops = {node.op_type for node in onnx_lib.load(str(int8_file)).graph.node}
    assert {"QuantizeLinear", "DequantizeLinear"} <= ops
    int8 = DeepPRT(ckpt, int8_file, device="cpu", pytorch=False)
    assert set(int8.engines) == {"onnxruntime"}
    approx = int8.predict(val)
    assert np.abs(approx - loaded).mean() <= 0.05 * np.abs(loaded).mean()
    assert np.abs(approx - target).mean() < bound


@pytest.mark.parametrize("window", [1, 3, 15])
def test_the_separable_local_mean_is_the_2d_mean_with_borders_of_the_pixels_inside(window):
    x = torch.randn(2, 3, 20, 17, dtype=torch.float64)
    half = window // 2
    expected = torch.nn.functional.avg_pool2d(
        x, window, stride=1, padding=half, count_include_pad=False
    )
    torch.testing.assert_close(local_mean(x, window), expected)
    # A corner's mean is that of the pixels inside its window, by hand.
    corner = x[:, :, : half + 1, : half + 1].mean(dim=(2, 3))
    torch.testing.assert_close(local_mean(x, window)[:, :, 0, 0], corner)


@pytest.mark.parametrize("material", ["diffuse", "glossy"])
@pytest.mark.parametrize("architecture", ["dilated", "unet"])
def test_a_core_that_outputs_the_encoded_term_reproduces_the_targets(architecture, material):
    """What training fits, ``encode(targets - estimates_of(x)[0])``, decodes in :meth:`forward` to
    the targets; the dilated term has unit standard deviation per channel, the unet's lies
    inside (0, 1) for its sigmoid."""
    cfg = _local(material=material, architecture=architecture, occlusion_grid=4)
    model = _trained_like(cfg)
    x = np.concatenate([_raw(_bumpy(seed=s)) for s in range(3)])
    targets = np.random.default_rng(1).normal(size=(3, cfg.out_channels, 16, 16))
    base, occlusion = model.estimates_of(x, batch=2)
    gap = (targets - base).astype(np.float32)
    model.fit_normalisation(gap, occlusion)
    z = model.encode(torch.from_numpy(gap))
    decoded = torch.from_numpy(base) + z * model.t_scale + model.t_offset
    np.testing.assert_allclose(decoded.numpy(), targets, atol=1e-5)
    if architecture == "dilated":
        np.testing.assert_allclose(z.std(dim=(0, 2, 3), unbiased=False), 1.0, rtol=1e-4)
    else:
        assert 0 < z.min() and z.max() < 1


def test_correction_gate_is_each_colours_dc_magnitude():
    occlusion = torch.randn(2, 3 * 16, 5, 4)
    gate = correction_gate(occlusion, 3)
    for c in range(3):
        want = occlusion[:, 16 * c].abs()
        for k in range(16):
            torch.testing.assert_close(gate[:, 16 * c + k], want)
    torch.testing.assert_close(
        correction_gate(occlusion[:, :16], 1), occlusion[:, :1].abs().expand(-1, 16, -1, -1)
    )


@pytest.mark.parametrize("material", ["diffuse", "glossy"])
def test_a_gated_network_adds_nothing_where_the_disks_see_no_occlusion(material):
    """On a flat plane nothing occludes and the disks see nothing: a gated network with
    random weights returns its base estimate exactly (the unshadowed transfer), an
    ungated one does not; on a bumpy shape the gated one corrects."""
    t = np.linspace(-1, 1, 16)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    flat = torch.from_numpy(_raw(np.stack([xx, yy, np.zeros_like(xx)], -1)))
    bumpy = torch.from_numpy(_raw(_bumpy()))
    cfg = _local(material=material, architecture="dilated", width=8, dilations=(1, 2))
    differences = {}
    for gated in (True, False):
        model = _trained_like(replace(cfg, gated=gated))
        with torch.no_grad():
            model.t_offset.zero_()  # as fit_normalisation leaves the dilated core's
            differences[gated] = [
                float((model(x) - model.base(x)).abs().max()) for x in (flat, bumpy)
            ]
    assert differences[True][0] == 0.0 and differences[False][0] > 1e-3
    assert differences[True][1] > 1e-3


def test_gated_needs_the_occlusion_input_and_the_dilated_core():
    with pytest.raises(ValueError, match="gated"):
        LocalConfig(n_bands=4, widths=(8,), blocks=1, occlusion_input=False)
    with pytest.raises(ValueError, match="gated"):
        LocalConfig(n_bands=4, widths=(8,), blocks=1, architecture="unet")


def test_a_checkpoint_from_before_the_gate_loads_ungated(tmp_path):
    """Checkpoints written before ``gated`` existed hold an ungated core: loaded as such."""
    cfg = _local(width=8, dilations=(1, 2), window=5, gated=False)
    model = _trained_like(cfg)
    local_config = dataclasses.asdict(cfg)
    del local_config["gated"]
    torch.save(
        {
            "model": model.state_dict(),
            "config": {},
            "extra": {"local_config": local_config, "glossy_coeffs": None, "light": None},
        },
        tmp_path / "old.pt",
    )
    loaded = load_local(tmp_path / "old.pt")
    assert loaded.cfg.gated is False
    x = torch.from_numpy(_raw(_bumpy()))
    with torch.no_grad():
        torch.testing.assert_close(loaded(x), model(x))


def test_shadowing_training_reads_the_variants_own_batch_size_and_learning_rate():
    cfg = {"batch_size": 5, "lr": 1e-3, "shadowing_batch_size": 2, "shadowing_lr": 4e-3}
    own = shadowing_training(cfg)
    assert (own["batch_size"], own["lr"]) == (2, 4e-3)
    assert (cfg["batch_size"], cfg["lr"]) == (5, 1e-3)  # the paper form's config untouched
