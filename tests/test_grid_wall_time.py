"""``benchmarks/grid_wall_time.py``: a grid's wall time per panel from its cells' records,
the time at least one cell ran (a grid relaunched across sessions counts no gap)."""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "grid_wall_time.py"
spec = importlib.util.spec_from_file_location("grid_wall_time", SCRIPT)
grid_wall_time = importlib.util.module_from_spec(spec)
spec.loader.exec_module(grid_wall_time)


@pytest.mark.parametrize(
    ("intervals", "length"),
    [
        ([], 0.0),
        ([(0.0, 10.0), (5.0, 12.0)], 12.0),  # two cells at a time
        ([(0.0, 10.0), (100.0, 130.0)], 40.0),  # a gap between launches does not count
        ([(0.0, 50.0), (10.0, 20.0), (30.0, 60.0)], 60.0),  # one inside another
    ],
)
def test_the_union_of_the_cells_intervals(intervals, length):
    assert grid_wall_time.union_length(intervals) == pytest.approx(length)


def _cell(folder: Path, name: str, mass: float, yaw: float, seconds: float, end: float, **kw):
    (folder / name).mkdir(parents=True)
    record = folder / name / "cell.json"
    fields = {"box_mass": mass, "initial_yaw": yaw, "wall_time_s": seconds, **kw}
    record.write_text(json.dumps(fields))
    os.utime(record, (end, end))


def test_panels_are_timed_from_their_records_and_say_whether_they_are_whole(tmp_path):
    folder = tmp_path / "data" / "s2_trolley" / "grid" / "fig6"
    _cell(folder, "none_m5_yaw+0", 5.0, 0.0, 600.0, 1000.0)
    _cell(folder, "base_m5_yaw+0", 5.0, 0.0, 300.0, 900.0)  # beside the first
    _cell(folder, "all_m2.5_yaw-0.6", 2.5, -0.6, 900.0, 5000.0, evaluate_wall_time_s=60.0)
    (folder / ".warm_m5_yaw+0.staging").mkdir()  # running: not counted
    out = tmp_path / "wall.json"
    assert (
        grid_wall_time.main(["s2_trolley", "fig6", str(out), "--data", str(tmp_path / "data")]) == 0
    )
    result = json.loads(out.read_text())
    assert result["cells"] == [
        {"box_mass": 2.5, "initial_yaw": -0.6, "runs": 1, "whole": False, "wall_time_s": 60},
        {"box_mass": 5.0, "initial_yaw": 0.0, "runs": 2, "whole": False, "wall_time_s": 600},
    ]
    assert result["runs"] == 3 and result["wall_time_s"] == 660


def test_a_grid_that_never_ran_says_how_to_run_it(tmp_path, capsys):
    assert (
        grid_wall_time.main(["tiny", "fig6", str(tmp_path / "w.json"), "--data", str(tmp_path)])
        == 2
    )
    assert "python -m locoman.grid tiny fig6" in capsys.readouterr().err
