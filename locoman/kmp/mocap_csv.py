"""Recorded motion-capture demonstrations as CSV files.

Layout: one file per demonstration, comma-separated, a header row naming the columns below
(in any order; extra columns are ignored), then one row per sample with strictly increasing
time. World frame, z up, SI units; quaternions are (w, x, y, z).

=========================================  =============================================
column                                     meaning
=========================================  =============================================
``time_s``                                 sample time [s]
``wrist_x``, ``wrist_y``, ``wrist_z``      wrist position [m]
``wrist_qw``, ``wrist_qx``, ...            wrist orientation (unused by the learning)
``pelvis_x``, ``pelvis_y``, ``pelvis_z``   pelvis position [m]
``pelvis_qw``, ``pelvis_qx``, ...          pelvis orientation; its yaw is learned
=========================================  =============================================

Loading shifts time to start at 0, takes the wrist velocity by central differences (as a
motion-capture pipeline does), and resamples every file onto one grid: a longer file is cut, a
shorter one refused (padding it would teach the robot to stop where the recording stopped).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from locoman.artifacts.io import write_text_atomic
from locoman.errors import DemoError
from locoman.kmp.demos import Demos

QUAT = ("qw", "qx", "qy", "qz")
COLUMNS = (
    "time_s",
    "wrist_x",
    "wrist_y",
    "wrist_z",
    *(f"wrist_{q}" for q in QUAT),
    "pelvis_x",
    "pelvis_y",
    "pelvis_z",
    *(f"pelvis_{q}" for q in QUAT),
)


def read_demo_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Columns of one recorded file, as float arrays keyed by :data:`COLUMNS`.

    Raises:
        DemoError: The file is missing or empty, a column is missing, a value is not a finite
            number (naming the row and column), or time does not increase.
    """
    path = Path(path)
    if not path.is_file():
        raise DemoError(f"demo file {path} does not exist")
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (UnicodeDecodeError, csv.Error) as err:
        raise DemoError(f"demo file {path} is not a text CSV file ({err})") from None
    if not rows:
        raise DemoError(f"demo file {path} is empty; expected a header with {list(COLUMNS)}")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise DemoError(f"demo file {path}: header lacks columns {missing}")
    if len(rows) < 3:
        raise DemoError(f"demo file {path} has {len(rows) - 1} samples; need at least 2")
    where = {c: header.index(c) for c in COLUMNS}
    out = {c: np.empty(len(rows) - 1) for c in COLUMNS}
    for r, row in enumerate(rows[1:]):
        line = r + 2
        if len(row) != len(header):
            raise DemoError(
                f"demo file {path}, row {line}: {len(row)} values, the header has {len(header)}"
            )
        for c, i in where.items():
            try:
                value = float(row[i])
            except ValueError:
                value = float("nan")
            if not np.isfinite(value):
                raise DemoError(
                    f"demo file {path}, row {line}, column {c!r}: {row[i]!r} is not a finite number"
                )
            out[c][r] = value
    steps = np.diff(out["time_s"])
    if np.any(steps <= 0.0):
        bad = int(np.argmax(steps <= 0.0)) + 3
        raise DemoError(f"demo file {path}, row {bad}, column 'time_s': time must increase")
    return out


