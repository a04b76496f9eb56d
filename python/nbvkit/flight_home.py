"""Where a run's real flight takes off and lands, and the ways home from each of its points.

The simulated vehicle starts in the air at the start pose; the real one takes off from the
launch point (home) on the ground below it (the workspace floor, summary.json), climbs straight
up to it, and lands there again (find_launch). The way back from a point of the flight is the
cheapest of (a) an A* path (nbvkit's ``plan_path``, the vehicle's collision radius, above the
height the views keep) through the known free space of the run's final map (map.ot) between the
point and the start pose, and (b) the flight itself flown backwards to an earlier point and (a)
or (b) from there: both stay in space the simulation flew or knew free (ReturnPaths). The
sorties of nbvkit.flight fly them.
"""
from __future__ import annotations

import math

import numpy as np

from .flight_rows import RunFlight
from .flight_time import FlightModel


def load_map(fl: RunFlight):
    """The run's final OccupancyMap (map.ot in its workspace), or None without one."""
    if fl.map_path is None:
        return None
    from . import _core

    ws = fl.workspace
    return _core.OccupancyMap.load(
        str(fl.map_path), ws["bounds_min"], ws["bounds_max"], options=fl.config.map.options()
    )


def path_floor(fl: RunFlight):
    """The height the run's A* paths kept above (Workspace.path_floor: the navigation space's
    floor), or None for a run folder whose summary has no navigation space."""
    nav_min = fl.workspace.get("nav_min")
    return None if nav_min is None else float(nav_min[2])


def _column_clear(fl: RunFlight, occ_map, x: float, y: float, top: float) -> bool:
    """Whether the vertical line at (x, y) from the ground to `top` stays farther than the
    collision radius from every cell the run's map holds occupied (unknown cells pass: near the
    ground the simulation never looked; the launch site is the user's to check)."""
    ground = fl.home[2]
    res = occ_map.resolution
    n = max(2, int(math.ceil((top - ground) / (0.5 * res))) + 1)
    z = np.linspace(ground, top, n)
    ring = [(0.0, 0.0)] + [
        (fl.radius * math.cos(t), fl.radius * math.sin(t))
        for t in np.linspace(0, 2 * math.pi, 9)[:-1]
    ]
    pts = np.array([[x + dx, y + dy, zz] for zz in z for dx, dy in ring])
    lo, hi = np.asarray(fl.workspace["bounds_min"]), np.asarray(fl.workspace["bounds_max"])
    pts = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
    return not (len(pts) and np.any(occ_map.state(pts) == 1))


def find_launch(fl: RunFlight, occ_map, model: FlightModel) -> None:
    """Sets fl.launch (the top of the take-off climb, at the start's height) and fl.home (the
    launch point on the ground below it) and fl.launch_path (launch -> start).

    The launch point is the ground below the start when the climb there is clear of the
    structure (_column_clear); otherwise the nearest point of the workspace floor, on rings
    round the start, whose climb is clear and from whose top an A* path through the map's known
    free space reaches the start. ValueError when there is none. Without a map: below the
    start."""
    from . import _core

    s = fl.start
    fl.launch, fl.launch_path = s.copy(), s[None, :].copy()
    fl.home = np.array([s[0], s[1], fl.home[2]])
    if occ_map is None or _column_clear(fl, occ_map, s[0], s[1], s[2]):
        return
    nav_lo = np.asarray(fl.workspace.get("nav_min", fl.workspace["bounds_min"]), float)
    nav_hi = np.asarray(fl.workspace.get("nav_max", fl.workspace["bounds_max"]), float)
    step, floor = max(occ_map.resolution, 0.5), path_floor(fl)
    reach = float(np.max(nav_hi[:2] - nav_lo[:2]))
    for r in np.arange(step, reach + step, step):
        n = max(8, int(math.ceil(2 * math.pi * r / step)))
        for t in np.arange(n) * (2 * math.pi / n):
            q = np.array([s[0] + r * math.cos(t), s[1] + r * math.sin(t), s[2]])
            if np.any(q[:2] < nav_lo[:2]) or np.any(q[:2] > nav_hi[:2]):
                continue
            if not _column_clear(fl, occ_map, q[0], q[1], q[2]):
                continue
            path = _core.plan_path(occ_map, q, s, fl.radius, floor=floor)
            if len(path) >= 2:
                fl.launch, fl.launch_path = q, np.asarray(path, float)
                fl.home = np.array([q[0], q[1], fl.home[2]])
                return
    raise ValueError(
        f"no launch point: the climb from the ground below the start {np.round(s, 2).tolist()} "
        "meets the structure, and no point of the workspace floor has a clear climb and a "
        "known-free way to the start"
    )


