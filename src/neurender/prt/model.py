"""DeepPRT model (paper 3.2) and the MoMoPRT linear baseline (Schneider et al. 2017).

Inputs are the position and normal images ``(B, 6, n, n)``: P mapped to [-1, 1] by the
training set's bounding box, N as unit vectors. Targets are the transfer images, diffuse
``(B, K, n, n)`` or glossy ``(B, 3 K, n, n)`` (colour-major, as the EXR channels), mapped
per channel to [0, 1] by an affine normalisation stored with the checkpoint (with a 10%
margin on both sides so extrapolated shapes are not clipped by the sigmoid).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.utils.data import TensorDataset

from neurender import io, train
from neurender.nn.inference import OnnxNetwork, export_onnx, prepare_for_inference
from neurender.nn.unet import ResUNet, count_parameters
from neurender.prt.data import read_frame

log = logging.getLogger(__name__)

MATERIALS = ("diffuse", "glossy")


@dataclasses.dataclass
class Split:
    """One split of one object, loaded in memory.

    Attributes:
        positions, normals: ``(F, n, n, 3)`` float32.
        diffuse: ``(F, n, n, K)``; glossy: ``(F, n, n, 3, K)`` float32.
        params: ``(F, P)`` shape parameters from the sequence file.
    """

    positions: np.ndarray
    normals: np.ndarray
    diffuse: np.ndarray
    glossy: np.ndarray
    params: np.ndarray

    def targets(self, material: str) -> np.ndarray:
        """``(F, C, n, n)`` target images of a material."""
        if material == "diffuse":
            t = self.diffuse
        elif material == "glossy":
            t = self.glossy.reshape(*self.glossy.shape[:3], -1)
        else:
            raise ValueError(f"material {material!r}: expected one of {MATERIALS}")
        return np.ascontiguousarray(np.moveaxis(t, -1, 1))


def load_split(
    frames_dir: str | Path, manifest: str | Path, params: np.ndarray, n_bands: int
) -> Split:
    """Read every frame EXR listed in a split's manifest."""
    files = io.read_csv(manifest, ["frame", "file"]).sort_values("frame")["file"]
    frames = [read_frame(Path(frames_dir) / f, n_bands) for f in files]
    if len(frames) != len(params):
        raise ValueError(
            f"{manifest} lists {len(frames)} frames but the sequence has {len(params)}"
        )
    return Split(*(np.stack([fr[k] for fr in frames]) for k in ("P", "N", "T", "G")), params=params)


def raw_inputs(split: Split) -> np.ndarray:
    """``(F, 6, n, n)`` float32: the P (world units) and N (unit vectors) images, unscaled."""
    x = np.concatenate([split.positions, split.normals], -1)
    return np.ascontiguousarray(np.moveaxis(x, -1, 1), np.float32)


