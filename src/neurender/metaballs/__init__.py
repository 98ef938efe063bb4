"""Image-space metaballs (the thesis): a network renders metaball G-buffers from circles.

Pipeline: :mod:`scenes` (camera, random balls) -> :mod:`raymarch` (exact targets) and
:mod:`inputs` (circles, sphere impostors) -> :mod:`ab` (AB images) -> :mod:`dataset`,
:mod:`model`, :mod:`training` -> :mod:`renderer` (inference) -> :mod:`evaluate`,
:mod:`user_scenes` (your CSV of balls), :mod:`demo`, :mod:`speed`, :mod:`summary`,
:mod:`figures`. The G-buffer layout and the silhouette tests are :mod:`gbuffers`; each
rule's job is in :mod:`jobs`.

This module names what the workflow's rules refer to; it imports nothing heavy, so the
Snakefile can read it when it builds the DAG.
"""

#: Example splits, one AB folder each.
SPLITS = ("train", "val", "test")

#: The networks (see :mod:`neurender.metaballs.model`): the thesis's pix2pix, its L1-only
#: ablation and our sphere-residual model.
VARIANTS = ("pix2pix", "l1only", "sphere_residual")

#: The variants trained with a GAN term (the others get ``gan_weight`` 0).
GAN_VARIANTS = ("pix2pix",)

#: The thesis's network and ours: the demo animates and times both.
DEMO_VARIANTS = ("pix2pix", "sphere_residual")

#: Copies of each training example with ``metaballs_model.flips``: as it is and mirrored in
#: x, in y and in both (:class:`neurender.metaballs.dataset.ABDataset`).
MIRRORINGS = 4
