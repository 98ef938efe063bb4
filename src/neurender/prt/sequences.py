"""Deformation sequences of every DeepPRT dataset (paper 3.2.2, 4.2.2).

Train and val are one smooth sequence (val frames a random subset, as the paper's 450/50
split); test frames lie outside it: unseen blendshape combinations with weights up to 1.3
(head), a separately seeded simulation (cloth; training joins four), or unseen lattice
motion (creature, user meshes), or the last frames of a user animation
(:func:`user_sequences`). ``head_linear``: S_lin = a S_head + (1 - a) S_plane with a
in [0, 1] for training, evenly spaced over ``linear_range`` for test. ``head_excluded``:
the head without the ``excluded_expression`` blendshape in training; test shapes move from
the mean training shape to that expression. Positions are geometry images ``(F, n, n, 3)``
of the object's grid mesh, so a pixel is the same surface point in every frame.
"""

from __future__ import annotations

import numpy as np

from neurender.prt import EXPERIMENTS, SPLITS, deform, held_out_frames
from neurender.rng import stable_seed


def build_sequences(name: str, gim: dict[str, np.ndarray], cfg: dict) -> dict[str, np.ndarray]:
    """The arrays of ``sequence.npz`` (:mod:`neurender.prt.frames`) for dataset ``name``
    from its geometry-image file's arrays ``gim``."""
    kind = name if name in EXPERIMENTS else str(gim["kind"])
    rest = gim["rest"].astype(np.float64)
    n_train, n_val, n_test = (cfg["frames"][s] for s in SPLITS)
    if kind in EXPERIMENTS:
        n_train, n_test = min(n_train, cfg["experiment_train_frames"]), cfg["experiment_points"]
    seq_len = n_train + n_val
    rng = np.random.default_rng(stable_seed(cfg["seed"], name, "sequence"))
    test_rng = np.random.default_rng(stable_seed(cfg["seed"], name, "test"))
    builders = {
        "head": _head_sequences,
        "cloth": _cloth_sequences,
        "head_linear": _linear_sequences,
        "head_excluded": _excluded_sequences,
    }
    build = builders.get(kind, _lattice_sequences)
    seq_pos, seq_params, test_pos, test_params, extrapolated = build(
        gim, rest, seq_len, n_test, rng, test_rng, cfg
    )
    return _split_arrays(
        name, cfg["seed"], n_val, seq_pos, seq_params, test_pos, test_params, extrapolated, kind
    )


def user_sequences(
    name: str, frames: np.ndarray, test: np.ndarray | None, cfg: dict
) -> dict[str, np.ndarray]:
    """The arrays of ``sequence.npz`` for a user animation (``prt.user_sequences``).

    Args:
        frames: ``(F, n, n, 3)`` geometry images of the animation's frames, in order.
        test: ``(T, n, n, 3)`` of its separate test frames, or None: then the last
            ``cfg["test_fraction"]`` of ``frames`` is held out (extrapolation in time,
            flagged ``test_extrapolated``).
        cfg: ``seed``, ``frames`` (the built-ins' train/val counts, whose ratio splits the
            rest into train and val as for them) and ``test_fraction``.

    Shape parameters (MoMoPRT's, without blendshapes) are the leading PCA coefficients of
    the position images, as for the cloth.
    """
    entry = f"prt.user_sequences.{name}"
    extrapolated = test is None
    if test is None:
        held = held_out_frames(len(frames), cfg["test_fraction"])
        frames, test = frames[:-held], frames[-held:]
    seq_len = len(frames)
    if seq_len < 2:
        raise ValueError(
            f"{entry}: {seq_len} frame(s) left for training and validation; a sequence needs "
            "at least 2 besides its test frames"
        )
    share = cfg["frames"]["val"] / (cfg["frames"]["train"] + cfg["frames"]["val"])
    n_val = min(seq_len - 1, max(1, round(share * seq_len)))
    seq_params, test_params = _pca_params(frames, test)
    extrapolated_frames = np.full(len(test), extrapolated)
    return _split_arrays(
        name,
        cfg["seed"],
        n_val,
        frames,
        seq_params,
        test,
        test_params,
        extrapolated_frames,
        "user_sequence",
    )


def _split_arrays(
    name, seed, n_val, seq_pos, seq_params, test_pos, test_params, extrapolated, kind
) -> dict[str, np.ndarray]:
    """``sequence.npz``'s arrays: the sequence's frames split at random (seeded by the
    dataset's name) into ``n_val`` validation frames and the training frames, each split
    in time order; positions and parameters as float32."""
    order = np.random.default_rng(stable_seed(seed, name, "split")).permutation(len(seq_pos))
    val_idx, train_idx = np.sort(order[:n_val]), np.sort(order[n_val:])
    return {
        "train_positions": seq_pos[train_idx].astype(np.float32),
        "val_positions": seq_pos[val_idx].astype(np.float32),
        "test_positions": test_pos.astype(np.float32),
        "train_params": seq_params[train_idx].astype(np.float32),
        "val_params": seq_params[val_idx].astype(np.float32),
        "test_params": test_params.astype(np.float32),
        "train_frame": train_idx,
        "val_frame": val_idx,
        "test_extrapolated": extrapolated,
        "kind": np.array(kind),
    }


