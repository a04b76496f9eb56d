"""End-of-run mesh speed: nbvkit.report.reconstruct_mesh (voxel thinning, normals, Poisson,
trimming) on a mission's cloud, as a mission or an experiment run writes its mesh.ply.

``--against DIR`` times the same call, on the same cloud and in the same run, with the nbvkit
package (and its built extension) of another checkout, DIR/python or DIR (e.g. a saved copy of the
package before a change), and prints the ratio. Prints figures; asserts nothing.

    .venv/bin/python bench/bench_mesh.py                      # runs/main/cloud.ply (`make`)
    .venv/bin/python bench/bench_mesh.py --cloud runs/x2/cloud.ply --depth 7 --against /tmp/old
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from _timing import checkouts, run_snippet

ROOT = Path(__file__).resolve().parent.parent

# Runs in this checkout or, through --against, in another one.
SNIPPET = r"""
import json, sys, time
import numpy as np
from nbvkit.cloud import read_points
from nbvkit.config import Config
from nbvkit.report import reconstruct_mesh
pts = read_points(sys.argv[1])
depth, repeat = int(sys.argv[2]), int(sys.argv[3])
rep = Config().report
best, info = float("inf"), None
for _ in range(repeat):
    t = time.perf_counter()
    mesh, info = reconstruct_mesh(pts, depth=depth, max_points=rep.mesh_max_points,
                                  density_quantile=rep.density_quantile,
                                  trim_distance=rep.trim_distance)
    best = min(best, time.perf_counter() - t)
print(json.dumps({"points": len(pts), "s": best,
                  **{k: info.get(k) for k in ("points_used", "voxel_m", "triangles", "area_m2")}}))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cloud", default=str(ROOT / "runs" / "main" / "cloud.ply"))
    ap.add_argument("--depth", type=int, default=8, help="Poisson depth (missions 8, tables 7)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--against", help="another checkout to time the same call in, in the same run")
    args = ap.parse_args()
    cloud = Path(args.cloud).resolve()
    if not cloud.is_file():
        sys.exit(f"no cloud at {cloud}: run `make` first (it writes runs/main) or pass --cloud")
    rows = [
        (label, run_snippet(SNIPPET, (cloud, args.depth, args.repeat), py))
        for label, py in checkouts(args.against)
    ]
    print(f"{cloud}: {rows[0][1]['points']:,} points, Poisson depth {args.depth}")
    for label, r in rows:
        print(
            f"  {label}: {r['s']:.2f} s best of {args.repeat} ({r['points_used']:,} points "
            f"thinned at {r['voxel_m']:.3f} m, {r['triangles']:,} triangles, "
            f"{r['area_m2']:.0f} m^2)"
        )
    if len(rows) == 2:
        print(f"  {rows[1][1]['s'] / rows[0][1]['s']:.2f}x faster than {rows[1][0]}")


if __name__ == "__main__":
    main()
