"""A run folder's flight (read_run: flight.csv, summary.json, config.yaml, map.ot), for the
flight-time model of nbvkit.flight_time, the launch point and ways home of nbvkit.flight_home
and the sorties of nbvkit.flight (whose names are importable from here too); the names of the
files an export writes, and how it puts them in place (move_into_place).
"""
from __future__ import annotations

import csv
import json
import os
import re
import shutil
from pathlib import Path

from ..flight import Sortie, SortiePlanner, Waypoint, simplify, sortie_planner  # noqa: F401
from ..flight_home import ReturnPaths, find_launch, load_map  # noqa: F401  (re-exported)
from ..flight_rows import RunFlight, flight_arrays, run_flight
from ..flight_time import FRAME, VIEW, FlightModel  # noqa: F401  (re-exported)
from ..limits import check_input_file
from ..runfolder import read_summary, run_workspace


def read_run(run_dir) -> RunFlight:
    """Reads a run folder (flight.csv, summary.json, config.yaml; map.ot if there).
    FileNotFoundError naming what is missing; ValueError for an unreadable flight."""
    from ..config import load_config

    run = Path(run_dir).expanduser()
    if not run.is_dir():
        raise FileNotFoundError(f"run folder {run} does not exist")
    for name in ("flight.csv", "summary.json", "config.yaml", "map.ot"):
        if os.path.lexists(run / name):  # a FIFO, a device, a folder: said so, not "not found"
            check_input_file(run / name, f"run file {name}")
    flight = run / "flight.csv"
    if not flight.is_file():
        extra = (
            " (its trajectory.csv holds only the legs' ends: a run made before nbvkit recorded "
            "every point flown; fly it again)"
            if (run / "trajectory.csv").is_file()
            else ""
        )
        raise FileNotFoundError(f"no trajectory in {run}: {flight} not found{extra}")
    for name in ("summary.json", "config.yaml"):
        if not (run / name).is_file():
            raise FileNotFoundError(f"{run / name} not found (a run folder of `nbvkit run`?)")
    try:
        with open(flight, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (csv.Error, UnicodeDecodeError) as e:  # a damaged file (same size: manifest passes)
        raise ValueError(f"{flight} is damaged, not a flight table ({e}); fly the run again")
    need = ("stage", "x", "y", "z", "yaw", "capture")
    if not rows or any(k not in rows[0] for k in need):
        raise ValueError(f"{flight}: expected a header with {', '.join(need)} and at least one row")
    try:
        arrays = flight_arrays(rows)
    except ValueError as e:
        raise ValueError(f"{flight}: {e}") from None
    ws = run_workspace(read_summary(run), run / "summary.json")
    cfg = load_config(run / "config.yaml")
    map_path = run / "map.ot"
    return run_flight(run, rows, ws, cfg, map_path if map_path.is_file() else None, arrays)


#: the names of the files an export writes (sortie_names), which the next export into its
#: folder replaces: nothing else is removed there
EXPORT_FILE = re.compile(
    r"(mission|sortie_\d{2,})\.(plan|waypoints|kmz|kml|geojson|csv)|sorties\.csv"
    r"|colmap/(cameras|images|points3D)\.txt"
)


def sortie_names(numbers) -> list:
    """The files' names of sorties `numbers` (1, 2, ...): numbered to one width, two digits at
    least (sortie_01 ... sortie_09; sortie_001 ... sortie_120), so that they list by name in
    flight order (sortie_100 came between sortie_10 and sortie_11)."""
    width = max(2, len(str(max(numbers, default=0))))
    return [f"sortie_{n:0{width}d}" for n in numbers]


def move_into_place(tmp: Path, out: Path, files: list) -> None:
    """Moves the finished export from tmp to out: a rename, or the previous export's files there
    (export.json's list, of EXPORT_FILE's names) removed and the new ones moved in."""
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        os.rename(tmp, out)
        return
    old, previous = out / "export.json", []
    if old.is_file():
        try:
            previous = json.loads(old.read_text()).get("files", [])
        except (ValueError, OSError, AttributeError):  # (not an export's: no list)
            previous = []
        if not (isinstance(previous, list) and all(isinstance(n, str) for n in previous)):
            previous = []  # (names only)
    # a folder an export wrote (its export.json lists itself): the export's names there are an
    # export's, whichever it wrote (one stopped while it moved its files in left new names
    # beside the old list); elsewhere a file of one of them is the user's
    ours = "export.json" in previous
    taken = [
        n
        for n in files
        if os.path.lexists(out / n)
        and n not in previous
        and not (ours and (n == "export.json" or EXPORT_FILE.fullmatch(n)))
    ]
    if taken:
        raise FileExistsError(
            f"{out} holds {', '.join(taken[:3])}{' ...' if len(taken) > 3 else ''}, which no "
            "earlier export wrote there: give another --out, or move them"
        )
    if old.is_file():
        for name in previous:
            p = out / str(name)  # an export's own name, a file within out: not the user's
            if name not in files and EXPORT_FILE.fullmatch(str(name)) and p.is_file():
                if out.resolve() in p.resolve().parents:  # (not through a link out of it)
                    p.unlink()
        if (out / "colmap").is_dir() and not (out / "colmap").is_symlink():
            if not any((out / "colmap").iterdir()):
                (out / "colmap").rmdir()  # (colmap not exported again)
    for name in files:
        dst = out / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp / name, dst)
    shutil.rmtree(tmp, ignore_errors=True)
