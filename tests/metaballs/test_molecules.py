"""Structure and fluid-frame readers: a tiny PDB written here with known atoms, and every
shipped structure, trajectory and fluid frame."""

import fnmatch
import gzip
import json
import tomllib
from pathlib import Path

import gemmi
import numpy as np
import pandas as pd
import pytest

from neurender.display import linear_from_srgb
from neurender.metaballs import molecules
from neurender.metaballs.molecules import (
    CPK_SRGB,
    FALLBACK_RADIUS,
    FLUID,
    FLUID_RADIUS,
    PDB_ENTRIES,
    STRUCTURES,
    TRAJECTORY,
    model_count,
    read_frames,
    read_particles,
    read_structure,
)

ROOT = Path(__file__).resolve().parents[2]


def atom_line(serial, name, resname, resseq, xyz, element, altloc=" ", occ=1.0, het=False):
    """One fixed-column PDB ATOM/HETATM record."""
    record = "HETATM" if het else "ATOM  "
    x, y, z = xyz
    return (
        f"{record}{serial:5d} {name:<4}{altloc}{resname:>3} A{resseq:4d}    "
        f"{x:8.3f}{y:8.3f}{z:8.3f}{occ:6.2f}{0:6.2f}          {element:>2}"
    )


# Serine's N, CA (two conformers), OG and an HG hydrogen, a selenium, an unknown "X" atom,
# and a water (O and H).
TINY = [
    (" N", "SER", 1, (1.0, 2.0, 3.0), "N", " ", 1.0, False),
    (" CA", "SER", 1, (2.0, 2.0, 3.0), "C", "A", 0.6, False),
    (" CA", "SER", 1, (2.5, 2.5, 3.5), "C", "B", 0.4, False),
    (" OG", "SER", 1, (3.0, 2.0, 3.0), "O", " ", 1.0, False),
    (" HG", "SER", 1, (3.5, 2.0, 3.0), "H", " ", 1.0, False),
    ("SE", "SE", 2, (5.0, 0.0, 0.0), "SE", " ", 1.0, True),
    (" X1", "UNL", 3, (6.0, 0.0, 0.0), "X", " ", 1.0, True),
    (" O", "HOH", 101, (9.0, 9.0, 9.0), "O", " ", 1.0, True),
    (" H1", "HOH", 101, (9.5, 9.0, 9.0), "H", " ", 1.0, True),
]


def tiny_lines(shift=0.0, atoms=TINY):
    return [
        atom_line(i + 1, name, res, seq, tuple(c + shift for c in xyz), el, alt, occ, het)
        for i, (name, res, seq, xyz, el, alt, occ, het) in enumerate(atoms)
    ]


@pytest.fixture
def tiny_pdb(tmp_path):
    path = tmp_path / "tiny.pdb"
    path.write_text("\n".join([*tiny_lines(), "END", ""]))
    return path


def write_models(path, models):
    """A multi-model PDB, one list of atom lines per model."""
    lines = []
    for number, atoms in enumerate(models, 1):
        lines += [f"MODEL     {number:4d}", *atoms, "ENDMDL"]
    path.write_text("\n".join([*lines, "END", ""]))
    return path


def test_a_tiny_pdb_reads_positions_elements_and_gemmis_radii(tiny_pdb):
    atoms = read_structure(tiny_pdb)
    assert list(atoms.elements) == ["N", "C", "O", "H", "Se", "X"]
    np.testing.assert_allclose(atoms.positions[:4], [[1, 2, 3], [2, 2, 3], [3, 2, 3], [3.5, 2, 3]])
    assert atoms.positions.dtype == np.float64 and atoms.positions.shape == (6, 3)
    expected = [gemmi.Element(e).vdw_r for e in ["N", "C", "O", "H", "Se"]]
    np.testing.assert_allclose(atoms.radii[:5], expected)
    assert atoms.radii[5] == FALLBACK_RADIUS  # gemmi has no radius for the unknown X
    assert atoms.colours.shape == (6, 3)
    assert ((atoms.colours >= 0) & (atoms.colours <= 1)).all()


def test_water_is_dropped_by_default_and_kept_on_request(tiny_pdb):
    assert len(read_structure(tiny_pdb)) == 6
    kept = read_structure(tiny_pdb, drop_water=False)
    assert len(kept) == 8
    np.testing.assert_allclose(kept.positions[6], [9, 9, 9])
    assert list(kept.elements[6:]) == ["O", "H"]


