"""A grid's provenance: what it read, and whether today's checkout would give it again."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest
import yaml

from locoman.errors import ArtifactError
from locoman.grid.provenance import (
    canonical_folders,
    compare,
    fingerprint,
    read_provenance,
    results_settings,
    stamp,
    status,
    status_line,
)


@pytest.fixture
def checkout(repo, tmp_path) -> Path:
    """A copy of the checkout's ``locoman/`` and ``params.yaml`` to change."""
    root = tmp_path / "checkout"
    shutil.copytree(
        repo / "locoman", root / "locoman", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(repo / "params.yaml", root / "params.yaml")
    return root


def _grid(tmp_path: Path) -> Path:
    folder = tmp_path / "results" / "tiny" / "fig6"
    folder.mkdir(parents=True)
    (folder / "summary.md").write_text("# tiny: paper A's Fig. 6\n\n## Where the claims stand\n")
    return folder


def test_a_grid_stamped_at_this_checkout_is_at_its_code(checkout, tmp_path):
    folder = _grid(tmp_path)
    record = stamp(folder, "tiny", "fig6", "python benchmarks/figures_subset.py tiny", checkout)
    assert record["fingerprint"]["solve_code"]["locoman/to/pipeline.py"]
    assert "locoman/grid/cell.py" in record["fingerprint"]["solve_code"]
    assert status(folder, checkout) == []
    assert status_line(folder, checkout).startswith("at main's code")
    summary = (folder / "summary.md").read_text()
    assert summary.splitlines()[0] == "# tiny: paper A's Fig. 6"
    assert "> Ran at `" in summary and "figures_subset.py tiny" in summary
    # Stamped again, the quote is replaced, not repeated.
    stamp(folder, "tiny", "fig6", "again", checkout)
    assert (folder / "summary.md").read_text().count("> Ran at") == 1


def test_a_changed_source_or_parameter_is_named(checkout, tmp_path):
    folder = _grid(tmp_path)
    stamp(folder, "tiny", "fig6", "", checkout)
    with (checkout / "locoman" / "to" / "problem" / "schedule.py").open("a") as f:
        f.write("\n# a change\n")
    (checkout / "locoman" / "sim" / "pipeline.py").write_text(
        (checkout / "locoman" / "sim" / "pipeline.py").read_text() + "\n# another\n"
    )
    params = yaml.safe_load((checkout / "params.yaml").read_text())
    params["solve"]["contact"]["slack_max_m"] = 0.01
    params["solve"]["solver"]["print_level"] = 5  # how loud a solve is: no result of it
    (checkout / "params.yaml").write_text(yaml.safe_dump(params))
    changes = status(folder, checkout)
    assert "solve code: locoman/to/problem/schedule.py changed" in changes
    assert "evaluation code: locoman/sim/pipeline.py changed" in changes
    assert any(c.startswith("parameter solve.contact.slack_max_m: ") for c in changes)
    assert not any("print_level" in c for c in changes)
    assert len(changes) == 3
    assert "2 source file(s) and 1 parameter(s)" in status_line(folder, checkout)


def test_a_verified_change_moves_the_fingerprint_and_keeps_the_commit(checkout, tmp_path):
    folder = _grid(tmp_path)
    stamp(folder, "tiny", "fig6", "run", checkout, commit="abc1234", date="2026-11-01")
    (checkout / "locoman" / "to" / "problem" / "schedule.py").write_text("# moved\n")
    assert status(folder, checkout)
    stamp(folder, "tiny", "fig6", "", checkout, verified="every dvc repro output bit-identical")
    record = read_provenance(folder)
    assert record["commit"] == "abc1234" and record["command"] == "run"
    assert record["verified"][0]["note"] == "every dvc repro output bit-identical"
    assert status(folder, checkout) == []
    assert "Verified unchanged at" in (folder / "summary.md").read_text()


def test_compare_names_added_and_removed_files():
    then = {"solve_code": {"a.py": "1", "b.py": "2"}, "evaluate_code": {}, "params": {"x": 1}}
    now = {"solve_code": {"a.py": "1", "c.py": "3"}, "evaluate_code": {}, "params": {"x": 1}}
    assert compare(then, now) == ["solve code: c.py added", "solve code: b.py removed"]


def test_a_folder_without_provenance_says_how_to_stamp_it(tmp_path):
    with pytest.raises(ArtifactError, match="provenance stamp"):
        read_provenance(tmp_path)


def test_display_settings_are_no_part_of_a_result(params):
    loud = dataclasses.replace(
        params.solve, solver=dataclasses.replace(params.solve.solver, print_level=5)
    )
    quiet = dataclasses.asdict(params.solve)
    assert results_settings(dataclasses.asdict(loud)) == results_settings(quiet)
    assert "cache_dir" not in results_settings(quiet)
    assert "progress_every" not in results_settings(quiet)["solver"]
    assert quiet["solver"]["print_level"] == 0  # the input is left as it was


def test_every_committed_grid_has_its_provenance_and_lives_in_a_canonical_folder(repo):
    results = repo / "benchmarks" / "results"
    folders = canonical_folders(results)
    assert folders, "no canonical grid"
    for folder in folders:
        record = read_provenance(folder)
        assert (record["scenario"], record["figure"]) == (folder.parent.name, folder.name)
        assert (folder / "summary.md").read_text().count("> Ran at `") == 1
    # Nothing else under benchmarks/results/ but <scenario>/<figure>/ folders, one JSON per
    # benchmark script (and its picture, where it draws one), and the README.
    scripts = {p.stem for p in (repo / "benchmarks").glob("*.py")}
    for entry in results.iterdir():
        if entry.is_dir():
            assert all((f / "provenance.json").is_file() for f in entry.iterdir()), entry
        elif entry.suffix == ".json":
            assert entry.stem in scripts, f"{entry.name}: no benchmark of that name"
            assert json.loads(entry.read_text()).get("commit"), f"{entry.name}: no commit"
        elif entry.suffix == ".png":  # a benchmark's picture beside its JSON
            assert (results / f"{entry.stem}.json").is_file(), entry
        else:
            assert entry.name == "README.md", entry


def test_another_checkouts_fingerprint_reads_its_own_files(checkout):
    (checkout / "locoman" / "to" / "pipeline.py").write_text("from locoman.to import io\n")
    ours = fingerprint(checkout, "tiny")
    assert "locoman/to/pipeline.py" in ours["solve_code"]
    assert "locoman/to/solve/optimizer.py" not in ours["solve_code"]  # no longer imported
