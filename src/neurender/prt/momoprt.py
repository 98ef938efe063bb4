"""MoMoPRT (Schneider et al. 2017): the linear baseline, an affine map from shape
parameters to every texel's transfer, fitted by ridge regression.

Shape parameters are an object's blendshape weights where it has them, else the leading
PCA coefficients of its training position images. Transfer images as in
:meth:`neurender.prt.frames.Split.targets`: ``(F, C, n, n)``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from neurender import io
from neurender.prt.frames import Split


@dataclasses.dataclass
class MoMoPRT:
    """Affine map from shape parameters to every texel's transfer (ridge regression).

    Attributes:
        weights: ``(P + 1, C n n)`` (last row the bias).
        basis, mean: PCA basis ``(P, 3 n n)`` and mean ``(3 n n,)`` of training position
            images when the object has no blendshapes (empty otherwise).
        ridge: the regularisation chosen on the validation split.
    """

    weights: np.ndarray
    basis: np.ndarray
    mean: np.ndarray
    ridge: float
    shape: tuple[int, int, int]

    def features(self, split: Split) -> np.ndarray:
        if self.basis.size:
            x = split.positions.reshape(len(split.positions), -1) - self.mean
            return x @ self.basis.T
        return split.params

    def predict(self, split: Split) -> np.ndarray:
        """``(F, C, n, n)`` transfer."""
        f = self.features(split)
        return (np.column_stack([f, np.ones(len(f))]) @ self.weights).reshape(len(f), *self.shape)

    def save(self, path: str | Path) -> None:
        io.save_npz(
            path,
            weights=self.weights,
            basis=self.basis,
            mean=self.mean,
            ridge=np.array(self.ridge),
            shape=np.array(self.shape),
        )

    @classmethod
    def load(cls, path: str | Path) -> MoMoPRT:
        d = io.load_npz(path)
        return cls(
            d["weights"],
            d["basis"],
            d["mean"],
            float(d["ridge"]),
            tuple(int(s) for s in d["shape"]),
        )

    @property
    def parameters(self) -> int:
        return int(self.weights.size + self.basis.size + self.mean.size)


def fit_momoprt(
    train_split: Split,
    val_split: Split,
    material: str,
    use_params: bool,
    pca_components: int,
    ridges: list[float],
) -> MoMoPRT:
    """Regularised least squares ``min ||X W - T||^2 + lambda ||W||^2`` (bias unregularised).

    Shape parameters are the blendshape weights when ``use_params``, else the leading PCA
    coefficients of the training position images. ``lambda`` (relative to the mean
    diagonal of ``X^T X``) is picked from ``ridges`` by validation L1.
    """
    t = train_split.targets(material)
    shape = t.shape[1:]
    if use_params:
        basis = mean = np.zeros(0)
    else:
        x = train_split.positions.reshape(len(t), -1).astype(np.float64)
        mean = x.mean(0)
        _, _, vt = np.linalg.svd(x - mean, full_matrices=False)
        basis = vt[: min(pca_components, len(t) - 1)]
    model = MoMoPRT(np.zeros(0), basis, mean, 0.0, shape)
    f = model.features(train_split).astype(np.float64)
    x = np.column_stack([f, np.ones(len(f))])
    gram = x.T @ x
    rhs = x.T @ t.reshape(len(t), -1).astype(np.float64)
    scale = np.trace(gram[:-1, :-1]) / max(len(gram) - 1, 1)
    best = None
    for ridge in ridges:
        reg = np.eye(len(gram)) * ridge * scale
        reg[-1, -1] = 0.0
        w = np.linalg.solve(gram + reg, rhs)
        candidate = MoMoPRT(w.astype(np.float32), basis, mean, ridge, shape)
        err = float(np.abs(candidate.predict(val_split) - val_split.targets(material)).mean())
        if best is None or err < best[0]:
            best = (err, candidate)
    return best[1]
