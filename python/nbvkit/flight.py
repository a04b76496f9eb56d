"""What a run flew, how long it takes, and its split into one flight per battery.

A run folder's ``flight.csv`` (written by Mission.write_results) lists every point the vehicle
flew, in order: the start, the profiling flight, and each leg to a view with the A* waypoints and
in-flight camera frames between (stage, x, y, z, yaw, pitch, capture, distance_m). The simulated
vehicle starts in the air at the start pose; the real one takes off from the launch point (home)
on the ground below it (the workspace floor, summary.json) and climbs straight up to it, and
lands there again.

Flight-time model (FlightModel) and the waits at each capture (capture_waits): nbvkit.flight_time.

Sorties (split_sorties): each starts and ends at home within budget * (1 - reserve). A sortie
resumes where the last one stopped: at the first point of the flight that is still to be
flown and counts - a view, an in-flight frame, or a point of the profiling flight (the laser
sweeps along all of it); the transit waypoints of a leg to a view are not flown again, the
sortie flies out to the view directly. The way out to a point and back from it is the cheapest
of (a) an A* path (nbvkit's ``plan_path``, the vehicle's collision radius) through the known free
space of the run's final map (map.ot) between the point and the start pose, and (b) the flight
itself flown backwards to an earlier point and (a) or (b) from there: both stay in space the
simulation flew or knew free. A point whose way out, hover and way back alone do not fit in one
battery is reported (``unreachable``), not dropped silently.

A RunFlight comes from a run folder (nbvkit.export.plan.read_run: flight.csv, summary.json,
config.yaml) or from a finished Mission in memory (run_flight: the end-of-run report, written
before summary.json); this module loads no configuration, so the report can use it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .flight_rows import flight_arrays
from .flight_time import FRAME, TARGETS, VIEW, FlightModel, capture_waits, waits_s


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


def load_map(fl: RunFlight):
    """The run's final OccupancyMap (map.ot in its workspace), or None without one."""
    if fl.map_path is None:
        return None
    from . import _core

    ws = fl.workspace
    return _core.OccupancyMap.load(
        str(fl.map_path), ws["bounds_min"], ws["bounds_max"], options=fl.config.map.options()
    )


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
    step = max(occ_map.resolution, 0.5)
    reach = float(np.max(nav_hi[:2] - nav_lo[:2]))
    for r in np.arange(step, reach + step, step):
        n = max(8, int(math.ceil(2 * math.pi * r / step)))
        for t in np.arange(n) * (2 * math.pi / n):
            q = np.array([s[0] + r * math.cos(t), s[1] + r * math.sin(t), s[2]])
            if np.any(q[:2] < nav_lo[:2]) or np.any(q[:2] > nav_hi[:2]):
                continue
            if not _column_clear(fl, occ_map, q[0], q[1], q[2]):
                continue
            path = _core.plan_path(occ_map, q, s, fl.radius)
            if len(path) >= 2:
                fl.launch, fl.launch_path = q, np.asarray(path, float)
                fl.home = np.array([q[0], q[1], fl.home[2]])
                return
    raise ValueError(
        f"no launch point: the climb from the ground below the start {np.round(s, 2).tolist()} "
        "meets the structure, and no point of the workspace floor has a clear climb and a "
        "known-free way to the start"
    )