def _head_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    deltas = gim["deltas"].astype(np.float64)
    weights = deform.smooth_walk(seq_len, len(deltas), rng)
    # Test: random combinations; every other frame has weights beyond the training
    # range [0, 1] (scaled by 1.1-1.3).
    test_w = test_rng.uniform(0.0, 1.0, (n_test, len(deltas)))
    extrapolated = np.zeros(n_test, bool)
    extrapolated[1::2] = True
    test_w[1::2] *= test_rng.uniform(1.1, 1.3, (len(test_w[1::2]), 1))
    seq_pos = deform.apply_blendshapes(rest, deltas, weights)
    return seq_pos, weights, deform.apply_blendshapes(rest, deltas, test_w), test_w, extrapolated


def _cloth_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg, simulations: int = 4):
    """Training: ``simulations`` runs with their own sphere position and wind, back to back
    (one run shows too few fold configurations to generalise); test: one more run."""
    lengths = [len(c) for c in np.array_split(np.arange(seq_len), simulations) if len(c)]
    seq_pos = np.concatenate([deform.simulate_cloth(rest, n, rng) for n in lengths])
    test_pos = deform.simulate_cloth(rest, n_test, test_rng)
    seq_params, test_params = _pca_params(seq_pos, test_pos)
    return seq_pos, seq_params, test_pos, test_params, np.zeros(n_test, bool)


def _lattice_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """Creature and user meshes: a moving free-form-deformation lattice."""
    lower, upper = rest.reshape(-1, 3).min(0), rest.reshape(-1, 3).max(0)
    pad = 0.05 * (upper - lower).max()
    lower, upper = lower - pad, upper + pad
    shape = (4, 4, 3)
    lattice = deform.ffd_lattice(lower, upper, shape)
    amplitude = 0.12 * float((upper - lower).max())
    flat = rest.reshape(-1, 3)

    def frames(disp):
        return np.stack([deform.ffd(flat, lower, upper, lattice + d) for d in disp]).reshape(
            -1, *rest.shape
        )

    seq_disp = deform.lattice_displacements(seq_len, shape, amplitude, rng)
    test_disp = deform.lattice_displacements(n_test, shape, amplitude, test_rng, period=37.0)
    return (
        frames(seq_disp),
        seq_disp.reshape(seq_len, -1),
        frames(test_disp),
        test_disp.reshape(n_test, -1),
        np.zeros(n_test, bool),
    )


def _linear_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """S_lin = a S_head + (1 - a) S_plane; the plane is the head's grid flattened (z = 0)."""
    plane = rest.copy()
    plane[..., 2] = 0.0
    a_train = rng.uniform(0.0, 1.0, seq_len)
    a_test = np.linspace(*cfg["linear_range"], n_test)

    def frames(a):
        return a[:, None, None, None] * rest + (1 - a[:, None, None, None]) * plane

    return (
        frames(a_train),
        a_train[:, None],
        frames(a_test),
        a_test[:, None],
        (a_test < 0) | (a_test > 1),
    )


def _excluded_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """Head walk without one expression; test moves from the mean shape to that expression."""
    deltas = gim["deltas"].astype(np.float64)
    names = [str(b) for b in gim["blendshapes"]]
    excluded = cfg["excluded_expression"]
    if excluded not in names:
        raise ValueError(f"prt.excluded_expression {excluded!r}: expected one of {names}")
    k = names.index(excluded)
    weights = deform.smooth_walk(seq_len, len(deltas), rng)
    weights[:, k] = 0.0
    target = np.zeros(len(deltas))
    target[k] = 1.0
    t = np.linspace(0.0, 1.0, n_test)[:, None]
    test_w = (1 - t) * weights.mean(0) + t * target
    seq_pos = deform.apply_blendshapes(rest, deltas, weights)
    return seq_pos, weights, deform.apply_blendshapes(rest, deltas, test_w), test_w, t[:, 0] > 0


def _pca_params(
    seq_pos: np.ndarray, test_pos: np.ndarray, count: int = 16
) -> tuple[np.ndarray, np.ndarray]:
    """Leading PCA coefficients of the position images (the shape parameters of a simulation)."""
    x = seq_pos.reshape(len(seq_pos), -1)
    mean = x.mean(0)
    _, _, vt = np.linalg.svd(x - mean, full_matrices=False)
    basis = vt[:count]
    return (x - mean) @ basis.T, (test_pos.reshape(len(test_pos), -1) - mean) @ basis.T
