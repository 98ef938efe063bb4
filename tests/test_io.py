import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from neurender import io, unique_keys

ROOT = Path(__file__).resolve().parents[1]


def test_exr_round_trip_named_channels(tmp_path):
    rng = np.random.default_rng(0)
    chans = {f"T.{i:02d}": rng.normal(size=(7, 9)).astype(np.float32) for i in range(16)}
    chans["P.x"] = rng.normal(size=(7, 9)).astype(np.float32)
    io.write_exr(tmp_path / "a.exr", chans)
    back = io.read_exr(tmp_path / "a.exr")
    assert set(back) == set(chans)  # all 17 channels survive (not just 4)
    for k, v in chans.items():
        np.testing.assert_array_equal(back[k], v)
    sub = io.read_exr(tmp_path / "a.exr", ["P.x"])
    assert list(sub) == ["P.x"]


def test_exr_half(tmp_path):
    a = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    io.write_exr(tmp_path / "h.exr", {"Y": a}, half=True)
    back = io.read_exr(tmp_path / "h.exr")["Y"]
    assert back.dtype == np.float16
    np.testing.assert_allclose(back, a, atol=1e-3)


def test_exr_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.exr"):
        io.read_exr(tmp_path / "nope.exr")
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"not an exr at all")
    with pytest.raises(OSError, match="bad.exr"):
        io.read_exr(bad)
    io.write_exr(tmp_path / "c.exr", {"R": np.zeros((2, 2))})
    with pytest.raises(KeyError, match="lacks channels"):
        io.read_exr(tmp_path / "c.exr", ["G"])
    with pytest.raises(ValueError, match="expected \\(H, W\\)"):
        io.write_exr(tmp_path / "d.exr", {"R": np.zeros((2, 2, 3))})


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_round_trip(tmp_path, dtype, channels):
    rng = np.random.default_rng(channels)
    img = rng.integers(0, np.iinfo(dtype).max, size=(5, 6, channels), endpoint=True).astype(dtype)
    io.write_png(tmp_path / "a.png", img)
    back = io.read_png(tmp_path / "a.png")
    assert back.dtype == dtype
    np.testing.assert_array_equal(back, img)


def test_png_errors(tmp_path):
    with pytest.raises(TypeError, match="uint8 or uint16"):
        io.write_png(tmp_path / "a.png", np.zeros((2, 2), np.float32))
    (tmp_path / "bad.png").write_bytes(b"garbage")
    with pytest.raises(OSError, match="bad.png"):
        io.read_png(tmp_path / "bad.png")


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(RuntimeError):
        with io.atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_gives_the_mode_of_a_plain_open(tmp_path):
    with io.atomic_path(tmp_path / "atomic.txt") as tmp:
        tmp.write_text("x")
    (tmp_path / "plain.txt").write_text("x")
    modes = {p.name: p.stat().st_mode & 0o777 for p in tmp_path.iterdir()}
    assert modes["atomic.txt"] == modes["plain.txt"]


def test_write_json_round_trips_ends_in_a_newline_and_leaves_nothing_it_cannot_write(tmp_path):
    data = {"b": [1, 2.5, None], "a": {"note": "ü"}}
    io.write_json(tmp_path / "sidecar.json", data)
    text = (tmp_path / "sidecar.json").read_text()
    assert json.loads(text) == data and text.endswith("}\n") and '\n  "b"' in text
    io.write_json(tmp_path / "sorted.json", data, indent=None, sort_keys=True)
    assert (tmp_path / "sorted.json").read_text() == json.dumps(data, sort_keys=True) + "\n"
    io.write_json(tmp_path / "sets.json", {"s": {3}}, default=list)
    assert json.loads((tmp_path / "sets.json").read_text()) == {"s": [3]}
    before = sorted(tmp_path.iterdir())
    with pytest.raises(TypeError):
        io.write_json(tmp_path / "bad.json", {"s": {3}})
    assert sorted(tmp_path.iterdir()) == before


def test_csv_round_trip_and_required_columns(tmp_path):
    df = pd.DataFrame({"method": ["prt"], "metric": ["ssim"], "value": [0.9]})
    io.write_csv(tmp_path / "m.csv", df)
    pd.testing.assert_frame_equal(io.read_csv(tmp_path / "m.csv", ["metric"]), df)
    with pytest.raises(ValueError, match="lacks columns \\['split'\\]"):
        io.read_csv(tmp_path / "m.csv", ["split"])
    with pytest.raises(FileNotFoundError, match="x.csv"):
        io.read_csv(tmp_path / "x.csv")


