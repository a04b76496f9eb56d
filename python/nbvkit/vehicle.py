"""The vehicle: its pose (a view: x, y, z, yaw and the camera gimbal's pitch) and the record of
its flight (the trajectory's legs and every point flown, with the captures taken there)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .limits import is_number, read_only


#: The columns of VehicleState.flight (and of a run's flight.csv).
FLIGHT_COLUMNS = ("stage", "x", "y", "z", "yaw", "pitch", "capture", "distance_m")


#: The stages of a flight (the trajectory's and flight.csv's `stage`): the laser's profile, then
#: the next-best views.
STAGES = ("profile", "nbv")


def check_stage(stage) -> None:
    """ValueError unless `stage` is one of STAGES."""
    if not isinstance(stage, str) or stage not in STAGES:
        raise ValueError(f"stage must be one of {', '.join(STAGES)}, got {stage!r}")


def as_positions(positions, what: str) -> np.ndarray:
    """`positions` as (K, 3) float64 (one position (3,): K = 1); ValueError naming `what` and
    the shape expected for any other shape."""
    p = np.asarray(positions, float)
    if p.ndim == 1 and p.size in (0, 3):
        return p.reshape(-1, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{what} must be (K, 3) positions (x, y, z), got shape {p.shape}")
    return p


def as_view(pose) -> np.ndarray:
    """A pose (x, y, z, yaw) or view (x, y, z, yaw, pitch) as a view (5,) float64: 4 numbers
    mean the level camera (pitch 0). The pitch is the camera gimbal's, radians, > 0 looks
    down (camera.gimbal_pitch_deg)."""
    a = np.asarray(pose)
    if a.ndim != 1 or len(a) not in (4, 5):
        raise ValueError(
            "a pose must be 4 numbers (x, y, z, yaw) or 5 (x, y, z, yaw, pitch), got an array "
            f"of shape {a.shape}"
        )
    if a.dtype.kind not in "iuf":  # (a complex part, a bool or a string is not a coordinate)
        raise ValueError(f"a pose must be real numbers, got {a.dtype} values: {a.tolist()}")
    return np.append(a, 0.0) if len(a) == 4 else a.astype(float)


@dataclass
class VehicleState:
    """Where the vehicle is and has been: pose (x, y, z, yaw, pitch) (the camera gimbal's pitch,
    radians, > 0 looks down), distance flown (m), the trajectory rows (stage, x, y, z, yaw,
    pitch, distance_m: the start and each leg's end), and the flight rows (FLIGHT_COLUMNS: every
    point flown, the A* waypoints between the legs' ends included; capture "view" where a
    counted view was taken, "frame" where an in-flight camera frame was, else "": one capture
    per row)."""

    pose: np.ndarray
    distance_m: float = 0.0
    views: int = 0  # counted views taken (in-flight frames are not counted)
    frames_skipped: int = 0  # leg frames not taken: their previews found too little new
    trajectory: list = field(default_factory=list)
    flight: list = field(default_factory=list)

    def __setattr__(self, name, value) -> None:
        """The pose is kept read-only (a part that wrote into it moved the vehicle without a
        flight; World.fly_to moves it) and the distance a finite number of metres."""
        if name == "pose":
            value = read_only(value, "pose")
        elif name == "distance_m" and not (is_number(value) and math.isfinite(value)):
            raise ValueError(f"distance_m must be a finite number of metres, got {value!r}")
        super().__setattr__(name, value)

    def record_leg(self, stage: str, pts: np.ndarray, d0: float) -> None:
        """Flight rows of a leg flown along `pts` (P, 3; first = where it started) from the
        distance d0 to the current pose: the waypoints in between, then the pose."""
        pitch = float(self.pose[4]) if len(self.pose) > 4 else 0.0
        yaw = float(self.pose[3])
        d = d0
        for a, b in zip(pts[:-2], pts[1:-1]):
            d += float(np.linalg.norm(b - a))
            self.flight.append([stage, *map(float, b), yaw, pitch, "", d])
        p = self.pose
        self.flight.append([stage, *map(float, p[:3]), yaw, pitch, "", self.distance_m])

    def capture(self, kind: str = "view") -> None:
        """Marks the last flight row (where the vehicle is) as a camera capture: a counted view
        ("view", which also counts in `views`) or an in-flight frame ("frame")."""
        if kind == "view":
            self.views += 1
        if self.flight[-1][6]:  # a second capture here: a row of its own
            self.flight.append(list(self.flight[-1]))
        self.flight[-1][6] = kind