@dataclasses.dataclass
class Normalisation:
    """Affine maps of inputs and targets; ``x_normalised = (x - offset) / scale``.

    Targets either span [0, 1] per channel (the paper: ``offset``, ``scale`` ``(C, 1, 1)``)
    or, with ``residual``, are the deviation from the training set's mean image centred on
    0.5 (``offset`` ``(C, n, n)``): the network then spends no capacity on the part of
    the transfer that every frame shares, which a small network learns only slowly.
    """

    p_offset: np.ndarray  # (3,)
    p_scale: np.ndarray  # (3,)
    t_offset: np.ndarray  # (C, 1, 1) or (C, n, n)
    t_scale: np.ndarray  # (C, 1, 1)

    @classmethod
    def fit(
        cls, split: Split, material: str, residual: bool = True, margin: float = 0.1
    ) -> Normalisation:
        p = split.positions.reshape(-1, 3)
        lo, hi = p.min(0), p.max(0)
        t = split.targets(material)
        if residual:
            mean = t.mean(0)
            span = 2 * np.maximum(np.abs(t - mean).max(axis=(0, 2, 3)), 1e-6)[:, None, None]
            scale = (1 + 2 * margin) * span
            offset = mean - 0.5 * scale
        else:
            tlo, thi = t.min(axis=(0, 2, 3)), t.max(axis=(0, 2, 3))
            span = np.maximum(thi - tlo, 1e-6)[:, None, None]
            scale = (1 + 2 * margin) * span
            offset = tlo[:, None, None] - margin * span
        return cls(
            p_offset=(lo + hi) / 2,
            p_scale=np.maximum(hi - lo, 1e-6).max() / 2 * np.ones(3, np.float32),
            t_offset=offset.astype(np.float32),
            t_scale=scale.astype(np.float32),
        )

    def inputs(self, split: Split) -> np.ndarray:
        """``(F, 6, n, n)`` float32 network inputs (P normalised)."""
        x = raw_inputs(split)
        x[:, :3] = (x[:, :3] - self.p_offset[:, None, None]) / self.p_scale[:, None, None]
        return x

    def encode(self, targets: np.ndarray) -> np.ndarray:
        """Targets ``(F, C, n, n)`` to network outputs in [0, 1]."""
        return ((targets - self.t_offset) / self.t_scale).astype(np.float32)

    def decode(self, values: np.ndarray) -> np.ndarray:
        """Network outputs ``(F, C, n, n)`` to transfer."""
        return values * self.t_scale + self.t_offset

    def state(self) -> dict[str, np.ndarray]:
        return dataclasses.asdict(self)


def build_network(out_channels: int, widths: list[int], blocks: int) -> ResUNet:
    return ResUNet(6, out_channels, list(widths), blocks)


def _l1_loss(model: torch.nn.Module, batch) -> tuple[torch.Tensor, dict[str, float]]:
    x, y = batch
    return torch.nn.functional.l1_loss(model(x), y), {}


def train_deepprt(
    train_split: Split,
    val_split: Split,
    material: str,
    cfg: dict,
    threads: int,
    checkpoint: str,
    log_csv: str,
) -> ResUNet:
    """Train one DeepPRT network (one object, one material) with the shared loop."""
    torch.manual_seed(cfg["seed"])
    norm = Normalisation.fit(train_split, material, residual=cfg["residual_targets"])
    make = lambda s: TensorDataset(  # noqa: E731
        torch.from_numpy(norm.inputs(s)), torch.from_numpy(norm.encode(s.targets(material)))
    )
    out_channels = train_split.targets(material).shape[1]
    # Channels-last weights make oneDNN (CPU) and cuDNN pick their faster NHWC kernels:
    # a training step of the default network takes 12% less time on the CPU.
    model = build_network(out_channels, cfg["widths"], cfg["blocks"]).to(
        memory_format=torch.channels_last
    )
    config = train.TrainConfig.from_stage(cfg, threads)
    start = time.perf_counter()
    train.fit(
        model,
        make(train_split),
        make(val_split),
        _l1_loss,
        config,
        checkpoint,
        log_csv,
        extra_state={
            "normalisation": norm.state(),
            "widths": list(cfg["widths"]),
            "blocks": cfg["blocks"],
            "out_channels": out_channels,
            "material": material,
            "parameters": count_parameters(model),
        },
    )
    log.info("trained %s in %.1f s", checkpoint, time.perf_counter() - start)
    return model


class TransferNetwork(nn.Module):
    """A trained network with its normalisation, the graph a renderer ships.

    ``(B, 6, n, n)`` raw P and N images (:func:`raw_inputs`) to ``(B, C, n, n)`` transfer
    in the targets' units: ``decode(network(normalised inputs))``.
    """

    def __init__(self, network: nn.Module, norm: Normalisation):
        super().__init__()
        self.network = network
        tensor = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
        self.register_buffer("p_offset", tensor(norm.p_offset).reshape(1, 3, 1, 1))
        self.register_buffer("p_scale", tensor(norm.p_scale).reshape(1, 3, 1, 1))
        self.register_buffer("t_offset", tensor(norm.t_offset)[None])
        self.register_buffer("t_scale", tensor(norm.t_scale)[None])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p = (x[:, :3] - self.p_offset) / self.p_scale
        return self.network(torch.cat([p, x[:, 3:]], 1)) * self.t_scale + self.t_offset


