"""A trained metaballs generator for inference: scene in, G-buffers out."""

from __future__ import annotations

from pathlib import Path

import torch

from neurender import train
from neurender.deployment import shipped_network
from neurender.devices import resolve_device
from neurender.metaball import Scene
from neurender.metaballs.model import build_generator, network_inputs
from neurender.nn.inference import OnnxNetwork


class MetaballRenderer:
    """A trained generator for inference: :meth:`inputs` builds its input from a scene,
    calling it gives the G-buffer stacks (:mod:`neurender.metaballs.gbuffers`).

    A GAN-trained generator normalises batch norm with the statistics of the image being
    rendered, as in the pix2pix authors' test code: its running averages failed (held-out
    IoU 0.27 against 0.73). L1-trained ones use the running averages (the residual model
    scored IoU 0.81 with per-image statistics, 0.88 with running averages). Dropout is off.

    Given its shipped graph (``onnx``, :mod:`neurender.metaballs.deploy`), a renderer on the
    CPU runs the network as that graph in ONNX Runtime (:attr:`engine`), the engine a CPU
    renderer ships with (``deployment.csv`` times both: 1.7x to 2.8x faster than PyTorch
    per frame at the default config on 2 cores), the same output to within the export's
    checked 1e-3.
    """

    def __init__(
        self,
        checkpoint: str | Path,
        device: str = "auto",
        threads: int = 1,
        onnx: str | Path | None = None,
    ):
        state = train.load_checkpoint(checkpoint)
        extra = state["extra"]
        self.device = resolve_device(device, threads)
        self.variant = extra["variant"]
        self.width = extra["width"]
        self.ngf = extra["ngf"]
        self.model = build_generator(self.width, extra["ngf"], self.variant)
        self.model.load_state_dict(state["model"])
        self.model.to(self.device).eval()
        self.image_statistics = extra["gan_weight"] > 0
        if self.image_statistics:
            for module in self.model.modules():
                if isinstance(module, torch.nn.BatchNorm2d):
                    module.train()
        if onnx is not None and shipped_network(onnx) != ("metaballs", self.variant):
            method, network = shipped_network(onnx)
            raise ValueError(
                f"{onnx} is the graph of {method} {network!r}; checkpoint {checkpoint} is "
                f"metaballs {self.variant!r}: expected each checkpoint with its own graph"
            )
        shipped = onnx is not None and self.device.type == "cpu"
        # Not spinning: a frame runs PyTorch (inputs, shading) on the same cores right after.
        self.graph = OnnxNetwork(onnx, threads, spinning=False) if shipped else None

    @property
    def engine(self) -> str:
        """What runs the network: ``onnxruntime`` (the shipped graph) or ``pytorch``."""
        return "pytorch" if self.graph is None else "onnxruntime"

    def inputs(self, scene: Scene, circles: torch.Tensor | None = None) -> torch.Tensor:
        """The ``(C, W, W)`` input in [0, 1] (see :func:`network_inputs`), drawn on the
        renderer's device (on a GPU, drawing on the CPU would cost more than the network)."""
        tensors = (scene.centres, scene.radii, scene.colours)
        on_device = Scene(*(t.to(self.device) for t in tensors), scene.kernel)
        if circles is not None:
            circles = circles.to(self.device)
        return network_inputs(on_device, self.width, self.variant, circles)

    @torch.no_grad()
    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """Inputs ``(B, C, W, W)`` in [0, 1] to G-buffer stacks ``(B, 7, W, W)`` in [0, 1],
        on the CPU."""
        if self.graph is not None:
            return torch.from_numpy(self.graph(x.numpy()))
        x = x.to(self.device, torch.float32) * 2 - 1
        if self.image_statistics:  # one image per pass: batch statistics must not mix images
            out = torch.cat([self.model(x[i : i + 1]) for i in range(len(x))])
        else:
            out = self.model(x)
        return ((out + 1) / 2).clamp(0, 1).cpu()


def load_renderers(
    checkpoints: list[str], device: str, threads: int, onnx: list[str] | None = None
) -> dict[str, MetaballRenderer]:
    """Variant name (the one each checkpoint was trained as) to its renderer, in the order
    of ``checkpoints`` (and, if given, their shipped graphs ``onnx``, same order: each
    renderer refuses a graph that names another variant)."""
    graphs = [None] * len(checkpoints) if onnx is None else onnx
    renderers = [
        MetaballRenderer(path, device, threads, graph)
        for path, graph in zip(checkpoints, graphs, strict=True)
    ]
    return {r.variant: r for r in renderers}
