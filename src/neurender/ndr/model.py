"""NDR training (paper 3.1, 3.3), its ablations (Table 1) and the learned baselines (Table 2).

Tone mapping: every unbounded quantity (S_D, S_S, I_D, I_S, I_R) enters the networks and
the losses Reinhard tone-mapped, ``t = x / (1 + x)``; a sigmoid output ``t`` maps back to
HDR by the inverse ``x = t / (1 - t)`` (the paper's ``-I / (I - 1)``). The loss is
``DSSIM(I_D) + DSSIM(I_S) + DSSIM(I_R)`` on tone-mapped images within the eroded mask, with
``I_R = I_S * A_S + I_D * A_D`` formed in HDR (paper eq. 2). The SH light vector enters as
``sign(c) log(1 + |c|)`` (compresses the sun's range; the paper does not say how it scales it).

Our change (``shading_residual``, on by default, off in the ``ndr_direct`` variant that is the
paper's formulation): a decoder whose output has a coarse-shading counterpart predicts a
correction to it, ``t = sigmoid(logit(reinhard(S)) + out)``, so an untrained network
already renders the shading input and training learns occlusion and the rest.

Variants (``VARIANTS``): what each network sees and predicts; ``pix2pix`` is the U-Net +
PatchGAN of :mod:`neurender.nn.pix2pix` on the same buffers (albedos included) targeting
``I_R``; the single-decoder ablations have twice the decoder channels (paper 4.2);
``real_shading`` is Deep Shading's normals-to-diffuse-shading CNN (Nalbach et al.
2017) for the fixed-illumination diffuse data.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import Dataset

from neurender import io, metrics, train
from neurender.ndr.data import BUFFERS, NOISY, RGB
from neurender.ndr.environments import SH_FEATURES
from neurender.nn.ndr import NDRNet
from neurender.nn.pix2pix import NLayerDiscriminator, UnetGenerator, init_weights

log = logging.getLogger(__name__)

EPS = 1e-4


def reinhard(x: torch.Tensor) -> torch.Tensor:
    """HDR ``x >= 0`` to [0, 1)."""
    return x / (1 + x)


def inverse_reinhard(t: torch.Tensor) -> torch.Tensor:
    """[0, 1) back to HDR (clamped away from the pole at 1)."""
    t = t.clamp(0, 1 - EPS)
    return t / (1 - t)


@dataclasses.dataclass(frozen=True)
class Variant:
    """One network of the comparison.

    ``inputs``: buffer groups stacked as input channels, in order; ``targets``: the shading
    maps it predicts (one decoder each when ``decoders == len(targets)``); ``light``: takes
    the SH vector; ``data``: ``complex`` or ``diffuse`` dataset; ``arch``: ``ndr`` or
    ``pix2pix``.
    """

    inputs: tuple[str, ...]
    targets: tuple[str, ...] = ("I_D", "I_S")
    decoders: int = 2
    decoder_scale: int = 1
    light: bool = True
    residual: bool = True
    data: str = "complex"
    arch: str = "ndr"
    description: str = ""


_NDR_INPUTS = ("N", "R", "D", "S_D", "S_S")
VARIANTS: dict[str, Variant] = {
    "ndr": Variant(_NDR_INPUTS, description="NDR (two decoders; ours: residual on S_D, S_S)"),
    "ndr_direct": Variant(_NDR_INPUTS, residual=False, description="NDR as published"),
    "single_decoder": Variant(
        _NDR_INPUTS, decoders=1, decoder_scale=2, description="Decoder separation ablation"
    ),
    "no_intrinsic": Variant(
        _NDR_INPUTS + ("A_D", "A_S"),
        targets=("I_R",),
        decoders=1,
        decoder_scale=2,
        description="Intrinsic image ablation (albedos in, I_R out)",
    ),
    "no_shading": Variant(("N", "R", "D"), residual=False, description="Shading input ablation"),
    "no_sh": Variant(_NDR_INPUTS, light=False, description="SH input ablation"),
    "no_depth": Variant(("N", "R", "S_D", "S_S"), description="Depth input ablation"),
    "pix2pix": Variant(
        _NDR_INPUTS + ("A_D", "A_S"),
        targets=("I_R",),
        decoders=1,
        light=False,
        residual=False,
        arch="pix2pix",
        description="pix2pix (U-Net + PatchGAN)",
    ),
    "ndr_diffuse": Variant(
        _NDR_INPUTS, data="diffuse", description="NDR, diffuse material, fixed illumination"
    ),
    "real_shading": Variant(
        ("N", "D"),
        targets=("I_D",),
        decoders=1,
        light=False,
        residual=False,
        data="diffuse",
        description="Real Shading (Deep Shading, Nalbach et al. 2017)",
    ),
}
#: Baselines without training: the coarse shading composite ``S_D * A_D + S_S * A_S``.
SHADING_INPUT = "shading_input"


def channel_count(group: str) -> int:
    return max(1, len(BUFFERS.get(group) or NOISY.get(group, ())))


def model_input_channels(variant: Variant) -> int:
    return sum(channel_count(g) for g in variant.inputs)


def light_features(sh: np.ndarray | torch.Tensor) -> torch.Tensor:
    """SH features ``(..., 75)`` as the networks take them: ``sign(c) log(1 + |c|)``."""
    light = torch.tensor(np.asarray(sh, np.float32))
    return torch.sign(light) * torch.log1p(light.abs())


def stack_samples(samples: list[dict[str, np.ndarray]], erosion: int) -> dict[str, torch.Tensor]:
    """EXR channel dicts of one kind (see :mod:`neurender.ndr.data`) to buffer tensors
    ``(N, C, H, W)`` keyed by group, the mask eroded by ``erosion`` pixels."""
    first = samples[0]
    groups = [g for g in {**BUFFERS, **NOISY} if any(c.split(".")[0] == g for c in first)]
    buffers = {}
    for g in groups:
        suffixes = BUFFERS.get(g) or NOISY.get(g) or ()
        keys = [f"{g}.{s}" for s in suffixes] if suffixes else [g]
        stacked = np.stack([np.stack([c[k] for k in keys]) for c in samples])
        buffers[g] = torch.from_numpy(stacked.astype(np.float32))
    if erosion > 0:
        mask = buffers["mask"]
        buffers["mask"] = 1 - F.max_pool2d(1 - mask, 2 * erosion + 1, stride=1, padding=erosion)
    return buffers


class NDRDataset(Dataset):
    """A split in memory. Items are dicts of float32 tensors:

    ``N`` (3, H, W) in [-1, 1], ``R`` (1), ``D`` (1), ``A_D``/``A_S`` (3) in [0, 1],
    ``S_D``/``S_S``/``I_D``/``I_S`` (3) linear HDR, ``mask`` (1) eroded by ``erosion`` px,
    ``light`` (75) the SH features (:func:`light_features`), and ``I_D_noisy``,
    ``I_S_noisy`` on test splits.
    """

    def __init__(
        self, folder: str | Path, manifest: str | Path, lighting: str | Path, erosion: int
    ):
        frame = io.read_csv(manifest, ["sample", "file"]).sort_values("sample")
        sh = io.read_csv(lighting, ["sample", "coefficient", "channel", "value"])
        sh = sh.assign(
            k=sh["coefficient"] * 3 + sh["channel"].map({c: i for i, c in enumerate(RGB)})
        )
        table = sh.pivot(index="sample", columns="k", values="value").loc[frame["sample"]]
        if table.shape[1] != SH_FEATURES or table.isna().any().any():
            raise ValueError(f"{lighting}: expected {SH_FEATURES} SH values for every sample")
        self.light = light_features(table.to_numpy(np.float32))
        self.buffers = stack_samples(
            [io.read_exr(Path(folder) / name) for name in frame["file"]], erosion
        )

    def __len__(self) -> int:
        return len(self.light)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"light": self.light[i], **{g: v[i] for g, v in self.buffers.items()}}


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


class NDRModel(torch.nn.Module):
    """A :class:`Variant` around its network: batch dict in, HDR ``{I_D, I_S, I_R}`` out
    (only ``I_R`` for variants that predict it directly)."""

    def __init__(
        self,
        variant: Variant,
        widths: list[int],
        sh_hidden: int,
        ngf: int,
        width: int,
        shading_residual: bool = True,
    ):
        super().__init__()
        self.variant = variant
        # The prior is the shading input: only variants that see it may build on it.
        sees_shading = {"S_D", "S_S"} <= set(variant.inputs)
        self.residual = variant.residual and shading_residual and sees_shading
        cin = model_input_channels(variant)
        per_decoder = 3 if variant.decoders == len(variant.targets) else 3 * len(variant.targets)
        if variant.arch == "pix2pix":
            downs = int(round(math.log2(width)))
            self.net = init_weights(UnetGenerator(cin, 3 * len(variant.targets), downs, ngf))
        else:
            self.net = NDRNet(
                cin,
                per_decoder,
                widths,
                variant.decoders,
                decoder_scale=variant.decoder_scale,
                sh_features=SH_FEATURES if variant.light else 0,
                sh_hidden=sh_hidden,
            )

    def tone_mapped(self, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Predicted tone-mapped maps in [0, 1), one per target."""
        v = self.variant
        x = network_input(batch, v.inputs)
        if v.arch == "pix2pix":
            out = (self.net(x) + 1) / 2
            return {t: out[:, 3 * i : 3 * i + 3].clamp(0, 1) for i, t in enumerate(v.targets)}
        logits = self.net(x, batch["light"] if v.light else None)
        prior = shading_input(batch) if self.residual else {}
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


