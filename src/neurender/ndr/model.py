"""The NDR networks (paper 3.1) around each variant's U-Net, and their loss (paper 3.3).

Tone mapping: every unbounded quantity (S_D, S_S, I_D, I_S, I_R) enters the networks and
the losses Reinhard tone-mapped, ``t = x / (1 + x)``; a sigmoid output ``t`` maps back to
HDR by the inverse ``x = t / (1 - t)`` (the paper's ``-I / (I - 1)``). The loss is
``DSSIM(I_D) + DSSIM(I_S) + DSSIM(I_R)`` on tone-mapped images within the eroded mask, with
``I_R = I_S * A_S + I_D * A_D`` formed in HDR (paper eq. 2). The SH light vector enters as
:func:`neurender.ndr.buffers.light_features`.

Our change (``shading_residual``, on by default, off in the ``ndr_direct`` variant that is the
paper's formulation): a decoder whose output has a coarse-shading counterpart predicts a
correction to it, ``t = sigmoid(logit(reinhard(S)) + out)``, so an untrained network
already renders the shading input and training learns occlusion and the rest.

Variants (:data:`neurender.ndr.variants.VARIANTS`): what each network sees and predicts;
``pix2pix`` is the U-Net + PatchGAN of :mod:`neurender.nn.pix2pix` on the same buffers
(albedos included) targeting ``I_R``; the single-decoder ablations have twice the decoder
channels (paper 4.2); ``real_shading`` is Deep Shading's normals-to-diffuse-shading CNN
(Nalbach et al. 2017) for the fixed-illumination diffuse data.

Batches are dicts of ``(B, C, H, W)`` float32 tensors keyed by buffer group, plus
``light`` ``(B, 75)`` (see :class:`neurender.ndr.buffers.NDRDataset`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch

from neurender import metrics, train
from neurender.display import reinhard
from neurender.ndr.buffers import channel_count
from neurender.ndr.environments import SH_FEATURES
from neurender.ndr.variants import VARIANTS, Variant
from neurender.nn.ndr import NDRNet
from neurender.nn.pix2pix import UnetGenerator, init_weights

EPS = 1e-4
#: Baselines without training: the coarse shading composite ``S_D * A_D + S_S * A_S``.
SHADING_INPUT = "shading_input"


def inverse_reinhard(t: torch.Tensor) -> torch.Tensor:
    """Tone-mapped ``t`` in [0, 1) back to HDR (clamped away from the pole at 1)."""
    t = t.clamp(0.0, 1.0 - EPS)
    return t / (1 - t)


def model_input_channels(variant: Variant) -> int:
    """Input channels of a variant's network: its buffer groups stacked."""
    return sum(channel_count(g) for g in variant.inputs)


def network_input(batch: dict[str, torch.Tensor], inputs: tuple[str, ...]) -> torch.Tensor:
    """Stack input buffers ``(B, C, H, W)``: unbounded ones tone-mapped, normals as stored."""
    parts = [reinhard(batch[g]) if g.startswith("S_") else batch[g] for g in inputs]
    return torch.cat(parts, 1)


