"""User animations (prt.user_sequences): frame files written by PyVista and trimesh, through
the geometry-image and sequence jobs."""

import math

import numpy as np
import pytest
import pyvista as pv
import trimesh

from neurender import io
from neurender.prt import animations, data_jobs, mesh_files

FRAMES = 10


def _wave(p, t):
    r = np.hypot(p[:, 0] + 0.3, p[:, 1])
    return 0.15 * np.sin(5.0 * r - 2 * math.pi * t)


def write_wave(folder, frames=FRAMES, resolution=20, suffix=".obj", start=0):
    """An open PyVista plane with a travelling wave, one OBJ per frame (VTK's writer)."""
    folder.mkdir(parents=True, exist_ok=True)
    plane = pv.Plane(i_size=2, j_size=2, i_resolution=resolution, j_resolution=resolution)
    plane = plane.triangulate()
    for f in range(start, start + frames):
        frame = plane.copy()
        p = np.asarray(plane.points, np.float64).copy()
        p[:, 2] = _wave(p, f / FRAMES)
        frame.points = p
        frame.save(str(folder / f"frame_{f}{suffix}"))
    return folder


def write_mesh_sequence(folder, mesh, frames=6, suffix=".ply"):
    """A trimesh mesh breathing (scaled about its centre), one file per frame."""
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(frames):
        frame = mesh.copy()
        frame.vertices = mesh.vertices * (1 + 0.05 * math.sin(f))
        frame.export(folder / f"frame_{f:03d}{suffix}")
    return folder


def run_jobs(prt_params, tmp_path, name, inputs):
    """The geometry-image and sequence jobs of the user animation ``name`` (its files are
    ``inputs``) at 12^2, 20 % of its frames held out for testing."""
    animation = {"frames": str(tmp_path / name), "test_fraction": 0.2}
    config = {"prt": {"resolution": 12, "user_sequences": {name: animation}}}
    gim = {"gim": tmp_path / f"{name}_gim.npz", "stats": tmp_path / f"{name}_gim.csv"}
    params = prt_params("prt_geometry_image", config, object=name)
    data_jobs.prt_geometry_image(inputs, gim, params, 1)
    seq = tmp_path / f"{name}_seq.npz"
    params = prt_params("prt_sequence", config, object=name)
    data_jobs.prt_sequence({**inputs, "gim": gim["gim"]}, {"seq": seq}, params, 1)
    stats = io.read_csv(gim["stats"]).set_index("metric")["value"]
    return io.load_npz(gim["gim"]), io.load_npz(seq), stats


def test_frames_are_sorted_by_name_with_numbers_in_order(tmp_path):
    write_wave(tmp_path / "w", frames=12)
    (tmp_path / "w" / "notes.txt").write_text("not a mesh")
    names = [p.name for p in mesh_files(str(tmp_path / "w"))]
    assert names == [f"frame_{f}.obj" for f in range(12)]
    assert [p.name for p in mesh_files(str(tmp_path / "w" / "frame_1*.obj"))] == [
        "frame_1.obj",
        "frame_10.obj",
        "frame_11.obj",
    ]


def test_wave_sequence_pixels_follow_the_surface(tmp_path, prt_params):
    folder = write_wave(tmp_path / "wave")
    gim, seq, stats = run_jobs(prt_params, tmp_path, "wave", {"frames": [str(folder)]})
    assert stats["flipped_triangles"] == 0 and stats["frames"] == FRAMES
    assert stats["seam_length"] == 0 and stats["genus"] == 0
    # 20 % held out at the end (extrapolation in time); the rest split 6:2 into train, val
    assert seq["test_positions"].shape == (2, 12, 12, 3)
    assert seq["test_extrapolated"].all()
    assert len(seq["train_frame"]) == 6 and len(seq["val_frame"]) == 2
    assert sorted(np.concatenate([seq["train_frame"], seq["val_frame"]])) == list(range(8))
    # only z moves: a pixel is the same (x, y) in every frame, and on that frame's wave
    frames = np.empty((FRAMES, 12, 12, 3), np.float32)
    frames[seq["train_frame"]] = seq["train_positions"]
    frames[seq["val_frame"]] = seq["val_positions"]
    frames[8:] = seq["test_positions"]
    np.testing.assert_allclose(frames[..., :2], frames[:1, ..., :2].repeat(FRAMES, 0), atol=1e-6)
    for f in range(FRAMES):
        z = _wave(frames[f].reshape(-1, 3).astype(np.float64), f / FRAMES)
        np.testing.assert_allclose(frames[f].reshape(-1, 3)[:, 2], z, atol=0.02)
    # PCA shape parameters for MoMoPRT, one row per frame
    assert seq["train_params"].shape[0] == 6 and seq["test_params"].shape[0] == 2
    assert str(seq["kind"]) == "user_sequence"


