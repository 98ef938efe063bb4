"""simplification.user_assets in the config: the schema's types and defaults, and the rules
checked before any job starts (neurender.config), each naming the key and the file."""

import copy
import os
from pathlib import Path

import pytest
import trimesh
import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import update_config, validate

from neurender import config as rules
from neurender.asset_files import asset_inputs

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = str(ROOT / "workflow/schemas/config.schema.yaml")


def load(*names):
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    for name in names:
        update_config(cfg, yaml.safe_load((ROOT / "config" / name).read_text()))
    validate(cfg, SCHEMA)
    return cfg


@pytest.fixture(scope="module")
def base():
    return load()


def with_assets(cfg, assets):
    changed = copy.deepcopy(cfg)
    changed["simplification"]["user_assets"] = assets
    validate(changed, SCHEMA)
    return changed


def simplification_problems(cfg):
    return [p for p in rules.problems(cfg) if p.startswith("simplification")]


@pytest.mark.parametrize("name", ["smoke.yaml", "examples/own_assets.yaml"])
def test_shipped_configs_with_user_assets_break_no_rule(name):
    cfg = load(name)
    assert cfg["simplification"]["user_assets"]
    assert simplification_problems(cfg) == []


def test_defaults_fill_ratio_triangles_and_views(base):
    cfg = with_assets(base, {"rock": {"path": "rock.glb"}})
    assert cfg["simplification"]["user_assets"]["rock"] == {
        "path": "rock.glb",
        "ratio": 0.02,
        "triangles": None,
        "views": "all_around",
    }
    assert base["simplification"]["user_assets"] == {}  # opt-in: the default runs none


@pytest.mark.parametrize(
    "assets",
    [
        {"rock": {"path": "rock.glb", "ratoi": 0.1}},  # a typo
        {"rock": {"ratio": 0.1}},  # no path
        {"my rock": {"path": "rock.glb"}},  # not a wildcard-safe name
        {"rock": {"path": "rock.glb", "ratio": 1.5}},
        {"rock": {"path": "rock.glb", "triangles": 2}},
        {"rock": {"path": "rock.glb", "views": "top"}},
    ],
)
def test_the_schema_refuses_bad_entries(base, assets):
    with pytest.raises(WorkflowError):
        with_assets(base, assets)


def test_missing_files_unknown_formats_and_built_in_names_are_refused(base, tmp_path):
    trimesh.creation.box().export(tmp_path / "box.ply")
    (tmp_path / "crate.obj").write_text("mtllib crate.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "crate.mtl").write_text("newmtl a\nmap_Kd crate.png\n")
    os.mkfifo(tmp_path / "pipe.glb")
    (tmp_path / "mesh.fbx").write_bytes(b"Kaydara FBX Binary  \x00")
    cfg = with_assets(
        base,
        {
            "ok": {"path": str(tmp_path / "box.ply")},
            "gone": {"path": str(tmp_path / "gone.glb")},
            "pipe": {"path": str(tmp_path / "pipe.glb")},
            "fbx": {"path": str(tmp_path / "mesh.fbx")},
            "head": {"path": str(tmp_path / "box.ply")},
            "crate": {"path": str(tmp_path / "crate.obj")},
            "made": {"path": "results/examples/rock.glb"},  # written by the workflow: later
        },
    )
    assert simplification_problems(cfg) == [
        f"simplification.user_assets.gone.path = '{tmp_path / 'gone.glb'}': does not exist; "
        "expected a mesh file (.obj, .glb, .gltf, .ply, .off, .stl)",
        f"simplification.user_assets.pipe.path = '{tmp_path / 'pipe.glb'}': is a named pipe "
        "(FIFO), not a file; expected a mesh file (.obj, .glb, .gltf, .ply, .off, .stl)",
        f"simplification.user_assets.fbx.path = '{tmp_path / 'mesh.fbx'}': expected a mesh file "
        "(.obj, .glb, .gltf, .ply, .off, .stl)",
        "simplification.user_assets.head: the name of a built-in case (head, metaballs); "
        "pick another",
        f"simplification.user_assets.crate.path = '{tmp_path / 'crate.obj'}': "
        f"{tmp_path / 'crate.mtl'} names crate.png ({tmp_path / 'crate.png'}), "
        "which does not exist",
    ]


def test_an_objs_material_and_textures_are_inputs_of_its_jobs(tmp_path):
    (tmp_path / "tex").mkdir()
    (tmp_path / "crate.obj").write_text("mtllib crate.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "crate.mtl").write_text(
        "newmtl a\nmap_Kd -o 0 0 0 tex\\wood.png\nnorm tex/bumps.png\nmap_Ks ignored.png\n"
    )
    assert asset_inputs(str(tmp_path / "crate.obj")) == sorted(
        str(p)
        for p in (tmp_path / "crate.mtl", tmp_path / "tex/wood.png", tmp_path / "tex/bumps.png")
    )
