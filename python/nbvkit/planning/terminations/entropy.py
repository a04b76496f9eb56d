"""The paper's termination (sec. 3.5): the entropy change per viewable voxel, |dE_v| =
|E_{n-1} - E_n| / C_view, below entropy.threshold for entropy.window consecutive views
(paper: 0.001 and N = 5). C_view is nbvkit.termination.viewable_cells."""
from __future__ import annotations

from dataclasses import dataclass

from ...settings import positive, within


@dataclass(frozen=True)
class EntropyConfig:
    """The entropy termination (section ``entropy``, formerly ``termination``), sec. 3.5:
    |dE_v| < threshold for `window` iterations."""

    threshold: float = positive(0.001)  # |dE_v| (paper)
    # consecutive quiet iterations that end the mission (paper: N = 5, the authors' window;
    # the paper's "true for more than N consecutive iterations" read literally is 6)
    window: int = within(5, 1, 10**6)
    count_partial_cells: bool = True  # C_view counts cells the frustum touches partially


class EntropyChange:
    Settings = EntropyConfig

    def __init__(self, settings: EntropyConfig, context=None):
        self.threshold = settings.threshold
        self.window = settings.window
        self.quiet = 0

    def check(self, world, step):
        self.quiet = self.quiet + 1 if abs(step.delta_ev) < self.threshold else 0
        return "entropy_converged" if self.quiet >= self.window else None
