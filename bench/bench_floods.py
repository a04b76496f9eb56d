"""The collision test of a path search, where it costs most: the flood of the vehicle's free
component (``_core.FreeComponent``, what the selection builds when a search fails) and A* paths
(``_core.plan_path``) on a flown map, with this checkout and (--against DIR) another one, each in
a process of its own, alternating; the components and the paths must be the same.

The map is a mission's (``--run DIR``: DIR/map.ot, DIR/summary.json, DIR/trajectory.csv);
otherwise ``--scenario`` (default surface, the recommended planner) first flies ``--iterations``
views on ``--mesh``. Starts are
flown poses; goals random positions in the navigation space whose collision sphere is free.

    .venv/bin/python bench/bench_floods.py --run runs/plant --against /tmp/before
    .venv/bin/python bench/bench_floods.py --mesh ../shared/meshes/office_building.obj
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from _timing import alternate, flown_map, flown_map_parser
from nbvkit import _core

TIME_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
from nbvkit import _core
path, lo, hi, radius, cases = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3]), \
    float(sys.argv[4]), np.load(sys.argv[5])
m = _core.OccupancyMap.load(path, lo, hi)
starts, froms, goals = cases["starts"], cases["froms"], cases["goals"]
digest, out = hashlib.sha256(), {"flood": 0.0, "paths": 0.0}
for s in starts:
    t = time.perf_counter()
    c = _core.FreeComponent(m, s, radius)
    out["flood"] += time.perf_counter() - t
    digest.update(np.asarray(c.contains(m, goals), bool).tobytes())
for s, g in zip(froms, goals):
    t = time.perf_counter()
    p = _core.plan_path(m, s, g, radius)
    out["paths"] += time.perf_counter() - t
    digest.update(np.ascontiguousarray(p, float).tobytes())
out["time"] = out["flood"] + out["paths"]
out["digest"] = digest.hexdigest()
print(json.dumps(out))
"""


def main():
    ap = flown_map_parser(__doc__, iterations=60)
    ap.set_defaults(scenario="surface")
    ap.add_argument("--run", help="a finished mission's folder: its map, workspace and poses")
    ap.add_argument("--against", help="another checkout (or a saved package) to compare with")
    ap.add_argument("--starts", type=int, default=6, help="floods, from flown poses")
    ap.add_argument("--goals", type=int, default=30, help="paths, from the starts in turn")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        flown = flown_map(args, tmp)
        path, lo, hi, nav = flown["path"], flown["lo"], flown["hi"], flown["nav"]
        poses, radius = flown["poses"], flown["radius"]
        grid = _core.OccupancyMap.load(path, lo, hi)
        rng = np.random.default_rng(args.seed)
        goals = []
        while len(goals) < args.goals:
            for g in rng.uniform(np.asarray(nav[0]), np.asarray(nav[1]), (1000, 3)):
                if len(goals) < args.goals and _core.sphere_is_free(grid, g, radius):
                    goals.append(g)
        starts = poses[rng.integers(0, len(poses), args.starts)]
        froms = poses[rng.integers(0, len(poses), args.goals)]
        cases = Path(tmp) / "cases.npz"
        np.savez(cases, starts=starts, froms=froms, goals=np.array(goals))
        snippet_args = [path, json.dumps(list(lo)), json.dumps(list(hi)), radius, cases]
        best, same = alternate(TIME_SNIPPET, snippet_args, args.against, 2, ("time", "flood"))
    print(f"map {grid.shape} cells at {grid.resolution} m, collision radius {radius} m")
    print(f"{args.starts} floods and {args.goals} paths, least of 2 runs each, alternating")
    for label, t, flood in best:
        print(f"{label:>30}: {t:8.3f} s in all; floods {flood / args.starts * 1e3:8.1f} ms each")
    if len(best) == 2:
        print(f"ratio {best[1][1] / best[0][1]:.2f}x; the same components and paths: {same}")
    elif not same:
        raise SystemExit("the runs differ")


if __name__ == "__main__":
    main()
