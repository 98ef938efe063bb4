"""A property of the one reader of a user's mesh file (:mod:`neurender.mesh_file`), fuzzed
with Hypothesis: whatever the bytes, or edits of a valid OBJ or PLY, a clean
:class:`AssetFileError` naming the file or a valid mesh, never another exception."""

import numpy as np
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from neurender import mesh_file
from neurender.asset_files import AssetFileError

_SPHERE = trimesh.creation.icosphere(1)
_OBJ_TEXT = trimesh.exchange.obj.export_obj(_SPHERE)
_PLY_TEXT = trimesh.exchange.ply.export_ply(_SPHERE, encoding="ascii").decode()
_ALPHABET = "0123456789-+.eE /\nvtfn#\\abc"


def _assert_clean(path):
    """Read with materials (NDR, the simplification) and geometry only (DeepPRT)."""
    for materials in (True, False):
        try:
            mesh = mesh_file.read(path, materials=materials)
        except AssetFileError as err:
            assert str(path) in str(err)
            continue
        for part in mesh.parts:
            faces = np.asarray(part.faces)
            assert faces.ndim == 2 and faces.shape[1] == 3 and len(faces)
            assert faces.min() >= 0 and faces.max() < len(part.vertices)
            assert np.isfinite(np.asarray(part.vertices, np.float64)).all()


@st.composite
def _edited(draw, text: str) -> str:
    for _ in range(draw(st.integers(1, 4))):
        start = draw(st.integers(0, len(text)))
        end = draw(st.integers(start, min(len(text), start + 12)))
        text = text[:start] + draw(st.text(_ALPHABET, max_size=12)) + text[end:]
    return text


_TEXTURED = trimesh.creation.box()
_TEXTURED.visual = trimesh.visual.TextureVisuals(
    uv=np.random.default_rng(0).uniform(size=(8, 2)),
    material=trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.new("RGB", (4, 4), (200, 100, 50))
    ),
)
_GLB = _TEXTURED.export(file_type="glb")


@st.composite
def _edited_bytes(draw, data: bytes) -> bytes:
    for _ in range(draw(st.integers(1, 6))):
        start = draw(st.integers(0, len(data) - 1))
        data = data[:start] + draw(st.binary(min_size=1, max_size=8)) + data[start + 1 :]
    return data


#: ``(suffix, content)``: random bytes under any suffix, or small edits of a valid OBJ,
#: ASCII PLY and textured GLB.
_FILES = st.one_of(
    st.tuples(st.sampled_from([".obj", ".ply", ".glb", ".off", ".stl"]), st.binary(max_size=300)),
    st.tuples(st.just(".obj"), _edited(_OBJ_TEXT).map(str.encode)),
    st.tuples(st.just(".ply"), _edited(_PLY_TEXT).map(str.encode)),
    st.tuples(st.just(".glb"), _edited_bytes(_GLB)),
)


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(file=_FILES)
def test_fuzz_any_file_gives_a_clean_error_or_a_valid_mesh(tmp_path, file):
    suffix, content = file
    path = tmp_path / f"fuzzed{suffix}"
    path.write_bytes(content)
    _assert_clean(path)
