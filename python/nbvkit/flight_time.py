"""The flight-time model of an exported flight (FlightModel) and the waits the written missions
command at each capture (capture_waits), the one place both the time model (nbvkit.flight's
sorties) and the mission writers (nbvkit.export) take them from.

A straight leg between two stops takes the longer of its horizontal and its vertical flight,
each accelerating at a = ACCEL_M_S2 up to its speed limit v (speed; climb_rate up, and down
never faster than DESCENT_M_S, the autopilots' default descent speed), cruising, and braking to
the stop: d / v + v / a, or 2 sqrt(d / a) on a leg too short to reach v (stop_leg_s).
A mission file stops at every waypoint it writes (the DJI route's
toPointAndStopWithDiscontinuityCurvature; ArduPilot and PX4 slow down at each corner and stop
at each hold): the exported sortie is timed so, from its written waypoints. Points along a
straight line are flown through (leg_times: the flight's rows and the ways home, where the
corners, captures and heading changes are the stops). Each capture adds the waits
the written missions command there (capture_waits: the settle, the photo, the rest of `hover_s`,
and in the ArduPilot and DJI files the turn to the capture's heading). A sortie's time is that of
the format that waits longest (the .waypoints file as a rule); the times per format are reported
too. The take-off and the landing at each end of a sortie are each file's own (ends_s): the
autopilots' automatic take-off and landing at their default parameters, which descend slower
near the ground than any --climb-rate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: capture kinds of a flight row
VIEW, FRAME = "view", "frame"

#: the acceleration and braking of the time model (m/s^2, horizontal and vertical): ArduPilot's
#: default WPNAV_ACCEL (2.5 m/s^2), the lowest of the autopilots' (PX4's MPC_ACC_HOR: 3)
ACCEL_M_S2 = 2.5
#: points off the line between their neighbours by less than this (m) are flown through
#: (nbvkit.flight.simplify drops them from the written waypoints with the same tolerance)
LINE_TOL_M = 1e-3
#: the turn rate the ArduPilot file asks CONDITION_YAW for (deg/s, its param 2); the time model
#: also bounds the DJI route's rotateYaw by it (ArduPilot's own default is ATC_SLEW_YAW, 60 deg/s)
YAW_RATE_DEG_S = 30.0
#: the hold between the arrival at a view and its photo (s), whatever --hover is: the aircraft
#: stops (ArduCopter stops at a waypoint only when its hold is > 0) and the gimbal settles
SETTLE_S = 1.0
#: The slowest horizontal speed and climb rate of the flight-time model (m/s), and the longest
#: hover at a view (s): beyond them no drone's mission, and the times overflowed.
MIN_SPEED_M_S = 0.1
MAX_HOVER_S = 3600.0
#: the mission files whose waits capture_waits models: the .plan (PX4), the .waypoints
#: (ArduPilot) and the DJI .kmz
TARGETS = ("px4", "ardupilot", "dji")
#: the mission files each export format writes
FORMAT_FILES = {"qgc": ("px4", "ardupilot"), "wpml": ("dji",)}


def timed_files(formats) -> tuple:
    """The mission files (TARGETS) an export of `formats` writes, whose times it gives (a DJI
    export was timed and split by the ArduPilot file it did not write); all of them where it
    writes none (KML, GeoJSON, CSV, COLMAP alone: the slowest file's time)."""
    files = {t for f in formats for t in FORMAT_FILES.get(f, ())}
    return tuple(t for t in TARGETS if t in files) or TARGETS


#: the .plan's acceptance radius at a capture, at most (NAV_WAYPOINT p2, m; capture_radii): PX4
#: counts a waypoint reached within p2 (NAV_ACC_RAD, 2 m, where p2 is 0), then runs its photo
CAPTURE_RADIUS_M = 0.5
#: PX4's altitude acceptance of a multicopter's waypoint (NAV_MC_ALT_RAD's default, m): within it
#: and p2 a waypoint counts reached, whatever p2 is (px4_reach_s)
PX4_ALT_RAD_M = 0.8

#: ArduCopter's return to launch from straight above home (the .waypoints file's last item,
#: NAV_RETURN_TO_LAUNCH), at its default parameters: it first climbs, below RTL_ALT (1500 cm),
#: RTL_ABS_MIN_CLIMB (250 cm) at most towards it (mode_rtl.cpp compute_return_target: at no
#: distance from home RTL_CONE_SLOPE leaves that much), at WPNAV_SPEED_UP; waits RTL_LOIT_TIME
#: (5000 ms) above home, then lands at WPNAV_SPEED_DN (150 cm/s, LAND_SPEED_HIGH being 0) down to
#: LAND_ALT_LOW (1000 cm) and at LAND_SPEED (50 cm/s) below it. Its take-off climbs at
#: WPNAV_SPEED_UP (250 cm/s).
AP_RTL_LOITER_S, AP_DESCENT_M_S, AP_LAND_ALT_LOW_M, AP_LAND_SPEED_M_S = 5.0, 1.5, 10.0, 0.5
AP_RTL_ALT_M, AP_RTL_MIN_CLIMB_M = 15.0, 2.5
AP_TAKEOFF_M_S = 2.5
#: PX4's return to launch from straight above home (the .plan's last item), at its default
#: parameters: RTL_LAND_DELAY 0 s, then the landing at MPC_Z_V_AUTO_DN (1.5 m/s) above
#: MPC_LAND_ALT1 (10 m), slowing linearly with the height to MPC_LAND_SPEED (0.7 m/s) at
#: MPC_LAND_ALT2 (5 m) and at that speed below it. Its take-off climbs at MPC_TKO_SPEED (1.5 m/s).
PX4_DESCENT_M_S, PX4_LAND_ALT1_M, PX4_LAND_ALT2_M, PX4_LAND_SPEED_M_S = 1.5, 10.0, 5.0, 0.7
PX4_TAKEOFF_M_S = 1.5
#: the fastest descent of the time model (m/s): ArduCopter's WPNAV_SPEED_DN and PX4's
#: MPC_Z_V_AUTO_DN (150 cm/s and 1.5 m/s by default), on every leg down and not only the landing
DESCENT_M_S = min(AP_DESCENT_M_S, PX4_DESCENT_M_S)


def signed_deg(deg: float) -> float:
    """An angle in [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def _holds_opposite(possible, heading: float) -> bool:
    """Whether the arc `possible` (lo, hi) of unwrapped degrees holds the heading opposite
    `heading`: from there a turn to it is 180 degrees, either way round."""
    lo, hi = possible
    return lo + (heading + 180.0 - lo) % 360.0 <= hi


def _turn_bound(possible, target: float) -> float:
    """The largest turn (degrees, the shortest way) to `target` from any heading within
    `possible`: an arc (lo, hi) of unwrapped degrees, lo <= hi, or None (any heading: 180).
    """
    if possible is None or _holds_opposite(possible, target):
        return 180.0
    lo, hi = possible
    return max(abs(signed_deg(target - lo)), abs(signed_deg(target - hi)))


def _towards(possible, heading: float):
    """The headings possible after a turn towards `heading` (the shortest way) started from any
    heading within `possible` and stopped anywhere (a plain waypoint holds nothing: its turn may
    be cut short by the next leg's): the arc widened to reach `heading`; None (any) when the
    turns from it go both ways round or the arc closes."""
    if possible is None or _holds_opposite(possible, heading):
        return None
    lo, hi = possible
    h = lo + signed_deg(heading - lo)  # the same turn's end from every heading of the arc
    lo, hi = min(lo, h), max(hi, h)
    return None if hi - lo >= 360.0 else (lo, hi)


def capture_radii(actions, gaps) -> np.ndarray:
    """(N,) the .plan's p2 (m) of each waypoint: at a capture CAPTURE_RADIUS_M or, if less, 0.45
    of the distance to its nearer neighbour (no two radii meet: one reached never counts the
    next reached, its photo fired off its point), at least 0.01 m (gaps None:
    CAPTURE_RADIUS_M); 0 (NAV_ACC_RAD) elsewhere. gaps (N,): m from the previous waypoint (the
    first's not read)."""
    capture = np.array([a in (VIEW, FRAME) for a in actions], bool)
    if gaps is None or len(capture) == 0:
        return np.where(capture, CAPTURE_RADIUS_M, 0.0)
    gap = np.asarray(gaps, float)
    before = np.where(np.arange(len(gap)) > 0, gap, np.inf)  # the first has none before it
    near = 0.45 * np.minimum(before, np.append(gap[1:], np.inf))
    return np.where(capture, np.clip(near, 0.01, CAPTURE_RADIUS_M), 0.0)


def px4_reach_s(actions, xyz, model: "FlightModel") -> np.ndarray:
    """(N,) seconds the .plan's hold (p1) adds at each capture of the waypoints xyz (N, 3) for
    the vehicle to get there before its photo. PX4 counts a waypoint reached once within p2
    horizontally (capture_radii) and PX4_ALT_RAD_M vertically, and runs the photo then (after
    the hold); on a leg mostly up or down (a profile's vertical sweep: frames 0.82 m apart) the
    altitude test passes almost at once, 0.8 m short. Where the point so counted reached lies
    farther than CAPTURE_RADIUS_M from the capture, its hold covers the rest of the leg, flown
    from a stop to a stop (stop_leg_s), rounded up to 0.1 s: PX4 flies on to the waypoint while
    it holds. 0 elsewhere."""
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    d = np.diff(xyz, axis=0, prepend=xyz[:1])
    h, v = np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2])
    radii = capture_radii(actions, np.linalg.norm(d, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        by_xy = np.where(h > 0, radii / h, np.inf)
        by_z = np.where(v > 0, PX4_ALT_RAD_M / v, np.inf)
    left = np.minimum(1.0, np.minimum(by_xy, by_z))  # the share of the leg left when reached
    short = (radii > 0) & (left * np.hypot(h, v) > CAPTURE_RADIUS_M + 1e-9)
    rest = model.stop_leg_s(left[:, None] * d)
    return np.where(short, np.ceil(10.0 * rest - 1e-9) / 10.0, 0.0)


def capture_waits(actions, headings_deg, hover_s: float, reach=None) -> dict:
    """The waits of each waypoint (N,) in each mission file (TARGETS), the one function both the
    time model and the writers use: target -> (hold, rest, turn_s), arrays (N,) of seconds.

    hold: from the arrival to the photo; rest: after the photo (NAV_DELAY, a DJI hover); turn_s:
    the DJI route's rotateYaw before the photo, bounded at YAW_RATE_DEG_S (0 elsewhere). Only
    captures (view, frame) wait. A view settles SETTLE_S (1 s) before its photo whatever
    `hover_s` is and stays max(hover_s, its hold) in all; a frame does not settle. The turn of a
    capture: the largest from a heading the vehicle may hold on arriving there. A capture's wait
    ends facing its heading; a take-off or a transit leg (their heading is not commanded) leaves
    any heading (180 degrees to turn); a plain waypoint holds nothing (no wait: its turn may be
    cut short), so after one the vehicle may face any heading between those it held and turned
    to since the last capture (180 degrees when those turns go both ways round): the turn after
    a take-off or transit leg is counted at the first capture, whatever points come first.
    px4: hold = the settle + reach (px4_reach_s, (N,) or None: 0), rest = hover_s - settle.
    ardupilot: CONDITION_YAW turns at
    YAW_RATE_DEG_S, and the hold covers the whole turn and the settle, ceil(turn / 30 + settle)
    whole seconds (ArduPilot keeps NAV_WAYPOINT's hold in whole seconds; the leg's time is not
    counted: the copter may fly faster than --speed), rest = hover_s - hold. dji: rotateYaw
    (turn / 30 at most), the settle, the photo, the rest of hover_s. headings_deg: the heading
    of each waypoint (degrees, any origin: only differences count)."""
    n = len(actions)
    out = {t: (np.zeros(n), np.zeros(n), np.zeros(n)) for t in TARGETS}
    possible = None  # before the take-off: any heading
    for k in range(n):
        a, h = actions[k], float(headings_deg[k])
        if a in ("takeoff", "transit"):
            possible = None
            continue
        if a not in (VIEW, FRAME):
            possible = _towards(possible, h)
            continue
        settle = SETTLE_S if a == VIEW else 0.0
        turn_s = _turn_bound(possible, h) / YAW_RATE_DEG_S
        possible = (h, h)  # the capture's wait ends facing its heading
        hover = max(float(hover_s), settle) if a == VIEW else 0.0
        ap = float(math.ceil(turn_s + settle - 1e-9))
        rest = round(hover - settle, 3)  # to the millisecond, as the DJI route writes it: no
        reach_s = 0.0 if reach is None else float(reach[k])
        out["px4"][0][k], out["px4"][1][k] = settle + reach_s, rest  # NAV_DELAY of 0.0004 s
        out["ardupilot"][0][k], out["ardupilot"][1][k] = ap, max(0.0, round(hover - ap, 3))
        out["dji"][0][k], out["dji"][1][k], out["dji"][2][k] = settle, rest, turn_s
    return out


def waits_s(waits: dict) -> dict:
    """target -> the seconds a mission file waits in all (capture_waits' sum)."""
    return {t: float(sum(float(np.sum(v)) for v in waits[t])) for t in TARGETS}


@dataclass(frozen=True)
class FlightModel:
    """Flight-time model: speed (m/s, horizontal), climb_rate (m/s, up, and down at most
    DESCENT_M_S: descent_rate), hover_s (seconds per counted view, at least SETTLE_S:
    capture_waits)."""

    speed: float = 5.0
    climb_rate: float = 2.0
    hover_s: float = 2.0

    def __post_init__(self):
        for name in ("speed", "climb_rate"):  # (slower, a mission's times overflowed to inf)
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= MIN_SPEED_M_S):
                raise ValueError(
                    f"{name.replace('_', ' ')} must be a finite number >= {MIN_SPEED_M_S:g} m/s, "
                    f"got {v:g}"
                )
        if not (math.isfinite(self.hover_s) and 0 <= self.hover_s <= MAX_HOVER_S):
            raise ValueError(f"hover must be 0..{MAX_HOVER_S:g} s a view, got {self.hover_s:g}")

    def stop_leg_s(self, d: np.ndarray) -> np.ndarray:
        """(L,) seconds of straight legs d (L, 3) each flown from a stop to a stop (module
        docstring)."""
        d = np.asarray(d, float).reshape(-1, 3)
        up = _accelerated(np.maximum(d[:, 2], 0.0), self.climb_rate, ACCEL_M_S2)
        down = _accelerated(np.maximum(-d[:, 2], 0.0), self.descent_rate, ACCEL_M_S2)
        return np.maximum(
            _accelerated(np.hypot(d[:, 0], d[:, 1]), self.speed, ACCEL_M_S2), np.maximum(up, down)
        )

    @property
    def descent_rate(self) -> float:
        """m/s down on a leg: climb_rate, at most DESCENT_M_S."""
        return min(self.climb_rate, DESCENT_M_S)

    def leg_times(self, pts: np.ndarray, stops=None) -> np.ndarray:
        """(P-1,) seconds of the legs between consecutive points (P, 3), flown through the points
        on a straight line and stopping at the others (corners(pts)), and at those `stops`
        (a (P,) bool mask) marks: each run between two stops takes stop_leg_s of its length,
        shared among its legs by their length."""
        pts = np.asarray(pts, float).reshape(-1, 3)
        if len(pts) < 2:
            return np.zeros(0)
        stop = corners(pts)
        if stops is not None:
            stop |= np.asarray(stops, bool)
        ends = np.flatnonzero(stop)  # the first and the last are stops
        d = np.diff(pts, axis=0)
        length = np.linalg.norm(d, axis=1)
        run = self.stop_leg_s(pts[ends[1:]] - pts[ends[:-1]])  # each run's time
        of = np.searchsorted(ends, np.arange(len(d)), side="right") - 1  # each leg's run
        total = np.add.reduceat(length, ends[:-1])[of]
        legs = np.diff(ends)[of]
        return np.where(
            total > 0, run[of] * length / np.where(total > 0, total, 1.0), run[of] / legs
        )

    def path_time(self, pts, stops=None) -> float:
        return float(self.leg_times(pts, stops).sum())

    def ends_s(self, height: float) -> dict:
        """target -> (take-off, landing) seconds of a sortie that climbs `height` m straight up
        from the launch point and comes down the same line. The DJI route (autoLand: DJI
        publishes no landing profile) as any vertical leg (climb_rate, descent_rate); the
        MAVLink files at their autopilot's defaults, never faster than climb_rate: ArduPilot's
        and PX4's take-off speeds (AP_TAKEOFF_M_S, PX4_TAKEOFF_M_S) and the return to launch of
        each, which descends slower near the ground (AP_*, PX4_*)."""
        h = max(float(height), 0.0)
        up = {t: self._vertical_s(h, self.climb_rate) for t in TARGETS}
        up["ardupilot"] = self._vertical_s(h, min(self.climb_rate, AP_TAKEOFF_M_S))
        up["px4"] = self._vertical_s(h, min(self.climb_rate, PX4_TAKEOFF_M_S))
        top = h if h >= AP_RTL_ALT_M else min(AP_RTL_ALT_M, h + AP_RTL_MIN_CLIMB_M)
        ap = self._vertical_s(top - h, min(self.climb_rate, AP_TAKEOFF_M_S)) + AP_RTL_LOITER_S
        fast = max(top - AP_LAND_ALT_LOW_M, 0.0)
        ap += fast / min(self.climb_rate, AP_DESCENT_M_S)
        ap += (top - fast) / min(self.climb_rate, AP_LAND_SPEED_M_S)
        dji = self._vertical_s(h, self.descent_rate)
        down = {"dji": dji, "ardupilot": ap, "px4": _px4_landing_s(h, self.climb_rate)}
        return {t: (up[t], down[t]) for t in TARGETS}

    @staticmethod
    def _vertical_s(h: float, v: float) -> float:
        return float(_accelerated(np.array([h]), v, ACCEL_M_S2)[0])


def _px4_landing_s(h: float, climb_rate: float) -> float:
    """Seconds of PX4's landing from h m (its speed at each height, by PX4_*, never above
    climb_rate): the parts above MPC_LAND_ALT1 and below MPC_LAND_ALT2 at constant speeds, the
    part between at a speed rising linearly with the height, dz / v(z) integrated in closed
    form (where climb_rate caps it, at the cap)."""
    lo, hi = PX4_LAND_ALT2_M, PX4_LAND_ALT1_M
    v_lo, v_hi = min(PX4_LAND_SPEED_M_S, climb_rate), min(PX4_DESCENT_M_S, climb_rate)
    t = min(h, lo) / v_lo + max(h - hi, 0.0) / v_hi
    top = min(max(h, lo), hi)  # the ramp from lo to top
    if top <= lo:
        return t
    slope = (PX4_DESCENT_M_S - PX4_LAND_SPEED_M_S) / (hi - lo)
    cap = lo + (climb_rate - PX4_LAND_SPEED_M_S) / slope  # where the ramp reaches climb_rate
    if climb_rate <= PX4_LAND_SPEED_M_S:
        return t + (top - lo) / climb_rate
    ramp_top = min(top, cap)
    t += math.log((PX4_LAND_SPEED_M_S + slope * (ramp_top - lo)) / PX4_LAND_SPEED_M_S) / slope
    return t + max(top - ramp_top, 0.0) / min(climb_rate, v_hi)


def _accelerated(d: np.ndarray, v: float, a: float) -> np.ndarray:
    """Seconds to fly d from a stop to a stop, at most at speed v and accelerating and braking
    at a: d / v + v / a when d reaches v (d >= v^2 / a), else 2 sqrt(d / a)."""
    return np.where(d >= v * v / a, d / v + v / a, 2.0 * np.sqrt(d / a))


def off_segment(p, a, b) -> np.ndarray:
    """(N,) distances (m) of the points p (N, 3) from the segment a-b (each (3,)), or from the
    segments a[i]-b[i] (each (N, 3))."""
    p, a, b = (np.asarray(x, float) for x in (p, a, b))
    ab = b - a
    n = np.einsum("...i,...i->...", ab, ab)
    t = np.einsum("...i,...i->...", p - a, ab) / np.where(n > 0, n, 1.0)
    t = np.clip(np.where(n > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def corners(pts: np.ndarray, tol: float = LINE_TOL_M) -> np.ndarray:
    """(P,) bool: the points (P, 3) a flight stops at: the first, the last, and each farther
    than tol from the segment between its neighbours (a corner, or a turn back)."""
    pts = np.asarray(pts, float).reshape(-1, 3)
    out = np.ones(len(pts), bool)
    if len(pts) >= 3:
        out[1:-1] = off_segment(pts[1:-1], pts[:-2], pts[2:]) > tol
    return out
