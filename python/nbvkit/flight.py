"""A run's flight split into one flight per battery (sorties), and its whole estimate.

What a run flew: nbvkit.flight_rows (RunFlight, read from flight.csv). The launch point and the
ways home from each point: nbvkit.flight_home. Flight-time model (FlightModel) and the waits at
each capture (capture_waits): nbvkit.flight_time.

Sorties (split_sorties): each starts and ends at home within budget * (1 - reserve). A sortie
resumes where the last one stopped: at the first point of the flight that is still to be
flown and counts - a view, an in-flight frame, or a point of the profiling flight (the laser
sweeps along all of it); the transit waypoints of a leg to a view are not flown again, the
sortie flies out to the view directly. The way out to a point and back from it is the cheapest
known-safe one (flight_home.ReturnPaths: an A* path through the run's final map's known free
space, or the flight itself flown backwards). A point whose way out, hover and way back alone do
not fit in one battery is reported (``unreachable``), not dropped silently.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .flight_home import ReturnPaths, find_launch, load_map
from .flight_rows import RunFlight
from .flight_time import (
    FRAME,
    LINE_TOL_M,
    TARGETS,
    VIEW,
    FlightModel,
    capture_waits,
    off_segment,
    px4_reach_s,
    waits_s,
)


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


def simplify(wps: list, tol: float = LINE_TOL_M) -> list:
    """The waypoints without the plain ones ("waypoint", "transit": no capture) that lie within
    `tol` (m) of the straight line between their neighbours and have the next kept point's yaw
    and pitch: the same path and headings in fewer items (the profile's sweep is flown, and
    retraced out and back, in steps of a few centimetres). A point is dropped when every point
    dropped since the last kept one, and itself, lies within `tol` of the segment from the last
    kept point to the next point (_Run: about linear in the points of a straight run, where
    measuring each run again was quadratic: 62 s of 108,377 waypoints, a building's flight
    estimate flown 310 m above the ground, in centimetre steps)."""
    if len(wps) < 3:
        return list(wps)
    keep = [wps[0]]
    run = _Run()  # positions dropped since the last kept point
    for k in range(1, len(wps) - 1):
        w, nxt = wps[k], wps[k + 1]
        if plain_as_next(w, nxt) and run.within(w.xyz, keep[-1].xyz, nxt.xyz, tol):
            run.add(w.xyz)
        else:
            keep.append(w)
            run = _Run()
    keep.append(wps[-1])
    return keep


def plain_as_next(w: Waypoint, nxt: Waypoint) -> bool:
    """Whether w captures nothing ("waypoint", "transit") and has the next point's yaw and
    pitch: simplify may drop it where it lies on the line."""
    return (
        w.action in ("waypoint", "transit")
        and abs(w.yaw - nxt.yaw) < 1e-12
        and abs(w.pitch - nxt.pitch) < 1e-12
    )


class _Run:
    """The points dropped since the last kept waypoint, and a bound on their distance from the
    segment they were last measured against. Each was within that bound of the segment a-w (a
    the last kept point, w the point dropped last, as the next point when they were measured),
    and every point of a-w lies within |w, a-b| of a segment a-b (the distance to a segment is
    convex along a-w and 0 at a): so the bound plus |w, a-b| bounds their distance from a-b.
    Only when that sum is not clearly within tol are the points measured again, exactly."""

    def __init__(self):
        self.pts = np.empty((16, 3))
        self.n = 0
        self.bound = 0.0  # the points' largest distance from a-w, at most

    def within(self, w, a, b, tol: float) -> bool:
        """Whether the points and w all lie within tol of the segment a-b."""
        step = float(off_segment(np.asarray(w, float)[None], a, b)[0])
        if self.n and self.bound + step <= tol - 1e-9:  # clearly within, as measured exactly
            self.bound += step
            return True
        d = max(step, float(off_segment(self.pts[: self.n], a, b).max())) if self.n else step
        self.bound = d
        return d <= tol

    def add(self, p) -> None:
        """Adds a point found within: the next segment's w."""
        if self.n == len(self.pts):
            self.pts = np.concatenate([self.pts, np.empty_like(self.pts)])
        self.pts[self.n] = p
        self.n += 1


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

    def __init__(self, fl: RunFlight, model: FlightModel, returns: ReturnPaths, files=TARGETS):
        self.fl, self.model, self.returns = fl, model, returns
        self.files = tuple(files)  # the mission files (TARGETS) timed: the slowest is the time
        self.cum = np.cumsum(returns.leg)  # s from row 0 along the flight (an estimate: sortie())
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
        #: each file's (take-off, landing) seconds (FlightModel.ends_s)
        self.ends = model.ends_s(float(fl.launch[2] - fl.home[2]))
        #: seconds from the ground to the start (climb, then the way over) and back, the
        #: longest file's
        self.ends_total_s = max(sum(self.ends[t]) for t in self.files)
        self.ends_total_s += 2 * model.path_time(fl.launch_path)
        self.work = self.work_rows(fl)

    def _longest(self, waits: dict) -> np.ndarray:
        """(N,) the longest of the timed mission files' waits at each waypoint."""
        return np.max([sum(waits[t]) for t in self.files], axis=0)

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
        s = self.ends_total_s + self.returns.cost[r] + self.cum[e] - self.cum[r]
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
        legs = np.diff(pts, axis=0)
        s.distance_m = float(np.linalg.norm(legs, axis=1).sum())
        # the waits the mission files write at these waypoints (the same function as theirs)
        acts = [w.action for w in wps]
        reach = px4_reach_s(acts, [w.xyz for w in wps], self.model)
        s.waits = capture_waits(acts, [math.degrees(w.yaw) for w in wps], self.model.hover_s, reach)
        waits = waits_s(s.waits)
        # its legs as written: each from a stop to a stop (flight_time's module docstring), but
        # the take-off and the landing, each file's own (self.ends)
        leg = self.model.stop_leg_s(legs)
        leg[0] = leg[-1] = 0.0
        rows = [k for k, w in enumerate(wps) if w.row >= 0] or [len(wps) - 1]
        a, b = rows[0] + 1, rows[-1] + 1  # the first and last flight rows' legs end there
        s.times = {t: float(leg.sum()) + sum(self.ends[t]) + waits[t] for t in self.files}
        s.time_s = max(s.times.values())
        longest = max(self.files, key=s.times.get)
        s.legs = {
            "out_s": float(leg[:a].sum()) + self.ends[longest][0],
            "along_s": float(leg[a:b].sum()) + waits[longest],
            "back_s": float(leg[b:].sum()) + self.ends[longest][1],
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
                break  # the estimated way along alone is too long from here on
            if self.cost(r, e) <= usable_s:
                best = j

        def ok(j: int):
            s = self.sortie(number, r, int(work[j]))
            return s.time_s <= usable_s + 1e-9 and (fits is None or fits(s)), s

        # the sortie's own waits (its waypoints' turns) may pass the estimate: fly less, one
        # row at a time; with fits, from work[k]. The estimate's ways out and back (ReturnPaths:
        # a way back along the flight stops at each of its captures and turns, which the
        # sortie's transit does not) may be longer than the sortie's own, its way out too: then
        # fly more while it fits. Gallop (each try costs about what the sortie found will), then
        # halve.
        hi = len(work)  # lo fits; hi does not, or is past the last row
        if fits is None:
            good, s = ok(best)
            while not good and best > k:
                hi, best = best, best - 1
                good, s = ok(best)
            if not good:
                return None, s
            lo = best
        else:
            good, s = ok(k)
            if not good:
                return None, s
            lo = k
        step = 1
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


def sortie_planner(fl: RunFlight, model, need_all_returns: bool, occ_map=None, files=TARGETS):
    """A SortiePlanner over the flight fl (its launch point found): occ_map, the run's final
    OccupancyMap (default: read from its map.ot); with need_all_returns the ways back from every
    capture a sortie may end at (a battery budget), else from the last row only; `files`: the
    mission files timed (flight_time.timed_files)."""
    occ = load_map(fl) if occ_map is None else occ_map
    find_launch(fl, occ, model)
    # A* ways back from the captures a sortie may end at (the profile's other points go back
    # along the profile to one); without a budget only the last row's way back matters
    work = SortiePlanner.work_rows(fl)
    caps = [i for i in work if fl.capture[i]]
    targets = [*caps, work[-1]] if need_all_returns else work[-1:]
    returns = ReturnPaths(fl, model, occ, targets)
    return SortiePlanner(fl, model, returns, files)


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
