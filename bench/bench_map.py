"""Map integration speed through the Python API: OccupancyMap.integrate (fast) vs integrate_exact.

Prints, for 640x480 camera frames of the default airliner (or --mesh) from 8 poses on a ring of
radius 10 m around it at z = 4 m, integrated in sequence into a 0.2 m map over the paper's
40 x 40 x 10 m workspace: ms per frame of the fast path and of integrate_exact (OctoMap's own
computeUpdate + updateNode loop, i.e. insertPointCloud with the free rays in the same key sets)
in the same run, their ratio, the agreement of the two maps (share of cells touched by either
whose free/occupied/unknown state is the same), and the time of total_entropy().
The C++ benchmark bench/bench_map.cpp also times a bare octomap::OcTree (no mirror).

--mission flies a mission instead (Scenario 5, start 0, on the structure; --scenario to change)
with two shadow maps beside the mission's: every scan the mission integrates (the profile's laser
scans, and every camera frame, which the mission's map takes through integrate_frame with the
camera cloud and observations) is also integrated into one shadow with the fast path and into
the other with integrate_exact, and every other change of the map (the vehicle's free path,
predicted cells) is made in all three. The shadows' octrees are brought up to date before each
timed call. Prints ms per camera frame for both and their ratio: the issue's baseline on the
mission's own frames and maps.

--against DIR times the fast path in this checkout and in another one (DIR/python, or a saved
package), alternating, in the same run: the 8 frames integrated again and again into one map
that already holds them (a mission's steady state: the scratch the integration keeps between
frames, or hands back after each, counts here), and checks both maps end the same.

Run: .venv/bin/python bench/bench_map.py [--mesh PATH] [--repeat N] [--mission [--scenario S]]
     .venv/bin/python bench/bench_map.py --against /tmp/before [--repeat N]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import nbvkit
from _timing import alternate, bench_mesh, mesh_parser

# Runs in either checkout: ms per frame of the fast path, frames integrated again into a map
# that holds them, and a digest of the final map.
AGAIN_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
import nbvkit
sys.path.insert(0, sys.argv[1])
from _timing import bench_mesh
mesh, lo, hi, c = bench_mesh(sys.argv[2] or None)
cam = nbvkit.DepthCamera(mesh)
poses = [(c[0] + 10 * np.cos(t), c[1] + 10 * np.sin(t), 4.0, t + np.pi)
         for t in np.arange(8) * np.pi / 4]
scans = [cam.scan_pose(p) for p in poses]
m = nbvkit.OccupancyMap(0.2)
for s in scans:
    m.integrate(s)
ms = []
for _ in range(int(sys.argv[3])):
    for s in scans:
        t = time.perf_counter()
        m.integrate(s)
        ms.append((time.perf_counter() - t) * 1e3)
digest = hashlib.sha1(np.ascontiguousarray(m.log_odds_grid()).tobytes()).hexdigest()
print(json.dumps({"ms": float(np.median(ms)), "digest": digest}))
"""


def against(args) -> None:
    """The fast path in both checkouts, alternating (see the module's doc)."""
    bench = str(Path(__file__).resolve().parent)
    snippet_args = (bench, args.mesh or "", args.repeat)
    ((la, ta), (lb, tb)), same = alternate(AGAIN_SNIPPET, snippet_args, args.against, 3, "ms")
    print(
        f"8 frames integrated again into a map holding them, best of 3 runs of {args.repeat} "
        f"passes each, {nbvkit.get_num_threads()} threads"
    )
    print(f"  fast path: {la} {ta:.2f} ms, {lb} {tb:.2f} ms per frame -> {tb / ta:.2f}x")
    print(f"  the same final map: {same}")


def agreement(a: nbvkit.OccupancyMap, b: nbvkit.OccupancyMap) -> float:
    sa, sb = a.state_grid(), b.state_grid()
    touched = (sa != nbvkit.CellState.UNKNOWN) | (sb != nbvkit.CellState.UNKNOWN)
    return float((sa[touched] == sb[touched]).mean())


