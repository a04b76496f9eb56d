"""The end-of-run evaluation of a large structure's cloud: its time and the memory it adds, with
this checkout and (--against DIR) another one, each in a process of its own, in the same run,
and whether every figure is the same. The cloud: a noisy sample of the part of a generated
structure (bench/large_structures.py, a layout per seed) below 55 % of its length, through the
camera's 0.02 m voxel filter, as a flight that saw about half of it; the ground truth: the
evaluator's default (1,000 samples per m^2, capped at 8 M).

    .venv/bin/python bench/bench_final_evaluation.py --points 60e6 --against /tmp/before

DIR is another checkout (DIR/python) or a saved copy of a built package (its folder's parent).
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from large_structures import compare_on_structure, structure_parser  # noqa: E402

SNIPPET = r"""
import json, resource, sys, time, warnings
import numpy as np
import nbvkit
from nbvkit.cloud import PointCloud
from nbvkit.evaluation import Evaluator
def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20
mesh = nbvkit.load_mesh(sys.argv[1])
n, rng, cloud = int(float(sys.argv[2])), np.random.default_rng(0), PointCloud()
cut = mesh.bounds[0][0] + 0.55 * (mesh.bounds[1][0] - mesh.bounds[0][0])
for s in range(8):
    p = mesh.sample_surface(n // 8, seed=s + 1)
    p = p[p[:, 0] < cut]
    cloud.add(p + rng.normal(0, 0.004, p.shape))
t0 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # the sample cap's warning
    ev = Evaluator(mesh)
held = rss_mb()
t = time.perf_counter()
r = ev([cloud])
end = time.perf_counter()
print(json.dumps({"s": end - t, "with_gt_s": end - t0, "held_mb": held,
    "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "points": len(cloud),
    "figures": {k: r[k] for k in ("coverage", "area_coverage", "completeness", "accuracy")},
    "chamfer_m": r["chamfer_m"]}))
"""


def main() -> None:
    ap = structure_parser(__doc__, seed=2)
    ap.add_argument("--points", type=float, default=60e6, help="points sampled (default 60e6)")
    a = ap.parse_args()
    rows = compare_on_structure(
        a,
        f"{a.points:.3g} points sampled over 55 % of it",
        ("cloud", "evaluation", "with the ground truth", "held before", "peak", "chamfer"),
        SNIPPET,
        [a.points],
        lambda label, r: f"| {label} | {r['points']:,} points | {r['s']:.1f} s | "
        f"{r['with_gt_s']:.1f} s | {r['held_mb'] / 1024:.2f} GB | "
        f"{r['peak_mb'] / 1024:.2f} GB | {r['chamfer_m']!r} m |",
    )
    if len(rows) == 2:
        now, then = rows
        print(
            f"time ratio (this / {a.against}): {now['s'] / then['s']:.2f}, with the ground "
            f"truth {now['with_gt_s'] / then['with_gt_s']:.2f}; peak ratio: "
            f"{now['peak_mb'] / then['peak_mb']:.2f}; the same coverage, completeness and "
            f"accuracy: {'yes' if now['figures'] == then['figures'] else 'NO'}"
        )


if __name__ == "__main__":
    main()