def test_exr_mixed_precision(tmp_path):
    io.write_exr(tmp_path / "m.exr", {"P.x": np.ones((2, 3)), "T.00": np.ones((2, 3), np.float16)})
    back = io.read_exr(tmp_path / "m.exr")
    assert back["P.x"].dtype == np.float32 and back["T.00"].dtype == np.float16


def test_a_tidy_table_keeps_names_that_look_missing_or_numeric(tmp_path):
    # Names a user may give (objects, assets, scenes), written by pandas as every stage
    # writes its table; read back they are the same strings and the values numbers.
    names = ["NA", "None", "null", "nan", "N/A", "", "001", "1.0", "True"]
    df = pd.DataFrame(
        {
            "method": "ndr",
            "dataset": names,
            "model": names[::-1],
            "split": "test",
            "object": names,
            "metric": ["psnr", "NaN", "ssim", "null", "a", "b", "c", "d", "e"],
            "value": [1.5, np.nan, 3.0, np.inf, -1.0, 0.0, 2.0, 3.0, 4.0],
            "frame": range(9),
        }
    )
    io.write_csv(tmp_path / "metrics.csv", df)
    back = io.read_csv(tmp_path / "metrics.csv")
    for column in ("dataset", "model", "object", "metric"):
        assert back[column].tolist() == df[column].tolist()
    assert back["value"].dtype == np.float64 and back["frame"].dtype == np.int64
    np.testing.assert_array_equal(back["value"], df["value"])  # NaN and inf included
    assert back.shape == df.shape


def test_csv_errors_name_the_file_and_what_it_is(tmp_path):
    (tmp_path / "folder.csv").mkdir()
    with pytest.raises(FileNotFoundError, match=f"CSV file {tmp_path / 'folder.csv'} is a folder"):
        io.read_csv(tmp_path / "folder.csv")
    with pytest.raises(FileNotFoundError, match=f"EXR file {tmp_path / 'folder.csv'} is a folder"):
        io.read_exr(tmp_path / "folder.csv")
    (tmp_path / "long.csv").write_text("a,b\n1,2\n3,4,5\n")
    with pytest.raises(OSError, match=f"CSV file {tmp_path / 'long.csv'}: .*line 3, saw 3"):
        io.read_csv(tmp_path / "long.csv")


@pytest.mark.parametrize(("separator", "name"), [(";", "semicolons"), ("\t", "tabs")])
def test_csv_separated_by_semicolons_or_tabs_is_refused_naming_the_file(tmp_path, separator, name):
    # A spreadsheet in a locale with decimal commas saves "x;y" rows as "1,5;2".
    path = tmp_path / "scenes.csv"
    path.write_text(f"scene{separator}x{separator}y\na{separator}1,5{separator}2\n")
    with pytest.raises(OSError, match=f"CSV file {path}: it is separated by {name}"):
        io.read_csv(path, ["scene", "x", "y"])


