"""A DeepPRT variant that learns shadowing as a local rule.

The paper's network (:mod:`neurender.prt.model`) maps the whole P and N images to the
whole transfer, so it can memorise the training animation's global pose. This variant:

* predicts only what its estimate of shadowing misses: the target is the true transfer
  minus the analytic unshadowed transfer of the input normals
  (:mod:`neurender.prt.unshadowed`), exact where nothing occludes, plus what the
  surface's own elements occlude as disks (:mod:`neurender.prt.disk_occlusion`, a
  ``grid^4``-pair sum over the whole shape: occluders far apart on the geometry image,
  such as a cloth's folds, are seen by no local network);
* reads that estimate too (``occlusion_input``): the disks' occluded transfer, divided
  per channel by its training standard deviation, is an input of the core beside the
  local features, so the network can learn where the disks over-count (overlapping
  occluders, the far side of a closed surface) or under-count, and sees a fold's
  occlusion that lies beyond its receptive field;
* scales its correction per pixel (``gated``) by the disks' occluded solid angle there
  (the DC channel of their estimate, per colour, over its training standard deviation):
  where the disks see nothing occluded the network adds nothing, so a shape smoother than
  any training frame (a cloth's mean shape) is not given the corrections learnt on folds;
* sees positions only relative to their neighbourhood: ``P`` minus its ``window x window``
  mean (average pooling), divided by ``window / 2`` times the frame's mean grid-edge
  length. These inputs do not change under a translation or a uniform scaling of the
  whole shape (visibility does not either), and their magnitudes not under a rotation;
* keeps normals (and the position differences) in the world frame: the transfer's SH are
  world-frame, so a rotation of the whole shape must rotate the answer, which a local
  frame would only give with a per-pixel SH rotation in the graph (not done here);
* has a receptive field sized to the distance over which a surface shadows itself:
  3x3 convolutions with growing dilations (:class:`DilatedNet`; 33 px for the default
  dilations 1, 2, 4, 8, 1, half a 64-px geometry image), or any other core network
  (e.g. :class:`neurender.nn.unet.ResUNet`, whose sigmoid the target scaling allows for).

:class:`ShadowingTransfer` is the graph a renderer ships, with the same contract as
:class:`neurender.prt.model.TransferNetwork`: raw ``(B, 6, n, n)`` P (world units) and N
(unit vectors) images in, ``(B, C, n, n)`` transfer in physical units out (``C = K``
diffuse, ``3 K`` glossy colour-major); everything it derives is computed in the graph.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812 - the usual name
from torch import nn

from neurender import train
from neurender.nn.norms import PixelNorm
from neurender.nn.unet import ResUNet
from neurender.prt import disk_occlusion, unshadowed

#: Core networks a :class:`LocalConfig` can name.
ARCHITECTURES = ("dilated", "unet")


@dataclasses.dataclass(kw_only=True)
class LocalConfig:
    """Architecture of the variant (stored in its checkpoint). The fields without a
    default are config keys (``prt.n_bands``, ``prt_model.widths``, ``prt_model.blocks``),
    whose defaults live in the schema only; the others are the variant's own constants."""

    n_bands: int  # SH bands of the transfer
    material: str = "diffuse"
    architecture: str = "dilated"  # one of ARCHITECTURES
    width: int = 48  # dilated: channels of every layer
    dilations: tuple[int, ...] = (1, 2, 4, 8, 1)  # dilated: one 3x3 layer each
    widths: tuple[int, ...]  # unet: channels per level
    blocks: int  # unet: ResNet blocks per level
    window: int = 15  # side of the local-mean window, pixels (odd)
    occlusion_grid: int = disk_occlusion.DEFAULT_GRID  # blocks per side of the disks (0: none)
    occlusion_input: bool = True  # the core reads the disks' estimate (needs occlusion_grid)
    gated: bool = True  # correction scaled by the disks' occlusion (dilated, occlusion_input)

    def __post_init__(self):
        if self.architecture not in ARCHITECTURES:
            raise ValueError(f"architecture {self.architecture!r}: expected one of {ARCHITECTURES}")
        if self.occlusion_grid < 0:
            raise ValueError(f"occlusion_grid {self.occlusion_grid}: expected >= 0 (0: none)")
        if self.window < 1 or self.window % 2 == 0:
            raise ValueError(f"window {self.window}: expected an odd number of pixels >= 1")
        if self.occlusion_input and not self.occlusion_grid:
            raise ValueError("occlusion_input needs disks: occlusion_grid is 0")
        if self.gated and not (self.occlusion_input and self.architecture == "dilated"):
            raise ValueError(
                "gated needs occlusion_input and the dilated core (the unet's term has an offset)"
            )
        self.dilations, self.widths = tuple(self.dilations), tuple(self.widths)

    @property
    def colours(self) -> int:
        """Colour groups of the transfer: 1 diffuse, 3 glossy (colour-major)."""
        return 1 if self.material == "diffuse" else 3

    @property
    def out_channels(self) -> int:
        return self.colours * self.n_bands**2


