"""Your structure files as real scenes: one scene per single-model file, a trajectory's
frames framed alike, and unreadable files named in the dry run."""

import numpy as np

from neurender.metaball import Kernel
from neurender.metaballs import method, molecules, real_scenes

from .test_molecules import tiny_lines, write_models

KERNEL = Kernel("wyvill", 2.0, 1.0)


def test_a_single_model_file_is_one_scene_named_by_the_file(tmp_path):
    path = write_models(tmp_path / "mine.pdb", [tiny_lines()])
    scenes = real_scenes.user_structure_scenes((str(path),), KERNEL, ball_scale=1.5)
    assert list(scenes) == ["mine.pdb"]
    atoms = molecules.read_structure(path)
    assert len(scenes["mine.pdb"]) == len(atoms)
    # Framed on its own balls: the same scene as a shipped structure's framing of them.
    framed = real_scenes._framed(atoms, KERNEL, 1.5)
    np.testing.assert_allclose(scenes["mine.pdb"].centres, framed.centres)


def test_a_trajectory_gives_evenly_spaced_frames_under_one_camera(tmp_path):
    shifts = (0.0, 1.0, 2.0, 3.0, 4.0)
    path = write_models(tmp_path / "md.pdb", [tiny_lines(s) for s in shifts])
    scenes = real_scenes.user_structure_scenes((str(path),), KERNEL, frames=3)
    assert list(scenes) == ["md.pdb frame 0", "md.pdb frame 2", "md.pdb frame 4"]
    first, last = scenes["md.pdb frame 0"], scenes["md.pdb frame 4"]
    # One framing: the molecule moves 4 angstroms along (1, 1, 1) in view space, rigidly.
    step = (last.centres - first.centres).numpy()
    np.testing.assert_allclose(step, np.broadcast_to(step[0], step.shape), atol=1e-5)
    assert np.linalg.norm(step[0]) > 0
    np.testing.assert_allclose(first.radii, last.radii)


def test_an_unreadable_structure_file_fails_the_dry_run_naming_key_and_file(tmp_path):
    bad = tmp_path / "notes.pdb"
    bad.write_text("these are my notes, not atoms\n")
    good = write_models(tmp_path / "mine.pdb", [tiny_lines()])
    config = {"metaballs_scale": {"user_structures": [str(good), str(bad)]}}
    problems = list(method._structure_problems(config["metaballs_scale"]["user_structures"]))
    assert len(problems) == 1
    assert problems[0].startswith(f"metaballs_scale.user_structures[1] = {str(bad)!r}: ")
    assert str(bad) in problems[0].split(": ", 1)[1]