class ReturnPaths:
    """For each point of the flight, the cheapest known-safe way back to the start (see the
    module's docstring): its time (s) and its points (first = the point, last = the start).

    The A* ways back of all targets come from one search out from the start
    (nbvkit.plan_paths_to: what an A* search from each finds), which expands at most what the
    run's capped A* searches (vehicle.path_expansions cells) from each would have together."""

    def __init__(self, fl: RunFlight, model: FlightModel, occ_map, targets):
        n = len(fl.xyz)
        self.fl, self.model = fl, model
        leg = np.concatenate([[0.0], model.leg_times(fl.xyz)])
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
    the map, on a wide profiling circle, has none)."""
    from . import _core

    if not points:
        return []
    xyz = fl.xyz[points]
    at_start = np.all(np.isclose(xyz, fl.start), axis=1)
    ask = np.flatnonzero(~at_start)
    out = [fl.start[None, :] if s else np.zeros((0, 3)) for s in at_start]
    if len(ask):
        cap = int(fl.config.vehicle.path_expansions) * len(ask)
        found = _core.plan_paths_to(occ_map, xyz[ask], fl.start, fl.radius, max_expansions=cap)
        for k, path in zip(ask, found.paths):
            out[k] = np.asarray(path, float) if len(path) >= 2 else np.zeros((0, 3))
    return out


@dataclass
class Waypoint:
    """A point of an exported flight, in the mesh frame: xyz, the vehicle's yaw (rad), the
    camera's pitch (rad, the row's own; 0 = level), what happens there (action: "takeoff" - the
    climb from home ends here, "waypoint" - a flown point, "view" - a counted view is taken,
    "frame" - an in-flight camera frame, "transit" - on the way out to or back from the flight,
    "home" - back above the launch point), the flight row (-1 for none) and the stage."""

    xyz: np.ndarray
    yaw: float
    pitch: float
    action: str
    row: int
    stage: str


def simplify(wps: list, tol: float = 1e-3) -> list:
    """The waypoints without the plain ones ("waypoint", "transit": no capture) that lie within
    `tol` (m) of the straight line between their neighbours and have the next kept point's yaw
    and pitch: the same path and headings in fewer items (the profile's sweep is flown, and
    retraced out and back, in steps of a few centimetres)."""
    if len(wps) < 3:
        return list(wps)
    keep = [wps[0]]
    run = []  # positions dropped since the last kept point
    for k in range(1, len(wps) - 1):
        w, nxt = wps[k], wps[k + 1]
        droppable = (
            w.action in ("waypoint", "transit")
            and abs(w.yaw - nxt.yaw) < 1e-12
            and abs(w.pitch - nxt.pitch) < 1e-12
            and _off_segment(np.array([*run, w.xyz]), keep[-1].xyz, nxt.xyz).max() <= tol
        )
        if droppable:
            run.append(w.xyz)
        else:
            keep.append(w)
            run = []
    keep.append(wps[-1])
    return keep


def _off_segment(p: np.ndarray, a, b) -> np.ndarray:
    """(N,) distances (m) of the points p (N, 3) from the segment a-b."""
    ab = b - a
    n = float(ab @ ab)
    t = np.zeros(len(p)) if n == 0 else np.clip((p - a) @ ab / n, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


@dataclass
class Sortie:
    """One flight from home and back: its waypoints (take-off first, "home" last: the vehicle
    then lands at the launch point), the flight rows it flies (first..last), and its estimates."""

    number: int
    waypoints: list
    first_row: int
    last_row: int
    views: int = 0
    frames: int = 0
    distance_m: float = 0.0
    time_s: float = 0.0
    legs: dict = field(default_factory=dict)
    #: the seconds of the sortie in each mission file (TARGETS); time_s is the longest
    times: dict = field(default_factory=dict)
    #: capture_waits of its waypoints: the holds, rests and turns the writers write
    waits: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "sortie": self.number,
            "views": self.views,
            "frames": self.frames,
            "first_row": self.first_row,
            "last_row": self.last_row,
            "waypoints": len(self.waypoints),
            "distance_m": round(self.distance_m, 3),
            "time_s": round(self.time_s, 1),
            "time_min": round(self.time_s / 60.0, 2),
            **{k: round(v, 1) for k, v in self.legs.items()},
            "time_s_by_file": {k: round(v, 1) for k, v in self.times.items()},
        }


class SortiePlanner:
    """Builds sorties over a RunFlight with a FlightModel and return paths (ReturnPaths)."""

    def __init__(self, fl: RunFlight, model: FlightModel, returns: ReturnPaths):
        self.fl, self.model, self.returns = fl, model, returns
        leg = np.concatenate([[0.0], model.leg_times(fl.xyz)])
        self.cum = np.cumsum(leg)  # s from row 0 along the flight
        # an estimate of each capture's longest wait (capture_waits over the flight's rows: the
        # turn from the previous row), and first: the same after a transit leg (a sortie's first
        # row); split() checks each sortie against the waits of its own waypoints
        deg = np.degrees(fl.yaw)
        acts = [c or "waypoint" for c in fl.capture]
        self.wait_row = self._longest(capture_waits(acts, deg, model.hover_s))
        self.wait_first = np.zeros(len(acts))
        for i, c in enumerate(fl.capture):
            if c:
                w = capture_waits(["transit", c], [0.0, deg[i]], model.hover_s)
                self.wait_first[i] = self._longest(w)[1]
        self.cum_wait = np.cumsum(self.wait_row)
        if fl.launch is None:
            fl.launch, fl.launch_path = fl.start.copy(), fl.start[None, :].copy()
        #: seconds from the ground to the start (climb, then the way over) and back
        self.climb_s = float(abs(fl.launch[2] - fl.home[2]) / model.climb_rate)
        self.climb_s += model.path_time(fl.launch_path)
        self.work = self.work_rows(fl)

    @staticmethod
    def _longest(waits: dict) -> np.ndarray:
        """(N,) the longest of the mission files' waits at each waypoint."""
        return np.max([sum(waits[t]) for t in TARGETS], axis=0)

    @staticmethod
    def work_rows(fl: RunFlight) -> np.ndarray:
        """The rows a sortie must fly (it may not skip them): the start, the profiling flight,
        the captures."""
        n = len(fl.xyz)
        return np.array(
            [i for i in range(n) if i == 0 or fl.stage[i] == "profile" or fl.capture[i]], int
        )

    def fly_s(self, r: int, e: int, back: bool = True) -> float:
        """Seconds a sortie flying rows r..e is in the air, its captures' waits left out: the
        climb and the descent, the way out to row r, along the flight to row e and (back) the
        way back from it; without the way back a bound that only grows with e (split's stop)."""
        s = 2 * self.climb_s + self.returns.cost[r] + self.cum[e] - self.cum[r]
        return s + self.returns.cost[e] if back else s

    def cost(self, r: int, e: int) -> float:
        """Estimated seconds of a sortie flying rows r..e: fly_s and the captures' waits (the
        sortie itself counts the waits of its own waypoints)."""
        return self.fly_s(r, e) + self.wait_first[r] + self.cum_wait[e] - self.cum_wait[r]

    def sortie(self, number: int, r: int, e: int) -> Sortie:
        fl = self.fl
        wps = [Waypoint(fl.launch.copy(), float(fl.yaw[r]), 0.0, "takeoff", -1, "takeoff")]
        for p in fl.launch_path[1:]:  # from the top of the climb to the start
            wps.append(Waypoint(p, float(fl.yaw[r]), 0.0, "transit", -1, "out"))
        if r > 0:  # out to row r: its way back, reversed (without the start and the row)
            for p in self.returns.path(r)[::-1][1:-1]:
                wps.append(Waypoint(p, float(fl.yaw[r]), 0.0, "transit", -1, "out"))
        for i in range(r, e + 1):
            if i == 0 and not fl.capture[0]:
                continue  # the start: the take-off point itself
            wps.append(
                Waypoint(
                    fl.xyz[i].copy(),
                    float(fl.yaw[i]),
                    float(fl.pitch[i]),
                    fl.capture[i] or "waypoint",
                    i,
                    fl.stage[i],
                )
            )
        back = [*self.returns.path(e)[1:], *fl.launch_path[::-1][1:]]
        if e > 0 or fl.capture[0] or len(fl.launch_path) > 1:
            for p in back[:-1]:
                wps.append(Waypoint(p, float(fl.yaw[e]), 0.0, "transit", -1, "back"))
            wps.append(Waypoint(fl.launch.copy(), float(fl.yaw[e]), 0.0, "home", -1, "back"))
        wps = simplify(wps)
        pts = np.array([fl.home, *[w.xyz for w in wps], fl.home])
        s = Sortie(number, wps, r, e)
        s.views = sum(1 for i in range(r, e + 1) if fl.capture[i] == VIEW)
        s.frames = sum(1 for i in range(r, e + 1) if fl.capture[i] == FRAME)
        s.distance_m = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        # the waits the mission files write at these waypoints (the same function as theirs)
        s.waits = capture_waits(
            [w.action for w in wps], [math.degrees(w.yaw) for w in wps], self.model.hover_s
        )
        waits = waits_s(s.waits)
        fly = self.fly_s(r, e)
        s.times = {t: fly + waits[t] for t in TARGETS}
        s.time_s = max(s.times.values())
        s.legs = {
            "out_s": self.climb_s + self.returns.cost[r],
            "along_s": self.cum[e] - self.cum[r] + max(waits.values()),
            "back_s": self.returns.cost[e] + self.climb_s,
        }
        return s

    def whole(self) -> Sortie:
        """The whole mission in one flight (no battery limit)."""
        return self.sortie(1, 0, int(self.work[-1]))

    def split(self, usable_s: float, fits=None):
        """(sorties, unreachable): sorties within usable_s seconds each (math.inf: no limit) for
        which fits(sortie) holds (None: any), and the rows no sortie can fly (dicts: row,
        capture, stage, needed_s; reason: "flight time" or "fits", the limit it broke)."""
        sorties, unreachable = [], []
        k = 0  # index into work: the next row to fly
        while k < len(self.work):
            j, s = self._sortie_from(k, len(sorties) + 1, usable_s, fits)
            if j is None:  # no sortie from this row fits: it is left out, the next one tried
                r = int(self.work[k])
                where = {"row": r, "capture": self.fl.capture[r], "stage": self.fl.stage[r]}
                reason = "flight time" if s.time_s > usable_s + 1e-9 else "fits"
                unreachable.append({**where, "needed_s": round(s.time_s, 1), "reason": reason})
                k += 1
                continue
            sorties.append(s)
            k = j + 1
        return sorties, unreachable

    def _sortie_from(self, k: int, number: int, usable_s: float, fits=None):
        """(j, sortie `number` flying work[k..j]): the longest from work[k] within usable_s (and
        fits); or (None, the shortest one, what it needs) when none fits."""
        work, r = self.work, int(self.work[k])
        best = k
        for j in range(k, len(work)):
            e = int(work[j])
            if self.fly_s(r, e, back=False) > usable_s:
                break  # the way along alone is too long from here on
            if self.cost(r, e) <= usable_s:
                best = j

        def ok(j: int):
            s = self.sortie(number, r, int(work[j]))
            return s.time_s <= usable_s + 1e-9 and (fits is None or fits(s)), s

        # the sortie's own waits (its waypoints' turns) may pass the estimate: fly less, one
        # row at a time; with fits, gallop from work[k] (each try costs about what the sortie
        # found will), then halve
        if fits is None:
            good, s = ok(best)
            while not good and best > k:
                best -= 1
                good, s = ok(best)
            return (best if good else None), s
        good, s = ok(k)
        if not good:
            return None, s
        lo, hi, step = k, best + 1, 1  # lo fits; hi does not, or is past best
        while lo + step < hi:
            g, s_next = ok(lo + step)
            if not g:
                hi = lo + step
                break
            lo, s, step = lo + step, s_next, 2 * step
        while hi - lo > 1:
            mid = (lo + hi) // 2
            g, s_mid = ok(mid)
            lo, hi, s = (mid, hi, s_mid) if g else (lo, mid, s)
        return lo, s


