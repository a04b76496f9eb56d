"""Surface-coverage stall: stall.window consecutive views each showed the camera less than
stall.min_gain m^2 of surface it had never seen (cells seen for the first time, from any side:
measured from the camera observations, not predicted; a view that sees known surface from a new
side, which the surface utility credits, adds nothing here). On a structure smaller than
planner.reference_area the threshold shrinks with it (parts.threshold_scale)."""
from __future__ import annotations

from ..parts import threshold_scale


class SurfaceStall:
    def __init__(self, config):
        self.window = config.stall.window
        self.min_gain = config.stall.min_gain
        self.reference_area = config.planner.reference_area
        self.quiet = 0

    def check(self, world, step):
        min_gain = self.min_gain * threshold_scale(world.map, self.reference_area)
        self.quiet = self.quiet + 1 if step.new_surface_m2 < min_gain else 0
        return "surface_stall" if self.quiet >= self.window else None
