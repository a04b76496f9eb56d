"""The stand-off a run's flight keeps from the structure and the ground, as the export states it:
the planner keeps the vehicle's collision sphere (vehicle.collision_radius) off every occupied or
unknown cell, and its centre vehicle.min_altitude (the radius + 0.1 m by default) above the
ground (its paths between views to within half a map cell), so a flown point may lie that close
to the surface. Without RTK, a drone's GNSS and barometer place it within about 1-2 m; a flight
planned closer than that is a simulation's, not a real one's."""
from __future__ import annotations

import numpy as np

from ..workspace import ground_clearance

#: m: the position error of a drone without RTK (GNSS horizontally, the barometer vertically)
#: below which a planned stand-off is warned of
GNSS_ERROR_M = 2.0


def clearance(fl) -> dict:
    """{"structure_m", "ground_m", "min_altitude_m", "lowest_row"} of a RunFlight `fl`: the least
    distance its flight keeps from the structure (its collision radius), the least height above
    the ground (the workspace's floor) of the points it flew, measured, at flight row
    `lowest_row`, and the height its views keep (vehicle.min_altitude, the radius + 0.1 m by
    default; the A* paths between them keep it to within half a map cell)."""
    radius = float(fl.config.vehicle.collision_radius)
    planned = float(ground_clearance(fl.config.vehicle))
    heights = fl.xyz[:, 2] - float(fl.workspace["bounds_min"][2])
    low = int(np.argmin(heights))
    return {
        "structure_m": round(radius, 3),
        "ground_m": round(float(heights[low]), 3),
        "min_altitude_m": round(planned, 3),
        "lowest_row": low,  # (flight.csv's data rows from 0, as a CSV's flight_row)
    }


def clearance_warnings(c: dict, cell: float) -> list:
    """The export's warnings where clearance `c` is within GNSS_ERROR_M, and where the flight
    passed below the height its views keep by more than half a map cell of `cell` m (what the
    A* paths between views may: they keep the height with their cells' tops)."""
    out = []
    if c["ground_m"] < c["min_altitude_m"] - cell / 2 - 0.005:
        out.append(
            f"the flight passes {c['ground_m']:g} m above the ground (at flight row "
            f"{c['lowest_row']}), below the {c['min_altitude_m']:g} m its views keep "
            "(vehicle.min_altitude; its paths between views keep it to within half a map cell)"
        )
    if min(c["structure_m"], c["ground_m"]) >= GNSS_ERROR_M:
        return out
    return out + [
        f"the run was planned {c['structure_m']:g} m from the structure "
        f"(vehicle.collision_radius) and flies {c['ground_m']:g} m above the ground at its "
        f"lowest: a drone without RTK is placed within about "
        f"{GNSS_ERROR_M:g} m. Fly it with RTK positioning and obstacle sensing on, or fly the "
        f"run again with --set vehicle.collision_radius={GNSS_ERROR_M:g} (and "
        f"vehicle.min_altitude) for a flight that keeps clear"
    ]


def left_out_warnings(unreachable: list) -> list:
    """The captures a sortie split left out (export_mission's unreachable): a warning, for a
    mission that does not take every photo the run planned is not the run's coverage."""
    if not unreachable:
        return []
    n = len(unreachable)
    views, frames = (sum(u["capture"] == c for u in unreachable) for c in ("view", "frame"))
    return [
        f"{n} point{'s' if n > 1 else ''} of the flight ({views} view{'' if views == 1 else 's'}"
        f", {frames} frame{'' if frames == 1 else 's'} in flight) left out of every sortie: a "
        "battery (--flight-time) or --max-items too small for them (export.json: unreachable)"
    ]