def shading_input(batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The no-learning baseline in HDR: ``I_D = S_D``, ``I_S = S_S``, ``I_R`` by eq. 2."""
    return compose(batch["S_D"], batch["S_S"], batch)


def compose(
    i_d: torch.Tensor, i_s: torch.Tensor, batch: dict[str, torch.Tensor]
) -> dict[str, torch.Tensor]:
    """HDR shading maps to ``{I_D, I_S, I_R}`` with ``I_R = I_S * A_S + I_D * A_D``."""
    return {"I_D": i_d, "I_S": i_s, "I_R": i_s * batch["A_S"] + i_d * batch["A_D"]}


def _logit(t: torch.Tensor) -> torch.Tensor:
    t = t.clamp(EPS, 1 - EPS)
    return torch.log(t / (1 - t))


#: The config keys each architecture is built from (stored in the checkpoint).
ARCH_KEYS = {"ndr": ("widths", "sh_hidden"), "pix2pix": ("ngf", "width")}


def architecture(variant: Variant, cfg: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword arguments of :class:`NDRModel` for ``variant`` taken from ``cfg``: the
    :data:`ARCH_KEYS` of its ``arch``, and ``shading_residual`` where it applies."""
    keys = ARCH_KEYS[variant.arch] + (("shading_residual",) if variant.uses_prior else ())
    return {k: cfg[k] for k in keys}


class NDRModel(torch.nn.Module):
    """A :class:`Variant` around its network: batch dict in, HDR ``{I_D, I_S, I_R}`` out
    (only ``I_R`` for variants that predict it directly).

    Args:
        widths, sh_hidden: the NDR U-Net's encoder channels per level and SH layer width
            (``arch`` ``ndr``, see :class:`neurender.nn.ndr.NDRNet`).
        ngf, width: pix2pix generator filters and image width (``arch`` ``pix2pix``).
        shading_residual: predict a correction to the coarse shading (module doc) where
            the variant allows it (:attr:`Variant.uses_prior`).
    """

    def __init__(
        self,
        variant: Variant,
        *,
        widths: Sequence[int] | None = None,
        sh_hidden: int | None = None,
        ngf: int | None = None,
        width: int | None = None,
        shading_residual: bool = True,
    ):
        super().__init__()
        self.variant = variant
        self.residual = variant.uses_prior and shading_residual
        cin = model_input_channels(variant)
        per_decoder = 3 if variant.decoders == len(variant.targets) else 3 * len(variant.targets)
        if variant.arch == "pix2pix":
            downs = int(round(math.log2(width)))
            self.net = init_weights(UnetGenerator(cin, 3 * len(variant.targets), downs, ngf))
        else:
            self.net = NDRNet(
                cin,
                per_decoder,
                list(widths),
                variant.decoders,
                decoder_scale=variant.decoder_scale,
                sh_features=SH_FEATURES if variant.light else 0,
                sh_hidden=sh_hidden,
                conv_before_upsample=variant.conv_before_upsample,
            )

    def tone_mapped(self, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Predicted tone-mapped maps in [0, 1), one per target."""
        v = self.variant
        x = network_input(batch, v.inputs)
        if v.arch == "pix2pix":
            out = (self.net(x) + 1) / 2
            return {t: out[:, 3 * i : 3 * i + 3].clamp(0, 1) for i, t in enumerate(v.targets)}
        logits = self.net(x, batch["light"] if v.light else None)
        coarse = shading_input(batch) if self.residual else {}
        prior = {t: coarse[t] for t in v.prior_targets}
        return {
            t: torch.sigmoid(
                logits[:, 3 * i : 3 * i + 3] + (_logit(reinhard(prior[t])) if t in prior else 0)
            )
            for i, t in enumerate(v.targets)
        }

    def forward(self, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        tone = self.tone_mapped(batch)
        hdr = {t: inverse_reinhard(v) for t, v in tone.items()}
        if "I_R" in hdr:
            return hdr
        i_s = hdr.get("I_S", torch.zeros_like(hdr["I_D"]))
        return compose(hdr["I_D"], i_s, batch)


def masked_dssim(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean DSSIM within ``mask`` of tone-mapped images ``(B, 3, H, W)`` (background zeroed)."""
    return metrics.dssim(pred * mask, target * mask, mask).mean()


def loss_terms(
    model: NDRModel, batch: dict[str, torch.Tensor]
) -> tuple[torch.Tensor, dict[str, float], dict[str, torch.Tensor]]:
    """Paper 3.3: DSSIM of every predicted map plus of ``I_R``; tone-mapped, masked.

    Returns the loss, its terms by name and the HDR predictions (see :func:`neurender.train.
    fit`)."""
    pred = model(batch)
    truth = compose(batch["I_D"], batch["I_S"], batch)
    mask = batch["mask"]
    names = set(model.variant.targets) | {"I_R"}
    if model.variant.data == "diffuse":
        names -= {"I_S"}  # zero by construction
    terms = {
        f"dssim_{n}": masked_dssim(reinhard(pred[n]), reinhard(truth[n]), mask)
        for n in sorted(names)
    }
    loss = sum(terms.values())
    return loss, {k: v.item() for k, v in terms.items()}, pred


def load_model(checkpoint: str | Path, device: torch.device) -> NDRModel:
    """A trained variant in eval mode on ``device`` (the checkpoint's ``extra`` holds the
    variant's name and :func:`architecture`)."""
    state = train.load_checkpoint(checkpoint)
    arch = dict(state["extra"])
    model = NDRModel(VARIANTS[arch.pop("variant")], **arch)
    model.load_state_dict(state["model"])
    return model.to(device).eval()
