"""The networks of the NDR comparison as data: the paper's model, its ablations (Table 1)
and the learned baselines (Table 2).

Plain data only (no torch): the Snakefile reads this table when it builds the DAG, to
know which data each variant trains on and which config keys its training reads.
"""

from __future__ import annotations

import dataclasses

#: The shading maps a network can be given as its coarse-shading prior.
SHADING_GROUPS = ("S_D", "S_S")
#: The coarse shading each predicted map's prior is made of (``I_R`` by paper eq. 2).
PRIOR_OF = {"I_D": ("S_D",), "I_S": ("S_S",), "I_R": SHADING_GROUPS}


@dataclasses.dataclass(frozen=True)
class Variant:
    """One network of the comparison.

    ``inputs``: buffer groups stacked as input channels, in order (see
    :mod:`neurender.ndr.buffers`); ``targets``: the shading maps it predicts (one decoder
    each when ``decoders == len(targets)``); ``light``: takes the SH vector; ``residual``:
    may predict a correction to the coarse shading (see :mod:`neurender.ndr.model`);
    ``data``: ``complex`` or ``diffuse`` dataset; ``arch``: ``ndr`` (:mod:`neurender.nn.ndr`)
    or ``pix2pix`` (:mod:`neurender.nn.pix2pix`); ``conv_before_upsample``: the NDR
    decoders convolve before they upsample (ours, and our ablations; NDR as published and
    Real Shading upsample first, see :mod:`neurender.nn.ndr`). Every variant trains for the same
    ``ndr_model.epochs`` (the comparison is at an equal budget).
    """

    inputs: tuple[str, ...]
    targets: tuple[str, ...] = ("I_D", "I_S")
    decoders: int = 2
    decoder_scale: int = 1
    light: bool = True
    residual: bool = True
    data: str = "complex"
    arch: str = "ndr"
    conv_before_upsample: bool = True
    description: str = ""

    @property
    def prior_targets(self) -> tuple[str, ...]:
        """The targets a residual may correct: those whose coarse counterpart
        (:data:`PRIOR_OF`) the network sees, so that none builds on a map it is not given."""
        if not self.residual:
            return ()
        return tuple(t for t in self.targets if set(PRIOR_OF[t]) <= set(self.inputs))

    @property
    def uses_prior(self) -> bool:
        """Whether ``shading_residual`` applies (some target has its prior as an input)."""
        return bool(self.prior_targets)


_NDR_INPUTS = ("N", "R", "D", "S_D", "S_S")
VARIANTS: dict[str, Variant] = {
    "ndr": Variant(
        _NDR_INPUTS,
        description="NDR (two decoders; ours: residual on S_D, S_S)",
    ),
    "ndr_direct": Variant(
        _NDR_INPUTS, residual=False, conv_before_upsample=False, description="NDR as published"
    ),
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
        _NDR_INPUTS,
        data="diffuse",
        description="NDR, diffuse material, fixed illumination",
    ),
    "real_shading": Variant(
        ("N", "D"),
        targets=("I_D",),
        decoders=1,
        light=False,
        residual=False,
        data="diffuse",
        conv_before_upsample=False,
        description="Real Shading (Deep Shading, Nalbach et al. 2017)",
    ),
}
