"""Timing helper shared by the benchmark scripts (imported from the scripts' own folder)."""
import time

import numpy as np


def median_time(fn, repeat: int) -> float:
    """Median wall time (s) of `repeat` calls of fn, after one warm-up call."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))
