"""The rows of a run's flight.csv read as numbers, each row checked: a file edited or damaged
by hand is refused naming its row, line and column, never exported as a wrong flight."""
from __future__ import annotations

import math

import numpy as np

from .flight_time import FRAME, VIEW
from .vehicle import STAGES

__all__ = ["CAPTURES", "FLIGHT_STAGES", "flight_arrays"]

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
