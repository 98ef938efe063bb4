"""Config keys of DeepPRT's user animations (prt.user_sequences): schema and config rules."""

import copy
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
import yaml
from snakemake.utils import update_config, validate

from neurender import config as rules
from neurender.prt import mesh_files

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = str(ROOT / "workflow/schemas/config.schema.yaml")


def _config(name: str) -> dict:
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    update_config(cfg, yaml.safe_load((ROOT / "config" / name).read_text()))
    validate(cfg, SCHEMA)
    return cfg


@pytest.fixture
def smoke():
    return _config("smoke.yaml")


def _with_sequences(cfg, sequences, objects=None):
    changed = copy.deepcopy(cfg)
    changed["prt"]["user_sequences"] = sequences
    changed["prt"]["objects"] = objects or ["head", *sequences]
    validate(changed, SCHEMA)  # fills the entries' defaults
    return changed


#: Three more vertices of an OBJ stand-in, so its header declares enough to map (4).
QUAD = "v 1 0 0\nv 1 1 0\nv 0 1 0\n"


def _frames(folder: Path, count: int, suffix: str = ".obj") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(count):  # every frame its own content, so no two files are equal
        (folder / f"frame_{f:03d}{suffix}").write_text(f"v {f} 0 0\n{QUAD}# {folder.name}\n")
    return folder


def test_smoke_and_example_configs_run_a_user_sequence(smoke):
    assert "wave" in smoke["prt"]["objects"]
    assert smoke["prt"]["user_sequences"]["wave"] == {
        "frames": "results/examples/wave",
        "test_frames": "",
        "test_fraction": 0.1,
    }
    assert rules.problems(smoke) == []
    example = _config("examples/own_assets.yaml")
    assert set(example["prt"]["objects"]) == {"wave", "blob", "torus"}
    assert set(example["prt"]["user_sequences"]) == {"wave", "blob", "torus"}
    assert [p for p in rules.problems(example) if p.startswith("prt")] == []


@pytest.mark.parametrize(
    "entry",
    [
        {"frames": "x", "test_fraction": 1.0},  # nothing left to train on
        {"frames": "x", "test_fraction": 0},
        {"frames": "x", "fraction": 0.2},  # a typo
        {"test_frames": "x"},  # frames missing
        {"frames": 3},
    ],
)
def test_schema_refuses_bad_entries(smoke, entry):
    changed = copy.deepcopy(smoke)
    changed["prt"]["user_sequences"] = {"mine": entry}
    with pytest.raises(Exception, match="validat"):
        validate(changed, SCHEMA)


def test_schema_refuses_names_the_rules_cannot_use(smoke):
    changed = copy.deepcopy(smoke)
    changed["prt"]["user_sequences"] = {"my-anim": {"frames": "x"}}
    with pytest.raises(Exception, match="validat"):
        validate(changed, SCHEMA)


def test_an_object_must_be_built_in_or_a_user_entry(smoke):
    changed = copy.deepcopy(smoke)
    changed["prt"]["objects"] = ["head", "dancer"]
    found = rules.problems(changed)
    assert any("prt.objects entry 'dancer'" in f and "wave" in f for f in found), found


def test_user_mesh_and_user_sequence_names_must_not_clash(smoke, tmp_path):
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\n" + QUAD)
    changed = _with_sequences(smoke, {"wave": {"frames": "results/examples/wave"}})
    changed["prt"]["user_meshes"] = {"wave": str(mesh)}
    (found,) = rules.problems(changed)
    assert "prt.user_meshes.wave and prt.user_sequences.wave" in found


@pytest.mark.parametrize("name", ["head", "plane", "head_linear"])
def test_user_names_must_not_take_a_built_in_name(smoke, name):
    changed = _with_sequences(smoke, {name: {"frames": "results/examples/wave"}}, ["cloth"])
    found = rules.problems(changed)
    assert len(found) == 1 and f"prt.user_sequences.{name}: the name of a built-in" in found[0]