def mission(args) -> None:
    """The camera frames of a mission, integrated by two shadow maps beside the mission's own:
    one with the fast path, one with integrate_exact (see the module's doc)."""
    from nbvkit import _core
    from nbvkit.config import Config
    from nbvkit.mission import Mission

    cls = nbvkit.OccupancyMap
    real = {k: getattr(cls, k) for k in ("integrate", "mark_free_segment", "set_unknown_cells")}
    real_frame = _core.integrate_frame  # the mission's camera frames: map, cloud, observations
    state = {"map": None, "fast": None, "exact": None}
    ms = {"fast": [], "exact": []}

    def shadows(scan, *a, **kw):
        """The scan into both shadows, each timed (a camera frame's times kept)."""
        fast, exact = state["fast"], state["exact"]
        fast.octree_num_nodes  # brings the octrees up to date (not timed)
        exact.octree_num_nodes
        t0 = time.perf_counter()
        real["integrate"](fast, scan, *a, **kw)
        t1 = time.perf_counter()
        exact.integrate_exact(scan, *a, **kw)
        t2 = time.perf_counter()
        if len(scan.hits) + len(scan.free_ends) > 10000:  # a camera frame, not a laser scan
            ms["fast"].append((t1 - t0) * 1e3)
            ms["exact"].append((t2 - t1) * 1e3)

    def integrate(self, scan, *a, **kw):
        if self is state["map"]:
            shadows(scan, *a, **kw)
        return real["integrate"](self, scan, *a, **kw)

    def integrate_frame(occ_map, cloud, surface, scan, **kw):
        if occ_map is state["map"]:
            extra = {"max_range": kw["max_range"]} if "max_range" in kw else {}
            shadows(scan, **extra)
        return real_frame(occ_map, cloud, surface, scan, **kw)

    def both(name):
        def call(self, *a, **kw):
            if self is state["map"]:
                real[name](state["fast"], *a, **kw)
                real[name](state["exact"], *a, **kw)
            return real[name](self, *a, **kw)

        return call

    cls.integrate = integrate
    _core.integrate_frame = integrate_frame
    cls.mark_free_segment = both("mark_free_segment")
    cls.set_unknown_cells = both("set_unknown_cells")
    over = [f"scenario={args.scenario}", "start=0", "progress=false", "report.enabled=false"]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    m = Mission(Config().with_overrides(over))
    fm = m.world.map
    lo, hi = fm.bounds
    state["map"] = fm
    for k in ("fast", "exact"):
        state[k] = nbvkit.OccupancyMap(fm.resolution, lo, hi, options=fm.options)
    try:
        m.run()
    finally:
        for k, v in real.items():
            setattr(cls, k, v)
        _core.integrate_frame = real_frame
    f, e = np.array(ms["fast"]), np.array(ms["exact"])
    agree = agreement(state["fast"], state["exact"])
    print(
        f"scenario {args.scenario}, start 0: {len(f)} camera frames, "
        f"{nbvkit.get_num_threads()} threads; final maps agree on {100 * agree:.3f}% of the "
        "cells either touched"
    )
    print(
        f"  ms per frame: fast {f.mean():.2f} (median {np.median(f):.2f}), integrate_exact "
        f"{e.mean():.1f} (median {np.median(e):.1f}) -> {e.sum() / f.sum():.1f}x"
    )


def main():
    ap = mesh_parser(__doc__, repeat=3)
    ap.add_argument("--mission", action="store_true", help="a mission's frames (see above)")
    ap.add_argument("--scenario", default="5")
    ap.add_argument("--against", help="another checkout to time the fast path in (see above)")
    args = ap.parse_args()
    if args.mission:
        return mission(args)
    if args.against:
        return against(args)
    mesh, lo, hi, c = bench_mesh(args.mesh)
    cam = nbvkit.DepthCamera(mesh)
    poses = [
        (c[0] + 10 * np.cos(t), c[1] + 10 * np.sin(t), 4.0, t + np.pi)
        for t in np.arange(8) * np.pi / 4
    ]
    scans = [cam.scan_pose(p) for p in poses]
    fast_ms = np.zeros((args.repeat, len(scans)))
    exact_ms = np.zeros_like(fast_ms)
    agree = []
    for rep in range(args.repeat):
        fast, exact = nbvkit.OccupancyMap(0.2), nbvkit.OccupancyMap(0.2)
        for i, s in enumerate(scans):
            t0 = time.perf_counter()
            fast.integrate(s)
            fast_ms[rep, i] = (time.perf_counter() - t0) * 1e3
            t0 = time.perf_counter()
            exact.integrate_exact(s)
            exact_ms[rep, i] = (time.perf_counter() - t0) * 1e3
            if rep == 0:
                agree.append(agreement(fast, exact))
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        fast.total_entropy()
    te_us = (time.perf_counter() - t0) / n * 1e6
    t0 = time.perf_counter()
    fast.recompute_total_entropy()
    tre_ms = (time.perf_counter() - t0) * 1e3
    f, e = np.median(fast_ms, axis=0), np.median(exact_ms, axis=0)
    print(
        f"{len(scans)} frames {cam.width}x{cam.height}, map 0.2 m over (-20,-20,0)-(20,20,10), "
        f"{nbvkit.get_num_threads()} threads; median of {args.repeat} runs"
    )
    print(f"{'frame':>5} {'hits':>7} {'fast ms':>8} {'exact ms':>9} {'ratio':>6} {'agree':>8}")
    for i, s in enumerate(scans):
        print(
            f"{i:5d} {len(s.hits):7d} {f[i]:8.2f} {e[i]:9.1f} "
            f"{e[i] / f[i]:5.1f}x {100 * agree[i]:7.3f}%"
        )
    print(
        f"median: fast {np.median(f):.2f} ms, exact {np.median(e):.1f} ms, "
        f"ratio {np.median(e) / np.median(f):.1f}x; "
        f"worst agreement {100 * min(agree):.3f}%"
    )
    print(
        f"total_entropy(): {te_us:.2f} us per call from Python (incremental); "
        f"recompute_total_entropy(): {tre_ms:.2f} ms"
    )


if __name__ == "__main__":
    main()
