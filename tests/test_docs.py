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