def test_csv_with_a_semicolon_inside_a_comma_separated_header_reads(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text('"a;b",c\n1,2\n')
    assert list(io.read_csv(path).columns) == ["a;b", "c"]


def test_copy_file_gives_the_same_bytes_and_names_a_missing_source(tmp_path):
    source = tmp_path / "net.onnx"
    source.write_bytes(bytes(range(256)) * 3)
    io.copy_file(source, tmp_path / "out" / "shipped.onnx")
    assert (tmp_path / "out" / "shipped.onnx").read_bytes() == source.read_bytes()
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["shipped.onnx"]
    with pytest.raises(FileNotFoundError, match="missing.onnx"):
        io.copy_file(tmp_path / "missing.onnx", tmp_path / "x.onnx")
    assert not (tmp_path / "x.onnx").exists()


def test_read_yaml_refuses_a_section_set_twice_naming_the_file_key_and_lines(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("ndr:\n  width: 32\nseed: 3\nndr:\n  width: 64\n")
    with pytest.raises(unique_keys.DuplicateKeyError) as raised:
        io.read_yaml(bad)
    message = str(raised.value)
    assert message.startswith(f"{bad}: key 'ndr' is set twice, on lines 1 and 4")
    assert yaml.safe_load(bad.read_text()) == {"ndr": {"width": 64}, "seed": 3}  # what it hid


def test_read_yaml_names_a_nested_key_by_its_dotted_path_and_every_repeat(tmp_path):
    bad = tmp_path / "nested.yaml"
    bad.write_text(
        "prt:\n  user_meshes:\n    mine: {path: a.obj}\n    other: {path: b.obj}\n"
        "    mine: {path: c.obj}\nlist:\n  - {a: 1}\n  - a: 2\n    b: 3\n    a: 4\n    a: 5\n"
    )
    with pytest.raises(unique_keys.DuplicateKeyError) as raised:
        io.read_yaml(bad)
    message = str(raised.value)
    assert str(bad) in message
    assert "key 'prt.user_meshes.mine' is set twice, on lines 3 and 5" in message
    assert "key 'list[1].a' is set 3 times, on lines 8, 10 and 11" in message


def test_read_yaml_refuses_keys_that_are_equal_once_read_but_keeps_merges(tmp_path):
    bad = tmp_path / "numbers.yaml"
    bad.write_text("counts:\n  1: a\n  1.0: b\n  '1': c\n")
    with pytest.raises(
        unique_keys.DuplicateKeyError, match=r"'counts\.1' is set twice, on lines 2 and 3"
    ):
        io.read_yaml(bad)
    merged = tmp_path / "merged.yaml"
    merged.write_text("base: &b {x: 1, y: 2}\nother:\n  <<: *b\n  x: 3\n")
    assert io.read_yaml(merged) == {"base": {"x": 1, "y": 2}, "other": {"x": 3, "y": 2}}


def test_read_yaml_reads_a_valid_file_as_safe_load_does(tmp_path):
    text = (
        "seed: 0\ndevice: cpu\nname: '001'\nflag: yes\nnone: null\nwhen: 2024-01-02\n"
        "ndr: {width: 32, sizes: [1, 2.5, 1e3]}\nmulti: |\n  two\n  lines\n"
        "anchors: {a: &x [1, 2], b: *x}\n"
    )
    (tmp_path / "ok.yaml").write_text(text)
    assert io.read_yaml(tmp_path / "ok.yaml") == yaml.safe_load(text)
    (tmp_path / "empty.yaml").write_text("")
    assert io.read_yaml(tmp_path / "empty.yaml") is None
    for config in sorted((ROOT / "config").rglob("*.yaml")):
        assert io.read_yaml(config) == yaml.safe_load(config.read_text()), config


def test_read_yaml_reads_json_as_snakemake_does_and_names_its_repeated_keys(tmp_path):
    ok = tmp_path / "ok.json"
    ok.write_text('{\n\t"ndr": {"width": 1e2},\n\t"seed": 3\n}\n')  # tabs: JSON, not YAML
    assert io.read_yaml(ok) == {"ndr": {"width": 100.0}, "seed": 3}
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "ndr": {"width": 32},\n  "ndr": {"width": 64}\n}\n')
    with pytest.raises(
        unique_keys.DuplicateKeyError, match="key 'ndr' is set twice, on lines 2 and 3"
    ):
        io.read_yaml(bad)
    tabbed = tmp_path / "tabbed.json"
    tabbed.write_text('{\n\t"ndr": {"width": 32,\n\t\t"width": 64}\n}\n')
    with pytest.raises(unique_keys.DuplicateKeyError) as raised:
        io.read_yaml(tabbed)
    assert str(raised.value).startswith(
        f"{tabbed}: key 'ndr.width' is set twice in one JSON object"
    )


def test_read_yaml_names_the_file_of_a_syntax_error_or_a_missing_file(tmp_path):
    (tmp_path / "broken.yaml").write_text("a: [1\nb: 2\n")
    with pytest.raises(yaml.YAMLError, match=f'in "{tmp_path / "broken.yaml"}", line 1'):
        io.read_yaml(tmp_path / "broken.yaml")
    with pytest.raises(FileNotFoundError, match=f"YAML file {tmp_path / 'none.yaml'} does not"):
        io.read_yaml(tmp_path / "none.yaml")
