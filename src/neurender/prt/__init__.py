"""DeepPRT (Li et al. 2019): SH transfer of deforming surfaces predicted from geometry images.

This module names what the workflow's rules refer to; it imports nothing heavy, so the
Snakefile can read it when it builds the DAG.
"""

#: Built-in animated objects (:mod:`neurender.prt.objects`).
OBJECTS = ("head", "cloth", "creature")
#: Frame splits of every object: one smooth training sequence (train, val) and test frames
#: outside it.
SPLITS = ("train", "val", "test")
#: Transfer kinds, one network each: diffuse (K coefficients) and glossy (3 K).
MATERIALS = ("diffuse", "glossy")
#: Datasets of paper section 4.2.2 (Fig. 6), built on the head's geometry image: a linear
#: shape space with a plane, and the head without one expression in training.
EXPERIMENTS = ("head_linear", "head_excluded")
