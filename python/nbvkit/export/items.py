"""Mission items: how many a MAVLink file's upload holds, how many an autopilot keeps, and a
sortie's count before it is written (``nbvkit export --max-items``)."""
from __future__ import annotations

import json
from pathlib import Path

from . import writers
from ..limits import is_number

#: The mission items an autopilot keeps: PX4 on NuttX boards (NUM_MISSIONS_SUPPORTED, its
#: navigator's navigation.h), ArduPilot on a Pixhawk 1 (its StorageManager: "718 waypoints",
#: home the first of them; boards with more storage keep more).
MAX_MISSION_ITEMS = {".plan": ("PX4", 2000), ".waypoints": ("ArduPilot on a Pixhawk 1", 718)}

#: The fewest items a sortie's file can hold: take-off, two speed changes, a view's five (gimbal,
#: heading, waypoint, photo, rest), the way home (a waypoint and its heading), return to launch,
#: and ArduPilot's home.
MIN_ITEMS = 12


def mission_items(folder: Path, files) -> dict:
    """file -> the mission items its upload holds, of each MAVLink file among `files`: a
    .plan's items (PX4 keeps home apart), a .waypoints' lines after its header (the home line
    included: ArduPilot uploads and stores home as item 0)."""
    out = {}
    for name in files:
        path = Path(folder) / name
        if path.suffix == ".plan":
            out[name] = len(json.loads(path.read_text())["mission"]["items"])
        elif path.suffix == ".waypoints":
            out[name] = len(path.read_text().splitlines()) - 1  # the header
    return out


def sortie_items(g: writers.GeoWaypoints) -> int:
    """The items of the larger of a sortie's two MAVLink files, as mission_items counts them
    once written (the .plan's, the .waypoints' with home)."""
    return max(len(writers.mavlink_items(g)), len(writers.mavlink_items(g, ardupilot=True)) + 1)


def check_max_items(max_items) -> int | None:
    """max_items as an int (None: no limit); ValueError naming it when it is not a whole number
    of at least MIN_ITEMS."""
    if max_items is None:
        return None
    if not is_number(max_items):
        raise ValueError(f"max_items must be a whole number, got {max_items!r}")
    if not float(max_items).is_integer():
        raise ValueError(f"max_items must be a whole number, got {max_items!r}")
    if int(max_items) < MIN_ITEMS:
        raise ValueError(
            f"max_items must be at least {MIN_ITEMS} (a sortie's own items and one view's), "
            f"got {max_items!r}"
        )
    return int(max_items)


def item_warnings(items: dict) -> list:
    """The export's warnings on `items` (mission_items): each MAVLink file with more mission
    items than its autopilot keeps (MAX_MISSION_ITEMS), the upload would be refused."""
    out = []
    for suffix, (who, limit) in MAX_MISSION_ITEMS.items():
        over = {n: k for n, k in items.items() if n.endswith(suffix) and k > limit}
        if over:
            worst = max(over, key=over.get)
            out.append(
                f"{len(over)} of {sum(n.endswith(suffix) for n in items)} {suffix} files hold "
                f"more mission items than {who} keeps ({limit:,}; {worst}: {over[worst]:,}): "
                f"its upload fails there. Split the flight (--max-items {limit}, or a shorter "
                "--flight-time), or fly a run with fewer in-flight frames (planner.frame_step, "
                "profiling.camera_step)"
            )
    return out
