"""Citations a reader can follow: the package and the docs cite their sources by author and
year ("Vitali 2018", "Tedaldi et al. 2014"), each such citation is a key of docs/sources.md,
and none uses the private names the project's source documents once had here (the word "seed"
and a three-digit number), which nobody reading a clone can resolve."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "tumblecal_cli"
SOURCES = (ROOT / "docs" / "sources.md").read_text(encoding="utf-8")
#: README.md and every page of docs/ but the sources page itself
PAGES = [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").rglob("*.md") if p.name != "sources.md")]

#: The old private names, in any of the spellings they had: one or several, with a space, a
#: hyphen or a backtick before the number, or as the start of a file name.
PRIVATE = re.compile(r"\bseeds?[\s`'\"-]*0\d\d(?!\d)", re.IGNORECASE)

_NAME = r"[A-Z][A-Za-z'’-]+"
_YEAR = r"(?:(?:19|20)\d\d|n\.d\.)"
#: A name and a year: "White 1980", "Ding and Uchida 2012", "Tedaldi et al. 2014", "Howe, Allan
#: and Barnes 1981", "Okasho n.d." (no year given). Also the spellings the keys do not use
#: ("Iglewicz & Hoaglin (1993)"), so that one fails instead of going unseen. Of a name of two
#: words ("Sports Sensing 2023") it finds the last word and the year; the key supplies the rest.
CITATION = re.compile(rf"\b{_NAME}(?: et al\.|(?:, {_NAME})*,? (?:and|&) {_NAME})? (?:{_YEAR}|\({_YEAR}\))")


def source_keys() -> list[str]:
    """The first cell of each row of docs/sources.md's tables, their header rows left out."""
    lines = SOURCES.splitlines()
    keys = []
    for line, following in zip(lines, [*lines[1:], ""], strict=True):
        if line.startswith("| ") and not following.startswith("|---"):
            keys.append(line.split("|")[1].strip())
    return keys


def prose(text: str) -> str:
    """``text`` with each line's comment marker dropped and all whitespace one space, so a
    citation split over two docstring or comment lines reads as one."""
    return " ".join(" ".join(re.sub(r"^\s*#:?", "", line) for line in text.splitlines()).split())


def texts() -> dict[str, str]:
    """Every module of the package, README.md and the docs pages but docs/sources.md, as prose."""
    found = {str(path.relative_to(ROOT)): prose(path.read_text(encoding="utf-8")) for path in PACKAGE.rglob("*.py")}
    found.update({str(path.relative_to(ROOT)): prose(path.read_text(encoding="utf-8")) for path in PAGES})
    return dict(sorted(found.items()))


def key_of(text: str, match: re.Match[str], keys: list[str]) -> str | None:
    """The key of "Sources" that the citation ``match`` in ``text`` is, or None."""
    cited, before = match.group(0), text[: match.end()]
    return next((key for key in keys if key.endswith(cited) and before.endswith(key)), None)


def test_no_private_document_names() -> None:
    paths = [*sorted(PACKAGE.rglob("*.py")), *PAGES, ROOT / "docs" / "sources.md"]
    found = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in paths
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if PRIVATE.search(line)
    ]
    assert found == []


def test_sources_list_each_work_once() -> None:
    keys = source_keys()
    assert len(keys) >= 4
    assert sorted(key for key in set(keys) if keys.count(key) > 1) == []


def test_every_author_year_citation_resolves_to_sources() -> None:
    keys = source_keys()
    unresolved = [
        f"{name}: {match.group(0)!r} in ...{text[max(0, match.start() - 40) : match.end()]}"
        for name, text in texts().items()
        for match in CITATION.finditer(text)
        if key_of(text, match, keys) is None
    ]
    assert unresolved == []


def test_every_author_year_source_is_cited() -> None:
    """An author–year entry of "Sources" that nothing cites is stale (or the pattern above has
    stopped seeing citations, which would let the test before pass on nothing)."""
    keys = source_keys()
    cited = {key_of(text, match, keys) for text in texts().values() for match in CITATION.finditer(text)}
    author_year = [key for key in keys if re.search(rf" {_YEAR}$", key)]
    assert len(author_year) >= 4
    assert [key for key in author_year if key not in cited] == []
