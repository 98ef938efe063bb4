"""Real scenes as balls: molecular structures (PDB, mmCIF, gzipped or not, read by gemmi;
a multi-model file is a trajectory) and particle-fluid frames (a CSV of positions).

An :class:`Atoms` record holds world-space balls: positions and radii in the file's units
(angstroms for structures, the simulation's units, metres, for fluids), one element symbol
per ball (``""`` for fluid particles) and a colour, linear RGB in [0, 1] (CPK colours of
Jmol's table, :data:`CPK_SRGB`, converted from sRGB). An atom's radius is gemmi's van der
Waals radius of its element (``gemmi.Element(name).vdw_r``), or :data:`FALLBACK_RADIUS`
where gemmi has none (0, or its placeholder for the unknown element ``X``).
:mod:`neurender.metaballs.framing` puts such balls in the metaballs' view space.

Structures are read with water left out by default and the first alternative conformer of
every atom only; hydrogens are kept where the file has them. The shipped examples lie in
:data:`STRUCTURES` (their README names their sources and licences).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gemmi
import numpy as np
import pandas as pd

from neurender import user_paths
from neurender.display import linear_from_srgb

#: The shipped structures, trajectory and fluid frame (see the folder's README.md).
STRUCTURES = Path(__file__).resolve().parent / "structures"
#: Protein Data Bank entries (single models), by PDB ID.
PDB_ENTRIES = {"1a28": "1a28.pdb.gz", "19hc": "19hc.pdb.gz", "6msm": "6msm.pdb.gz"}
#: Adenylate kinase's DIMS transition, 12 models of 3341 atoms (a trajectory).
TRAJECTORY = "adk_dims.pdb.gz"
#: One frame of a SPlisHSPlasH dam break (x, y, z in metres, y up) and its particle radius
#: (metres; also in ``dam_break.json``).
FLUID = "dam_break.csv.gz"
FLUID_RADIUS = 0.02

#: CPK colours (Jmol's table, sRGB hex) of the common elements; others get
#: :data:`FALLBACK_SRGB`. Deuterium takes hydrogen's colour.
CPK_SRGB = {
    "H": "FFFFFF",
    "D": "FFFFFF",
    "C": "909090",
    "N": "3050F8",
    "O": "FF0D0D",
    "F": "90E050",
    "Na": "AB5CF2",
    "Mg": "8AFF00",
    "P": "FF8000",
    "S": "FFFF30",
    "Cl": "1FF01F",
    "K": "8F40D4",
    "Ca": "3DFF00",
    "Mn": "9C7AC7",
    "Fe": "E06633",
    "Co": "F090A0",
    "Ni": "50D050",
    "Cu": "C88033",
    "Zn": "7D80B0",
    "Se": "FFA100",
    "Br": "A62929",
    "I": "940094",
}
#: A darker grey than carbon's, for elements outside :data:`CPK_SRGB`.
FALLBACK_SRGB = "606060"
#: Van der Waals radius (angstroms) of an element gemmi gives none (carbon's).
FALLBACK_RADIUS = 1.7
#: Fluid colours (sRGB): one water blue, or deep at the bottom to foam at the top.
WATER_SRGB = "1E6EC8"
DEEP_SRGB = "0A3C8C"
FOAM_SRGB = "BEE6FF"


@dataclasses.dataclass(frozen=True, eq=False)
class Atoms:
    """World-space balls (module docstring).

    Attributes:
        positions: ``(N, 3)`` float64 centres (angstroms for structures).
        elements: ``(N,)`` str element symbols as gemmi spells them (``"C"``, ``"Fe"``).
        radii: ``(N,)`` float64 van der Waals radii, same units as ``positions``.
        colours: ``(N, 3)`` float64 linear RGB in [0, 1].
    """

    positions: np.ndarray
    elements: np.ndarray
    radii: np.ndarray
    colours: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


def srgb_hex_to_linear(code: str) -> np.ndarray:
    """``(3,)`` float64 linear RGB of an sRGB hex code such as ``"FF0D0D"``."""
    srgb = np.array([int(code[i : i + 2], 16) for i in (0, 2, 4)], np.float64) / 255
    return linear_from_srgb(srgb)


def element_colours(elements: np.ndarray) -> np.ndarray:
    """``(N, 3)`` linear CPK colours of element symbols ``(N,)`` (:data:`CPK_SRGB`)."""
    table = {name: srgb_hex_to_linear(code) for name, code in CPK_SRGB.items()}
    fallback = srgb_hex_to_linear(FALLBACK_SRGB)
    return np.array([table.get(e, fallback) for e in elements], np.float64).reshape(-1, 3)


def vdw_radius(element: gemmi.Element) -> float:
    """gemmi's van der Waals radius of ``element`` (angstroms), :data:`FALLBACK_RADIUS`
    where it has none (0, or the unknown element ``X``)."""
    radius = float(element.vdw_r)
    return radius if radius > 0 and element.atomic_number > 0 else FALLBACK_RADIUS


def model_count(path: str | Path) -> int:
    """Number of models (frames) in a structure file."""
    return len(_read(path))


def read_structure(path: str | Path, model: int = 0, drop_water: bool = True) -> Atoms:
    """The atoms of one model of a PDB or mmCIF file (gzipped or not).

    Args:
        path: the structure file.
        model: index of the model (0 is the first; a trajectory's frame).
        drop_water: leave water molecules out.

    Raises:
        FileNotFoundError: ``path`` is no regular file.
        ValueError: naming the file: gemmi cannot read it, or the model has no atoms.
        IndexError: naming the file and its model count: no such model.
    """
    structure = _read(path, drop_water)
    if not -len(structure) <= model < len(structure):
        raise IndexError(
            f"structure file {path} has {len(structure)} model(s); model {model} asked for"
        )
    atoms, _ = _model_atoms(structure[model])
    if not len(atoms):
        raise ValueError(f"structure file {path}: model {model} has no atoms but water")
    return atoms


def read_frames(path: str | Path, drop_water: bool = True) -> list[Atoms]:
    """Every model of a multi-model structure file (a trajectory), one :class:`Atoms` per
    frame; the models must hold the same atoms (chain, residue, atom name) in one order.

    Raises:
        FileNotFoundError, ValueError: as :func:`read_structure`; ``ValueError`` naming
            the file and model when a model's atoms differ from the first's.
    """
    structure = _read(path, drop_water)
    frames, first = [], None
    for index, model in enumerate(structure):
        atoms, labels = _model_atoms(model)
        if not len(atoms):
            raise ValueError(f"structure file {path}: model {index} has no atoms but water")
        if first is None:
            first = labels
        elif labels != first:
            raise ValueError(
                f"structure file {path}: model {index} has other atoms than model 0 "
                f"({len(labels)} vs {len(first)} atoms); a trajectory's frames must match"
            )
        frames.append(atoms)
    return frames


def read_particles(path: str | Path, radius: float, colour_by_height: bool = False) -> Atoms:
    """A particle-fluid frame: a CSV (gzipped or not) with columns ``x, y, z``.

    Args:
        path: the CSV; other columns are ignored.
        radius: every particle's radius (> 0), the file's units.
        colour_by_height: colour from deep blue at the lowest ``y`` (up) to foam at the
            highest, rather than one water blue.

    Returns:
        :class:`Atoms` with elements ``""`` and positions in the file's units.

    Raises:
        FileNotFoundError: ``path`` is no regular file.
        ValueError: naming the file: unreadable, a missing column, a column with a
            non-numeric or non-finite value (named), no rows, or a radius not positive.
    """
    if not radius > 0:
        raise ValueError(f"particle radius for {path} must be positive; got {radius}")
    frame = _read_table(path)
    missing = [c for c in "xyz" if c not in frame.columns]
    if missing:
        raise ValueError(f"CSV file {path} lacks columns {missing}; it has {list(frame.columns)}")
    for column in "xyz":
        values = pd.to_numeric(frame[column], errors="coerce")
        if not np.isfinite(values.to_numpy(np.float64)).all():
            raise ValueError(f"CSV file {path}: column {column} has non-numeric or missing values")
    if frame.empty:
        raise ValueError(f"CSV file {path} has no particles")
    positions = frame[["x", "y", "z"]].to_numpy(np.float64)
    n = len(positions)
    if colour_by_height:
        colours = _height_colours(positions[:, 1])
    else:
        colours = np.tile(srgb_hex_to_linear(WATER_SRGB), (n, 1))
    return Atoms(positions, np.full(n, "", dtype="<U2"), np.full(n, float(radius)), colours)


def _height_colours(height: np.ndarray) -> np.ndarray:
    """``(N, 3)`` linear colours from :data:`DEEP_SRGB` at the lowest ``height`` ``(N,)``
    to :data:`FOAM_SRGB` at the highest (blended in linear RGB)."""
    span = np.ptp(height)
    t = (height - height.min()) / span if span > 0 else np.zeros_like(height)
    deep, foam = srgb_hex_to_linear(DEEP_SRGB), srgb_hex_to_linear(FOAM_SRGB)
    return deep + t[:, None] * (foam - deep)


def _read_table(path: str | Path) -> pd.DataFrame:
    """The CSV at ``path`` (compression from its suffix); errors name the file."""
    problem = user_paths.file_problem(path)
    if problem:
        raise FileNotFoundError(f"CSV file {path} {problem}")
    try:
        return pd.read_csv(path, index_col=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as err:
        raise ValueError(f"cannot parse CSV file {path}: {err}") from err


def _read(path: str | Path, drop_water: bool = True) -> gemmi.Structure:
    """The structure at ``path``, first conformers only, water dropped if asked; errors
    name the file."""
    problem = user_paths.file_problem(path)
    if problem:
        raise FileNotFoundError(f"structure file {path} {problem}")
    try:
        structure = gemmi.read_structure(str(path))
    except (RuntimeError, ValueError, OSError) as err:
        raise ValueError(f"structure file {path} is not a structure gemmi can read: {err}") from err
    if sum(model.count_atom_sites() for model in structure) == 0:
        raise ValueError(f"structure file {path} has no atoms (is it a PDB or mmCIF file?)")
    structure.remove_alternative_conformations()
    if drop_water:
        structure.remove_waters()
    return structure


def _model_atoms(model: gemmi.Model) -> tuple[Atoms, list[tuple[str, str, str, str]]]:
    """The :class:`Atoms` of a gemmi model and each atom's (chain, residue number and
    insertion code, residue name, atom name) label."""
    positions, elements, radii, labels = [], [], [], []
    for chain in model:
        for residue in chain:
            for atom in residue:
                positions.append((atom.pos.x, atom.pos.y, atom.pos.z))
                elements.append(atom.element.name)
                radii.append(vdw_radius(atom.element))
                labels.append((chain.name, str(residue.seqid), residue.name, atom.name))
    elements = np.array(elements, dtype="<U2")
    atoms = Atoms(
        np.array(positions, np.float64).reshape(-1, 3),
        elements,
        np.array(radii, np.float64),
        element_colours(elements),
    )
    return atoms, labels
