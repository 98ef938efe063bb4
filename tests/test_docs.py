"""The front page and the docs pages: every relative link names a file that exists."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

# [text](target) and ![alt](target); the target ends at whitespace or ")".
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
_FENCE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r"`[^`\n]*`")


def relative_links(markdown: str) -> list[str]:
    """Link targets of a Markdown text that point into the repository.

    Links inside fenced code blocks and code spans are not links; URLs with a scheme
    (https:, mailto:) and same-page anchors (#...) are skipped; a target's own
    "#anchor" is dropped, leaving the file part.
    """
    text = _CODE_SPAN.sub("", _FENCE.sub("", markdown))
    targets = []
    for target in _LINK.findall(text):
        if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("#"):
            continue
        targets.append(target.split("#", 1)[0])
    return targets


def test_relative_links_finds_links_and_skips_urls_anchors_and_code():
    text = (
        "See [a](docs/a.md), ![pic](img/p.png) and [sec](b.md#part).\n"
        "[web](https://example.org) [mail](mailto:x@y.z) [here](#top)\n"
        "`[not](code.md)`\n```\n[not](fenced.md)\n```\n"
    )
    assert relative_links(text) == ["docs/a.md", "img/p.png", "b.md"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page):
    missing = [
        target
        for target in relative_links(page.read_text(encoding="utf-8"))
        if not (page.parent / target).exists()
    ]
    assert not missing, f"{page.relative_to(ROOT)}: links to missing files {missing}"


def test_front_page_starts_with_the_two_commands():
    """The README's first lines are one bash block of two commands: install + run, and the
    tests, which CI runs as written."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "```bash" and lines[3] == "```", lines[:4]
    assert "snakemake" in lines[1] and "results/report.html" in lines[1], lines[1]
    assert lines[2].startswith("python -m pytest ") and lines[2].endswith(" tests"), lines[2]
    assert lines[2] in (ROOT / ".ci/run").read_text().splitlines()
