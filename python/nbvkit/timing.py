"""Stage timers: the mission's per-stage wall time, kept out of the method's code."""
from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager


class StageTimers:
    """``with timers("sensing"): ...`` adds the block's wall time to the stage; ``last`` holds
    each stage's most recent time (s) and ``total`` its sum."""

    def __init__(self):
        self.total = defaultdict(float)
        self.last = {}

    @contextmanager
    def __call__(self, stage: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t0
            self.total[stage] += dt
            self.last[stage] = dt
