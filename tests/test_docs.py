"""The README and docs/: every relative link resolves, the README stays short and names no
commit, and CITATION.cff holds what a citation needs."""

from __future__ import annotations

import re

import pytest
import yaml

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CODE_PATH = re.compile(r"`((?:docs|benchmarks|locoman|conf|tests|stages|data)/[^`\s*<>]+)`")


def _pages(repo):
    return [repo / "README.md", *sorted((repo / "docs").glob("*.md"))]


def test_every_relative_link_of_the_readme_and_docs_resolves(repo):
    broken = []
    for page in _pages(repo):
        for target in LINK.findall(page.read_text()):
            if re.match(r"[a-z]+://|#|mailto:", target):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            if not path.exists():
                broken.append(f"{page.relative_to(repo)} -> {target}")
    assert not broken, broken


def test_every_docs_page_is_named_in_the_readme(repo):
    readme = (repo / "README.md").read_text()
    missing = [p.name for p in (repo / "docs").glob("*.md") if p.name not in readme]
    assert not missing, f"docs pages the README does not name: {missing}"


def test_the_readme_is_short_and_names_no_commit(repo):
    text = (repo / "README.md").read_text()
    assert len(text.encode()) < 10_000
    assert not re.search(r"\b[0-9a-f]{7,40}\b", text), "a commit hash in the README"
    assert text.splitlines()[0].startswith("# ") and "![" in "\n".join(text.splitlines()[:8])


@pytest.mark.parametrize("page", ["README.md", "docs/trajectory-optimisation.md"])
def test_the_source_paths_a_page_names_exist(repo, page):
    text = (repo / page).read_text()
    missing = [
        p for p in CODE_PATH.findall(text) if "<" not in p and not (repo / p.rstrip("/.,")).exists()
    ]
    missing = [p for p in missing if not p.startswith("data/")]  # outputs of a run
    assert not missing, missing


def test_the_citation_file_cites_the_software_and_both_papers(repo):
    cff = yaml.safe_load((repo / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["title"] and cff["authors"]
    assert cff["message"] and cff["type"] == "software"
    titles = [ref["title"] for ref in cff["references"]]
    papers = sorted((repo.parent / "shared" / "papers").glob("*.txt"))
    if not papers:
        pytest.skip("../shared/papers is not beside the checkout")
    for paper in papers:
        first_line = next(line for line in paper.read_text().splitlines() if line.strip())
        assert first_line.strip() in titles
    assert all(ref["authors"] for ref in cff["references"])
    assert (repo / "LICENSE").read_text().startswith("MIT License")


DOCS_BUDGET_BYTES = 80_000
PAGE_BUDGET_BYTES = 20_000


def test_the_docs_are_short_enough_to_read(repo):
    """The docs describe the product as it is: under 80 KB in all, no page over 20 KB."""
    sizes = {p.name: len(p.read_bytes()) for p in (repo / "docs").glob("*.md")}
    assert sum(sizes.values()) < DOCS_BUDGET_BYTES, sizes
    assert not {n: s for n, s in sizes.items() if s > PAGE_BUDGET_BYTES}


def _text_files(repo):
    yield repo / "README.md"
    yield repo / "CHANGELOG.md"
    for folder in ("docs", "benchmarks"):
        for path in sorted((repo / folder).rglob("*")):
            if path.is_file() and path.suffix in {".md", ".py", ".json", ".csv", ".txt"}:
                yield path


def test_no_page_tells_the_story_of_its_making(repo):
    """History is CHANGELOG.md and git: no file of the docs, the README, the changelog or
    the benchmarks speaks of the sessions the work was done in."""
    found = [
        str(p.relative_to(repo))
        for p in _text_files(repo)
        if re.search(r"\bsessions?\b", p.read_text(errors="replace"), re.IGNORECASE)
    ]
    assert not found, found
