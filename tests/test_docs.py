"""The repository explains itself: code cites ``docs/`` (not pages outside the repository), every
cited ``docs/methods.md §N`` is a heading there, and ``scripts/repoint_citations.py`` (which
re-points the old citations) is idempotent and complete."""

from __future__ import annotations

import importlib.util
import re

import pytest

from tests.conftest import REPO_DIR

DOCS = REPO_DIR / "docs"
#: A citation of a page outside the repository, or of the old unqualified names.
OUTSIDE = re.compile(r"\.\./shared|(?<![\w.-])shared/|\bMETHODS(?:\.md| ?§)|\bDESIGN\b|\bPITFALLS\b")
#: "docs/methods.md §1.2", with continuations "-1.7", "-§1.7", ", §3" (a second "§" after a space
#: only, as in "§2 §3.3", is the paper's own section and is not checked).
CITATION = re.compile(r"docs/methods\.md ?§(\d+(?:\.\d+)*)((?:\s*(?:-|,\s*)§?\d+(?:\.\d+)*)*)")
HEADING = re.compile(r"^#{1,6}\s+§(\d+(?:\.\d+)*)\b", re.M)
#: 'docs/design.md "Scan format on disk"': the quoted part must appear on the page.
DESIGN_PART = re.compile(r'docs/design\.md "([^"]+)"')


def _repoint():
    spec = importlib.util.spec_from_file_location("repoint_citations", REPO_DIR / "scripts" / "repoint_citations.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


RP = _repoint()


def _sources() -> dict[str, str]:
    return {str(rel): (REPO_DIR / rel).read_text(encoding="utf-8") for rel in RP.source_files(REPO_DIR)}


def _docs() -> dict[str, str]:
    return {f"docs/{p.name}": p.read_text(encoding="utf-8") for p in sorted(DOCS.glob("*.md"))}


def _sections(text: str) -> list[str]:
    out = []
    for m in CITATION.finditer(text):
        out.append(m.group(1))
        out += re.findall(r"\d+(?:\.\d+)*", m.group(2))
    return out


def test_docs_pages_exist_and_have_the_numbered_sections():
    docs = _docs()
    assert {"docs/methods.md", "docs/design.md", "docs/pitfalls.md"} <= set(docs)
    heads = set(HEADING.findall(docs["docs/methods.md"]))
    # the numbering of the former external page, which the code's citations use
    assert {"1", "2", "3", "4", "5"} | {f"1.{i}" for i in range(1, 9)} <= heads, sorted(heads)


def test_no_citation_outside_the_repository():
    bad = [f"{name}:{i}: {line.strip()}" for name, text in _sources().items()
           for i, line in enumerate(text.splitlines(), 1) if OUTSIDE.search(line)]
    assert not bad, "cite docs/ instead (scripts/repoint_citations.py):\n" + "\n".join(bad)


def test_repoint_leaves_no_outside_citation_and_is_idempotent():
    """What the first test will see after the script runs: no citation outside, nothing left to do."""
    for name, text in _sources().items():
        once = RP.rewrite(text)
        assert RP.rewrite(once) == once, name
        assert len(once.splitlines()) == len(text.splitlines()), name
        left = [line.strip() for line in once.splitlines() if OUTSIDE.search(line)]
        assert not left, (name, left)


@pytest.mark.parametrize("old, new", [
    ("(METHODS §1.2-§1.7)", "(docs/methods.md §1.2-§1.7)"),
    ("see ../shared/METHODS.md §3 and shared/DESIGN.md", "see docs/methods.md §3 and docs/design.md"),
    ('(DESIGN.md "EnvMap"; METHODS §2, §3)', '(docs/design.md "EnvMap"; docs/methods.md §2, §3)'),
    ('(DESIGN "capture/", issue 4)', '(docs/design.md "capture/", issue 4)'),
    ("(PITFALLS: 0.20 fails) (shared/PITFALLS.md)", "(docs/pitfalls.md: 0.20 fails) (docs/pitfalls.md)"),
    ("errors in ``bench/shading.py``; out/bench/shading", "errors in ``furrow/bench/shading.py``; out/bench/shading"),
    ('METHODS = ("icp", "colmap")  # not a citation', 'METHODS = ("icp", "colmap")  # not a citation'),
])
def test_repoint_examples(old, new):
    assert RP.rewrite(old) == new
    assert RP.rewrite(new) == new


def test_every_cited_methods_section_is_a_heading():
    """Citations as they will read after the re-pointing (old-style ones included), and the docs'
    own cross references."""
    heads = set(HEADING.findall(_docs()["docs/methods.md"]))
    texts = {name: RP.rewrite(text) for name, text in _sources().items()} | _docs()
    cited = {(name, s) for name, text in texts.items() for s in _sections(text)}
    assert len(cited) > 50  # the code really cites the page
    missing = sorted(f"{name}: §{s}" for name, s in cited if s not in heads)
    assert not missing, "cited but not a heading of docs/methods.md:\n" + "\n".join(missing)


def test_quoted_design_sections_exist():
    design = _docs()["docs/design.md"]
    texts = {name: RP.rewrite(text) for name, text in _sources().items()} | _docs()
    quoted = {(name, q) for name, text in texts.items() for q in DESIGN_PART.findall(text)}
    assert quoted
    missing = sorted(f"{name}: {q!r}" for name, q in quoted if q not in design)
    assert not missing, "\n".join(missing)