def stop_rows(fl: RunFlight) -> np.ndarray:
    """(N,) bool: the rows of the flight a written mission stops at besides its corners
    (FlightModel.leg_times): the captures, and the points whose heading or camera pitch is not
    the next point's (nbvkit.flight.simplify keeps them)."""
    yaw, pitch = np.asarray(fl.yaw, float), np.asarray(fl.pitch, float)
    turns = (np.abs(np.diff(yaw)) >= 1e-12) | (np.abs(np.diff(pitch)) >= 1e-12)
    return np.r_[turns, True] | np.array([bool(c) for c in fl.capture], bool)


class ReturnPaths:
    """For each point of the flight, the cheapest known-safe way back to the start (see the
    module's docstring): its time (s) and its points (first = the point, last = the start).

    The A* ways back of all targets come from one search out from the start
    (nbvkit.plan_paths_to: what an A* search from each finds), which expands at most what the
    run's capped A* searches (vehicle.path_expansions cells) from each would have together."""

    def __init__(self, fl: RunFlight, model: FlightModel, occ_map, targets):
        n = len(fl.xyz)
        self.fl, self.model = fl, model
        #: (N,) s of the leg to each point along the flight (0 for the first)
        self.leg = leg = np.concatenate([[0.0], model.leg_times(fl.xyz, stop_rows(fl))])
        self.cost = np.zeros(n)
        self.back = np.full(n, -1)  # previous point along the retrace, or -1: A* (or the start)
        self.astar: dict[int, np.ndarray] = {}
        todo = [] if occ_map is None else sorted({int(t) for t in targets if 1 <= int(t) < n})
        found = dict(zip(todo, _searches(occ_map, fl, todo)))
        for i in range(1, n):  # the retrace to the point before, or the A* way when shorter
            self.cost[i] = leg[i] + self.cost[i - 1]
            self.back[i] = i - 1
            path = found.get(i)
            if path is None or not len(path):
                continue
            t = 0.0 if len(path) == 1 else model.path_time(path)  # 1 point: the start itself
            if len(path) == 1 or t < self.cost[i]:
                self.cost[i], self.back[i] = t, -1
                self.astar[i] = path

    def path(self, i: int) -> np.ndarray:
        """(P, 3) the way back from flight point i to the start (i itself first)."""
        pts = []
        while i > 0 and self.back[i] >= 0:
            pts.append(self.fl.xyz[i])
            i = int(self.back[i])
        if i == 0:
            pts.append(self.fl.xyz[0])
        else:
            pts.extend(self.astar[i])
        return np.asarray(pts, float)


def _searches(occ_map, fl: RunFlight, points: list) -> list:
    """The A* path (P, 3) from each flight point to the start through known free space (the
    start itself: its one point; none: (0, 3)), by one search out from the start (a point outside
    the map, on a wide profiling circle, has none), capped at what the run's A* searches from
    each would expand together; where that cap stops it short (a few points far out: the
    last point alone, without a budget, was flown back along the whole flight, 734 m against
    397 m on the airliner), by an A* search from the point itself under the run's cap."""
    from . import _core

    if not points:
        return []
    xyz = fl.xyz[points]
    at_start = np.all(np.isclose(xyz, fl.start), axis=1)
    ask = np.flatnonzero(~at_start)
    out = [fl.start[None, :] if s else np.zeros((0, 3)) for s in at_start]
    if len(ask):
        each = int(fl.config.vehicle.path_expansions)
        floor = path_floor(fl)
        found = _core.plan_paths_to(
            occ_map, xyz[ask], fl.start, fl.radius, max_expansions=each * len(ask), floor=floor
        )
        for k, path in zip(ask, found.paths):
            if len(path) < 2 and found.capped:  # the search out ran out: A* from the point
                path = _core.plan_path(
                    occ_map, xyz[k], fl.start, fl.radius, max_expansions=each, floor=floor
                )
            out[k] = np.asarray(path, float) if len(path) >= 2 else np.zeros((0, 3))
    return out