def test_only_the_first_alternative_conformer_is_kept(tiny_pdb):
    atoms = read_structure(tiny_pdb)
    carbons = atoms.positions[atoms.elements == "C"]
    np.testing.assert_allclose(carbons, [[2, 2, 3]])


@pytest.mark.parametrize(
    ("element", "srgb"),
    [("H", (255, 255, 255)), ("C", (144, 144, 144)), ("N", (48, 80, 248)),
     ("O", (255, 13, 13)), ("S", (255, 255, 48)), ("P", (255, 128, 0))],
)  # fmt: skip
def test_cpk_colours_are_jmols_converted_to_linear(element, srgb):
    assert CPK_SRGB[element] == "".join(f"{v:02X}" for v in srgb)
    linear = molecules.element_colours(np.array([element]))[0]
    np.testing.assert_allclose(linear, linear_from_srgb(np.array(srgb) / 255))


def test_an_element_outside_the_table_is_grey():
    (grey,) = molecules.element_colours(np.array(["Xe"]))
    assert grey[0] == grey[1] == grey[2]
    assert not np.allclose(grey, molecules.element_colours(np.array(["C"]))[0])


def test_srgb_to_linear_matches_the_standard_curve():
    np.testing.assert_allclose(molecules.srgb_hex_to_linear("FF8000"), [1, 0.21586, 0], atol=1e-5)


def test_a_multi_model_file_reads_as_frames(tmp_path):
    path = write_models(tmp_path / "traj.pdb", [tiny_lines(s) for s in (0.0, 1.0, 2.0)])
    assert model_count(path) == 3
    frames = read_frames(path)
    assert [len(f) for f in frames] == [6, 6, 6]
    np.testing.assert_allclose(frames[2].positions - frames[0].positions, 2.0)
    np.testing.assert_allclose(read_structure(path, model=1).positions, frames[1].positions)
    assert all(list(f.elements) == list(frames[0].elements) for f in frames)


def test_frames_with_other_atoms_are_refused_naming_the_file(tmp_path):
    path = write_models(tmp_path / "bad.pdb", [tiny_lines(), tiny_lines(atoms=TINY[:-3])])
    with pytest.raises(ValueError, match=r"bad\.pdb: model 1 has other atoms"):
        read_frames(path)


def test_a_model_out_of_range_is_refused_naming_the_file(tiny_pdb):
    with pytest.raises(IndexError, match=r"tiny\.pdb has 1 model\(s\); model 3"):
        read_structure(tiny_pdb, model=3)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nope\.pdb does not exist"):
        read_structure(tmp_path / "nope.pdb")
    with pytest.raises(FileNotFoundError, match=r"nope\.csv does not exist"):
        read_particles(tmp_path / "nope.csv", 1.0)


def test_a_file_gemmi_cannot_read_is_named(tmp_path):
    path = tmp_path / "balls.txt"
    path.write_text("x,y,z\n1,2,3\n")
    with pytest.raises(ValueError, match=r"balls\.txt is not a structure gemmi can read"):
        read_structure(path)


@pytest.mark.parametrize("text", ["hello, not a PDB\n", ""])
def test_a_file_without_atoms_is_named(tmp_path, text):
    path = tmp_path / "empty.pdb"
    path.write_text(text)
    with pytest.raises(ValueError, match=r"empty\.pdb has no atoms"):
        read_structure(path)


def test_a_file_of_only_water_is_named(tmp_path):
    path = tmp_path / "water.pdb"
    path.write_text("\n".join([*tiny_lines(atoms=TINY[-2:]), "END", ""]))
    with pytest.raises(ValueError, match=r"water\.pdb: model 0 has no atoms but water"):
        read_structure(path)
    assert len(read_structure(path, drop_water=False)) == 2


def test_gzipped_files_read_like_plain_ones(tiny_pdb, tmp_path):
    packed = tmp_path / "tiny.pdb.gz"
    packed.write_bytes(gzip.compress(tiny_pdb.read_bytes()))
    np.testing.assert_array_equal(
        read_structure(packed).positions, read_structure(tiny_pdb).positions
    )


# The shipped data (README.md in the folder).