def test_separate_test_frames_are_used_as_they_are(tmp_path, prt_params):
    train = write_wave(tmp_path / "train", frames=6)
    # Frames 7-9 of the cycle (start=20 was frames 0-2 again: the wave has period 10).
    test = write_wave(tmp_path / "test", frames=3, start=7)
    inputs = {"frames": [str(train)], "test_frames": [str(test)]}
    _, seq, stats = run_jobs(prt_params, tmp_path, "wave", inputs)
    assert stats["test_frames"] == 3
    assert len(seq["test_positions"]) == 3 and not seq["test_extrapolated"].any()
    assert len(seq["train_frame"]) + len(seq["val_frame"]) == 6


@pytest.mark.parametrize(
    ("name", "mesh", "genus"),
    [
        ("sphere", trimesh.creation.icosphere(2), 0),
        ("torus", trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12), 1),
    ],
)
def test_closed_sequences_are_cut_to_a_disk(tmp_path, prt_params, name, mesh, genus):
    folder = write_mesh_sequence(tmp_path / name, mesh)
    _, seq, stats = run_jobs(prt_params, tmp_path, name, {"frames": [str(folder)]})
    assert stats["flipped_triangles"] == 0
    assert stats["genus"] == genus and stats["boundary_loops"] == 0
    assert stats["seam_length"] > 0 and stats["seam_edges"] > 0
    assert np.isfinite(stats["stretch_l2"]) and stats["stretch_l2"] >= 1
    # every pixel lies on the surface in every frame: scale f of the rest position
    rest = seq["train_positions"][0] / (1 + 0.05 * math.sin(seq["train_frame"][0]))
    for split in ("train", "val"):
        for k, f in enumerate(seq[f"{split}_frame"]):
            np.testing.assert_allclose(
                seq[f"{split}_positions"][k], rest * (1 + 0.05 * math.sin(f)), atol=1e-5
            )


def test_a_vtk_sequence_is_read_by_pyvista(tmp_path):
    folder = write_wave(tmp_path / "vtp", frames=5, suffix=".vtp")
    sequence, test = animations.load_sequence([str(folder)], [], "prt.user_sequences.w")
    assert sequence.positions.shape == (5, 441, 3) and test is None


@pytest.mark.parametrize("suffix", [".glb", ".off", ".stl", ".ply"])
def test_trimesh_formats_keep_the_frames_apart(tmp_path, suffix):
    mesh = trimesh.creation.icosphere(1)
    folder = write_mesh_sequence(tmp_path / "seq", mesh, frames=3, suffix=suffix)
    sequence, _ = animations.load_sequence([str(folder / f"*{suffix}")], [], "x")
    assert len(sequence.files) == 3 and sequence.positions.shape[0] == 3
    scale = np.linalg.norm(sequence.positions, axis=2).mean(1)
    np.testing.assert_allclose(scale, 1 + 0.05 * np.sin(np.arange(3)), rtol=1e-5)


def test_a_vertex_count_mismatch_names_the_file_and_both_counts(tmp_path):
    folder = write_wave(tmp_path / "wave", frames=4)
    write_wave(tmp_path / "other", frames=1, resolution=21)
    (tmp_path / "other" / "frame_0.obj").rename(folder / "frame_2.obj")
    with pytest.raises(ValueError) as info:
        animations.load_sequence([str(folder)], [], "prt.user_sequences.wave")
    message = str(info.value)
    assert "prt.user_sequences.wave.frames: frame" in message
    assert "frame_2.obj has 484 vertices and 882 triangles" in message
    assert "frame_0.obj has 441 vertices and 800 triangles" in message


def test_changed_triangles_are_refused(tmp_path):
    folder = tmp_path / "seq"
    mesh = trimesh.creation.icosphere(1)
    write_mesh_sequence(folder, mesh, frames=3, suffix=".obj")
    shuffled = mesh.copy()
    shuffled.faces = mesh.faces[::-1]
    shuffled.export(folder / "frame_001.obj")
    with pytest.raises(ValueError, match=r"frame_001\.obj has 42 vertices and 80 triangles like"):
        animations.load_sequence([str(folder)], [], "prt.user_sequences.ball")


def test_test_frames_must_match_the_rest_frame(tmp_path):
    train = write_wave(tmp_path / "train", frames=4)
    test = write_wave(tmp_path / "test", frames=2, resolution=10)
    with pytest.raises(ValueError, match=r"test_frames: frame .*has 121 vertices"):
        animations.load_sequence([str(train)], [str(test)], "prt.user_sequences.wave")


