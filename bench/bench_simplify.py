"""Dropping the plain waypoints of an exported flight (nbvkit.flight.simplify) against the code
before it (every dropped point measured again at each next point: quadratic in a straight run),
in the same run, on the same waypoints: a synthetic climb in centimetre steps, or the waypoints
of a run folder's flight estimate. Prints the seconds, the ratio and whether both keep the same.

    .venv/bin/python bench/bench_simplify.py --climb 310
    .venv/bin/python bench/bench_simplify.py --run runs/surface
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import nbvkit.export as export
from nbvkit import flight
from nbvkit.flight import Waypoint, plain_as_next
from nbvkit.flight_time import off_segment


def measured_again(wps: list, tol: float = 1e-3) -> list:
    """The code before: every point of the run measured against each next segment."""
    keep, run = [wps[0]], []
    for k in range(1, len(wps) - 1):
        w, nxt = wps[k], wps[k + 1]
        pts = np.array([*run, w.xyz])
        if plain_as_next(w, nxt) and off_segment(pts, keep[-1].xyz, nxt.xyz).max() <= tol:
            run.append(w.xyz)
        else:
            keep.append(w)
            run = []
    return keep + [wps[-1]]


def run_waypoints(folder: str) -> list:
    """The waypoint lists the flight estimate of a run folder simplifies."""
    seen, real = [], flight.simplify
    flight.simplify = lambda wps, *a, **k: (seen.append(list(wps)), real(wps, *a, **k))[1]
    try:
        export.estimate_flight(folder)
    finally:
        flight.simplify = real
    return seen


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--climb",
        type=float,
        default=310.0,
        help="m of a vertical climb in 3 cm steps (1 um of noise)",
    )
    ap.add_argument("--run", help="a run folder: its flight estimate's waypoints instead")
    a = ap.parse_args()
    if a.run:
        lists = run_waypoints(a.run)
    else:
        rng = np.random.default_rng(0)
        z = np.arange(0.0, a.climb, 0.03)
        xyz = np.c_[rng.normal(scale=1e-6, size=(len(z), 2)), z]
        lists = [[Waypoint(p, 0.0, 0.0, "transit", -1, "out") for p in xyz]]
    for wps in lists:
        t0 = time.perf_counter()
        now = flight.simplify(wps)
        t1 = time.perf_counter()
        before = measured_again(wps)
        t2 = time.perf_counter()
        same = [id(w) for w in now] == [id(w) for w in before]
        print(
            f"{len(wps)} waypoints -> {len(now)}: {t1 - t0:.3f} s against {t2 - t1:.3f} s before "
            f"({(t2 - t1) / max(t1 - t0, 1e-9):.1f}x), the same kept: {same}"
        )


if __name__ == "__main__":
    main()
