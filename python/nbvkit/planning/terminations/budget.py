"""Hard limits on a mission after profiling: distance flown (m, profiling included), camera views
and wall time (s); 0 disables a limit."""
from __future__ import annotations

import time


class Budget:
    def __init__(self, config):
        self.b = config.budget
        self.t0 = time.perf_counter()

    def check(self, world, step):
        b = self.b
        if b.max_distance_m and world.state.distance_m >= b.max_distance_m:
            return "budget_distance"
        if b.max_views and world.state.views >= b.max_views:
            return "budget_views"
        if b.max_time_s and time.perf_counter() - self.t0 >= b.max_time_s:
            return "budget_time"
        return None
