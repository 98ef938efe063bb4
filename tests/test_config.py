"""Each cross-key config rule refuses a bad value, naming the key and the value."""

import copy
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from snakemake.utils import update_config, validate

from neurender import config as rules

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def smoke():
    """The smoke config as the workflow sees it: config.yaml updated by smoke.yaml, with
    the schema's defaults filled in."""
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    update_config(cfg, yaml.safe_load((ROOT / "config/smoke.yaml").read_text()))
    validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))
    return cfg


def _with(cfg, dotted, value):
    changed = copy.deepcopy(cfg)
    *path, key = dotted.split(".")
    node = changed
    for part in path:
        node = node[part]
    node[key] = value
    return changed


def test_the_shipped_configs_break_no_rule(smoke):
    assert rules.problems(smoke) == []
    for name in ("config.yaml", "paper.yaml"):
        cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
        update_config(cfg, yaml.safe_load((ROOT / "config" / name).read_text()))
        validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))
        assert rules.problems(cfg) == [], name


@pytest.mark.parametrize(
    ("key", "value", "named"),
    [
        ("metaballs.balls", [6, 2], "metaballs.balls = [6, 2]"),
        ("metaballs.radius", [1.6, 0.6], "metaballs.radius = [1.6, 0.6]"),
        ("ndr.primitives", [7, 2], "ndr.primitives = [7, 2]"),
        ("prt.linear_range", [1.25, -0.25], "prt.linear_range = [1.25, -0.25]"),
    ],
)
def test_reversed_ranges_are_refused(smoke, key, value, named):
    found = rules.problems(_with(smoke, key, value))
    assert len(found) == 1 and named in found[0] and "min <= max" in found[0]


@pytest.mark.parametrize(
    ("key", "value", "named"),
    [
        ("prt.directions", 50, "prt.directions = 50: expected a perfect square"),
        ("prt.reference_directions", 300, "prt.reference_directions = 300: expected a perfect"),
        ("ndr.coarse_samples", 20, "ndr.coarse_samples = 20: expected a perfect square"),
        (
            "prt_model.equal_quality_directions",
            [16, 60],
            "prt_model.equal_quality_directions entry = 60",
        ),
    ],
)
def test_sample_counts_that_are_not_squares_are_refused(smoke, key, value, named):
    found = rules.problems(_with(smoke, key, value))
    assert any(named in f for f in found), found


def test_a_reference_below_four_times_the_directions_is_refused(smoke):
    found = rules.problems(_with(smoke, "prt.reference_directions", 144))
    assert found == [
        "prt.reference_directions = 144: expected at least 4 x prt.directions = 256 "
        "(a clean reference for the test frames)"
    ]


def test_an_equal_quality_sweep_over_more_than_the_test_samples_is_refused(smoke):
    found = rules.problems(_with(smoke, "ndr.equal_quality_samples", 4))
    assert found == [
        "ndr.equal_quality_samples = 4: expected at most ndr.samples.test = 3 (the sweep "
        "renders test samples)"
    ]


def test_experiment_frames_above_the_training_frames_are_refused(smoke):
    found = rules.problems(_with(smoke, "prt.experiment_train_frames", 7))
    assert found == ["prt.experiment_train_frames = 7: expected at most prt.frames.train = 6"]


def test_a_resolution_the_unet_cannot_halve_is_refused(smoke):
    found = rules.problems(_with(smoke, "ndr.width", 35))
    assert any("ndr.width = 35: expected a multiple of 2" in f for f in found)
    found = rules.problems(_with(smoke, "prt.resolution", 15))
    assert any("prt.resolution = 15: expected a multiple of 2" in f for f in found)


def test_pix2pix_widths_must_be_powers_of_two(smoke):
    found = rules.problems(_with(smoke, "metaballs.width", 48))
    assert found == [
        "metaballs.width = 48: expected a power of two >= 32 (the pix2pix U-Net halves it to 1)"
    ]
    found = rules.problems(_with(smoke, "ndr.width", 48))
    assert any("ndr.width = 48: expected a power of two >= 32" in f for f in found)


def test_a_noisy_test_reference_is_refused(smoke):
    found = rules.problems(_with(smoke, "ndr.reference_spp", 32))
    assert found == [
        "ndr.reference_spp = 32: expected at least 8 x ndr.spp = 64 "
        "(a clean reference for the test samples)"
    ]


def test_a_relit_sample_outside_the_test_split_is_refused(smoke):
    found = rules.problems(_with(smoke, "ndr_model.relight_sample", 3))
    assert found == ["ndr_model.relight_sample = 3: expected below ndr.samples.test = 3"]


def test_a_missing_user_probe_folder_is_refused(smoke, tmp_path):
    found = rules.problems(_with(smoke, "ndr.user_probes_dir", str(tmp_path / "maps")))
    assert found == [
        f"ndr.user_probes_dir = '{tmp_path / 'maps'}': expected a folder holding *.exr "
        "lat-long maps"
    ]