def test_a_test_frame_with_a_training_pose_is_refused_naming_both(tmp_path):
    # The same pose exported again in another format: other bytes, the same vertices.
    mesh = trimesh.creation.icosphere(2)
    train = write_mesh_sequence(tmp_path / "train", mesh, frames=4, suffix=".ply")
    test = tmp_path / "test"
    test.mkdir()
    trimesh.load(train / "frame_002.ply", process=False).export(test / "pose.off")
    with pytest.raises(ValueError) as info:
        animations.load_sequence([str(train)], [str(test)], "prt.user_sequences.ball")
    assert str(info.value) == (
        f"prt.user_sequences.ball.test_frames: frame {test / 'pose.off'} has the same vertex "
        f"positions as the training frame {train / 'frame_002.ply'}; test frames must be "
        "other poses than those of frames"
    )


def test_several_components_are_refused_naming_the_file(tmp_path, prt_params):
    folder = tmp_path / "parts"
    parts = trimesh.util.concatenate(
        [trimesh.creation.icosphere(1), trimesh.creation.box().apply_translation([3, 0, 0])]
    )
    write_mesh_sequence(folder, parts, frames=3)
    with pytest.raises(ValueError, match=r"frame_000\.ply: 2 connected components \(80, 12"):
        run_jobs(prt_params, tmp_path, "parts", {"frames": [str(folder)]})


def test_a_sequence_too_short_to_train_is_refused(tmp_path, prt_params):
    folder = write_wave(tmp_path / "short", frames=2)
    with pytest.raises(ValueError, match="1 frame.* left for training and validation"):
        run_jobs(prt_params, tmp_path, "short", {"frames": [str(folder)]})


def test_unreadable_and_empty_inputs_name_the_file(tmp_path):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "frame_0.obj").write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(ValueError, match=r"frame_0\.obj: no faces; found PointCloud of 2 vertices"):
        animations.load_sequence([str(bad)], [], "prt.user_sequences.bad")
    with pytest.raises(ValueError, match=r"prt.user_sequences.none.frames: no mesh files"):
        animations.load_sequence([str(tmp_path / "missing")], [], "prt.user_sequences.none")


def _sphere_frames(folder, frames=6):
    """A breathing icosphere (642 vertices), one OBJ per frame, written as stored."""
    mesh = trimesh.creation.icosphere(3)
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(frames):
        scale = 1 + 0.1 * math.sin(f)
        frame = trimesh.Trimesh(mesh.vertices * scale, mesh.faces, process=False)
        frame.export(folder / f"frame_{f:03d}.obj")
    return folder, mesh


def test_a_frame_with_its_vertices_reordered_is_refused_naming_it(tmp_path):
    # The same triangles, the vertices' positions in another order: on the unit sphere
    # they move by up to its diameter, which edge lengths show and counts do not.
    folder, mesh = _sphere_frames(tmp_path / "ball")
    order = np.random.default_rng(0).permutation(len(mesh.vertices))
    scrambled = trimesh.Trimesh(mesh.vertices[order], mesh.faces, process=False)
    scrambled.export(folder / "frame_003.obj")
    with pytest.raises(ValueError) as info:
        animations.load_sequence([str(folder)], [], "prt.user_sequences.ball")
    message = str(info.value)
    assert "prt.user_sequences.ball.frames: frame 4 of 6" in message
    assert str(folder / "frame_003.obj") in message and str(folder / "frame_000.obj") in message
    assert "same vertices in the same order as the rest frame" in message
    share = int(message.split("but ")[1].split("%")[0])
    assert share > 80  # nearly every edge runs across the sphere
    # A test frame is checked against the rest frame the same way.
    test = tmp_path / "test"
    test.mkdir()
    (folder / "frame_003.obj").rename(test / "pose.obj")
    with pytest.raises(ValueError, match=r"ball\.test_frames: frame 1 of 1, .*pose\.obj, has"):
        animations.load_sequence([str(folder)], [str(test)], "prt.user_sequences.ball")


def test_deformations_scaling_and_the_example_animations_pass_the_edge_check(tmp_path):
    from neurender import examples

    folder, mesh = _sphere_frames(tmp_path / "ball", frames=4)
    # Scaled 5 x as a whole, and squashed to a fifth of its height: real, if extreme.
    for f, scale in ((4, [5, 5, 5]), (5, [1.5, 1.5, 0.2])):
        frame = trimesh.Trimesh(mesh.vertices * scale, mesh.faces, process=False)
        frame.export(folder / f"frame_{f:03d}.obj")
    assert len(animations.load_sequence([str(folder)], [], "ball")[0].files) == 6
    for make in (examples.wave_sequence, examples.blob_sequence, examples.torus_sequence):
        make(tmp_path / make.__name__)
        frames, _ = animations.load_sequence([str(tmp_path / make.__name__)], [], "x")
        assert len(frames.files) == examples.SEQUENCE_FRAMES
