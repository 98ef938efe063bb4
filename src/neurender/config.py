"""Config rules the JSON schema cannot state: ranges between keys, shapes a network needs,
files that must exist. :func:`check` runs in ``workflow/rules/common.smk`` right after the
schema has filled the defaults, so a dry run refuses a bad config before any job starts,
naming the keys and values and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from neurender import asset_files
from neurender.lights import BUILTIN_PROBES
from neurender.metaballs.scene_file import read_user_scenes
from neurender.ndr import MESH_SUFFIXES as NDR_MESH_SUFFIXES
from neurender.prt import OBJECTS, RESERVED, user_sequence_problems


class ConfigError(ValueError):
    """A config value that breaks one of the rules below."""


def made_by_the_workflow(path: str) -> bool:
    """Paths under ``results/`` are outputs of the workflow (e.g. the example assets),
    checked when the job that makes them has run."""
    return Path(path).parts[:1] == ("results",)


def _ordered(config: Mapping, section: str, key: str) -> Iterator[str]:
    low, high = config[section][key]
    if low > high:
        yield f"{section}.{key} = {[low, high]}: expected [min, max] with min <= max"


def _square(value: int, name: str) -> Iterator[str]:
    if math.isqrt(value) ** 2 != value:
        yield f"{name} = {value}: expected a perfect square (e.g. 16, 64, 256)"


def _power_of_two_at_least(value: int, minimum: int, name: str, why: str) -> Iterator[str]:
    if value < minimum or value & (value - 1):
        yield f"{name} = {value}: expected a power of two >= {minimum} ({why})"


def _halvable(size: int, widths: list, name: str, widths_name: str) -> Iterator[str]:
    factor = 2 ** (len(widths) - 1)
    if size % factor:
        yield (
            f"{name} = {size}: expected a multiple of {factor}, the downsampling of the "
            f"U-Net's {len(widths)} levels ({widths_name})"
        )


def _names(names: list, builtins: tuple, user: Mapping, name: str) -> Iterator[str]:
    for entry in names:
        if entry not in builtins and entry not in user:
            yield (
                f"{name} entry {entry!r} is neither built in ({', '.join(builtins)}) nor listed "
                f"under the user entries ({', '.join(user) or 'none'})"
            )


def _prt_problems(config: Mapping) -> Iterator[str]:
    prt, model = config["prt"], config["prt_model"]
    meshes, sequences = prt["user_meshes"], prt["user_sequences"]
    yield from _names(prt["objects"], OBJECTS, {**meshes, **sequences}, "prt.objects")
    for name in sorted(set(meshes) & set(sequences)):
        yield f"prt user object {name!r} is both in prt.user_meshes and in prt.user_sequences"
    for name in sorted((set(meshes) | set(sequences)) & set(RESERVED)):
        yield (
            f"prt user object {name!r}: the name of a built-in dataset; expected another name "
            f"(reserved: {', '.join(RESERVED)})"
        )
    for name, entry in sequences.items():
        yield from user_sequence_problems(name, entry, made_by_the_workflow)
    yield from _names(prt["probes"], BUILTIN_PROBES, prt["user_probes"], "prt.probes")
    if prt["light"] not in prt["probes"]:
        yield f"prt.light = {prt['light']!r}: expected one of prt.probes {prt['probes']}"
    yield from _square(prt["directions"], "prt.directions")
    yield from _square(prt["reference_directions"], "prt.reference_directions")
    for count in model["equal_quality_directions"]:
        yield from _square(count, "prt_model.equal_quality_directions entry")
    if prt["reference_directions"] < 4 * prt["directions"]:
        yield (
            f"prt.reference_directions = {prt['reference_directions']}: expected at least 4 x "
            f"prt.directions = {4 * prt['directions']} (a clean reference for the test frames)"
        )
    if prt["experiments"] and prt["experiment_train_frames"] > prt["frames"]["train"]:
        yield (
            f"prt.experiment_train_frames = {prt['experiment_train_frames']}: expected at most "
            f"prt.frames.train = {prt['frames']['train']}"
        )
    yield from _ordered(config, "prt", "linear_range")
    yield from _halvable(prt["resolution"], model["widths"], "prt.resolution", "prt_model.widths")
    for name, path in {**prt["user_meshes"], **prt["user_probes"]}.items():
        if not made_by_the_workflow(path) and (problem := asset_files.not_a_file(path)):
            yield f"prt user entry {name!r}: file {path} {problem}"


def _ndr_problems(config: Mapping) -> Iterator[str]:
    ndr, model = config["ndr"], config["ndr_model"]
    yield from _ordered(config, "ndr", "primitives")
    yield from _halvable(ndr["width"], model["widths"], "ndr.width", "ndr_model.widths")
    if "pix2pix" in model["variants"]:
        yield from _power_of_two_at_least(
            ndr["width"], 32, "ndr.width", "the pix2pix baseline's U-Net halves it to 1 pixel"
        )
    yield from _square(ndr["coarse_samples"], "ndr.coarse_samples")
    if ndr["reference_spp"] < 8 * ndr["spp"]:
        yield (
            f"ndr.reference_spp = {ndr['reference_spp']}: expected at least 8 x ndr.spp = "
            f"{8 * ndr['spp']} (a clean reference for the test samples)"
        )
    if ndr["coarse_height"] > ndr["environment_height"]:
        yield (
            f"ndr.coarse_height = {ndr['coarse_height']}: expected at most "
            f"ndr.environment_height = {ndr['environment_height']}"
        )
    if model["relight_sample"] >= ndr["samples"]["test"]:
        yield (
            f"ndr_model.relight_sample = {model['relight_sample']}: expected below "
            f"ndr.samples.test = {ndr['samples']['test']}"
        )
    folder = ndr["user_probes_dir"]
    if folder and not made_by_the_workflow(folder) and not any(Path(folder).glob("*.exr")):
        yield f"ndr.user_probes_dir = {folder!r}: expected a folder holding *.exr lat-long maps"
    for name, path in ndr["user_objects"].items():
        if made_by_the_workflow(path):
            continue
        if Path(path).suffix.lower() not in NDR_MESH_SUFFIXES:
            yield (
                f"ndr.user_objects entry {name!r}: {path} is not a mesh file NDR reads "
                f"({', '.join(NDR_MESH_SUFFIXES)})"
            )
        elif problem := asset_files.not_a_file(path):
            yield f"ndr.user_objects entry {name!r}: file {path} {problem}"
        else:
            yield from (
                f"ndr.user_objects entry {name!r}: {problem}"
                for problem in asset_files.missing(path)
            )


def _metaballs_problems(config: Mapping) -> Iterator[str]:
    yield from _ordered(config, "metaballs", "balls")
    yield from _ordered(config, "metaballs", "radius")
    yield from _power_of_two_at_least(
        config["metaballs"]["width"], 32, "metaballs.width", "the pix2pix U-Net halves it to 1"
    )
    scenes = config["metaballs"]["user_scenes"]
    if scenes and not made_by_the_workflow(scenes):
        try:
            read_user_scenes(scenes)
        except (OSError, ValueError) as err:
            yield f"metaballs.user_scenes = {scenes!r}: {err}"


def _simplify_problems(config: Mapping) -> Iterator[str]:
    from neurender.simplify import CASES

    simplify = config["simplify"]
    detail = 2 * simplify["head_vertices"]
    if "head" in simplify["cases"] and simplify["head_triangles"] >= detail:
        yield (
            f"simplify.head_triangles = {simplify['head_triangles']}: expected fewer than the "
            f"detailed head's about {detail} triangles (2 x simplify.head_vertices)"
        )
    for name, entry in simplify["user_assets"].items():
        key = f"simplify.user_assets.{name}"
        path = entry["path"]
        if name in CASES:
            yield f"{key}: the name of a built-in case ({', '.join(CASES)}); pick another"
        if Path(path).suffix.lower() not in asset_files.TRIMESH_SUFFIXES:
            suffixes = ", ".join(asset_files.TRIMESH_SUFFIXES)
            yield f"{key}.path = {path!r}: expected a mesh file ({suffixes})"
        elif made_by_the_workflow(path):
            continue
        elif problem := asset_files.not_a_file(path):
            yield f"{key}.path = {path!r}: file {problem}"
        else:
            yield from (
                f"{key}.path = {path!r}: {problem}" for problem in asset_files.missing(path)
            )


def problems(config: Mapping[str, Any]) -> list[str]:
    """Every rule the (defaults-filled) ``config`` breaks, one sentence each."""
    found = []
    for check in (_prt_problems, _ndr_problems, _metaballs_problems, _simplify_problems):
        found += list(check(config))
    return found


def check(config: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` listing every broken rule (nothing if there is none)."""
    found = problems(config)
    if found:
        raise ConfigError("config: " + "; ".join(found))
