"""Benchmark of a mission's progress refresh: Evaluator.coverage over the mission's clouds, read
in place (the cell figures of an evaluation: coverage, area coverage and precision at each
resolution, without distances), which `nbvkit compare` runs every 5 views and `nbvkit run` every
25. Prints figures; asserts nothing.

    .venv/bin/python bench/bench_refresh.py --cloud runs/main/cloud.ply            # airliner
    .venv/bin/python bench/bench_refresh.py --mesh M.obj --cloud RUN/cloud.ply --against DIR

The cloud (a mission's cloud.ply) is put in a SurfaceCloud at the camera's 0.02 m voxel, as a
mission keeps it. ``--against DIR`` times the same refresh, in the same run, with the nbvkit
package of another checkout (DIR/python or DIR) and prints the ratio and whether every figure
is the same.
"""
from __future__ import annotations

import json
from pathlib import Path

from _timing import checkouts, mesh_parser, run_snippet

import nbvkit

# Runs in this checkout or, through --against, in another one.
TIME_SNIPPET = r"""
import json, sys, time
import nbvkit
from nbvkit import _core
from nbvkit.evaluation import Evaluator
ev = Evaluator(nbvkit.load_mesh(sys.argv[1]), seed=0)
cloud = _core.SurfaceCloud(voxel_size=0.02, min_z=-1e9)
cloud.add(nbvkit.read_points(sys.argv[2]))
ev.coverage([cloud])  # warm-up
best = float("inf")
for _ in range(int(sys.argv[3])):
    t = time.perf_counter()
    r = ev.coverage([cloud])
    best = min(best, time.perf_counter() - t)
figures = {k: v for k, v in r.items() if isinstance(v, dict)}
print(json.dumps({"time": best, "points": len(cloud), "figures": figures}))
"""


def main():
    ap = mesh_parser(__doc__, repeat=5)
    ap.add_argument("--cloud", required=True, help="a mission's cloud.ply")
    ap.add_argument("--against", help="another checkout to time the refresh in, in the same run")
    args = ap.parse_args()
    mesh = str(Path(args.mesh or nbvkit.default_mesh_path()).resolve())
    cloud = str(Path(args.cloud).resolve())
    rows = [
        (label, run_snippet(TIME_SNIPPET, (mesh, cloud, args.repeat), py))
        for label, py in checkouts(args.against)
    ]
    for label, r in rows:
        cov = {k: round(v * 100, 2) for k, v in r["figures"]["coverage"].items()}
        print(
            f"  {label}: {r['time'] * 1e3:.0f} ms per refresh of {r['points']:,} points "
            f"(best of {args.repeat}); coverage % {cov}"
        )
    if len(rows) == 2:
        (_, a), (_, b) = rows
        same = json.dumps(a["figures"], sort_keys=True) == json.dumps(b["figures"], sort_keys=True)
        print(f"  {b['time'] / a['time']:.2f}x faster than {rows[1][0]}; same figures: {same}")


if __name__ == "__main__":
    main()
