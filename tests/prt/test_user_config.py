"""Config keys of DeepPRT's user animations (prt.user_sequences): schema and config rules."""

import copy
from pathlib import Path

import pytest
import yaml
from snakemake.utils import update_config, validate

from neurender import config as rules

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


def _frames(folder: Path, count: int, suffix: str = ".obj") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(count):
        (folder / f"frame_{f:03d}{suffix}").write_text("v 0 0 0\n")
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
    mesh.write_text("v 0 0 0\n")
    changed = _with_sequences(smoke, {"wave": {"frames": "results/examples/wave"}})
    changed["prt"]["user_meshes"] = {"wave": str(mesh)}
    found = rules.problems(changed)
    assert found == ["prt user object 'wave' is both in prt.user_meshes and in prt.user_sequences"]


@pytest.mark.parametrize("name", ["head", "plane", "head_linear"])
def test_user_names_must_not_take_a_built_in_name(smoke, name):
    changed = _with_sequences(smoke, {name: {"frames": "results/examples/wave"}}, ["cloth"])
    found = rules.problems(changed)
    assert len(found) == 1 and f"prt user object {name!r}: the name of a built-in" in found[0]


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
