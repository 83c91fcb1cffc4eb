"""A suite of user-written tasks, each run end to end at the defaults: does the TO generalise?

Usage: python benchmarks/scenarios.py [--tasks NAME ...] [--jobs 2] [--keep DIR]
       [--out benchmarks/results/scenarios.json]

Each file of ``benchmarks/scenarios/`` is a scenario as a user writes one for
``conf/scenario/`` (``docs/scenarios.md``): none has a setting of its own. Each runs in a
process of its own, ``--jobs`` at a time, through the stages' own code at the parameters of
``params.yaml`` with the task added as a scenario: ``validate`` (every check of the
configuration, the task's layout and plan), ``scene``, ``generate``, ``masks``,
``clouds``, ``contacts``, ``retarget``, ``solve``, ``evaluate``. The JSON has, per task,
how far it got, the solve's status, iterations, rounds and pairs found, the solve time, the
evaluation's verdict and failed checks; beside it ``scenarios.png`` lays out the tasks'
filmstrips. ``--keep`` keeps each task's outputs (``<DIR>/<task>/<stage>/``).
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy and OpenBLAS choose their kernels when they load

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from common import write_benchmark

TASKS_DIR = Path(__file__).parent / "scenarios"
RECORD = "record.json"


def task_params(task: str) -> dict[str, Any]:
    """``params.yaml`` with the task added as a scenario of every humanoid stage."""
    raw = yaml.safe_load(Path("params.yaml").read_text())
    raw["scenarios"][task] = yaml.safe_load((TASKS_DIR / f"{task}.yaml").read_text())
    raw["humanoid_scenarios"] = [*raw["humanoid_scenarios"], task]
    for section in ("perception", "solve"):
        raw[section]["scenarios"] = [*raw[section]["scenarios"], task]
    return raw


def run_task(task: str, root: Path) -> dict[str, Any]:
    """Every stage of ``task`` into ``root/<stage>/``; its record (how far it got, why not)."""
    from locoman.artifacts import write_png
    from locoman.config.load import validate
    from locoman.config.to import scenario_solve
    from locoman.contact.pipeline import contacts_scenario
    from locoman.errors import LocomanError
    from locoman.perception.clouds import clouds_scenario
    from locoman.perception.generate import generate_scenario
    from locoman.perception.masks import masks_scenario
    from locoman.retarget.pipeline import retarget_scenario
    from locoman.scene.builder import build_scene
    from locoman.scene.checks import check_scene
    from locoman.scene.io import write_scene
    from locoman.scene.render import render_camera
    from locoman.sim.pipeline import evaluate_scenario
    from locoman.stage import configure_logging
    from locoman.to.pipeline import solve_scenario

    configure_logging(f"scenarios {task}")  # the solve's progress lines into the task's log
    record: dict[str, Any] = {"task": task, "stage": "validate"}
    tic = time.perf_counter()
    try:
        cfg = validate(task_params(task))
        p, sc = cfg.perception, cfg.scenarios[task]
        d = {s: root / s for s in ("scene", "generate", "masks", "clouds", "contacts")}
        d |= {s: root / s for s in ("retarget", "solve", "evaluate")}
        record["stage"] = "scene"
        model, qpos = write_scene(d["scene"], build_scene(task, sc, (640, 480)))
        check_scene(model, qpos, sc.robot, cfg.scene.penetration_tol, cfg.scene.foot_ground_tol)
        write_png(d["scene"] / "overview.png", render_camera(model, qpos, "overview", 640, 480))
        record["stage"] = "perception"
        generate_scenario(task, d["scene"], d["generate"], p.generate, cfg.seed)
        masks_scenario(task, d["generate"], d["masks"], p.masks, cfg.seed)
        clouds_scenario(
            task, d["generate"], d["masks"], d["clouds"], p.clouds, p.depth_error, cfg.seed
        )
        record["stage"] = "contacts"
        contacts = contacts_scenario(
            task, d["scene"], d["generate"], d["masks"], d["clouds"], d["contacts"],
            cfg.contacts, cfg.seed,
        )  # fmt: skip
        record["contact_error_median_m"] = contacts.get("contact_error_median_m")
        record["stage"] = "retarget"
        retarget_scenario(
            task, d["scene"], d["generate"], d["masks"], d["contacts"], d["retarget"], cfg.retarget
        )
        record["stage"] = "solve"
        traj = solve_scenario(
            d["scene"], d["contacts"], d["retarget"], d["solve"], scenario_solve(cfg.solve, task)
        )
        solved = json.loads((d["solve"] / "metrics.json").read_text())
        record |= {
            "converged": bool(traj.success),
            "solver_status": traj.status,
            "iterations": traj.iterations,
            "solve_time_s": traj.solve_time_s,
            "rounds": sum(r["pairs_added"] > 0 for r in solved["collision_rounds"]),
            "pairs_found": solved["pairs_found"],
            "restarts": solved["restarts"],
        }
        record["stage"] = "evaluate"
        metrics = evaluate_scenario(d["scene"], d["solve"], d["evaluate"], cfg.evaluate)
        record |= {
            "passes": bool(metrics["success"]),
            "failed_checks": metrics["failed_checks"],
            "max_penetration_m": metrics["max_penetration_m"],
            "object_goal_error_m": metrics["object_goal_error_m"],
        }
        record["stage"] = "done"
    except LocomanError as exc:
        record["error"] = f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # a bug is a result of the suite too: recorded, the suite goes on
        record["error"] = f"{type(exc).__name__}: {exc}"
        record["traceback"] = traceback.format_exc()
    record["wall_time_s"] = time.perf_counter() - tic
    return record


def _child(task: str, root: Path) -> dict[str, Any]:
    """Run ``task`` in a process of its own (its kernels pinned, its memory its own)."""
    root.mkdir(parents=True, exist_ok=True)
    log = root / "log.txt"
    with log.open("w") as out:
        subprocess.run(
            [sys.executable, __file__, "--one", task, "--root", str(root)],
            stdout=out,
            stderr=subprocess.STDOUT,
            check=False,
        )
    try:
        return json.loads((root / RECORD).read_text())
    except (OSError, ValueError):
        tail = log.read_text()[-2000:]
        return {"task": task, "stage": "crashed", "error": tail}


def contact_sheet(records: list[dict[str, Any]], work: Path, out: Path, columns: int = 3) -> None:
    """The tasks' filmstrips in a grid, ``columns`` wide, each titled with its verdict."""
    import cv2

    from locoman.artifacts import write_png

    width = 560
    tiles = []
    for r in records:
        strip = work / r["task"] / "evaluate" / "plots" / "filmstrip.png"
        image = cv2.imread(str(strip), cv2.IMREAD_COLOR) if strip.is_file() else None
        if image is None:
            image = np.full((280, width, 3), 255, np.uint8)
        image = cv2.resize(image, (width, round(image.shape[0] * width / image.shape[1])))
        verdict = (
            f"{r['task']}: {'passes' if r.get('passes') else 'FAILS'}, "
            f"{r.get('iterations', '-')} its"
        )
        title = np.full((26, width, 3), 255, np.uint8)
        cv2.putText(title, verdict, (6, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1)
        tiles.append(np.vstack([title, image]))
    height = max(t.shape[0] for t in tiles)
    tiles = [
        np.pad(t, ((0, height - t.shape[0]), (0, 0), (0, 0)), constant_values=255) for t in tiles
    ]
    tiles += [np.full_like(tiles[0], 255)] * (-len(tiles) % columns)
    rows = [np.hstack(tiles[i : i + columns]) for i in range(0, len(tiles), columns)]
    write_png(out, cv2.cvtColor(np.vstack(rows), cv2.COLOR_BGR2RGB))


def summary(records: list[dict[str, Any]]) -> dict[str, Any]:
    solved = [r["solve_time_s"] for r in records if "solve_time_s" in r]
    return {
        "tasks": len(records),
        "converged": sum(bool(r.get("converged")) for r in records),
        "pass": sum(bool(r.get("passes")) for r in records),
        "solve_time_median_s": statistics.median(solved) if solved else None,
        "solve_time_max_s": max(solved) if solved else None,
        "iterations_median": statistics.median(
            [r["iterations"] for r in records if "iterations" in r] or [0]
        ),
    }


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tasks", nargs="+", default=sorted(p.stem for p in TASKS_DIR.glob("*.yaml"))
    )
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", type=Path, help="keep each task's outputs here")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scenarios.json"))
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--root", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:  # a child: one task
        record = run_task(args.one, args.root)
        (args.root / RECORD).write_text(json.dumps(record, indent=2))
        return 0
    tic = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        with ThreadPoolExecutor(args.jobs) as pool:
            records = list(pool.map(lambda t: _child(t, work / t), args.tasks))
        for r in records:
            print(
                f"[scenarios] {r['task']}: {r.get('stage')} {r.get('solver_status', '')} "
                f"{r.get('iterations', '')} its, passes {r.get('passes')} "
                f"{r.get('failed_checks', '')} {r.get('error', '')[:300]}",
                flush=True,
            )
        contact_sheet(records, work, args.out.with_suffix(".png"))
    result = {
        "command": " ".join(["python", "benchmarks/scenarios.py", *argv]),
        "jobs": args.jobs,
        "wall_time_s": time.perf_counter() - tic,
        "summary": summary(records),
        "tasks": records,
    }
    write_benchmark(args.out, result)
    print(json.dumps(result["summary"]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