def sortie_planner(fl: RunFlight, model: FlightModel, need_all_returns: bool, occ_map=None):
    """A SortiePlanner over the flight fl (its launch point found): occ_map, the run's final
    OccupancyMap (default: read from its map.ot); with need_all_returns the ways back from every
    capture a sortie may end at (a battery budget), else from the last row only."""
    occ = load_map(fl) if occ_map is None else occ_map
    find_launch(fl, occ, model)
    # A* ways back from the captures a sortie may end at (the profile's other points go back
    # along the profile to one); without a budget only the last row's way back matters
    work = SortiePlanner.work_rows(fl)
    caps = [i for i in work if fl.capture[i]]
    targets = [*caps, work[-1]] if need_all_returns else work[-1:]
    returns = ReturnPaths(fl, model, occ, targets)
    return SortiePlanner(fl, model, returns)


def estimate(fl: RunFlight, model: FlightModel, occ_map=None) -> dict:
    """The whole mission's estimated flight (one battery, no limit): time_s, distance_m, views,
    frames, and the model (speed, climb_rate, hover_s)."""
    s = sortie_planner(fl, model, need_all_returns=False, occ_map=occ_map).whole()
    return {
        "time_s": s.time_s,
        "distance_m": s.distance_m,
        "views": s.views,
        "frames": s.frames,
        "model": {"speed": model.speed, "climb_rate": model.climb_rate, "hover_s": model.hover_s},
    }
