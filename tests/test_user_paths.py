"""User paths as users write them: a leading ``./``, symlinked folders, hidden files,
upper-case suffixes, braces, folders and FIFOs where a file belongs; checked by the config
rules and by a dry run."""

import copy
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from snakemake.utils import update_config, validate

from neurender import config as rules
from neurender import io, user_paths

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = str(ROOT / "workflow/schemas/config.schema.yaml")


@pytest.fixture(scope="module")
def smoke():
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    update_config(cfg, yaml.safe_load((ROOT / "config/smoke.yaml").read_text()))
    validate(cfg, SCHEMA)
    return cfg


def _with(cfg, section, key, value):
    changed = copy.deepcopy(cfg)
    changed[section][key] = value
    validate(changed, SCHEMA)
    return changed


def _map(path: Path) -> Path:
    """A 2:1 lat-long map as an EXR writer makes one (RGB channels)."""
    io.write_exr(path, {c: np.full((4, 8), 0.5, np.float32) for c in "RGB"})
    return path


@pytest.mark.parametrize(
    ("path", "made", "normal"),
    [
        ("results/examples/crate.obj", True, "results/examples/crate.obj"),
        ("./results/examples/crate.obj", True, "results/examples/crate.obj"),
        ("results//examples/./crate.obj", True, "results/examples/crate.obj"),
        ("data/../results/x.csv", True, "results/x.csv"),
        ("results/../data/x.csv", False, "results/../data/x.csv"),  # as written: not ours
        ("resultsx/a.obj", False, "resultsx/a.obj"),
        ("/abs/results/a.obj", False, "/abs/results/a.obj"),
        ("", False, ""),
    ],
)
def test_paths_under_results_are_the_workflows_however_spelled(path, made, normal):
    assert user_paths.made_by_the_workflow(path) is made
    assert user_paths.as_input(path) == normal


def test_a_folder_stands_for_its_visible_files_and_a_glob_for_its_files(tmp_path):
    (tmp_path / "frames").mkdir()
    for name in ("f2.obj", "f10.obj", "._f2.obj", ".DS_Store", "notes.txt"):
        (tmp_path / "frames" / name).write_text("x")
    (tmp_path / "frames" / "sub").mkdir()
    (tmp_path / "linked").symlink_to(tmp_path / "frames", target_is_directory=True)
    names = [p.name for p in user_paths.files_of(str(tmp_path / "linked"))]
    assert names == ["f10.obj", "f2.obj", "notes.txt"]
    assert [p.name for p in user_paths.files_of(str(tmp_path / "frames" / "*.obj"))] == [
        "f10.obj",
        "f2.obj",
    ]
    assert user_paths.with_suffix([Path("a.EXR"), Path("b.exr"), Path("c.hdr")], [".exr"]) == [
        Path("a.EXR"),
        Path("b.exr"),
    ]


def test_what_a_path_is_when_it_is_not_a_file(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "dir").mkdir()
    (tmp_path / "file").write_text("")
    (tmp_path / "dangling").symlink_to(tmp_path / "nothing")
    assert user_paths.file_problem(tmp_path / "file") is None
    assert user_paths.file_problem(tmp_path / "dir") == "is a folder, not a file"
    assert user_paths.file_problem(tmp_path / "pipe") == "is a named pipe (FIFO), not a file"
    assert user_paths.file_problem(tmp_path / "dangling") == (
        f"is a symbolic link to {tmp_path / 'nothing'}, which does not exist"
    )


@pytest.mark.parametrize("name", ["balls{v2}.csv", "balls{ v2 }.csv", "b{x,[0-9]+}.csv"])
def test_braces_snakemake_would_read_as_a_wildcard_are_refused_naming_key_and_file(
    smoke, tmp_path, name
):
    scenes = tmp_path / name
    scenes.write_text("scene,x,y,z,radius,r,g,b\na,0,0,15,1,0.5,0.5,0.5\n")
    found = rules.problems(_with(smoke, "metaballs", "user_scenes", str(scenes)))
    assert len(found) == 1
    assert found[0].startswith(f"metaballs.user_scenes = {str(scenes)!r}: {scenes} contains '{{")
    assert "Snakemake reads as a wildcard" in found[0]


