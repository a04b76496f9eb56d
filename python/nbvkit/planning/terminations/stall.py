"""Surface-coverage stall: stall.window consecutive views each showed the camera less than
stall.min_gain m^2 of surface it had never seen (cells seen for the first time, from any side:
measured from the camera observations, not predicted; a view that sees known surface from a new
side, which the surface utility credits, adds nothing here). On a structure smaller than
planner.reference_area the threshold shrinks with it (parts.threshold_scale)."""
from __future__ import annotations

from dataclasses import dataclass

from ...settings import nonneg, within
from ..parts import threshold_scale


@dataclass(frozen=True)
class StallConfig:
    """Surface-coverage stall: the chosen views stopped adding surface."""

    window: int = within(5, 1, 10**6)  # consecutive views
    min_gain: float = nonneg(0.8)  # m^2 of new surface each added, at most


class SurfaceStall:
    Settings = StallConfig

    def __init__(self, settings: StallConfig, context):
        self.window = settings.window
        self.min_gain = settings.min_gain
        self.reference_area = context.planner.reference_area
        self.quiet = 0

    def check(self, world, step):
        min_gain = self.min_gain * threshold_scale(world.map, self.reference_area)
        self.quiet = self.quiet + 1 if step.new_surface_m2 < min_gain else 0
        return "surface_stall" if self.quiet >= self.window else None
