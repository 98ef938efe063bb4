"""The deploy job: a case's optimised result as its shipped GLB and OBJ, read back and
checked against the optimised mesh, with its deployment table."""

import numpy as np
import pandas as pd
import pytest
import trimesh

from neurender import io
from neurender.simplification import EXPORT_FILES, deploy, export, formats, jobs, mesh_ops

DEPLOYED = {**EXPORT_FILES, "table": "deployment.csv"}


@pytest.fixture
def optimised(tmp_path):
    """An optimised case as its deploy job reads it: a QEM'd sphere's atlas (placed in its
    file's frame by a scale and an offset), positions moved off the QEM mesh, bumpy normal
    and coloured albedo maps; ``(inputs, low, positions, to_asset)``."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    low = mesh_ops.uv_atlas(*mesh_ops.decimate(sphere.vertices, sphere.faces, 200), 32)
    rng = np.random.default_rng(0)
    positions = low.positions * (1 + 0.02 * rng.standard_normal((len(low.positions), 1)))
    to_asset = np.diag([3.0, 3.0, 3.0, 1.0])
    to_asset[:3, 3] = [10.0, -4.0, 2.5]
    normal = np.clip(np.dstack([rng.uniform(0.3, 0.7, (32, 32, 2)), np.ones((32, 32))]), 0, 1)
    albedo = rng.uniform(0.1, 0.9, (32, 32, 3))
    inputs = {k: str(tmp_path / f"{k}.{ext}") for k, ext in (("lowpoly", "npz"), ("mesh", "npz"))}
    formats.save_lowpoly(inputs["lowpoly"], low, None, to_asset)
    io.save_npz(inputs["mesh"], positions=positions)
    for key, texture in (("normal", normal), ("albedo", albedo)):
        inputs[key] = str(tmp_path / f"{key}.png")
        formats.write_texture(inputs[key], texture)
    return inputs, low, positions, to_asset


def _outputs(folder):
    folder.mkdir()
    return {k: str(folder / name) for k, name in DEPLOYED.items()}


def test_deploy_writes_the_shipped_files_and_their_read_back_errors(optimised, tmp_path):
    inputs, low, positions, to_asset = optimised
    outputs = _outputs(tmp_path / "case")
    jobs.simplification_deploy(inputs, outputs, {"case": "ball"}, 1)
    table = pd.read_csv(outputs["table"])
    assert list(table.columns) == ["case", "file", "quantity", "value"]
    assert set(table.case) == {"ball"}
    value = table.set_index(["file", "quantity"])["value"]
    for name in EXPORT_FILES.values():
        assert value[name, "bytes"] == (tmp_path / "case" / name).stat().st_size
    for name in (EXPORT_FILES["glb"], EXPORT_FILES["obj"]):
        assert value[name, "triangles"] == len(low.uv_faces)
        assert 0 <= value[name, "max_position_error"] <= deploy.POSITION_TOLERANCE
        assert 0 <= value[name, "max_uv_error"] <= deploy.UV_TOLERANCE
    assert value["all", "export_seconds"] > 0 and value["all", "read_back_seconds"] > 0
    # The GLB holds the optimised positions in the file's frame, not the QEM mesh's.
    glb = trimesh.load(outputs["glb"], force="mesh", process=False)
    world = low.atlas_positions(positions) @ to_asset[:3, :3].T + to_asset[:3, 3]
    np.testing.assert_allclose(np.sort(glb.vertices, 0), np.sort(world, 0), atol=1e-5)


def test_a_file_that_reads_back_otherwise_is_refused_naming_it(optimised, tmp_path):
    _, low, positions, to_asset = optimised
    paths = {k: str(tmp_path / name) for k, name in EXPORT_FILES.items()}
    export.export(paths, low, positions, np.full((8, 8, 3), 0.5), np.full((8, 8, 3), 0.5), to_asset)
    errors = deploy.read_back_errors(paths["obj"], low, positions, to_asset)
    deploy.check(paths["obj"], errors, len(low.uv_faces))  # as written: no error
    moved = positions.copy()
    moved[0] += 1e-3  # a vertex off by 1e-3 of the unit sphere
    errors = deploy.read_back_errors(paths["obj"], low, moved, to_asset)
    assert errors["max_position_error"] == pytest.approx(1e-3 / np.ptp(moved, 0).max(), rel=0.1)
    with pytest.raises(deploy.ReadBackError, match=r"optimised\.obj reads back with max_position"):
        deploy.check(paths["obj"], errors, len(low.uv_faces))
    with pytest.raises(deploy.ReadBackError, match=r"with 196 triangles; 195 were written"):
        deploy.check(paths["glb"], {**errors, "triangles": 196}, 195)
