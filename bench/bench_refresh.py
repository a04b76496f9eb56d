"""Benchmark of a mission's progress refresh: Evaluator.coverage over the mission's clouds, read
in place (the cell figures of an evaluation: coverage, area coverage and precision at each
resolution, without distances), which `nbvkit compare` runs every 5 views and `nbvkit run` every
25. Prints figures.

    .venv/bin/python bench/bench_refresh.py --cloud runs/main/cloud.ply            # airliner
    .venv/bin/python bench/bench_refresh.py --mesh M.obj --cloud RUN/cloud.ply --against DIR
    .venv/bin/python bench/bench_refresh.py --mission [--scenario 5] [--every 25]

``--cloud``: one count from scratch (``evaluate_cells_of``) of a finished mission's cloud, put in
a SurfaceCloud at the camera's 0.02 m voxel as a mission keeps it. ``--against DIR`` times the
same count, in the same run, with the nbvkit package of another checkout (DIR/python or DIR) and
prints the ratio and whether every figure is the same.

``--mission``: flies a mission and, at every refresh, times the refresh as missions make it (the
evaluator's CoverageTracker, which looks again only at the voxels added or moved since the last
refresh) against a count from scratch of the same clouds, in alternating order, and asserts that
both give the same figures.
"""
from __future__ import annotations

import json
import time
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
count = getattr(ev._core, "evaluate_cells_of")  # a count from scratch, no tracker
count([cloud])  # warm-up
best = float("inf")
for _ in range(int(sys.argv[3])):
    t = time.perf_counter()
    r = count([cloud])
    best = min(best, time.perf_counter() - t)
figures = {k: v for k, v in nbvkit.evaluation._to_dict(r).items() if isinstance(v, dict)}
print(json.dumps({"time": best, "points": len(cloud), "figures": figures}))
"""


def mission(args) -> None:
    """Times every refresh of a mission both ways (see the module's docstring)."""
    from nbvkit import evaluation, mission
    from nbvkit.config import Config

    spent = {"tracked": 0.0, "scratch": 0.0}
    calls = [0]
    state = [0]  # the tracker's bytes after the last refresh

    class Paired(evaluation.Evaluator):
        def coverage(self, cloud):
            def tracked():
                return super(Paired, self).coverage(cloud)

            def scratch():
                return evaluation._to_dict(self._core.evaluate_cells_of(list(cloud)))

            out = {}
            calls[0] += 1
            order = (tracked, scratch) if calls[0] % 2 else (scratch, tracked)
            for fn in order:
                t = time.perf_counter()
                out[fn.__name__] = fn()
                spent[fn.__name__] += time.perf_counter() - t
            for k, v in out["tracked"].items():
                assert v == out["scratch"][k], f"{k} differs in refresh {calls[0]}"
            state[0] = self._tracker.bytes  # (the tracker is let go at the end of the run)
            return out["tracked"]

    mission.Evaluator = Paired
    over = [
        f"scenario={args.scenario}",
        f"start={args.start}",
        f"evaluation.coverage_every={args.every}",
        "progress=false",
        "report.enabled=false",
    ]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    m = mission.Mission(Config().with_overrides(over))
    m.run()
    n = calls[0]
    points = len(m.world.camera_cloud) + len(m.world.laser_cloud)
    print(
        f"scenario {args.scenario}, start {args.start}: {n} refreshes over {len(m.records)} "
        f"iterations, {points:,} cloud points at the end "
        f"(threads: {nbvkit.get_num_threads()})"
    )
    a, b = 1e3 * spent["tracked"] / n, 1e3 * spent["scratch"] / n
    print(
        f"  ms per refresh: tracked {a:.1f}, counted from scratch {b:.1f} -> {b / a:.1f}x; "
        f"in all {spent['tracked']:.2f} s against {spent['scratch']:.2f} s"
    )
    print(f"  tracker state at the end: {state[0] / 1e6:.1f} MB; every refresh the same")


def main():
    ap = mesh_parser(__doc__, repeat=5)
    ap.add_argument("--cloud", help="a mission's cloud.ply")
    ap.add_argument("--against", help="another checkout to time the refresh in, in the same run")
    ap.add_argument("--mission", action="store_true", help="time every refresh of a mission")
    ap.add_argument("--scenario", default="5")
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--every", type=int, default=25, help="views between two refreshes")
    args = ap.parse_args()
    if args.mission:
        return mission(args)
    if not args.cloud:
        ap.error("--cloud or --mission is required")
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
