"""The paper's viewpoint sampling (sec. 3.3): the CGVS lattice around the vehicle, scaled by
AGVS when the mission stalls (nbvkit.sampling)."""
from __future__ import annotations

from ...sampling import AdaptiveScale, candidate_poses
from ..parts import Proposal


class LatticeGenerator:
    def __init__(self, config):
        s = config.sampling
        self.s = s
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
        return Proposal(
            candidate_poses(pose, self.s.delta_d, self.s.delta_theta, self.scale.scale), "lattice"
        )

    def feedback(self, world, proposal, step):
        if step is not None:  # alpha follows every iteration's dE_v (Eq. 6 with N = 3, 0.005)
            step.extra["alpha"] = self.scale.update(step.delta_ev, world.state.pose[:3])