def yaw_from_quat_wxyz(q: np.ndarray) -> np.ndarray:
    """Yaw [rad] of (..., 4) quaternions (w, x, y, z), z-y-x convention."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def load_demo_dir(folder: str | Path, rate_hz: float, duration_s: float) -> Demos:
    """All ``*.csv`` demonstrations in ``folder`` (sorted by name) on a common grid.

    Raises:
        DemoError: The folder holds no CSV file, a file is malformed or implausible
            (:func:`check_plausible`), or shorter than ``duration_s``.
    """
    files = sorted(Path(folder).glob("*.csv"))
    if not files:
        raise DemoError(f"no demonstration files (*.csv) in {folder}")
    t = np.linspace(0.0, duration_s, round(duration_s * rate_hz) + 1)
    pos, vel, pel = [], [], []
    for f in files:
        cols = read_demo_csv(f)
        ts = cols["time_s"] - cols["time_s"][0]
        if ts[-1] < duration_s - 0.5 / rate_hz:
            raise DemoError(
                f"demo file {f} lasts {ts[-1]:.3f} s, shorter than the task (demos.duration_s "
                f"= {duration_s:g} s): record the whole task, or lower demos.duration_s to "
                f"{ts[-1]:.3f} s or less (with the phase times inside it)"
            )
        wrist = np.stack([cols[f"wrist_{a}"] for a in "xyz"], axis=1)
        quat = np.stack([cols[f"pelvis_{q}"] for q in QUAT], axis=1)
        pelvis = np.c_[cols["pelvis_x"], cols["pelvis_y"], np.unwrap(yaw_from_quat_wxyz(quat))]
        wrist_vel = np.gradient(wrist, ts, axis=0)
        check_plausible(f, cols, wrist_vel)
        pos.append(_resample(t, ts, wrist))
        vel.append(_resample(t, ts, wrist_vel))
        pel.append(_resample(t, ts, pelvis))
    return Demos(t, np.stack(pos), np.stack(vel), np.stack(pel))


# What a person's recorded motion stays within; a file beyond it is in other units or
# another frame (millimetres give positions of thousands and speeds of hundreds).
WORKSPACE_M = 50.0  # |x|, |y|, |z| of the wrist and the pelvis [m]
WRIST_SPEED_MAX_MPS = 10.0  # [m/s]; a fast human reach peaks near 5


def check_plausible(path: Path, cols: dict[str, np.ndarray], wrist_vel: np.ndarray) -> None:
    """Refuse a recording whose positions or speeds no person makes in metres and seconds.

    Raises:
        DemoError: Naming the file, the column and the value.
    """
    for name in ("wrist_x", "wrist_y", "wrist_z", "pelvis_x", "pelvis_y", "pelvis_z"):
        worst = float(np.max(np.abs(cols[name])))
        if worst > WORKSPACE_M:
            raise DemoError(
                f"demo file {path}, column {name!r}: a value of {worst:g} lies beyond the "
                f"{WORKSPACE_M:g} m workspace; positions must be in metres (millimetres? "
                "divide by 1000)"
            )
    speed = float(np.max(np.linalg.norm(wrist_vel, axis=1)))
    if speed > WRIST_SPEED_MAX_MPS:
        raise DemoError(
            f"demo file {path}: the wrist moves at up to {speed:g} m/s, faster than "
            f"{WRIST_SPEED_MAX_MPS:g} m/s; check that time_s is in seconds and positions in "
            "metres"
        )


def _resample(t: np.ndarray, ts: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t, ts, v) for v in values.T], axis=1)


def write_demo_csv(
    path: str | Path,
    time_s: np.ndarray,
    wrist_pos: np.ndarray,
    pelvis: np.ndarray,
    pelvis_height: float = 1.0,
) -> None:
    """Write one demonstration in the layout above (wrist orientation identity).

    Args:
        path: Output file (written atomically).
        time_s: (N,) [s].
        wrist_pos: (N, 3) [m].
        pelvis: (N, 3) pelvis (x [m], y [m], yaw [rad]).
        pelvis_height: Pelvis z [m], not learned.
    """
    yaw = pelvis[:, 2]
    lines = [",".join(COLUMNS)]
    for k in range(len(time_s)):
        row = [
            time_s[k],
            *wrist_pos[k],
            1.0,
            0.0,
            0.0,
            0.0,
            pelvis[k, 0],
            pelvis[k, 1],
            pelvis_height,
            np.cos(yaw[k] / 2),
            0.0,
            0.0,
            np.sin(yaw[k] / 2),
        ]
        lines.append(",".join(f"{v:.9g}" for v in row))
    write_text_atomic(path, "\n".join(lines) + "\n")