def loss_terms(model: NDRModel, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict]:
    """Paper 3.3: DSSIM of every predicted map plus of ``I_R``; tone-mapped, masked."""
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


def train_variant(
    name: str, data: dict[str, str], cfg: dict, threads: int, checkpoint: str, log_csv: str
) -> None:
    """Train variant ``name`` on the train/val splits in ``data`` (keys ``train_dir``,
    ``train_manifest``, ``train_lighting`` and the same for ``val``)."""
    if name not in VARIANTS:
        raise KeyError(f"NDR variant {name!r}: expected one of {sorted(VARIANTS)}")
    variant = VARIANTS[name]
    torch.manual_seed(cfg["seed"])
    train_set, val_set = (
        NDRDataset(
            data[f"{s}_dir"], data[f"{s}_manifest"], data[f"{s}_lighting"], cfg["mask_erosion"]
        )
        for s in ("train", "val")
    )
    model = NDRModel(
        variant, cfg["widths"], cfg["sh_hidden"], cfg["ngf"], cfg["width"], cfg["shading_residual"]
    )
    epochs = cfg["epochs"] if name in ("ndr", "ndr_diffuse") else cfg["baseline_epochs"]
    config = train.TrainConfig.from_stage(cfg, threads, epochs=epochs)
    adversary = None
    loss_fn = loss_terms
    if variant.arch == "pix2pix":
        config = dataclasses.replace(config, betas=(0.5, 0.999))
        discriminator = init_weights(
            NLayerDiscriminator(model_input_channels(variant) + 3, cfg["ndf"])
        )
        bce = torch.nn.BCEWithLogitsLoss()

        def condition_and_target(batch):
            """pix2pix works in [-1, 1]: the input buffers and the tone-mapped ``I_R``."""
            x = network_input(batch, variant.inputs) * 2 - 1
            real = reinhard(compose(batch["I_D"], batch["I_S"], batch)["I_R"]) * 2 - 1
            return x, real

        def loss_fn(m, batch):
            x, real = condition_and_target(batch)
            fake = m.tone_mapped(batch)["I_R"] * 2 - 1
            l1 = ((fake - real).abs() * batch["mask"]).mean()
            loss = cfg["l1_weight"] * l1
            logs = {"l1": l1.item()}
            if m.training:
                logits = discriminator(torch.cat([x, fake], 1))
                gan = bce(logits, torch.ones_like(logits))
                loss = loss + cfg["gan_weight"] * gan
                logs["gan"] = gan.item()
            return loss, logs, fake.detach()

        def discriminator_loss(module, batch, fake):
            x, real = condition_and_target(batch)
            r, f = module(torch.cat([x, real], 1)), module(torch.cat([x, fake], 1))
            return 0.5 * (bce(r, torch.ones_like(r)) + bce(f, torch.zeros_like(f))), {}

        adversary = train.Adversary(discriminator, discriminator_loss)
    train.fit(
        model,
        train_set,
        val_set,
        loss_fn,
        config,
        checkpoint,
        log_csv,
        extra_state={
            "variant": name,
            "widths": cfg["widths"],
            "sh_hidden": cfg["sh_hidden"],
            "ngf": cfg["ngf"],
            "width": cfg["width"],
            "shading_residual": cfg["shading_residual"],
        },
        adversary=adversary,
    )


def load_model(checkpoint: str | Path, device: torch.device) -> NDRModel:
    """A trained variant in eval mode on ``device``."""
    state = train.load_checkpoint(checkpoint)
    extra = state["extra"]
    model = NDRModel(
        VARIANTS[extra["variant"]],
        extra["widths"],
        extra["sh_hidden"],
        extra["ngf"],
        extra["width"],
        extra["shading_residual"],
    )
    model.load_state_dict(state["model"])
    return model.to(device).eval()
