"""The ways back of a battery split (nbvkit.flight_home.ReturnPaths): one search out from
the start for every capture a sortie may end at (nbvkit.plan_paths_to, now), against one capped
A* search from each capture in threads (the code before, vehicle.path_expansions cells at most
each), in the same run, on the same run folder. Prints the seconds, the ways back each found, and
what the ways back cost (the mean of the cheaper of A* and retrace, in flight seconds).

    .venv/bin/python bench/bench_return_paths.py runs/plant11 --captures 400
    .venv/bin/python bench/bench_return_paths.py runs/surface
"""
from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from nbvkit import _core, flight_home, get_num_threads
from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner, find_launch, load_map
from nbvkit.export.plan import read_run


def searched_each(occ_map, fl, points: list) -> list:
    """The code before (flight_home._searches): plan_path from each point to the start in threads,
    vehicle.path_expansions cells at most each."""
    cap = fl.config.vehicle.path_expansions

    def one(i: int) -> np.ndarray:
        if np.allclose(fl.xyz[i], fl.start):
            return fl.start[None, :]
        path = _core.plan_path(occ_map, fl.xyz[i], fl.start, fl.radius, max_expansions=cap)
        return np.asarray(path, float) if len(path) >= 2 else np.zeros((0, 3))

    with ThreadPoolExecutor(get_num_threads()) as pool:
        return list(pool.map(one, points))


def resident_gb() -> float:
    """This process's resident memory now (VmRSS), GB."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a run folder of nbvkit run (with map.ot)")
    ap.add_argument("--captures", type=int, default=0, help="the first N captures only (0: all)")
    args = ap.parse_args()
    fl = read_run(args.run)
    model = FlightModel()
    occ = load_map(fl)
    find_launch(fl, occ, model)
    caps = [i for i in SortiePlanner.work_rows(fl) if fl.capture[i]]
    caps = caps[: args.captures] if args.captures else caps
    now_searches = flight_home._searches
    out = {}
    for label, searches in (("before", searched_each), ("now", flight_home._searches)):
        flight_home._searches = searches
        try:
            t0 = time.perf_counter()
            out[label] = ReturnPaths(fl, model, occ, caps), time.perf_counter() - t0
            print(f"  resident after {label}: {resident_gb():.2f} GB")
        finally:
            flight_home._searches = now_searches
    print(f"{args.run}: {len(caps)} captures, {get_num_threads()} threads")
    t_before = out["before"][1]
    for label, what in (("before", "a capped A* from each"), ("now", "one search from the start")):
        rp, t = out[label]
        print(
            f"  {label} ({what}): {t:.2f} s ({t_before / t:.2f}x); A* taken for "
            f"{len(rp.astar)} of {len(caps)}; mean way back {rp.cost[caps].mean():.1f} s, "
            f"longest {rp.cost[caps].max():.1f} s"
        )


if __name__ == "__main__":
    main()
