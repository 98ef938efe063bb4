"""The committed viewer bundle was built from the viewer code and npm packages committed
beside it: ``npm run build`` heads it with their SHA-256 (``viewer/build.mjs``)."""

import hashlib
from pathlib import Path

import pytest

REPORT = Path(__file__).resolve().parents[1] / "src" / "neurender" / "report"


@pytest.mark.parametrize("source", ["viewers.js", "package-lock.json"])
def test_the_viewer_bundle_names_the_sources_it_was_built_from(source):
    first_line = (REPORT / "static" / "viewers.min.js").read_text().split("\n", 1)[0]
    digest = hashlib.sha256((REPORT / "viewer" / source).read_bytes()).hexdigest()
    assert f"{source} sha256:{digest}" in first_line, (
        f"src/neurender/report/viewer/{source} changed since viewers.min.js was built: "
        "run `npm ci && npm run build` in src/neurender/report/viewer"
    )