def test_unknown_objects_and_missing_user_files_are_refused(smoke, tmp_path):
    found = rules.problems(_with(smoke, "prt.objects", ["head", "teapot"]))
    assert found and "prt.objects entry 'teapot' is neither built in" in found[0]
    missing = {"blob": str(tmp_path / "blob.obj")}
    found = rules.problems(_with(smoke, "prt.user_meshes", missing))
    (problem,) = found
    assert problem.startswith(f"prt.user_meshes.blob = '{tmp_path / 'blob.obj'}': does not ")
    assert "expected a mesh file (.obj" in problem
    found = rules.problems(_with(smoke, "prt.light", "studio"))
    assert found == ["prt.light = 'studio': expected one of prt.probes ['sky', 'sunset']"]


def test_a_head_budget_above_its_detail_is_refused(smoke):
    found = rules.problems(_with(smoke, "simplification.head_triangles", 5000))
    assert found and found[0].startswith("simplification.head_triangles = 5000")


def _refused_dry_run(extra: Path) -> str:
    """The output of a dry run of the smoke config with ``extra`` over it, which must fail."""
    result = subprocess.run(
        [sys.executable, "-m", "snakemake", "results/report.html", "-n", "--cores", "1"]
        + ["--configfile", "config/smoke.yaml", str(extra)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode != 0
    return result.stdout + result.stderr


def test_the_dry_run_refuses_a_bad_config_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("metaballs:\n  balls: [6, 2]\n")
    out = _refused_dry_run(bad)
    assert "metaballs.balls = [6, 2]: expected [min, max] with min <= max" in out


def test_the_dry_run_refuses_a_shipped_variant_that_is_not_trained(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("prt_model:\n  variants: [paper]\n  shipped: shadowing\n")
    out = _refused_dry_run(bad)
    assert "prt_model.shipped = 'shadowing': expected one of prt_model.variants ['paper']" in out


def test_a_renamed_section_is_refused_naming_its_new_key_and_the_file_that_sets_it(tmp_path):
    old, other = tmp_path / "old.yaml", tmp_path / "other.yaml"
    old.write_text("simplify:\n  steps: 10\n")
    other.write_text("seed: 3\n")
    cfg = {"seed": 3, "simplify": {"steps": 10}, "simplification": {"steps": 20}}
    with pytest.raises(rules.ConfigError) as raised:
        rules.check_renamed(cfg, [other, old])
    assert str(raised.value) == (
        "config key 'simplify' was renamed to 'simplification' (neurender 0.2); "
        f"rename the section in {old}"
    )
    with pytest.raises(rules.ConfigError, match="rename the section in the --config arguments"):
        rules.check_renamed(cfg, [other])
    rules.check_renamed({"seed": 3, "simplification": {}}, [other])  # the new name passes


def test_the_dry_run_names_the_new_key_before_the_schema_refuses_the_old_one(tmp_path):
    old = tmp_path / "old.yaml"
    old.write_text("simplify:\n  steps: 10\n")
    out = _refused_dry_run(old)
    assert (
        "config key 'simplify' was renamed to 'simplification' (neurender 0.2); "
        f"rename the section in {old}"
    ) in out
    assert "Additional properties" not in out  # the rename's message, not the schema's


def test_a_key_set_twice_in_a_config_file_is_refused_naming_file_key_and_lines(tmp_path):
    top, nested, ok = tmp_path / "top.yaml", tmp_path / "nested.yaml", tmp_path / "ok.json"
    top.write_text("ndr:\n  width: 32\nseed: 3\nndr:\n  width: 64\n")
    nested.write_text("ndr:\n  width: 32\n  depth: 2\n  width: 64\n")
    ok.write_text('{\n\t"ndr": {"width": 32}\n}\n')  # JSON, as Snakemake also reads
    rules.check_files([ROOT / "config/config.yaml", ROOT / "config/smoke.yaml", ok])
    with pytest.raises(rules.ConfigError) as raised:
        rules.check_files([ok, top, nested])
    message = str(raised.value)
    assert f"{top}: key 'ndr' is set twice, on lines 1 and 4" in message
    assert f"{nested}: key 'ndr.width' is set twice, on lines 2 and 4" in message
    assert str(ok) not in message


def test_the_dry_run_refuses_a_config_file_that_sets_a_key_twice(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("metaballs:\n  balls: [2, 4]\nseed: 3\nmetaballs:\n  balls: [3, 5]\n")
    out = _refused_dry_run(bad)
    assert f"{bad}: key 'metaballs' is set twice, on lines 1 and 4" in out


#: Where the workflow's own files live (not tests/ or docs/, which may quote old names).
_OWN_FILES = ("Snakefile", "pyproject.toml", "src", "workflow", "config", "scripts", "benchmarks")
_TEXT_SUFFIXES = {"", ".py", ".smk", ".yaml", ".yml", ".csv", ".md", ".sh", ".json", ".j2", ".js"}
#: The lines that must still name an old key: the table of renames, and the seed salt
#: that keeps the renamed package's random numbers.
_KEPT = {
    "src/neurender/config.py": re.compile(r"^RENAMED\b"),
    "src/neurender/simplification/__init__.py": re.compile(r'^SEED_SALT = "simplify"$'),
}


def _old_name_patterns(old):
    """An old key as a config section, a dotted key, a module, a rule or a path."""
    return re.compile(
        rf"""["']{old}["']|^\s*{old}:|`{old}`|\b{old}\.\w|\b{old}_\w|(?<![\w.]){old}/"""
        rf"|\bneurender\.{old}\b"
    )


def _built(path: Path) -> bool:
    """Files a build or an install writes into the tree (bytecode, pip's egg-info, which
    copies the README of whichever release was installed), not the project's own."""
    return any(part == "__pycache__" or part.endswith(".egg-info") for part in path.parts)


def test_no_own_file_names_a_renamed_key_as_a_key_rule_or_module():
    files = [
        path
        for top in _OWN_FILES
        for path in ([ROOT / top] if (ROOT / top).is_file() else (ROOT / top).rglob("*"))
        if path.is_file() and path.suffix in _TEXT_SUFFIXES and not _built(path)
    ]
    assert len(files) > 100  # the walk found the tree
    found = []
    for old in rules.RENAMED:
        pattern = _old_name_patterns(old)
        for path in files:
            name = path.relative_to(ROOT).as_posix()
            if old in path.name:
                found.append(name)
            kept = _KEPT.get(name)
            for number, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line) and not (kept and kept.search(line)):
                    found.append(f"{name}:{number}: {line.strip()}")
    assert found == []


@pytest.mark.parametrize(
    "line",
    [
        "simplify:",
        '    s = config["simplify"]',
        "from neurender.simplify import jobs",
        "import neurender.simplify",
        "rule simplify_prepare:",
        '        "results/logs/simplify_prepare/{case}.log",',
        "Every other key of `simplify` (render size)",
        "| `simplify.user_assets.<name>.path` | (required) |",
        "`neurender/simplify/`, `simplify/render.py`",
    ],
)
def test_the_old_name_patterns_catch_each_use(line):
    assert _old_name_patterns("simplify").search(line)


@pytest.mark.parametrize(
    "line",
    [
        "    v, f = fast_simplification.simplify(",
        "# Your meshes to simplify, name -> entry",
        "the paper simplifies to 1-5 %",
    ],
)
def test_the_old_name_patterns_pass_prose_and_other_libraries(line):
    assert not _old_name_patterns("simplify").search(line)


def test_names_yaml_does_not_read_as_text_are_refused_naming_each(tmp_path):
    # Unquoted, YAML reads these names as None, 1, 1.5 and True: two could merge into one
    # entry, or a name come back as a missing value in the tables.
    cfg = yaml.safe_load(
        "prt:\n  user_meshes:\n    null: a.ply\n    001: b.ply\n"
        "ndr:\n  user_objects:\n    1.5: c.obj\n    yes: d.obj\n    ok: e.obj\n"
    )
    with pytest.raises(rules.ConfigError) as raised:
        rules.check_names_are_text(cfg)
    assert str(raised.value).endswith(
        "prt.user_meshes.None (read as NoneType), prt.user_meshes.1 (read as int), "
        "ndr.user_objects.1.5 (read as float), ndr.user_objects.True (read as bool)"
    )
    rules.check_names_are_text(yaml.safe_load("prt:\n  user_meshes:\n    'null': a.ply\n"))


def test_the_dry_run_refuses_an_unquoted_name_before_the_schema(tmp_path):
    extra = tmp_path / "extra.yaml"
    extra.write_text("ndr:\n  user_objects:\n    001: results/examples/crate.obj\n")
    out = _refused_dry_run(extra)
    assert "names must be text" in out
    assert "ndr.user_objects.1 (read as int)" in out


def test_a_coarse_map_too_large_for_the_prefilter_is_refused(smoke):
    cfg = _with(_with(smoke, "ndr.coarse_shading", "prefiltered"), "ndr.coarse_height", 64)
    found = rules.problems(cfg)
    expected = "ndr.coarse_height = 64: expected at most 32 with ndr.coarse_shading = prefiltered"
    assert any(f.startswith(expected) for f in found), found
    assert not any("at most 32" in f for f in rules.problems(_with(smoke, "ndr.coarse_height", 64)))


@pytest.mark.parametrize("seed", [2**31, 2**32, -1])
def test_the_schema_refuses_a_seed_outside_32_bits(smoke, seed):
    from snakemake.exceptions import WorkflowError

    with pytest.raises(WorkflowError, match=r"seed"):
        validate(_with(smoke, "seed", seed), str(ROOT / "workflow/schemas/config.schema.yaml"))


def test_the_schema_takes_the_largest_seed_mitsuba_can_offset(smoke):
    validate(_with(smoke, "seed", 2**31 - 1), str(ROOT / "workflow/schemas/config.schema.yaml"))
