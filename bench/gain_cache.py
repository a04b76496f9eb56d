"""Would caching view gains between iterations pay (aeplanner's idea, issue 9)? Flies a mission
and records every scoring call's candidates and results, then counts how many candidates were
scored before at the same pose (to 1e-6) and, of those, how many came out with the same gain and
status: the most a cache keyed by pose could serve, whatever its invalidation rule.

    .venv/bin/python bench/gain_cache.py                       # airliner, Scenario 5, start 0
    .venv/bin/python bench/gain_cache.py --scenario 1 --iterations 300

A candidate's gain changes when any cell its rays reach changes, and the last frame was taken
from the pose the new lattice is centred on, looking where the lattice's candidates look.
"""
from __future__ import annotations

import argparse

import numpy as np

from nbvkit import _core
from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.planning import scoring


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="5")
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--iterations", type=int, default=200)
    ap.add_argument("--mesh", default=None)
    args = ap.parse_args()
    calls = []

    class Recording:  # the scorer's _core, recording each scoring call
        def __getattr__(self, name):
            return getattr(_core, name)

        @staticmethod
        def evaluate_views(m, poses, pose, **kw):
            r = _core.evaluate_views(m, poses, pose, **kw)
            calls.append((np.array(poses), np.array(r["gain"]), np.array(r["status"])))
            return r

    scoring._core = Recording()
    over = [
        f"scenario={args.scenario}",
        f"start={args.start}",
        f"max_iterations={args.iterations}",
        "progress=false",
    ]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    Mission(Config().with_overrides(over)).run()
    last = {}  # pose -> (gain, status) when it was last scored
    total = repeated = unchanged = 0
    for poses, gain, status in calls:
        for k in range(len(poses)):
            key = tuple(np.round(poses[k], 6))
            total += 1
            if key in last:
                repeated += 1
                unchanged += last[key] == (gain[k], status[k])
            last[key] = (gain[k], status[k])
    head = f"scenario {args.scenario}, start {args.start}"
    print(f"{head}: {len(calls)} scoring calls, {total} candidates")
    print(f"  scored before at the same pose: {repeated} ({repeated / total:.1%})")
    print(f"  ... with the same gain and status: {unchanged} ({unchanged / total:.1%})")


if __name__ == "__main__":
    main()
