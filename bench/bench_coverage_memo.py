"""The recommended planner's view coverage with its memo of walks (CoverageMemo) against walking
every candidate: flies a mission of the `surface` planner (the airliner from start 0 by default:
what `make` flies) and makes each plan (plan_tour: its coverage sets, then the tour) twice, with
the memo and without, in alternating order, checking that both give the same plan. Prints per
plan the candidates, the views answered from their record and those whose record no longer held,
and the seconds of each; then the totals and the memo's size. With --missions N it flies the
whole mission N times each way instead (alternating), and prints wall time and tour planning per
view from the summaries.

Run: .venv/bin/python bench/bench_coverage_memo.py [--mesh PATH] [--start 0] [--missions N]
     [--keep-calls 3]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np

from nbvkit import _core
from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.planning.generators import tour


def overrides(args):
    over = [f"start={args.start}", "progress=false", "report.enabled=false"]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    return over


def paired_calls(args):
    memo = _core.CoverageMemo(keep_calls=args.keep_calls)
    rows = []

    class Paired:  # the tour's _core, each plan made both ways
        def __getattr__(self, name):
            return getattr(_core, name)

        @staticmethod
        def plan_tour(*a, memo=None, **kw):
            before = shared.stats()
            ways = [("memo", shared), ("walk", None)]
            spent, got = {}, {}
            for way, m in ways if len(rows) % 2 == 0 else ways[::-1]:
                t = time.perf_counter()
                got[way] = _core.plan_tour(*a, **kw, memo=m)
                spent[way] = time.perf_counter() - t
            for k in ("chosen", "gains", "order"):
                assert np.array_equal(getattr(got["walk"], k), getattr(got["memo"], k)), k
            after = shared.stats()
            n = len(a[2])  # the candidates
            reused, stale = (after[k] - before[k] for k in ("reused", "stale"))
            rows.append((n, reused, stale, spent["walk"], spent["memo"]))
            return got["memo"]

    shared = memo
    tour._core = Paired()
    m = Mission(Config().with_overrides(overrides(args)))
    s = m.run()
    tour._core = _core
    where = args.mesh or "the airliner"
    print(f"{where}, start {args.start}: {s['iterations']} views, {len(rows)} plans")
    print(f"{'plan':>4} {'candidates':>10} {'reused':>7} {'stale':>6} {'walk s':>7} {'memo s':>7}")
    for i, (n, reused, stale, tw, tm) in enumerate(rows):
        print(f"{i:>4} {n:>10,} {reused:>7,} {stale:>6,} {tw:>7.2f} {tm:>7.2f}")
    tw, tm = sum(r[3] for r in rows), sum(r[4] for r in rows)
    print(
        f"plan_tour in all: walking every view {tw:.2f} s, with the memo {tm:.2f} s -> "
        f"{tw / tm:.2f}x; the same plan in every call; memo at the end: {memo.entries:,} "
        f"records, {memo.bytes / 1e6:.0f} MB"
    )


MISSION = """
import json, sys, time
import numpy as np
from nbvkit.config import Config
from nbvkit.mission import Mission
over, keep = json.loads(sys.argv[1]), sys.argv[2] == "1"
m = Mission(Config().with_overrides(over))
tour = next(g for g in m.planner.generators if hasattr(g, "plans"))
if not keep:
    tour.memo = None
t = time.perf_counter()
s = m.run()
wall = time.perf_counter() - t
poses = [[r.x, r.y, r.z, r.yaw] for r in m.records]
print(json.dumps(dict(wall=wall, planning=s["ms_per_stage"]["sampling"],
                      peak=s["peak_memory_mb"], poses=poses)))
"""


def missions(args):
    """Whole missions, each in its own process (its own peak memory), alternating."""
    res = {True: [], False: []}
    for i in range(2 * args.missions):
        keep = i % 2 == 0
        out = subprocess.run(
            [sys.executable, "-c", MISSION, json.dumps(overrides(args)), "1" if keep else "0"],
            capture_output=True,
            text=True,
            check=True,
        )
        res[keep].append(json.loads(out.stdout.strip().splitlines()[-1]))
    for keep in (True, False):
        r = res[keep]
        wall, plan, mem = ([x[k] for x in r] for k in ("wall", "planning", "peak"))
        print(
            f"{'with the memo' if keep else 'without':>13}: mission {min(wall):.1f}-{max(wall):.1f}"
            f" s, tour planning {min(plan):.1f}-{max(plan):.1f} ms per view, peak memory "
            f"{min(mem):.0f}-{max(mem):.0f} MB"
        )
    ref = res[False][0]["poses"]
    same = all(x["poses"] == ref for k in (True, False) for x in res[k])
    print(f"the same {len(ref)} views in every mission: {same}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default=None)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--missions", type=int, default=0, help="whole missions each way (0: calls)")
    ap.add_argument("--keep-calls", type=int, default=3, help="the memo's (calls mode)")
    args = ap.parse_args()
    if args.missions > 0:
        missions(args)
    else:
        paired_calls(args)


if __name__ == "__main__":
    main()