def test_frames_and_test_frames_must_hold_mesh_files(smoke, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("")
    frames = _frames(tmp_path / "frames", 5)
    changed = _with_sequences(
        smoke,
        {
            "a": {"frames": str(empty)},
            "b": {"frames": str(tmp_path / "nothing" / "*.obj")},
            "c": {"frames": str(frames), "test_frames": str(empty)},
        },
    )
    found = rules.problems(changed)
    assert len(found) == 3, found
    assert f"prt.user_sequences.a.frames = {str(empty)!r}: no mesh files found" in found[0]
    assert "prt.user_sequences.b.frames" in found[1] and "no mesh files" in found[1]
    assert f"prt.user_sequences.c.test_frames = {str(empty)!r}: no mesh files" in found[2]


def test_a_glob_and_every_format_are_counted(smoke, tmp_path):
    folder = tmp_path / "mixed"
    for k, suffix in enumerate((".obj", ".ply", ".off", ".stl", ".glb", ".vtp")):
        _frames(folder, 1, suffix).joinpath(f"frame_000{suffix}").rename(folder / f"f{k}{suffix}")
    changed = _with_sequences(smoke, {"mixed": {"frames": str(folder / "f*")}})
    assert rules.problems(changed) == []


def test_too_few_frames_for_training_validation_and_testing(smoke, tmp_path):
    three = _frames(tmp_path / "three", 3)
    changed = _with_sequences(
        smoke,
        {
            "ok": {"frames": str(three)},  # 1 held out, 2 left
            "short": {"frames": str(three), "test_fraction": 0.5},  # 2 held out, 1 left
            "one": {"frames": str(_frames(tmp_path / "one", 1)), "test_frames": str(three)},
        },
    )
    found = rules.problems(changed)
    assert found == [
        "prt.user_sequences.short: 3 frames, 2 held out for testing (test_fraction = 0.5); "
        "expected at least 2 more for training and validation",
        "prt.user_sequences.one: 1 frame; expected at least 2 for training and validation",
    ]


def test_paths_the_workflow_makes_are_not_checked_at_dag_time(smoke):
    changed = _with_sequences(
        smoke,
        {"later": {"frames": "results/examples/not_yet", "test_frames": "results/x/*.obj"}},
    )
    assert rules.problems(changed) == []


def _wave_frames(folder: Path, count: int, start: int = 0, resolution: int = 6) -> Path:
    """Frames as Blender or PyVista export them: a plane with a moving wave, one OBJ each."""
    folder.mkdir(parents=True, exist_ok=True)
    plane = pv.Plane(i_resolution=resolution, j_resolution=resolution).triangulate()
    for f in range(start, start + count):
        frame = plane.copy()
        frame.points[:, 2] = 0.1 * np.sin(3 * frame.points[:, 0] + f)
        frame.save(str(folder / f"frame_{f:03d}.obj"))
    return folder


def test_test_frames_that_are_training_frames_are_refused_naming_both(smoke, tmp_path):
    train = _wave_frames(tmp_path / "train", 6)
    (tmp_path / "linked").symlink_to(train, target_is_directory=True)  # the same folder
    copies = tmp_path / "copies"
    copies.mkdir()
    shutil.copy(train / "frame_002.obj", copies / "pose.obj")  # the same bytes
    _wave_frames(copies, 1, start=40)  # and one real test frame
    changed = _with_sequences(
        smoke,
        {
            "same": {"frames": str(train), "test_frames": str(tmp_path / "linked" / "*3.obj")},
            "copy": {"frames": str(train), "test_frames": str(copies)},
        },
    )
    assert rules.problems(changed) == [
        f"prt.user_sequences.same.test_frames: {tmp_path / 'linked' / 'frame_003.obj'} is "
        f"the training frame {train / 'frame_003.obj'} (the same file); test frames must "
        "be other frames than those of frames",
        f"prt.user_sequences.copy.test_frames: {copies / 'pose.obj'} has the same content as "
        f"the training frame {train / 'frame_002.obj'}; test frames must be other frames "
        "than those of frames",
    ]
    fresh = _wave_frames(tmp_path / "fresh", 2, start=20)
    ok = _with_sequences(smoke, {"ok": {"frames": str(train), "test_frames": str(fresh)}})
    assert rules.problems(ok) == []


def test_a_frame_with_another_vertex_count_fails_the_dry_run(smoke, tmp_path):
    train = _wave_frames(tmp_path / "train", 4)
    _wave_frames(tmp_path / "other", 1, start=4, resolution=5)
    (tmp_path / "other" / "frame_004.obj").rename(train / "frame_004.obj")
    test = _wave_frames(tmp_path / "test", 1, start=9, resolution=4)
    changed = _with_sequences(smoke, {"w": {"frames": str(train)}})
    assert rules.problems(changed) == [
        f"prt.user_sequences.w: frame {train / 'frame_004.obj'} has 36 vertices but the rest "
        f"frame {train / 'frame_000.obj'} has 49; every frame needs the same vertices "
        "(export the animation as a mesh sequence, without modifiers that change the "
        "topology)"
    ]
    (train / "frame_004.obj").unlink()
    changed = _with_sequences(smoke, {"w": {"frames": str(train), "test_frames": str(test)}})
    (problem,) = rules.problems(changed)
    assert f"frame {test / 'frame_009.obj'} has 25 vertices" in problem


def test_hidden_files_in_a_frames_folder_are_not_frames(smoke, tmp_path):
    train = _wave_frames(tmp_path / "train", 3)
    # What macOS leaves on a USB stick or in a zip: AppleDouble resource forks.
    (train / "._frame_000.obj").write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X")
    (train / ".DS_Store").write_bytes(b"\x00\x00\x00\x01Bud1")
    assert [p.name for p in mesh_files(str(train))] == [
        "frame_000.obj",
        "frame_001.obj",
        "frame_002.obj",
    ]
    assert rules.problems(_with_sequences(smoke, {"w": {"frames": str(train)}})) == []


def test_a_fifo_or_a_folder_named_as_a_frame_is_named_as_such(smoke, tmp_path):
    fifo = tmp_path / "frame.obj"
    os.mkfifo(fifo)
    changed = _with_sequences(smoke, {"w": {"frames": str(fifo)}})
    assert rules.problems(changed) == [
        f"prt.user_sequences.w.frames = {str(fifo)!r}: is a named pipe (FIFO), not a file"
    ]


def test_a_folder_given_as_a_user_mesh_or_probe_names_its_key(smoke, tmp_path):
    folder = tmp_path / "some" / "folder"
    folder.mkdir(parents=True)
    changed = copy.deepcopy(smoke)
    changed["prt"]["user_meshes"] = {"mine": str(folder)}
    changed["prt"]["user_probes"] = {"sky2": str(folder)}
    mesh, probe = rules.problems(changed)
    assert mesh.startswith(f"prt.user_meshes.mine = {str(folder)!r}: is a folder, not a file")
    assert "expected a mesh file (.obj, .ply" in mesh
    assert probe.startswith(f"prt.user_probes.sky2 = {str(folder)!r}: is a folder, not a file")
    assert "expected a lat-long EXR light probe (.exr)" in probe


def test_a_file_of_another_format_given_as_a_user_mesh_is_refused(smoke, tmp_path):
    fbx = tmp_path / "mine.fbx"
    fbx.write_bytes(b"Kaydara FBX Binary  \x00")
    changed = copy.deepcopy(smoke)
    changed["prt"]["user_meshes"] = {"mine": str(fbx)}
    (problem,) = rules.problems(changed)
    assert problem.startswith(f"prt.user_meshes.mine = {str(fbx)!r}: expected a mesh file (")
    assert ".vtp" in problem and ".glb" in problem


def _triangle(path: Path) -> Path:
    """One triangle as Blender, trimesh or a text editor writes it, per format."""
    if path.suffix == ".obj":
        path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    elif path.suffix == ".off":
        path.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    else:
        pv.PolyData(np.eye(3), faces=[3, 0, 1, 2]).save(str(path))
    return path


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off"])
def test_a_one_triangle_user_mesh_fails_the_dry_run(smoke, tmp_path, suffix):
    tri = _triangle(tmp_path / f"tri{suffix}")
    changed = copy.deepcopy(smoke)
    changed["prt"]["user_meshes"] = {"tri": str(tri)}
    changed["prt"]["objects"] = ["tri"]
    (problem,) = rules.problems(changed)
    assert problem.startswith(f"prt.user_meshes.tri = {str(tri)!r}: 3 vertices; expected")
    assert "a boundary loop of at least 4 vertices" in problem
    quad = tmp_path / "quad.obj"  # two triangles: 4 boundary vertices, one per corner
    quad.write_text("v 0 0 0\n" + QUAD + "f 1 2 3\nf 1 3 4\n")
    changed["prt"]["user_meshes"] = {"tri": str(quad)}
    assert rules.problems(changed) == []


def test_a_one_triangle_rest_frame_fails_the_dry_run(smoke, tmp_path):
    folder = tmp_path / "tri"
    folder.mkdir()
    for f in range(4):
        (folder / f"frame_{f}.obj").write_text(f"v 0 0 {f}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (problem,) = rules.problems(_with_sequences(smoke, {"t": {"frames": str(folder)}}))
    assert problem.startswith(
        f"prt.user_sequences.t: the rest frame {folder / 'frame_0.obj'} has 3 vertices; expected"
    )
    assert "a boundary loop of at least 4 vertices" in problem
