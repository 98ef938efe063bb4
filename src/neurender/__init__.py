"""neurender: datasets, models and evaluation of four neural-rendering methods.

Subpackages: ``prt`` (DeepPRT). Core modules: ``sh`` (spherical harmonics), ``io``
(EXR/PNG/CSV), ``metrics`` (SSIM, L1, PSNR), ``train`` (the training loop), ``report``.
"""

__version__ = "0.1.0"
