"""Real scenes as metaballs: the shipped molecular structures, a molecular-dynamics
trajectory and a particle-fluid frame (:mod:`neurender.metaballs.molecules`, data and
licences in ``structures/README.md``) and your own structure files, framed into the view
volume (:mod:`neurender.metaballs.framing`) and drawn by every renderer of
:mod:`neurender.metaballs.scale` against the exact one.

Atoms are balls of their van-der-Waals radius times ``ball_scale`` in element colours;
fluid particles balls of the simulation's particle radius times ``ball_scale``, coloured by
height. The trajectory's frames share one framing (fitted on all of them), so the camera
stays still while the protein moves.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from neurender.metaball import Kernel, Scene
from neurender.metaballs import evaluate, framing, gbuffers, inputs, molecules, raymarch, scale
from neurender.metaballs.renderer import MetaballRenderer

#: The shipped scenes: the three Protein Data Bank entries, the trajectory, the fluid.
NAMES = (*molecules.PDB_ENTRIES, "adk_dims", "dam_break")


def _scene(atoms: molecules.Atoms, fit: framing.Framing, kernel: Kernel) -> Scene:
    scene = fit.scene(atoms.positions, atoms.radii, atoms.colours).to(torch.float32)
    return dataclasses.replace(scene, kernel=kernel)


def _framed(atoms: molecules.Atoms, kernel: Kernel, ball_scale: float) -> Scene:
    """One structure or fluid frame, framed on its own balls."""
    return _scene(atoms, framing.fit_framing(atoms.positions, atoms.radii, ball_scale), kernel)


def _picked(label: str, every: list[Scene], frames: int) -> dict[str, Scene]:
    """``frames`` of a trajectory's scenes ``every``, evenly spaced from the first
    (labels ``<label> frame k``)."""
    picks = np.linspace(0, len(every) - 1, min(frames, len(every))).round().astype(int)
    return {f"{label} frame {k}": every[k] for k in picks}


def real_scenes(
    names: tuple[str, ...], kernel: Kernel, ball_scale: float = 1.0, frames: int = 1
) -> dict[str, Scene]:
    """Label to framed float32 scene of each of ``names`` (:data:`NAMES`); the trajectory
    gives ``frames`` of its frames, evenly spaced from the first (labels ``adk_dims frame
    k``)."""
    out = {}
    for name in names:
        if name in molecules.PDB_ENTRIES:
            atoms = molecules.read_structure(molecules.STRUCTURES / molecules.PDB_ENTRIES[name])
            out[name] = _framed(atoms, kernel, ball_scale)
        elif name == "adk_dims":
            out |= _picked(name, trajectory(kernel, ball_scale), frames)
        elif name == "dam_break":
            atoms = molecules.read_particles(
                molecules.STRUCTURES / molecules.FLUID, molecules.FLUID_RADIUS, True
            )
            out[name] = _framed(atoms, kernel, ball_scale)
        else:
            raise ValueError(f"real scene {name!r}: expected one of {NAMES}")
    return out


def user_structure_scenes(
    paths: tuple[str, ...], kernel: Kernel, ball_scale: float = 1.0, frames: int = 1
) -> dict[str, Scene]:
    """Label (the file's name) to framed float32 scene of each of your structure files
    (:func:`neurender.metaballs.molecules.read_frames`); a file of several models is a
    trajectory that gives ``frames`` of them, evenly spaced from the first and framed alike
    (labels ``<name> frame k``)."""
    out = {}
    for path in paths:
        every, name = molecules.read_frames(path), Path(path).name
        if len(every) == 1:
            out[name] = _framed(every[0], kernel, ball_scale)
        else:
            out |= _picked(name, _framed_alike(every, kernel, ball_scale), frames)
    return out


def trajectory(kernel: Kernel, ball_scale: float = 1.0) -> list[Scene]:
    """Every frame of the shipped trajectory, framed alike (float32)."""
    every = molecules.read_frames(molecules.STRUCTURES / molecules.TRAJECTORY)
    return _framed_alike(every, kernel, ball_scale)


def _framed_alike(every: list[molecules.Atoms], kernel: Kernel, ball_scale: float) -> list[Scene]:
    """A trajectory's frames under one framing fitted on all of them (the camera stays
    still while the molecule moves)."""
    fit = framing.fit_framing(
        np.concatenate([a.positions for a in every]),
        np.concatenate([a.radii for a in every]),
        ball_scale,
    )
    return [_scene(atoms, fit, kernel) for atoms in every]


def showcase(scene: Scene, measured: scale.Measured, width: int) -> evaluate.Showcase:
    """A scene's figure row: its circles, the exact stack, and the networks' and each
    no-learning renderer's most exact setting's stacks (the last it measured), by name."""
    truth = measured.stacks[scale.EXACT, "reference"]
    predictions = {}
    for (renderer, _), stack in measured.stacks.items():
        if renderer != scale.EXACT:
            predictions[renderer] = stack  # later settings of a renderer are more exact
    return evaluate.Showcase(len(scene), inputs.draw_inputs(scene, width), truth, predictions)


def shown_models(shown: dict[str, evaluate.Showcase]) -> list[str]:
    """The renderers every showcase holds, in order of the first."""
    first = next(iter(shown.values()))
    return [m for m in first.predictions if all(m in s.predictions for s in shown.values())]


def trajectory_pictures(
    frames: list[Scene], renderer: MetaballRenderer, width: int
) -> list[torch.Tensor]:
    """Per frame ``(3, W, 2W)``: the exact renderer's colour buffer beside ``renderer``'s."""
    pictures = []
    for scene in tqdm(frames, desc="trajectory", mininterval=10):
        truth = raymarch.render_gbuffers(scene, width).stack()
        pred = renderer(renderer.inputs(scene)[None])[0]
        pictures.append(torch.cat([truth[gbuffers.COLOUR], pred[gbuffers.COLOUR]], 2))
    return pictures
