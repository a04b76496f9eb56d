"""The flight-time model of an exported flight (FlightModel) and the waits the written missions
command at each capture (capture_waits), the one place both the time model (nbvkit.flight's
sorties) and the mission writers (nbvkit.export) take them from.

A straight leg takes max(horizontal distance / speed, |climb| / climb_rate) seconds (a
multirotor flies it at its horizontal and vertical speed limits), and each capture adds the waits
the written missions command there (capture_waits: the settle, the photo, the rest of `hover_s`,
and in the ArduPilot and DJI files the turn to the capture's heading). A sortie's time is that of
the format that waits longest (the .waypoints file as a rule); the times per format are reported
too.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: capture kinds of a flight row
VIEW, FRAME = "view", "frame"

#: the turn rate the ArduPilot file asks CONDITION_YAW for (deg/s, its param 2); the time model
#: also bounds the DJI route's rotateYaw by it (ArduPilot's own default is ATC_SLEW_YAW, 60 deg/s)
YAW_RATE_DEG_S = 30.0
#: the hold between the arrival at a view and its photo (s), whatever --hover is: the aircraft
#: stops (ArduCopter stops at a waypoint only when its hold is > 0) and the gimbal settles
SETTLE_S = 1.0
#: the mission files whose waits capture_waits models: the .plan (PX4), the .waypoints
#: (ArduPilot) and the DJI .kmz
TARGETS = ("px4", "ardupilot", "dji")


def signed_deg(deg: float) -> float:
    """An angle in [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def capture_waits(actions, headings_deg, hover_s: float) -> dict:
    """The waits of each waypoint (N,) in each mission file (TARGETS), the one function both the
    time model and the writers use: target -> (hold, rest, turn_s), arrays (N,) of seconds.

    hold: from the arrival to the photo; rest: after the photo (NAV_DELAY, a DJI hover); turn_s:
    the DJI route's rotateYaw before the photo, bounded at YAW_RATE_DEG_S (0 elsewhere). Only
    captures (view, frame) wait. A view settles SETTLE_S (1 s) before its photo whatever
    `hover_s` is and stays max(hover_s, its hold) in all; a frame does not settle. The turn of a
    capture: from the previous waypoint's heading, 180 degrees after a take-off or a transit leg
    (their heading is not commanded). px4: hold = the settle, rest = hover_s - settle.
    ardupilot: CONDITION_YAW turns at YAW_RATE_DEG_S, and the hold covers the whole turn and the
    settle, ceil(turn / 30 + settle) whole seconds (ArduPilot keeps NAV_WAYPOINT's hold in whole
    seconds; the leg's time is not counted: the copter may fly faster than --speed), rest =
    hover_s - hold. dji: rotateYaw (turn / 30 at most), the settle, the photo, the rest of
    hover_s. headings_deg: the heading of each waypoint (degrees, any origin: only differences
    count)."""
    n = len(actions)
    out = {t: (np.zeros(n), np.zeros(n), np.zeros(n)) for t in TARGETS}
    for k in range(n):
        a = actions[k]
        if a not in (VIEW, FRAME):
            continue
        settle = SETTLE_S if a == VIEW else 0.0
        prev = actions[k - 1] if k > 0 else "takeoff"
        turn = 180.0
        if prev not in ("takeoff", "transit"):
            turn = abs(signed_deg(float(headings_deg[k]) - float(headings_deg[k - 1])))
        turn_s = turn / YAW_RATE_DEG_S
        hover = max(float(hover_s), settle) if a == VIEW else 0.0
        ap = float(math.ceil(turn_s + settle - 1e-9))
        out["px4"][0][k], out["px4"][1][k] = settle, hover - settle
        out["ardupilot"][0][k], out["ardupilot"][1][k] = ap, max(0.0, hover - ap)
        out["dji"][0][k], out["dji"][1][k], out["dji"][2][k] = settle, hover - settle, turn_s
    return out


def waits_s(waits: dict) -> dict:
    """target -> the seconds a mission file waits in all (capture_waits' sum)."""
    return {t: float(sum(float(np.sum(v)) for v in waits[t])) for t in TARGETS}


@dataclass(frozen=True)
class FlightModel:
    """Flight-time model: speed (m/s, horizontal), climb_rate (m/s, up and down), hover_s
    (seconds per counted view, at least SETTLE_S: capture_waits)."""

    speed: float = 5.0
    climb_rate: float = 2.0
    hover_s: float = 2.0

    def __post_init__(self):
        for name, lo in (("speed", 0.0), ("climb_rate", 0.0)):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > lo):
                raise ValueError(f"{name.replace('_', ' ')} must be a finite number > 0, got {v}")
        if not (math.isfinite(self.hover_s) and self.hover_s >= 0):
            raise ValueError(f"hover must be a finite number >= 0 s, got {self.hover_s}")

    def leg_times(self, pts: np.ndarray) -> np.ndarray:
        """(P-1,) seconds of the straight legs between consecutive points (P, 3)."""
        d = np.diff(np.asarray(pts, float).reshape(-1, 3), axis=0)
        return np.maximum(
            np.hypot(d[:, 0], d[:, 1]) / self.speed, np.abs(d[:, 2]) / self.climb_rate
        )

    def path_time(self, pts) -> float:
        return float(self.leg_times(pts).sum())