def test_braces_in_a_file_of_a_frames_folder_are_refused(smoke, tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for name in ("frame_0.obj", "frame_1.obj", "frame_{2}.obj"):
        (folder / name).write_text(f"v 0 0 0\n# {name}\n")
    cfg = copy.deepcopy(smoke)
    cfg["prt"]["user_sequences"] = {"anim": {"frames": str(folder)}}
    cfg["prt"]["objects"] = ["head", "anim"]
    validate(cfg, SCHEMA)
    (problem,) = rules.problems(cfg)
    assert problem.startswith(
        f"prt.user_sequences.anim.frames = {str(folder)!r}: {folder / 'frame_{2}.obj'} contains"
    )


def test_braces_that_are_no_wildcard_pass(smoke, tmp_path):
    scenes = tmp_path / "balls{a b}.csv"  # a space: not a wildcard name
    scenes.write_text("scene,x,y,z,radius,r,g,b\na,0,0,15,1,0.5,0.5,0.5\n")
    assert rules.problems(_with(smoke, "metaballs", "user_scenes", str(scenes))) == []


def test_ndr_maps_are_found_in_any_case_and_hidden_files_are_not_maps(smoke, tmp_path):
    from neurender.ndr import environments

    maps = tmp_path / "maps"
    maps.mkdir()
    _map(maps / "B.EXR")
    _map(maps / "a.exr")
    (maps / "._a.exr").write_bytes(b"\x00\x05\x16\x07Mac OS X")
    assert rules.problems(_with(smoke, "ndr", "user_probes_dir", str(maps))) == []
    assert environments.user_probes(maps) == [maps / "B.EXR", maps / "a.exr"]
    hidden = tmp_path / "hidden"
    hidden.mkdir()
    (hidden / "._a.exr").write_bytes(b"\x00\x05\x16\x07Mac OS X")
    assert rules.problems(_with(smoke, "ndr", "user_probes_dir", str(hidden))) == [
        f"ndr.user_probes_dir = {str(hidden)!r}: expected a folder holding *.exr lat-long maps"
    ]


def test_a_folder_or_fifo_given_as_a_probe_file_is_named_as_such(smoke, tmp_path):
    os.mkfifo(tmp_path / "sky.exr")
    (tmp_path / "sun.exr").mkdir()
    probes = {"pipe": str(tmp_path / "sky.exr"), "dir": str(tmp_path / "sun.exr")}
    found = rules.problems(_with(smoke, "prt", "user_probes", probes))
    assert found == [
        f"prt user entry 'pipe': file {tmp_path / 'sky.exr'} is a named pipe (FIFO), not a file",
        f"prt user entry 'dir': file {tmp_path / 'sun.exr'} is a folder, not a file",
    ]
    pipe = tmp_path / "sky.exr"
    with pytest.raises(FileNotFoundError, match=rf"EXR file {pipe} is a named pipe"):
        io.read_exr(tmp_path / "sky.exr")


@pytest.mark.parametrize("name", ["", "a/../b", "<script>", "-x", "a b"])
def test_ndr_object_names_follow_the_other_methods_pattern(smoke, name):
    changed = copy.deepcopy(smoke)
    changed["ndr"]["user_objects"] = {name: "results/examples/crate.obj"}
    with pytest.raises(Exception, match="does not match") as err:
        validate(changed, SCHEMA)
    assert "user_objects" in str(err.value)
    changed["ndr"]["user_objects"] = {"my-rock_2": "results/examples/crate.obj"}
    validate(changed, SCHEMA)


def _dry_run(tmp_path, text):
    extra = tmp_path / "extra.yaml"
    extra.write_text(text)
    result = subprocess.run(
        # --forceall: every job is listed, whatever this checkout's results/ already holds.
        [sys.executable, "-m", "snakemake", "results/report.html", "-n", "--forceall"]
        + ["--cores", "1"]
        + ["--configfile", "config/smoke.yaml", str(extra)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    return result.returncode, result.stdout + result.stderr


def test_the_dry_run_takes_a_leading_dot_slash_for_the_workflows_files(tmp_path):
    # The own-assets example's paths, written with ./ as a shell's tab completion does.
    code, out = _dry_run(
        tmp_path,
        "prt:\n  user_sequences:\n    wave: {frames: ./results/examples/wave}\n"
        "ndr:\n  user_objects:\n    crate: ./results/examples/crate.obj\n"
        "  user_probes_dir: ./results/examples/maps\n"
        "simplification:\n  user_assets:\n"
        "    crate: {path: ./results/examples/crate.obj, triangles: 96}\n"
        "metaballs:\n  user_scenes: ./results/examples/balls.csv\n",
    )
    assert code == 0, out
    inputs = [line.strip() for line in out.splitlines() if line.strip().startswith("input:")]
    assert not any("./results" in line for line in inputs)
    # The example_assets rule's outputs, as it spells them, are the jobs' inputs.
    for path in ("crate.obj", "wave", "maps", "balls.csv"):
        assert any(f"results/examples/{path}" in line for line in inputs), path
    assert "rule simplification_prepare" in out and "rule ndr_user_objects" in out


def test_the_dry_run_refuses_braces_naming_the_key(tmp_path):
    scenes = tmp_path / "balls{v2}.csv"
    scenes.write_text("scene,x,y,z,radius,r,g,b\na,0,0,15,1,0.5,0.5,0.5\n")
    code, out = _dry_run(tmp_path, f"metaballs:\n  user_scenes: '{scenes}'\n")
    assert code != 0
    assert f"metaballs.user_scenes = '{scenes}': {scenes} contains '{{v2}}'" in out
    assert "WildcardError" not in out


def test_braces_in_a_texture_an_obj_names_are_refused_naming_the_key(smoke, tmp_path):
    (tmp_path / "crate.obj").write_text("mtllib crate.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "crate.mtl").write_text("newmtl wood\nmap_Kd wood{v2}.png\n")
    (tmp_path / "wood{v2}.png").write_bytes(b"")
    changed = copy.deepcopy(smoke)
    changed["ndr"]["user_objects"] = {"crate": str(tmp_path / "crate.obj")}
    found = [p for p in rules.problems(changed) if "contains" in p]
    assert found == [
        f"ndr.user_objects.crate = {str(tmp_path / 'crate.obj')!r}: {tmp_path / 'wood{v2}.png'} "
        "contains '{v2}', which Snakemake reads as a wildcard in an input file (it has no "
        "escape for literal braces); rename the file or folder without braces"
    ]
