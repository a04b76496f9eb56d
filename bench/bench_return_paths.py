"""The ways back of a battery split (nbvkit.flight.ReturnPaths: one A* search from each capture a
sortie may end at to the start) searched in threads, against one search after another (the code
before), in the same run, on the same run folder; the costs and paths must be the same.

    .venv/bin/python bench/bench_return_paths.py runs/plant11 --captures 400
    .venv/bin/python bench/bench_return_paths.py runs/surface
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from nbvkit import get_num_threads
from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner, find_launch, load_map
from nbvkit.export.plan import read_run


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
    out = {}
    for label, workers in (("one after another", 1), (f"{get_num_threads()} threads", 0)):
        t0 = time.perf_counter()
        out[label] = ReturnPaths(fl, model, occ, caps, workers=workers)
        out[label + " s"] = time.perf_counter() - t0
    a, b = out["one after another"], out[f"{get_num_threads()} threads"]
    same = np.array_equal(a.cost, b.cost) and a.astar.keys() == b.astar.keys()
    same = same and all(np.array_equal(a.astar[k], b.astar[k]) for k in a.astar)
    ta, tb = out["one after another s"], out[f"{get_num_threads()} threads s"]
    print(f"{args.run}: {len(caps)} captures, {len(a.astar)} ways back by A*")
    print(f"  one after another: {ta:.2f} s ({1000 * ta / max(len(caps), 1):.1f} ms a capture)")
    print(f"  {get_num_threads()} threads: {tb:.2f} s -> {ta / tb:.2f}x; the same costs and paths: "
          f"{same}")  # fmt: skip
    if not same:
        raise SystemExit("the threaded searches differ from the serial ones")


if __name__ == "__main__":
    main()