class DilatedNet(nn.Module):
    """3x3 convolutions with the given dilations (:class:`PixelNorm`, ReLU), then a 1x1 head.

    ``(B, cin, H, W) -> (B, cout, H, W)``, any H and W; receptive field
    ``1 + 2 sum(dilations)`` pixels. The head starts at zero, so an untrained network
    predicts no shadowing (the unshadowed transfer).
    """

    def __init__(self, cin: int, cout: int, width: int, dilations: tuple[int, ...]):
        super().__init__()
        layers, c = [], cin
        for d in dilations:
            layers += [
                nn.Conv2d(c, width, 3, padding=d, dilation=d),
                PixelNorm(width),
                nn.ReLU(inplace=True),
            ]
            c = width
        self.body = nn.Sequential(*layers)
        self.head = nn.Conv2d(c, cout, 1)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(x))


def receptive_field(dilations: tuple[int, ...]) -> int:
    """Pixels seen by one output of :class:`DilatedNet` along each axis."""
    return 1 + 2 * sum(dilations)


def local_mean(x: torch.Tensor, window: int) -> torch.Tensor:
    """``(B, C, H, W)`` mean over each pixel's ``window x window`` neighbourhood (odd
    ``window``; at the borders, of the pixels inside).

    As two 1D means, rows then columns: the count of pixels inside is a product of the
    two axes' counts, so this equals the 2D mean, at ``2 window`` instead of ``window^2``
    additions per pixel (the 2D pooling was most of a narrow network's time).
    """
    half = window // 2
    rows = F.avg_pool2d(x, (window, 1), stride=1, padding=(half, 0), count_include_pad=False)
    return F.avg_pool2d(rows, (1, window), stride=1, padding=(0, half), count_include_pad=False)


def correction_gate(occlusion: torch.Tensor, colours: int) -> torch.Tensor:
    """``(B, C, n, n)`` per-pixel factor of a gated correction from the disks' normalised
    occlusion ``(B, C, n, n)`` (``C = colours * K``, colour-major): each colour's DC
    channel, ``|o_{c,0}|``, for all ``K`` channels of that colour."""
    per_colour = occlusion.unflatten(1, (colours, -1))
    return per_colour[:, :, :1].abs().expand_as(per_colour).flatten(1, 2)


def local_features(x: torch.Tensor, window: int) -> torch.Tensor:
    """``(B, 6, n, n)`` network inputs from raw P and N images ``(B, 6, n, n)``: P minus its
    ``window``-pixel local mean (borders: the mean of the pixels inside) over ``window / 2``
    mean grid-edge lengths of the frame, and N unchanged."""
    p, nrm = x[:, :3], x[:, 3:]
    mean = local_mean(p, window)
    du = (p[:, :, :, 1:] - p[:, :, :, :-1]).norm(dim=1).mean(dim=(1, 2))
    dv = (p[:, :, 1:, :] - p[:, :, :-1, :]).norm(dim=1).mean(dim=(1, 2))
    spacing = (0.5 * (du + dv)).clamp_min(1e-12).reshape(-1, 1, 1, 1)
    return torch.cat([(p - mean) / (spacing * (window / 2)), nrm], 1)


