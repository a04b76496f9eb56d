"""The paper's viewpoint sampling (sec. 3.3): the CGVS lattice around the vehicle, scaled by
AGVS when the mission stalls (nbvkit.sampling)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...sampling import AdaptiveScale, candidate_poses
from ...settings import choice, nonneg, positive, within
from ..parts import Proposal


@dataclass(frozen=True)
class LatticeConfig:
    """The lattice generator (section ``lattice``, formerly ``sampling``): the viewpoint
    sampling of Eq. 2, the CGVS lattice and the AGVS scale sigma**alpha."""

    method: str = choice("agvs", ("cgvs", "agvs"))  # "cgvs" (alpha fixed at 0) or "agvs"
    delta_d: float = positive(1.0)  # m
    delta_theta: float = nonneg(math.pi / 4)  # rad
    sigma: float = positive(1.5)
    alpha_max: int = within(5, 0, 100)
    stuck_threshold: float = positive(0.005)  # |dE_v| below this counts as stuck (paper)
    stuck_window: int = within(3, 1, 10**6)  # stuck iterations in a row before alpha grows
    scale_cap: Optional[float] = positive(None)  # authors' code: 7.5
    oscillation_is_stuck: bool = False  # authors' code: an A-B-A-B oscillation counts as stuck
    # > 0: each lattice view also at the gimbal's pitches this far apart (camera.gimbal_pitch_deg)
    delta_pitch_deg: float = within(0.0, 0, 180)  # deg; 0: level views


class LatticeGenerator:
    Settings = LatticeConfig

    def __init__(self, settings: LatticeConfig, context=None):
        s = settings
        self.s = s
        gimbal = context.camera.gimbal_pitch_deg if context is not None else (0.0, 0.0)
        self.pitches = gimbal_pitches(gimbal, s.delta_pitch_deg) if s.delta_pitch_deg else [0.0]
        self.scale = AdaptiveScale(
            s.sigma,
            s.alpha_max,
            s.stuck_threshold,
            s.stuck_window,
            s.scale_cap,
            s.oscillation_is_stuck,
            enabled=(s.method == "agvs"),
        )

    def propose(self, world):
        pose = world.state.pose
        poses = candidate_poses(pose, self.s.delta_d, self.s.delta_theta, self.scale.scale)
        if len(self.pitches) > 1:  # each view at every pitch: (K * P, 5)
            poses = np.column_stack(
                [np.repeat(poses[:, :4], len(self.pitches), 0), np.tile(self.pitches, len(poses))]
            )
        return Proposal(poses, "lattice")

    def feedback(self, world, proposal, step):
        if step is not None:  # alpha follows every iteration's dE_v (Eq. 6 with N = 3, 0.005)
            step.extra["alpha"] = self.scale.update(step.delta_ev, world.state.pose[:3])


def gimbal_pitches(gimbal_pitch_deg, step_deg: float) -> np.ndarray:
    """The pitches (radians) a lattice view is sampled at: 0 and every multiple of step_deg
    within the gimbal's [min, max] degrees (> 0 looks down); [0] for a level camera."""
    lo, hi = gimbal_pitch_deg
    k = np.arange(math.ceil(lo / step_deg - 1e-9), math.floor(hi / step_deg + 1e-9) + 1)
    return np.radians(np.union1d(k * step_deg, [0.0]))