class DeepPRT:
    """A trained network for inference on numpy splits.

    It runs the exported ONNX file with ONNX Runtime when one is given and the device is the
    CPU (the faster engine there), PyTorch otherwise; ``engines`` holds both on the CPU so
    they can be timed side by side.
    """

    def __init__(
        self,
        checkpoint: str | Path,
        onnx_file: str | Path | None = None,
        device: str = "auto",
        threads: int = 1,
    ):
        state = train.load_checkpoint(checkpoint)
        extra = state["extra"]
        self.device = train.resolve_device(device, threads)
        model = build_network(extra["out_channels"], extra["widths"], extra["blocks"])
        model.load_state_dict(state["model"])
        self.parameters = count_parameters(model)
        self.norm = Normalisation(**{k: np.asarray(v) for k, v in extra["normalisation"].items()})
        self.module = TransferNetwork(prepare_for_inference(model), self.norm).to(self.device)
        self.engines = {"pytorch": self._run_pytorch}
        if onnx_file is not None and self.device.type == "cpu":
            self.engines["onnxruntime"] = OnnxNetwork(onnx_file, threads)
        self.engine = "onnxruntime" if "onnxruntime" in self.engines else "pytorch"

    @torch.inference_mode()
    def _run_pytorch(self, x: np.ndarray) -> np.ndarray:
        x = torch.from_numpy(x).to(self.device, memory_format=torch.channels_last)
        return self.module(x).cpu().numpy()

    def predict(self, split: Split, batch: int = 8, engine: str | None = None) -> np.ndarray:
        """``(F, C, n, n)`` transfer in physical units, by ``engine`` (default ``self.engine``)."""
        run = self.engines[engine or self.engine]
        x = raw_inputs(split)
        return np.concatenate([run(x[i : i + batch]) for i in range(0, len(x), batch)])


def export_deepprt(checkpoint: str | Path, example: Split, out: str | Path) -> None:
    """Write the network file a renderer ships: ``checkpoint``'s network with its
    normalisation (:class:`TransferNetwork`) as ONNX, checked against PyTorch on the first
    two frames of ``example`` (the first twice if it has one)."""
    net = DeepPRT(checkpoint, device="cpu")
    x = raw_inputs(example)
    export_onnx(net.module, torch.from_numpy(x[np.arange(2) % len(x)]), out)


# ---------------------------------------------------------------- MoMoPRT


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


def load_splits(
    seq_path: str, dirs: dict[str, str], manifests: dict[str, str], n_bands: int, splits
):
    """Splits of one object by name, with the sequence file's shape parameters."""
    seq = io.load_npz(seq_path)
    return seq, {s: load_split(dirs[s], manifests[s], seq[f"{s}_params"], n_bands) for s in splits}


def run_train(
    seq_path: str,
    dirs: dict,
    manifests: dict,
    material: str,
    cfg: dict,
    threads: int,
    checkpoint: str,
    onnx_out: str,
    log_csv: str,
) -> None:
    """Train DeepPRT on an object's train split (val for model selection) and export the
    selected network as the ONNX file a renderer ships."""
    _, splits = load_splits(seq_path, dirs, manifests, cfg["n_bands"], ("train", "val"))
    train_deepprt(splits["train"], splits["val"], material, cfg, threads, checkpoint, log_csv)
    export_deepprt(checkpoint, splits["val"], onnx_out)


def run_momoprt(
    seq_path: str, dirs: dict, manifests: dict, material: str, cfg: dict, out: str
) -> None:
    """Fit MoMoPRT on the train split, on blendshape weights where the object has them."""
    seq, splits = load_splits(seq_path, dirs, manifests, cfg["n_bands"], ("train", "val"))
    use_params = str(seq["kind"]) in ("head", "head_linear", "head_excluded")
    fit_momoprt(
        splits["train"], splits["val"], material, use_params, cfg["pca_components"], cfg["ridges"]
    ).save(out)
