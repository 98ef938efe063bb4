"""The front page stays a front page: short, its two commands first, table cells a reader can
take in, the methods table's DOIs those CITATION.cff cites, the docs' install command its own.

Relative links in README.md are checked by tests/test_docs.py; anchors into README.md are
checked here.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 160
MAX_CELL = 250
TEST_COMMAND = "python -m pytest -n auto tests"

_FENCE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
_CELL_SPLIT = re.compile(r"(?<!\\)\|")  # GFM: an unescaped pipe ends a cell, even in code
_SEPARATOR_CELL = re.compile(r":?-+:?")
_DOI = re.compile(r"https://doi\.org/(10\.\d{4,9}/[^\s)\]]+)")


def _readme() -> str:
    return README.read_text(encoding="utf-8")


def _first_block(text: str) -> tuple[str, list[str]]:
    """The opening line of the first non-blank line's fence and the block's lines."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip())
    end = next(i for i in range(start + 1, len(lines)) if lines[i].strip() == "```")
    return lines[start], lines[start + 1 : end]


def _commands(block: list[str]) -> list[str]:
    """Shell commands of a block: its non-blank, non-comment lines (no continuations)."""
    assert not any(line.rstrip().endswith("\\") for line in block), block
    return [line.strip() for line in block if line.strip() and not line.lstrip().startswith("#")]


def tables(markdown: str) -> list[list[list[str]]]:
    """Markdown tables outside fenced code: each a list of rows of stripped cells,
    separator rows (|---|---|) left out."""
    found: list[list[list[str]]] = []
    current: list[list[str]] | None = None
    for line in _FENCE.sub("", markdown).splitlines():
        if line.lstrip().startswith("|"):
            if current is None:
                current = []
                found.append(current)
            body = line.strip().removeprefix("|")
            body = body[:-1] if body.endswith("|") and not body.endswith("\\|") else body
            cells = [cell.strip() for cell in _CELL_SPLIT.split(body)]
            if not all(_SEPARATOR_CELL.fullmatch(cell) for cell in cells):
                current.append(cells)
        else:
            current = None
    return found


def _methods_table(markdown: str) -> list[list[str]]:
    for table in tables(markdown):
        if table and [c.lower() for c in table[0][:2]] == ["method", "paper"]:
            return table
    raise AssertionError("README.md has no table headed | method | paper | ...")


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def test_tables_splits_cells_and_skips_separators_and_code():
    text = (
        "| a | b |\n|---|:--:|\n| `x` | [y](z.md) \\| w |\n\ntext\n"
        "```\n| not | a table |\n```\n| c |\n"
    )
    assert tables(text) == [[["a", "b"], ["`x`", "[y](z.md) \\| w"]], [["c"]]]


def test_slug_matches_githubs_anchors():
    assert _slug("Quickstart") == "quickstart"
    assert _slug("What a run gives you") == "what-a-run-gives-you"
    assert _slug("Configs, run times and running parts of the DAG") == (
        "configs-run-times-and-running-parts-of-the-dag"
    )


def test_readme_is_at_most_160_lines():
    n = len(_readme().splitlines())
    assert n <= MAX_LINES, f"README.md has {n} lines; the front page keeps to {MAX_LINES}"


def test_readme_opens_with_a_bash_block_of_install_and_run_then_the_tests():
    opening, block = _first_block(_readme())
    assert opening.strip() == "```bash", opening
    commands = _commands(block)
    assert len(commands) == 2, commands
    install_and_run, tests_ = commands
    assert tests_ == TEST_COMMAND
    # The first installs the lock (with PyTorch's CPU index for the CPU wheel) and the
    # package, then runs the default config's report.
    assert "-r requirements.lock" in install_and_run
    assert "--extra-index-url https://download.pytorch.org/whl/cpu" in install_and_run
    assert "pip install --no-deps -e ." in install_and_run
    assert install_and_run.split(" && ")[-1].startswith("snakemake ")
    assert "results/report.html" in install_and_run and "--configfile" not in install_and_run


def test_install_guide_gives_the_front_pages_install_command():
    """docs/install.md's first bash block is the install part of the README's first command."""
    install_and_run = _commands(_first_block(_readme())[1])[0]
    install = " && ".join(p for p in install_and_run.split(" && ") if p.startswith("pip "))
    guide = (ROOT / "docs/install.md").read_text(encoding="utf-8")
    block = re.search(r"^```bash\n(.*?)^```", guide, re.MULTILINE | re.DOTALL)
    assert block, "docs/install.md has no bash block"
    assert install in _commands(block.group(1).splitlines()), block.group(1)


def test_every_readme_table_cell_is_at_most_250_characters():
    long = [
        (len(cell), cell[:60])
        for table in tables(_readme())
        for row in table
        for cell in row
        if len(cell) > MAX_CELL
    ]
    assert tables(_readme()), "README.md has no tables"
    assert not long, f"README.md table cells over {MAX_CELL} characters: {long}"


def test_methods_table_dois_are_citation_cffs():
    table = _methods_table(_readme())
    paper = [c.lower() for c in table[0]].index("paper")
    in_readme = {doi for row in table[1:] for doi in _DOI.findall(row[paper])}
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    in_citation = {str(ref["doi"]) for ref in citation["references"] if "doi" in ref}
    assert in_readme == in_citation
    assert len(table) - 1 == len(citation["references"])  # one row per cited paper


def test_links_into_the_readme_name_its_headings():
    anchors = {
        _slug(line.lstrip("#"))
        for line in _FENCE.sub("", _readme()).splitlines()
        if line.startswith("#")
    }
    pages = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    link = re.compile(r"\]\(((?:[./]*README\.md)?)#([^)\s]+)\)")
    broken = []
    for page in pages:
        for target, anchor in link.findall(_FENCE.sub("", page.read_text(encoding="utf-8"))):
            into_readme = (page == README and not target) or (
                target and (page.parent / target).resolve() == README
            )
            if into_readme and anchor not in anchors:
                broken.append(f"{page.relative_to(ROOT)}: {target}#{anchor}")
    assert not broken, f"links to README headings that do not exist: {broken}"
