"""Image-space metaballs (the thesis): a network renders metaball G-buffers from circles.

Pipeline: :mod:`scenes` (camera, random balls) -> :mod:`raymarch` (exact targets) and
:mod:`inputs` (circles, sphere impostors) -> :mod:`ab` (AB images) -> :mod:`dataset`,
:mod:`model`, :mod:`training` -> :mod:`renderer` (inference) -> :mod:`evaluate`
(beside the no-learning baselines, the strongest :mod:`refined`),
:mod:`user_scenes` (your CSV of balls), :mod:`demo`, :mod:`speed`, :mod:`equal_quality`
(the cheapest ray marcher of a network's quality), :mod:`summary`, :mod:`figures`. The
G-buffer layout and the silhouette tests are :mod:`gbuffers`; each rule's job is in
:mod:`jobs`.

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


def trained_variants(chosen) -> tuple[str, ...]:
    """The networks a run trains, in the order of :data:`VARIANTS`: those ``chosen``
    (``metaballs_model.variants``) and always :data:`DEMO_VARIANTS`."""
    unknown = sorted(set(chosen) - set(VARIANTS))
    if unknown:
        raise ValueError(f"metaballs_model.variants: {unknown} not among {list(VARIANTS)}")
    return tuple(v for v in VARIANTS if v in chosen or v in DEMO_VARIANTS)


#: The strongest no-learning baseline: inflated impostors refined on the field
#: (:mod:`neurender.metaballs.refined`); every network is checked against it, and the
#: equal-quality sweep times it beside the networks.
REFINED_BASELINE = "refined spheres"

#: The per-frame row of the evaluation's tables that says whether the frame's reference
#: shows no surface (1) or some (0), and the per-model count of such frames in the means
#: table (:func:`neurender.metaballs.evaluate.example_metrics`, ``mean_metrics``): an empty
#: frame has no scores, so that nothing scores it as perfect.
EMPTY_FRAME = "empty_frame"
EMPTY_FRAMES = "empty_frames"

#: Copies of each training example with ``metaballs_model.flips``: as it is and mirrored in
#: x, in y and in both (:class:`neurender.metaballs.dataset.ABDataset`).
MIRRORINGS = 4

#: The equal-quality sweep's ray marchers (:func:`neurender.metaballs.equal_quality.sweep`):
#: every step floor (world units; the first, the reference's) x bisections (the first, the
#: reference's) x resolution (fraction of the width, upsampled by nearest neighbour).
EQUAL_QUALITY_MIN_STEPS = (0.02, 0.3, 1.0, 2.0)
EQUAL_QUALITY_BISECTIONS = (24, 4, 1)
EQUAL_QUALITY_RESOLUTIONS = (1.0, 0.75, 0.5, 0.375, 0.25)