class ShadowingTransfer(nn.Module):
    """Raw P and N images ``(B, 6, n, n)`` to transfer ``(B, C, n, n)`` in physical units:
    the :meth:`base` estimate plus ``shadowing * t_scale + t_offset``, the shadowing term
    being ``core(features)`` (``gated``: times :func:`correction_gate` of the normalised
    occlusion), the features the local ones and (``occlusion_input``) the disks'
    occlusion over ``o_scale``.

    Buffers: ``t_offset``, ``t_scale`` ``(1, C, 1, 1)`` (the shadowing target's affine
    normalisation), ``o_scale`` ``(1, C, 1, 1)`` (the occlusion input's) and, for
    glossy, ``glossy_coeffs`` ``(M, 3 K)``
    (:func:`neurender.prt.unshadowed.glossy_polynomial` of the training light) and that
    light, ``light`` ``(K, 3)`` (the glossy disk-occlusion estimate's).
    """

    def __init__(
        self,
        cfg: LocalConfig,
        glossy_coeffs: np.ndarray | None = None,
        light: np.ndarray | None = None,
    ):
        super().__init__()
        self.cfg = cfg
        c = cfg.out_channels
        cin = 6 + (c if cfg.occlusion_input else 0)
        if cfg.architecture == "dilated":
            self.core = DilatedNet(cin, c, cfg.width, cfg.dilations)
        else:
            self.core = ResUNet(cin, c, list(cfg.widths), cfg.blocks)
        self.register_buffer("t_offset", torch.zeros(1, c, 1, 1))
        self.register_buffer("t_scale", torch.ones(1, c, 1, 1))
        self.register_buffer("o_scale", torch.ones(1, c, 1, 1))
        if cfg.material == "glossy":
            if glossy_coeffs is None or light is None:
                raise ValueError("a glossy ShadowingTransfer needs the light and its glossy_coeffs")
            self.register_buffer(
                "glossy_coeffs", torch.as_tensor(glossy_coeffs, dtype=torch.float32)
            )
            if isinstance(light, np.ndarray):
                light = light.copy()  # contiguous (a slice of a probe may not be)
            self.register_buffer("light", torch.as_tensor(light, dtype=torch.float32))
        else:
            self.glossy_coeffs = self.light = None

    def unshadowed(self, normals: torch.Tensor) -> torch.Tensor:
        """``(B, C, n, n)`` unshadowed transfer of normal images ``(B, 3, n, n)`` (channels
        first throughout: see :mod:`neurender.prt.disk_occlusion` on ONNX Runtime)."""
        if self.glossy_coeffs is None:
            return unshadowed.diffuse(normals, self.cfg.n_bands, axis=1)
        return unshadowed.glossy(normals, self.glossy_coeffs, axis=1)

    def occlusion(self, x: torch.Tensor) -> torch.Tensor | None:
        """``(B, C, n, n)`` transfer the disks occlude in raw inputs ``(B, 6, n, n)``
        (:func:`neurender.prt.disk_occlusion.occluded_transfer`); None without disks."""
        if not self.cfg.occlusion_grid:
            return None
        return disk_occlusion.occluded_transfer(
            x, self.cfg.n_bands, self.cfg.occlusion_grid, self.light
        )

    def base(self, x: torch.Tensor, occlusion: torch.Tensor | None = None) -> torch.Tensor:
        """``(B, C, n, n)`` estimate without learning of raw inputs ``(B, 6, n, n)``: the
        unshadowed transfer of N minus what the disks occlude (:meth:`occlusion`, computed
        unless given)."""
        t = self.unshadowed(x[:, 3:])
        if self.cfg.occlusion_grid:
            t = t - (self.occlusion(x) if occlusion is None else occlusion)
        return t

    def shadowing(self, x: torch.Tensor, occlusion: torch.Tensor | None = None) -> torch.Tensor:
        """The normalised shadowing term ``(B, C, n, n)`` (what training fits): the core
        network's output (``gated``: scaled by :func:`correction_gate`) for raw inputs
        ``(B, 6, n, n)`` and (``occlusion_input``) their :meth:`occlusion`, computed unless
        given."""
        features = local_features(x, self.cfg.window)
        if not self.cfg.occlusion_input:
            return self.core(features)
        if occlusion is None:
            occlusion = self.occlusion(x)
        normalised = occlusion / self.o_scale
        out = self.core(torch.cat([features, normalised], 1))
        if self.cfg.gated:
            out = out * correction_gate(normalised, self.cfg.colours)
        return out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        occlusion = self.occlusion(x)  # once for the base and the core
        return self.base(x, occlusion) + self.shadowing(x, occlusion) * self.t_scale + self.t_offset

    def estimates_of(self, x: np.ndarray, batch: int = 16) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`base` and :meth:`occlusion` (zeros without disks) of inputs
        ``(F, 6, n, n)``, each ``(F, C, n, n)`` float32, in batches of ``batch`` frames
        without gradients (computed once per training set)."""
        inputs = torch.from_numpy(np.ascontiguousarray(x, np.float32))
        bases, occlusions = [], []
        with torch.no_grad():
            for i in range(0, len(inputs), batch):
                part = inputs[i : i + batch]
                occlusion = self.occlusion(part)
                bases.append(self.base(part, occlusion))
                occlusions.append(torch.zeros_like(bases[-1]) if occlusion is None else occlusion)
        return torch.cat(bases).numpy(), torch.cat(occlusions).numpy()

    def fit_normalisation(
        self, gap: np.ndarray, occlusion: np.ndarray | None = None, margin: float = 0.1
    ) -> None:
        """Set ``t_offset``, ``t_scale`` from the training frames' shadowing term
        ``gap = targets - base`` ``(F, C, n, n)``: divided per channel by its standard
        deviation (dilated), or mapped to [0, 1] with ``margin`` on both sides (unet,
        whose output is a sigmoid); and ``o_scale`` from their ``occlusion`` ``(F, C, n,
        n)`` (its standard deviation per channel; needed with ``occlusion_input``)."""
        if self.cfg.occlusion_input:
            if occlusion is None:
                raise ValueError("fit_normalisation: occlusion_input needs the occlusion")
            o_scale = np.maximum(occlusion.std(axis=(0, 2, 3)), 1e-6)
            self.o_scale.copy_(torch.as_tensor(o_scale, dtype=torch.float32).reshape(1, -1, 1, 1))
        if self.cfg.architecture == "dilated":
            offset = np.zeros(gap.shape[1])
            scale = np.maximum(gap.std(axis=(0, 2, 3)), 1e-6)
        else:
            lo, hi = gap.min(axis=(0, 2, 3)), gap.max(axis=(0, 2, 3))
            span = np.maximum(hi - lo, 1e-6)
            offset, scale = lo - margin * span, (1 + 2 * margin) * span
        self.t_offset.copy_(torch.as_tensor(offset, dtype=torch.float32).reshape(1, -1, 1, 1))
        self.t_scale.copy_(torch.as_tensor(scale, dtype=torch.float32).reshape(1, -1, 1, 1))

    def encode(self, gap: torch.Tensor) -> torch.Tensor:
        """The shadowing term ``targets - base`` ``(B, C, n, n)`` normalised as the core
        outputs it (the inverse of ``* t_scale + t_offset`` in :meth:`forward`)."""
        return (gap - self.t_offset) / self.t_scale


def load_local(checkpoint: str | Path) -> ShadowingTransfer:
    """The eval-mode :class:`ShadowingTransfer` of a checkpoint of
    :func:`neurender.prt.training.train_local` (best validation epoch)."""
    state = train.load_checkpoint(checkpoint)
    extra = state["extra"]
    # Checkpoints from before occlusion_input (gated) existed have cores that read no
    # occlusion (an ungated correction).
    cfg = LocalConfig(**{"occlusion_input": False, "gated": False, **extra["local_config"]})
    model = ShadowingTransfer(cfg, extra.get("glossy_coeffs"), extra.get("light"))
    model.load_state_dict({"o_scale": model.o_scale, **state["model"]})  # (ones before it)
    return model.eval()
