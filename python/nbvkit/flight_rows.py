"""The rows of a run's flight.csv read as numbers, each row checked: a file edited or damaged
by hand is refused naming its row, line and column, never exported as a wrong flight; and the
RunFlight they make.

A run folder's ``flight.csv`` (written by Mission.write_results) lists every point the vehicle
flew, in order: the start, the profiling flight, and each leg to a view with the A* waypoints and
in-flight camera frames between (stage, x, y, z, yaw, pitch, capture, distance_m). A RunFlight
comes from a run folder (nbvkit.export.plan.read_run: flight.csv, summary.json, config.yaml) or
from a finished Mission in memory (run_flight: the end-of-run report, written before
summary.json); this module loads no configuration, so the report can use it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import _core
from .flight_time import FRAME, VIEW
from .vehicle import STAGES

__all__ = ["CAPTURES", "FLIGHT_STAGES", "RunFlight", "flight_arrays", "run_flight"]

#: the stages of flight rows: "start" (the first row, World's start pose), then vehicle.STAGES
FLIGHT_STAGES = ("start", *STAGES)
#: the captures of flight rows: none, a counted view, an in-flight frame
CAPTURES = ("", VIEW, FRAME)


def flight_arrays(rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """xyz (N, 3), yaw and pitch (N,) of flight rows (mappings with FLIGHT_COLUMNS' keys, values
    as numbers or their text; no pitch: level). ValueError naming the row (counted from 0 below
    the header, as the export's flight_row; its line in flight.csv) and the column of a row with
    too few or too many fields, a stage not in FLIGHT_STAGES, a capture not in CAPTURES, a value
    that is no finite number, or a pitch outside [-pi/2, pi/2]."""
    values = np.array([_row_values(i, r) for i, r in enumerate(rows)], float).reshape(-1, 5)
    return values[:, :3], values[:, 3], values[:, 4]


def _row_values(i: int, row) -> list:
    """[x, y, z, yaw, pitch] of the flight row `row` (number i), checked (flight_arrays)."""
    where = f"row {i} (line {i + 2})"
    _check_fields(where, row)
    for col, legal in (("stage", FLIGHT_STAGES), ("capture", CAPTURES)):
        if row[col] not in legal:
            expected = ", ".join(repr(v) for v in legal)
            raise ValueError(f"{where}: column {col} is {row[col]!r}, expected one of {expected}")
    out = [_number(where, row, col) for col in ("x", "y", "z", "yaw")]
    for col, v in zip("xyz", out):
        if abs(v) > _core.MAX_COORDINATE:  # (where the ray caster and the map can place it)
            raise ValueError(
                f"{where}: column {col} is {v:g} m, beyond +-{_core.MAX_COORDINATE:g} m"
            )
    pitch = _number(where, row, "pitch") if row.get("pitch") not in (None, "") else 0.0
    if abs(pitch) > math.pi / 2:
        raise ValueError(
            f"{where}: column pitch is {pitch:g} rad, outside the gimbal's [-pi/2, pi/2]"
        )
    return [*out, pitch]


def _check_fields(where: str, row) -> None:
    """ValueError unless the row has one value per column (csv.DictReader gives a short row's
    missing columns None and a long row's extra fields under the key None)."""
    columns = [k for k in row if k is not None]
    extra = row.get(None) or []
    missing = [k for k in columns if row[k] is None]
    if extra or missing:
        n = len(columns) - len(missing) + len(extra)
        what = f"no {', '.join(missing)}" if missing else "fields beyond the last column"
        raise ValueError(f"{where} has {n} fields, its header {len(columns)} ({what})")


def _number(where: str, row, col: str) -> float:
    """The finite number in the row's column `col`; ValueError naming both otherwise."""
    try:
        v = float(row[col])
    except (TypeError, ValueError):
        v = None
    if v is None or not math.isfinite(v):
        raise ValueError(f"{where}: column {col} is {row[col]!r}, not a finite number")
    return v


@dataclass
class RunFlight:
    """The flight of a run folder: rows (N, 3) xyz, yaw and pitch (N,) radians, stage and capture
    (N,) strings; home (3,): the launch point on the ground (find_launch); radius: the
    vehicle's collision radius; config: the run's Config; map_path: its map.ot (or None)."""

    run_dir: Path
    xyz: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    stage: list
    capture: list
    home: np.ndarray
    radius: float
    config: object
    map_path: Path | None
    workspace: dict
    launch: np.ndarray | None = None  # top of the take-off climb (find_launch)
    launch_path: np.ndarray | None = None  # (P, 3) launch -> start through known free space

    @property
    def start(self) -> np.ndarray:
        return self.xyz[0]

    def views(self) -> np.ndarray:
        return np.array([i for i, c in enumerate(self.capture) if c == VIEW], int)


def run_flight(run_dir, rows, workspace: dict, config, map_path=None, arrays=None) -> RunFlight:
    """The RunFlight of a run from its flight rows (flight.csv's, or a Mission's
    ``world.state.flight`` as mappings), its workspace (summary.json's "workspace": the ground is
    its floor) and its Config; map_path: its map.ot or None; arrays: flight_arrays(rows) when
    already read."""
    if not len(rows):
        raise ValueError("the run flew no point")
    xyz, yaw, pitch = flight_arrays(rows) if arrays is None else arrays
    if "bounds_min" not in workspace:
        raise ValueError("the run's workspace has no bounds")
    ground = float(workspace["bounds_min"][2])
    home = np.array([xyz[0, 0], xyz[0, 1], ground])
    return RunFlight(
        Path(run_dir),
        xyz,
        yaw,
        pitch,
        [r["stage"] for r in rows],
        [r["capture"] for r in rows],
        home,
        float(config.vehicle.collision_radius),
        config,
        map_path,
        workspace,
    )
