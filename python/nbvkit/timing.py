"""Stage timers: the mission's per-stage wall time, kept out of the method's code."""
from __future__ import annotations

from collections import defaultdict
from contextlib import contextmanager
from time import perf_counter


class StageTimers:
    """``with timers("sensing"): ...`` adds the block's wall time to the stage; ``total`` holds
    each stage's sum (s) and ``lap()`` each stage's time since the previous lap."""

    def __init__(self):
        self.total = defaultdict(float)
        self._at_lap = {}

    def lap(self) -> dict:
        """Each stage's time (s) since the previous lap (or since the timers were made): all of
        an iteration's time, also where a stage ran more than once (tour views skipped, a new
        tour planned)."""
        out = self.pending()
        self._at_lap = dict(self.total)
        return out

    def pending(self) -> dict:
        """Each stage's time (s) since the previous lap, without taking one."""
        return {s: t - self._at_lap.get(s, 0.0) for s, t in self.total.items()}

    def call(self, stage: str, fn, *args, **kwargs):
        """fn(*args, **kwargs), its wall time added to `stage`."""
        with self(stage):
            return fn(*args, **kwargs)

    @contextmanager
    def __call__(self, stage: str):
        t0 = perf_counter()
        try:
            yield
        finally:
            dt = perf_counter() - t0
            self.total[stage] += dt
