"""View scoring across a mission with the memo of walks (ViewMemo) against walking every view:
flies a mission of the paper's IG (Scenario 5 by default) and scores every iteration's candidates
twice, with the planner's memo and without any, in alternating order, checking that both give the
same arrays. Prints ms per scoring call for each, their ratio, and how many views the memo served.
Every --baseline-every'th call is also scored by the reference backend (OctoMap's search per
cell, as in bench_views.py), on an octree brought up to date outside the timer: the issue's
baseline on the mission's own calls, with the memo's time on those same calls.

Run: .venv/bin/python bench/bench_memo.py [--scenario 5] [--start 0] [--iterations 1000]
     [--mesh PATH] [--threads N] [--baseline-every 10 (0: none)]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import nbvkit
from nbvkit import _core
from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.planning import scoring


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="5")
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--iterations", type=int, default=1000)
    ap.add_argument("--mesh", default=None)
    ap.add_argument("--threads", type=int, default=0, help="0: all cores")
    ap.add_argument("--baseline-every", type=int, default=10, help="0: no baseline calls")
    args = ap.parse_args()
    nbvkit.set_num_threads(args.threads)
    spent = {"memo": 0.0, "walk": 0.0}
    sampled = {"memo": 0.0, "octree": 0.0, "calls": 0}
    calls = [0]
    last = {}

    class Paired:  # the scorer's _core, each scoring call made both ways
        def __getattr__(self, name):
            return getattr(_core, name)

        @staticmethod
        def evaluate_views(*a, memo=None, **kw):
            def timed(name, **extra):
                t = time.perf_counter()
                r = _core.evaluate_views(*a, **kw, **extra)
                last[name] = time.perf_counter() - t
                spent[name] += last[name]
                return r

            calls[0] += 1
            if calls[0] % 2:
                with_memo, walked = timed("memo", memo=memo), timed("walk")
            else:
                walked, with_memo = timed("walk"), timed("memo", memo=memo)
            for k, v in walked.items():
                assert np.array_equal(v, with_memo[k]), f"{k} differs in call {calls[0]}"
            if args.baseline_every > 0 and calls[0] % args.baseline_every == 0:
                a[0].octree_num_nodes  # brings the octree mirror up to date (not timed)
                t = time.perf_counter()
                ref = _core.evaluate_views(*a, **kw, backend="octree")
                sampled["octree"] += time.perf_counter() - t
                sampled["memo"] += last["memo"]
                sampled["calls"] += 1
                assert np.array_equal(ref["status"], walked["status"]), f"call {calls[0]}"
                assert np.allclose(ref["gain"], walked["gain"], rtol=1e-6), f"call {calls[0]}"
            return with_memo

    scoring._core = Paired()
    over = [
        f"scenario={args.scenario}",
        f"start={args.start}",
        f"max_iterations={args.iterations}",
        "progress=false",
        "report.enabled=false",
    ]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    m = Mission(Config().with_overrides(over))
    m.run()
    s = m.planner.score.memo.stats()
    n = calls[0]
    views = s["reused"] + s["walked"]
    print(
        f"scenario {args.scenario}, start {args.start}: {n} scoring calls, {views} views scored "
        f"(threads: {nbvkit.get_num_threads()})"
    )
    print(
        f"  reused from the memo: {s['reused']} ({s['reused'] / max(views, 1):.1%}); walked "
        f"{s['walked']}, of which {s['stale']} had a record that no longer held"
    )
    memo = m.planner.score.memo
    print(f"  memo at the end: {memo.entries} records, {memo.bytes / 1e6:.1f} MB")
    a, b = 1e3 * spent["memo"] / n, 1e3 * spent["walk"] / n
    print(f"  ms per call: with the memo {a:.2f}, walking every view {b:.2f} -> {b / a:.2f}x")
    print("  every call: the same utility, gain, cells, occupied_seen and status both ways")
    if sampled["calls"]:
        k = sampled["calls"]
        a, b = 1e3 * sampled["memo"] / k, 1e3 * sampled["octree"] / k
        print(
            f"  {k} calls (every {args.baseline_every}th) also scored by OctoMap's search per "
            f"cell: {b:.1f} ms per call against {a:.2f} with the memo -> {b / a:.1f}x "
            "(the same status and gains)"
        )


if __name__ == "__main__":
    main()
