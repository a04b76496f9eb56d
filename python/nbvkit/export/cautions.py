"""The stand-off a run's flight keeps from the structure and the ground, as the export states it:
the planner keeps the vehicle's collision sphere (vehicle.collision_radius) off every occupied or
unknown cell of its map, and its centre vehicle.min_altitude (the radius + 0.1 m by default)
above the ground (its paths between views to within half a map cell). The export measures both on
what it writes: the least distance of its waypoints' lines from the structure's mesh (the one
the run flew), and the least height of the run's points. Without RTK, a drone's GNSS and
barometer place it within about 1-2 m; a flight closer than that is a simulation's, not a real
one's."""
from __future__ import annotations

import numpy as np

from .. import _core
from ..mesh import flown_mesh
from ..runfolder import read_summary
from ..workspace import ground_clearance

#: m: the position error of a drone without RTK (GNSS horizontally, the barometer vertically)
#: below which a planned stand-off is warned of
GNSS_ERROR_M = 2.0
#: m: the spacing of the points along the waypoints' lines whose distance from the structure is
#: measured (the least found is within half of it of the lines' least), and the most points: lines
#: longer than their spacing allows (80 km) are measured at a spacing as much wider
SAMPLE_M = 0.02
MAX_SAMPLES = 4_000_000


def clearance(fl, sorties) -> dict:
    """{"structure_m", "structure_point_mesh", "structure_measured", "collision_radius_m",
    "ground_m", "min_altitude_m", "lowest_row"} of a RunFlight `fl` and the `sorties` written:
    the least distance of the sorties' waypoint lines (from each take-off's climb top to its
    return over the launch point) from the structure the run flew, measured, and the point where
    it lies (structure_distance); the least height above the ground (the workspace's floor) of
    the points the run flew, measured, at flight row `lowest_row`; the radius and the height the
    planner keeps (vehicle.collision_radius; vehicle.min_altitude, the radius + 0.1 m by default;
    the A* paths between views keep it to within half a map cell)."""
    radius = float(fl.config.vehicle.collision_radius)
    planned = float(ground_clearance(fl.config.vehicle))
    heights = fl.xyz[:, 2] - float(fl.workspace["bounds_min"][2])
    low = int(np.argmin(heights))
    return {
        **structure_distance(fl, [np.array([w.xyz for w in s.waypoints]) for s in sorties]),
        "collision_radius_m": round(radius, 3),
        "ground_m": round(float(heights[low]), 3),
        "min_altitude_m": round(planned, 3),
        "lowest_row": low,  # (flight.csv's data rows from 0, as a CSV's flight_row)
    }


def structure_distance(fl, lines) -> dict:
    """{"structure_m", "structure_point_mesh", "structure_measured"}: the least distance of the
    polylines `lines` ((P, 3) each) from the mesh the run of `fl` flew (an Embree point query at
    points SAMPLE_M apart along them: within SAMPLE_M / 2 of the lines' own) and the point of
    them where it lies; where that mesh cannot be had (not found from here, changed since the
    run, given in memory), the collision radius, unmeasured, and "structure_note" says why."""
    mesh, why = flown_mesh(fl.config, read_summary(fl.run_dir))
    if mesh is None:
        radius = round(float(fl.config.vehicle.collision_radius), 3)
        return {
            "structure_m": radius,
            "structure_point_mesh": None,
            "structure_measured": False,
            "structure_note": f"{why}: structure_m is the planned collision radius",
        }
    scene = _core.RaycastScene(mesh)
    corners = np.vstack(lines)
    bound = float(scene.distances(corners).min())  # the lines' least is at most their corners'
    length = sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in lines)
    spacing = max(SAMPLE_M, length / MAX_SAMPLES)  # (a far-off row: not 1e10 points)
    pts = np.vstack([corners, *(_along(p, spacing) for p in lines)])
    d = scene.distances(pts, bound)
    i = int(np.argmin(d))
    return {
        "structure_m": round(float(d[i]), 3),
        "structure_point_mesh": [round(float(v), 3) for v in pts[i]],
        "structure_measured": True,
    }


def _along(line, spacing: float) -> np.ndarray:
    """Points `spacing` apart at most along the polyline `line` (P, 3), its corners among them."""
    a, b = line[:-1], line[1:]
    n = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / spacing)).astype(int)
    seg = np.repeat(np.arange(len(a)), n)
    t = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return a[seg] + (b - a)[seg] * t[:, None]


def clearance_warnings(c: dict, cell: float) -> list:
    """The export's warnings where clearance `c` is within GNSS_ERROR_M; where the flight passed
    nearer the structure than its collision radius by more than half a map cell's diagonal (the
    planner keeps the sphere off cells, and a cell's surface may lie that far beyond its centre);
    where it passed below the height its views keep by more than half a map cell of `cell` m
    (what the A* paths between views may: they keep the height with their cells' tops); and where
    the structure's distance could not be measured."""
    out = (
        []
        if c["structure_measured"]
        else [f"the flight's distance from the structure was not measured: {c['structure_note']}"]
    )
    where = c["structure_point_mesh"]
    if (
        c["structure_measured"]
        and c["structure_m"] < c["collision_radius_m"] - cell * 0.866 - 0.005
    ):
        out.append(
            f"the flight passes {c['structure_m']:g} m from the structure (at {where} in the "
            f"mesh's frame), nearer than its {c['collision_radius_m']:g} m collision radius"
        )
    if c["ground_m"] < c["min_altitude_m"] - cell / 2 - 0.005:
        out.append(
            f"the flight passes {c['ground_m']:g} m above the ground (at flight row "
            f"{c['lowest_row']}), below the {c['min_altitude_m']:g} m its views keep "
            "(vehicle.min_altitude; its paths between views keep it to within half a map cell)"
        )
    # measured: with the map's allowance (a flight planned 2 m off passes 1.999 m off at its
    # nearest: as planned); else the radius planned
    near = c["structure_m"] + (cell * 0.866 + 0.005 if c["structure_measured"] else 0.0)
    if min(near, c["ground_m"]) >= GNSS_ERROR_M:
        return out
    verb = "passes" if c["structure_measured"] else "was planned"
    return out + [
        f"the flight {verb} {c['structure_m']:g} m from the structure at its nearest "
        f"(vehicle.collision_radius {c['collision_radius_m']:g} m) and flies {c['ground_m']:g} m "
        f"above the ground at its lowest: a drone without RTK is placed within about "
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
