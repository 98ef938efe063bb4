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
        (folder / name).write_text(f"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n# {name}\n")
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


def _radiance_hdr(path: Path, height: int = 4) -> Path:
    """A Radiance RGBE map as HDRI sites ship them: header and flat uncompressed pixels of
    radiance 1 (mantissa 128, exponent 129)."""
    header = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, 2 * height)
    path.write_bytes(header + bytes([128, 128, 128, 129]) * (2 * height * height))
    return path


def _ndr_maps_problems(smoke, folder: Path) -> list[str]:
    return [
        p
        for p in rules.problems(_with(smoke, "ndr", "user_probes_dir", str(folder)))
        if p.startswith("ndr.user_probes_dir")
    ]


def test_maps_in_other_formats_beside_the_exr_maps_are_refused_naming_each(smoke, tmp_path):
    maps = tmp_path / "maps"
    maps.mkdir()
    _map(maps / "studio.exr")
    strays = [_radiance_hdr(maps / f"{n}_2k.hdr") for n in ("sunset", "forest", "city")]
    strays.append(maps / "sunset_preview.jpg")
    strays[-1].write_bytes(b"\xff\xd8\xff")
    # Notes and hidden files may sit beside the maps.
    (maps / "README.md").write_text("maps from polyhaven.com\n")
    (maps / "LICENSE").write_text("CC0\n")
    (maps / ".DS_Store").write_bytes(b"\x00")
    (problem,) = _ndr_maps_problems(smoke, maps)
    assert f"ndr.user_probes_dir = {str(maps)!r}" in problem
    assert "holds 4 files that are not OpenEXR maps" in problem
    assert all(p.name in problem for p in strays)
    assert not any(n in problem.split(";")[0] for n in ("README.md", "LICENSE", "DS_Store"))
    assert "and no .exr map" not in problem and "Convert HDR maps" in problem
    for p in strays:
        p.unlink()
    assert _ndr_maps_problems(smoke, maps) == []


def test_a_folder_of_hdr_maps_only_names_them(smoke, tmp_path):
    maps = tmp_path / "hdr_only"
    maps.mkdir()
    _radiance_hdr(maps / "city_2k.hdr")
    (problem,) = _ndr_maps_problems(smoke, maps)
    assert "holds a file that is not an OpenEXR map (city_2k.hdr) and no .exr map" in problem


def test_the_conversion_the_message_suggests_makes_a_map_that_loads(smoke, tmp_path):
    from neurender import lights

    maps = tmp_path / "maps"
    maps.mkdir()
    _radiance_hdr(maps / "city_2k.hdr")
    (problem,) = _ndr_maps_problems(smoke, maps)
    command = problem.split('python -c "')[1].split('"')[0]
    subprocess.run([sys.executable, "-c", command], cwd=maps, check=True)
    (maps / "city_2k.hdr").unlink()
    assert _ndr_maps_problems(smoke, maps) == []
    np.testing.assert_allclose(lights.load_probe(maps / "city_2k.exr"), 1.0)


def test_a_folder_or_fifo_given_as_a_probe_file_is_named_as_such(smoke, tmp_path):
    os.mkfifo(tmp_path / "sky.exr")
    (tmp_path / "sun.exr").mkdir()
    probes = {"pipe": str(tmp_path / "sky.exr"), "dir": str(tmp_path / "sun.exr")}
    found = rules.problems(_with(smoke, "prt", "user_probes", probes))
    assert found == [
        f"prt.user_probes.pipe = '{tmp_path / 'sky.exr'}': is a named pipe (FIFO), not a "
        "file; expected a lat-long EXR light probe (.exr)",
        f"prt.user_probes.dir = '{tmp_path / 'sun.exr'}': is a folder, not a file; expected "
        "a lat-long EXR light probe (.exr)",
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


def test_params_paths_are_relative_inside_the_working_directory_absolute_outside(
    tmp_path, monkeypatch
):
    tmp_path = tmp_path.resolve()  # as os.getcwd() spells it
    work = tmp_path / "checkout"
    (work / "config").mkdir(parents=True)
    monkeypatch.chdir(work)
    # Inside: relative however given, so that a moved checkout records the same params.
    assert user_paths.workdir_relative(work) == "."
    assert user_paths.workdir_relative(work / "config/smoke.yaml") == "config/smoke.yaml"
    assert user_paths.workdir_relative("./config/../config/smoke.yaml") == "config/smoke.yaml"
    # Outside (a config in the home folder): the same file wherever the checkout is.
    outside = tmp_path / "mine.yaml"
    assert user_paths.workdir_relative(outside) == str(outside)
    assert user_paths.workdir_relative("../mine.yaml") == str(outside)
    assert user_paths.workdir_relative(tmp_path) == str(tmp_path)
    # A sibling whose name starts like the checkout's is outside too.
    assert user_paths.workdir_relative(tmp_path / "checkout2/a.yaml") == str(
        tmp_path / "checkout2/a.yaml"
    )