@pytest.mark.parametrize("pdb_id", sorted(PDB_ENTRIES))
def test_every_shipped_pdb_entry_reads_with_thousands_of_atoms(pdb_id):
    atoms = read_structure(STRUCTURES / PDB_ENTRIES[pdb_id])
    assert 3_000 <= len(atoms) <= 50_000
    assert {"C", "N", "O"} <= set(atoms.elements)
    assert (atoms.radii > 1).all() and (atoms.radii < 2.5).all()
    assert np.isfinite(atoms.positions).all()


def test_the_shipped_counts_are_the_readmes():
    counts = {k: len(read_structure(STRUCTURES / f)) for k, f in PDB_ENTRIES.items()}
    assert counts == {"1a28": 4082, "19hc": 5136, "6msm": 9703}


def test_the_shipped_trajectory_is_twelve_frames_of_adenylate_kinase():
    path = STRUCTURES / TRAJECTORY
    assert model_count(path) == 12
    frames = read_frames(path)
    assert [len(f) for f in frames] == [3341] * 12
    elements, counts = np.unique(frames[0].elements, return_counts=True)
    assert dict(zip(elements, counts, strict=True)) == {
        "C": 1040, "H": 1685, "N": 289, "O": 320, "S": 7
    }  # fmt: skip
    np.testing.assert_allclose(frames[0].radii[frames[0].elements == "H"], gemmi.Element("H").vdw_r)
    # the protein moves (the closed-to-open transition) but stays in one piece
    moved = np.linalg.norm(frames[-1].positions - frames[0].positions, axis=1)
    assert moved.max() > 5 and np.ptp(frames[-1].positions, axis=0).max() < 100


def test_the_shipped_fluid_frame_has_ten_thousand_particles_in_its_box():
    fluid = read_particles(STRUCTURES / FLUID, FLUID_RADIUS)
    assert len(fluid) >= 10_000
    note = json.loads((STRUCTURES / "dam_break.json").read_text())
    assert note["particle_radius_m"] == FLUID_RADIUS and note["particles"] == len(fluid)
    box = note["container_m"]
    for axis, column in enumerate("xyz"):
        low, high = box[column]
        assert (fluid.positions[:, axis] >= low).all() and (fluid.positions[:, axis] <= high).all()
    np.testing.assert_array_equal(fluid.radii, FLUID_RADIUS)
    assert (fluid.elements == "").all()
    assert np.allclose(fluid.colours, fluid.colours[0])


def test_every_shipped_file_is_in_the_wheel_and_the_readme():
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]["neurender"]
    readme = (STRUCTURES / "README.md").read_text()
    for path in sorted(STRUCTURES.iterdir()):
        name = path.relative_to(ROOT / "src/neurender").as_posix()
        assert any(fnmatch.fnmatch(name, g) for g in globs), name
        if path.name != "README.md":
            assert f"`{path.name}`" in readme, path.name


# The fluid CSV reader.


def test_particles_read_positions_and_colour_by_height(tmp_path):
    path = tmp_path / "fluid.csv"
    pd.DataFrame({"x": [0.0, 1, 2], "y": [0.0, 0.5, 1], "z": [3.0, 4, 5], "t": 1}).to_csv(
        path, index=False
    )
    fluid = read_particles(path, 0.1, colour_by_height=True)
    np.testing.assert_allclose(fluid.positions, [[0, 0, 3], [1, 0.5, 4], [2, 1, 5]])
    np.testing.assert_allclose(fluid.colours[0], molecules.srgb_hex_to_linear(molecules.DEEP_SRGB))
    np.testing.assert_allclose(fluid.colours[2], molecules.srgb_hex_to_linear(molecules.FOAM_SRGB))
    np.testing.assert_allclose(fluid.colours[1], fluid.colours[[0, 2]].mean(0))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x,y\n1,2\n", r"fluid\.csv lacks columns \['z'\]"),
        ("x,y,z\n1,2,a\n", r"fluid\.csv: column z has non-numeric"),
        ("x,y,z\n1,,3\n", r"fluid\.csv: column y has non-numeric or missing"),
        ("x,y,z\n", r"fluid\.csv has no particles"),
        ("", r"cannot parse CSV file .*fluid\.csv"),
    ],
)
def test_a_bad_particle_file_is_named_with_its_column(tmp_path, text, message):
    path = tmp_path / "fluid.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_particles(path, 0.1)


def test_a_particle_radius_must_be_positive(tmp_path):
    with pytest.raises(ValueError, match=r"fluid\.csv must be positive"):
        read_particles(tmp_path / "fluid.csv", 0.0)
