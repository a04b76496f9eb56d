"""Map integration speed through the Python API: OccupancyMap.integrate (fast) vs integrate_exact.

Prints, for 640x480 camera frames of the default airliner (or --mesh) from 8 poses on a ring of
radius 10 m around it at z = 4 m, integrated in sequence into a 0.2 m map over the paper's
40 x 40 x 10 m workspace: ms per frame of the fast path and of integrate_exact (OctoMap's own
computeUpdate + updateNode loop, i.e. insertPointCloud with the free rays in the same key sets)
in the same run, their ratio, the agreement of the two maps (share of cells touched by either
whose free/occupied/unknown state is the same), and the time of total_entropy().
The C++ benchmark bench/bench_map.cpp also times a bare octomap::OcTree (no mirror).
Run: .venv/bin/python bench/bench_map.py [--mesh PATH] [--repeat N]
"""
from __future__ import annotations

import time

import numpy as np

import nbvkit
from _timing import bench_mesh, mesh_parser


def agreement(a: nbvkit.OccupancyMap, b: nbvkit.OccupancyMap) -> float:
    sa, sb = a.state_grid(), b.state_grid()
    touched = (sa != nbvkit.CellState.UNKNOWN) | (sb != nbvkit.CellState.UNKNOWN)
    return float((sa[touched] == sb[touched]).mean())


def main():
    args = mesh_parser(__doc__, repeat=3).parse_args()
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
