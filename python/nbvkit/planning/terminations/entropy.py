"""The paper's termination (sec. 3.5): the entropy change per viewable voxel, |dE_v| =
|E_{n-1} - E_n| / C_view, below termination.threshold for termination.window consecutive views
(paper: 0.001 and N = 5). C_view is nbvkit.termination.viewable_cells."""
from __future__ import annotations


class EntropyChange:
    def __init__(self, config):
        self.threshold = config.termination.threshold
        self.window = config.termination.window
        self.quiet = 0

    def check(self, world, step):
        self.quiet = self.quiet + 1 if abs(step.delta_ev) < self.threshold else 0
        return "entropy_converged" if self.quiet >= self.window else None
