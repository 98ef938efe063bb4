"""CITATION.cff and LICENSE agree with the package: its version and licence, and every
registered method's publication (its record's DOI and title) listed as a reference."""

from __future__ import annotations

import tomllib
from pathlib import Path

import yaml

from neurender.methods import METHODS

ROOT = Path(__file__).resolve().parents[1]


def _citation() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text())


def test_citation_version_and_licence_match_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    citation = _citation()
    assert citation["cff-version"] == "1.2.0"
    assert str(citation["version"]) == project["version"]
    assert citation["license"] == project["license"]
    assert (ROOT / "LICENSE").read_text().startswith(f"{project['license']} License")


def test_citation_lists_every_methods_publication():
    references = _citation()["references"]
    dois = {f"https://doi.org/{ref['doi']}" for ref in references if "doi" in ref}
    titles = {ref["title"].lower() for ref in references}
    for method in METHODS:
        if method.link.startswith("https://doi.org/"):
            assert method.link in dois, method.key
        # The record's citation names the publication's title.
        assert any(title in method.citation.lower() for title in titles), method.key
