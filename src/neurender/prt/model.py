"""The DeepPRT network (paper 3.2): normalisation, the shipped graph and inference.

Inputs are the position and normal images ``(B, 6, n, n)``: P mapped to [-1, 1] by the
training set's bounding box, N as unit vectors. Targets are the transfer images, diffuse
``(B, K, n, n)`` or glossy ``(B, 3 K, n, n)`` (colour-major, as the EXR channels), mapped
per channel to [0, 1] by an affine normalisation stored with the checkpoint (with a 10%
margin on both sides so extrapolated shapes are not clipped by the sigmoid).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
import torch
from torch import nn

from neurender import train
from neurender.devices import resolve_device
from neurender.nn.inference import (
    OnnxNetwork,
    export_onnx,
    prepare_for_inference,
    quantize_convolutions,
)
from neurender.nn.unet import ResUNet, count_parameters
from neurender.prt import CALIBRATION_FRAMES, CHECK_FRAMES
from neurender.prt.frames import Split
from neurender.prt.local_model import load_local

log = logging.getLogger(__name__)


def raw_inputs(split: Split) -> np.ndarray:
    """``(F, 6, n, n)`` float32: the P (world units) and N (unit vectors) images, unscaled."""
    x = np.concatenate([split.positions, split.normals], -1)
    return np.ascontiguousarray(np.moveaxis(x, -1, 1), np.float32)


@dataclasses.dataclass
class Normalisation:
    """Affine maps of inputs and targets; ``x_normalised = (x - offset) / scale``.

    Targets either span [0, 1] per channel (the paper: ``offset``, ``scale`` ``(C, 1, 1)``)
    or, with ``residual``, are the deviation from the training set's mean image centred on
    0.5 (``offset`` ``(C, n, n)``): the network then spends no capacity on the part of
    the transfer that every frame shares, which a small network learns only slowly.
    """

    p_offset: np.ndarray  # (3,)
    p_scale: np.ndarray  # (3,)
    t_offset: np.ndarray  # (C, 1, 1) or (C, n, n)
    t_scale: np.ndarray  # (C, 1, 1)

    @classmethod
    def fit(
        cls, split: Split, material: str, residual: bool = True, margin: float = 0.1
    ) -> Normalisation:
        p = split.positions.reshape(-1, 3)
        lo, hi = p.min(0), p.max(0)
        t = split.targets(material)
        if residual:
            mean = t.mean(0)
            span = 2 * np.maximum(np.abs(t - mean).max(axis=(0, 2, 3)), 1e-6)[:, None, None]
            scale = (1 + 2 * margin) * span
            offset = mean - 0.5 * scale
        else:
            tlo, thi = t.min(axis=(0, 2, 3)), t.max(axis=(0, 2, 3))
            span = np.maximum(thi - tlo, 1e-6)[:, None, None]
            scale = (1 + 2 * margin) * span
            offset = tlo[:, None, None] - margin * span
        return cls(
            p_offset=(lo + hi) / 2,
            p_scale=np.maximum(hi - lo, 1e-6).max() / 2 * np.ones(3, np.float32),
            t_offset=offset.astype(np.float32),
            t_scale=scale.astype(np.float32),
        )

    def inputs(self, split: Split) -> np.ndarray:
        """``(F, 6, n, n)`` float32 network inputs (P normalised)."""
        x = raw_inputs(split)
        x[:, :3] = (x[:, :3] - self.p_offset[:, None, None]) / self.p_scale[:, None, None]
        return x

    def encode(self, targets: np.ndarray) -> np.ndarray:
        """Targets ``(F, C, n, n)`` to network outputs in [0, 1]."""
        return ((targets - self.t_offset) / self.t_scale).astype(np.float32)

    def decode(self, values: np.ndarray) -> np.ndarray:
        """Network outputs ``(F, C, n, n)`` to transfer."""
        return values * self.t_scale + self.t_offset

    def state(self) -> dict[str, torch.Tensor]:
        """The arrays as tensors (dtype kept), what a checkpoint stores; ``Normalisation(
        **{k: np.asarray(v) for k, v in state.items()})`` gives this one back."""
        return {k: torch.from_numpy(np.asarray(v)) for k, v in dataclasses.asdict(self).items()}


def build_network(out_channels: int, widths: list[int], blocks: int) -> ResUNet:
    return ResUNet(6, out_channels, list(widths), blocks)


class TransferNetwork(nn.Module):
    """A trained network with its normalisation, the graph a renderer ships.

    ``(B, 6, n, n)`` raw P and N images (:func:`raw_inputs`) to ``(B, C, n, n)`` transfer
    in the targets' units: ``decode(network(normalised inputs))``.
    """

    def __init__(self, network: nn.Module, norm: Normalisation):
        super().__init__()
        self.network = network
        tensor = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
        self.register_buffer("p_offset", tensor(norm.p_offset).reshape(1, 3, 1, 1))
        self.register_buffer("p_scale", tensor(norm.p_scale).reshape(1, 3, 1, 1))
        self.register_buffer("t_offset", tensor(norm.t_offset)[None])
        self.register_buffer("t_scale", tensor(norm.t_scale)[None])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p = (x[:, :3] - self.p_offset) / self.p_scale
        return self.network(torch.cat([p, x[:, 3:]], 1)) * self.t_scale + self.t_offset


def load_transfer_module(checkpoint: str | Path) -> nn.Module:
    """The eval-mode graph of a checkpoint of either DeepPRT variant: raw P and N images
    ``(B, 6, n, n)`` to transfer ``(B, C, n, n)`` in physical units.

    The paper's form (:func:`neurender.prt.training.train_deepprt`) gives a
    :class:`TransferNetwork`; the shadowing variant (its checkpoint holds a
    ``local_config``, :func:`neurender.prt.training.train_local`) a
    :class:`neurender.prt.local_model.ShadowingTransfer`.
    """
    state = train.load_checkpoint(checkpoint)
    extra = state["extra"]
    if "local_config" in extra:
        return load_local(checkpoint)
    model = build_network(extra["out_channels"], extra["widths"], extra["blocks"])
    model.load_state_dict(state["model"])
    norm = Normalisation(**{k: np.asarray(v) for k, v in extra["normalisation"].items()})
    return TransferNetwork(model, norm).eval()


class DeepPRT:
    """A trained network of either variant (:func:`load_transfer_module`) for inference on
    numpy splits.

    It runs the exported ONNX file with ONNX Runtime when one is given and the device is the
    CPU (the faster engine there), PyTorch otherwise; ``engines`` holds both on the CPU so
    they can be timed side by side. ``pytorch=False`` leaves PyTorch out, for a file that
    computes something else than the checkpoint's graph (its int8 form, :func:`export_int8`).
    """

    def __init__(
        self,
        checkpoint: str | Path,
        onnx_file: str | Path | None = None,
        device: str = "auto",
        threads: int = 1,
        pytorch: bool = True,
    ):
        self.device = resolve_device(device, threads)
        if not pytorch and (onnx_file is None or self.device.type != "cpu"):
            raise ValueError(
                f"DeepPRT({checkpoint}): without PyTorch it needs an ONNX file and the CPU"
            )
        module = load_transfer_module(checkpoint)
        self.parameters = count_parameters(module)
        self.engines = {}
        if pytorch:  # prepared only where it runs
            self.module = prepare_for_inference(module).to(self.device)
            self.engines["pytorch"] = self._run_pytorch
        if onnx_file is not None and self.device.type == "cpu":
            self.engines["onnxruntime"] = OnnxNetwork(onnx_file, threads)
        self.engine = "onnxruntime" if "onnxruntime" in self.engines else "pytorch"

    @torch.inference_mode()
    def _run_pytorch(self, x: np.ndarray) -> np.ndarray:
        x = torch.from_numpy(x).to(self.device, memory_format=torch.channels_last)
        return self.module(x).cpu().numpy()

    def predict(self, split: Split, batch: int = 8, engine: str | None = None) -> np.ndarray:
        """``(F, C, n, n)`` transfer in physical units, by ``engine`` (default ``self.engine``)."""
        run = self.engines[engine or self.engine]
        x = raw_inputs(split)
        return np.concatenate([run(x[i : i + batch]) for i in range(0, len(x), batch)])


def export_deepprt(checkpoint: str | Path, example: Split, out: str | Path) -> None:
    """Write the network file a renderer ships: ``checkpoint``'s graph of either variant
    (:func:`load_transfer_module`) as ONNX, checked against PyTorch on the first
    :data:`~neurender.prt.CHECK_FRAMES` frames of ``example`` (repeated if it has fewer)
    relative to the output's magnitude (transfer is in physical units)."""
    net = DeepPRT(checkpoint, device="cpu")
    x = raw_inputs(example)
    frames = np.arange(CHECK_FRAMES) % len(x)
    export_onnx(net.module, torch.from_numpy(x[frames]), out, rtol=1e-4)


def export_int8(source: str | Path, train_split: Split, out: str | Path) -> None:
    """Write the int8 form of a shipped float32 graph ``source`` (:func:`export_deepprt`):
    its convolutions int8 (:func:`neurender.nn.inference.quantize_convolutions`),
    calibrated one frame at a time on the first :data:`~neurender.prt.CALIBRATION_FRAMES` frames of
    ``train_split``; same inputs and outputs. An approximation: the evaluation scores it
    as a network of its own."""
    x = raw_inputs(train_split)[:CALIBRATION_FRAMES]
    quantize_convolutions(source, out, [{"x": frame[None]} for frame in x])
