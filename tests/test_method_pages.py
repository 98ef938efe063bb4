"""The method pages are user guides: run history lives in docs/methods/history/.

- a method page (docs/methods/*.md) names commits sparingly: at most 10 % of its non-blank
  lines carry a commit hash;
- no page under docs/ (history/ aside) speaks of issues, "today" or sessions in its prose;
- every history page is linked from its method page's last section, "How we got here",
  and from no other page under docs/ or the README.
"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
METHODS = DOCS / "methods"
HISTORY = METHODS / "history"

METHOD_PAGES = sorted(METHODS.glob("*.md"))
HISTORY_PAGES = sorted(HISTORY.glob("*.md"))
CURRENT_DOCS = sorted(p for p in DOCS.rglob("*.md") if HISTORY not in p.parents)

MAX_HASH_SHARE = 0.10

# A commit hash: 7 to 40 hex digits as a word, with at least one letter and one digit.
_HASH = re.compile(
    r"(?<![0-9A-Za-z_])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![0-9A-Za-z_])",
    re.IGNORECASE,
)
_WORDS = re.compile(r"\b(?:issues?|today|sessions?)\b", re.IGNORECASE)
_FENCE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r"`[^`\n]*`")
_URL = re.compile(r"[a-zA-Z][a-zA-Z0-9+.-]*://\S+")
_LINK_TARGET = re.compile(r"\]\([^)\s]*\)")
_LINK = re.compile(r"\[[^\]]*\]\(([^)\s#]+)(?:#[^)\s]*)?\)")


def _ids(pages):
    return [str(p.relative_to(ROOT)) for p in pages]


def hash_share(markdown: str) -> tuple[float, list[str]]:
    """Share of the non-blank lines that contain a commit hash, and those lines."""
    lines = [line for line in markdown.splitlines() if line.strip()]
    hits = [line for line in lines if _HASH.search(line)]
    return (len(hits) / len(lines) if lines else 0.0), hits


def prose(markdown: str) -> str:
    """The text a reader reads as prose: no fenced blocks, code spans, URLs or link targets."""
    text = _FENCE.sub("", markdown)
    text = _CODE_SPAN.sub("", text)
    text = _LINK_TARGET.sub("]", text)
    return _URL.sub("", text)


def test_helpers_find_hashes_words_and_skip_code():
    share, hits = hash_share("at 8ad7c97 on 2 cores\n\n1024 directions, 0.9989\nface deadbeef\n")
    assert hits == ["at 8ad7c97 on 2 cores"] and share == pytest.approx(1 / 3)
    assert not _HASH.search("int8 float32 1234567 abcdefa 8ad7c97x")
    found = _WORDS.findall(prose("An issue, today. `issue 3` [x](https://h/issues/1) reissued"))
    assert [w.lower() for w in found] == ["issue", "today"]


@pytest.mark.parametrize("page", METHOD_PAGES, ids=_ids(METHOD_PAGES))
def test_method_pages_name_few_commits(page):
    share, hits = hash_share(page.read_text(encoding="utf-8"))
    assert share <= MAX_HASH_SHARE, (
        f"{page.relative_to(ROOT)}: {share:.0%} of its non-blank lines name a commit "
        f"(at most {MAX_HASH_SHARE:.0%}); move run history to docs/methods/history/: {hits}"
    )


@pytest.mark.parametrize("page", CURRENT_DOCS, ids=_ids(CURRENT_DOCS))
def test_docs_do_not_speak_of_issues_today_or_sessions(page):
    found = []
    for number, line in enumerate(prose(page.read_text(encoding="utf-8")).splitlines(), 1):
        found += [f"{number}: {w}" for w in _WORDS.findall(line)]
    assert not found, f"{page.relative_to(ROOT)}: {found}"


def test_every_method_has_at_most_one_history_page_named_like_it():
    methods = {p.stem for p in METHOD_PAGES}
    orphans = [p.name for p in HISTORY_PAGES if p.stem not in methods]
    assert not orphans, f"history pages without a method page: {orphans}"


@pytest.mark.parametrize("history", HISTORY_PAGES, ids=_ids(HISTORY_PAGES))
def test_history_page_is_a_record_linked_from_its_method_pages_end(history):
    lines = history.read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("# ") and lines[0].endswith(": how the current design was reached")
    opening = " ".join(lines[1:6]).lower()
    assert "record" in opening and "not the current numbers" in opening, opening

    method = METHODS / history.name
    text = method.read_text(encoding="utf-8")
    target = f"history/{history.name}"
    assert _LINK.findall(text).count(target) == 1, f"{method.name} must link {target} once"
    last_section = text.rsplit("\n## ", 1)[-1]
    assert last_section.startswith("How we got here"), "the last section is 'How we got here'"
    assert target in _LINK.findall(last_section)


@pytest.mark.parametrize("history", HISTORY_PAGES, ids=_ids(HISTORY_PAGES))
def test_history_page_is_linked_from_nothing_else(history):
    method = METHODS / history.name
    others = [ROOT / "README.md", *(p for p in CURRENT_DOCS if p != method)]
    linking = [
        str(page.relative_to(ROOT))
        for page in others
        for target in _LINK.findall(page.read_text(encoding="utf-8"))
        if (page.parent / target).resolve() == history.resolve()
    ]
    assert not linking, f"{history.relative_to(ROOT)} is linked from {linking}"
