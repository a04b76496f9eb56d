"""Viewpoint sampling: the constant grid (CGVS) lattice of Eq. 2 and the adaptive scale (AGVS).

CGVS: the 80 offsets (i dd, j dd, k dd, m dtheta), i, j, k, m in {-1, 0, 1}, not all zero,
expressed in the vehicle's body frame (x forward, y left, z up, rotated by its yaw).
AGVS: the linear part is scaled by sigma**alpha; alpha grows by one for every iteration that
completes a run of `window` consecutive iterations with |dE_v| < threshold (Eq. 6 with N = 3,
0.005), and resets to 0 on any iteration that is not quiet (paper, sec. 3.3).
"""
from __future__ import annotations

import itertools
import math
from collections import deque

import numpy as np

#: (80, 4) integer lattice (i, j, k, m), the zero offset excluded, in a fixed order.
LATTICE = np.array([c for c in itertools.product((-1, 0, 1), repeat=4) if any(c)], dtype=np.int64)


def wrap_angle(a):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def lattice_offsets(
    delta_d: float = 1.0, delta_theta: float = math.pi / 4, scale: float = 1.0
) -> np.ndarray:
    """(80, 4) body-frame offsets (dx, dy, dz, dyaw) of Eq. 2 with linear scale `scale`."""
    if not (delta_d > 0 and scale > 0 and delta_theta >= 0):
        raise ValueError("lattice needs delta_d > 0, scale > 0 and delta_theta >= 0")
    off = LATTICE.astype(np.float64)
    off[:, :3] *= delta_d * scale
    off[:, 3] *= delta_theta
    return off


def candidate_poses(
    pose, delta_d: float = 1.0, delta_theta: float = math.pi / 4, scale: float = 1.0
) -> np.ndarray:
    """(80, 4) world-frame candidate poses (x, y, z, yaw: level views) around a vehicle pose
    (x, y, z, yaw) or view (x, y, z, yaw, pitch; the pitch plays no part)."""
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape not in ((4,), (5,)) or not np.all(np.isfinite(pose)):
        raise ValueError(
            f"pose must be 4 finite numbers (x, y, z, yaw) or 5 (x, y, z, yaw, pitch), got {pose!r}"
        )
    pose = pose[:4]
    off = lattice_offsets(delta_d, delta_theta, scale)
    c, s = math.cos(pose[3]), math.sin(pose[3])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = np.empty_like(off)
    out[:, :3] = pose[:3] + off[:, :3] @ R.T
    out[:, 3] = wrap_angle(pose[3] + off[:, 3])
    return out


class AdaptiveScale:
    """The AGVS exponent alpha, driven by |dE_v| per iteration (CGVS: `enabled=False`, alpha 0).

    Options from the authors' code: `cap` on the total scale (7.5) and `oscillation_is_stuck`
    (an A-B-A-B alternation of the chosen positions counts as a stuck iteration).
    """

    def __init__(
        self,
        sigma: float = 1.5,
        alpha_max: int = 5,
        threshold: float = 0.005,
        window: int = 3,
        cap: float | None = None,
        oscillation_is_stuck: bool = False,
        enabled: bool = True,
    ):
        if not sigma > 0 or alpha_max < 0 or not threshold > 0 or window < 1:
            raise ValueError(
                "AdaptiveScale needs sigma > 0, alpha_max >= 0, threshold > 0, window >= 1"
            )
        self.sigma, self.alpha_max, self.threshold, self.window = (
            sigma,
            alpha_max,
            threshold,
            window,
        )
        self.cap, self.oscillation_is_stuck, self.enabled = cap, oscillation_is_stuck, enabled
        self.alpha = 0
        self._quiet = deque(maxlen=window)
        self._chosen = deque(maxlen=4)

    @property
    def scale(self) -> float:
        s = self.sigma**self.alpha
        return min(s, self.cap) if self.cap else s

    def update(self, delta_ev: float, chosen_position=None) -> int:
        """Record one iteration's dE_v (and chosen position); returns the new alpha."""
        if not self.enabled:
            return 0
        quiet = abs(delta_ev) < self.threshold
        if self.oscillation_is_stuck and chosen_position is not None:
            self._chosen.append(np.round(np.asarray(chosen_position, float), 6))
            if len(self._chosen) == 4:
                a, b, c, d = self._chosen
                if np.array_equal(a, c) and np.array_equal(b, d) and not np.array_equal(a, b):
                    quiet = True
        self._quiet.append(quiet)
        if len(self._quiet) == self.window and all(self._quiet):
            self.alpha = min(self.alpha + 1, self.alpha_max)
        elif not quiet:
            self.alpha = 0
        return self.alpha
