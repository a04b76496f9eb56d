"""Peak memory of a mission on a large structure, results folder written (the end-of-run outputs
but the report: the observable surface computed anew), with this checkout and
(--against DIR) another one or (--baseline OVERRIDES) this one with other settings, each in a
process of its own, in the same run: the peak resident
memory (ru_maxrss), what the flight reached (which must not change: the same views, the same
coverage) and the ratio of the peaks; also how much of the surface its views were expected to
bring they brought (realized_to_expected, new_surface_to_expected) and the time a view took.
Meshes come from bench/large_structures.py (a layout per seed, never tuned on). --views 0 flies
to the end (the view cap that follows the structure).

    .venv/bin/python bench/large_memory.py --seed 1 --views 300 --against /tmp/before
    .venv/bin/python bench/large_memory.py --structure bridge --seed 3 --views 300
    .venv/bin/python bench/large_memory.py --seed 2 --views 0
    .venv/bin/python bench/large_memory.py --seed 3 --views 1000 --baseline tour.pool_unknown=false

DIR is another checkout (DIR/python) or a saved copy of a built package (its folder's parent).
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from large_structures import compare_on_structure, structure_parser  # noqa: E402

FLY_SNIPPET = r"""
import json, resource, sys, tempfile, time
from pathlib import Path
from nbvkit.config import load_config
from nbvkit.mission import Mission
cfg = load_config(overrides=[
    f"mesh.path={sys.argv[1]}", f"max_iterations={sys.argv[2]}", "progress=false",
    "report.enabled=false", *sys.argv[3:]])
t = time.perf_counter()
with tempfile.TemporaryDirectory() as tmp:  # the end-of-run outputs: the observable surface
    s = Mission(cfg).run(Path(tmp) / "run", finish=True)
print(json.dumps({
    "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    "summary_peak_mb": s["peak_memory_mb"], "coverage": s["area_coverage"]["0.05"],
    "distance": s["distance_m"], "views": s["views"], "cloud_points": s["cloud_points"],
    "realized": s["realized_to_expected"], "first_seen": s["new_surface_to_expected"],
    "planning_ms": s["ms_per_stage"]["sampling"], "ms_per_view": s["ms_per_iteration"],
    "termination": s["termination"], "wall_s": time.perf_counter() - t}))
"""


def main() -> None:
    ap = structure_parser(__doc__, seed=1)
    ap.add_argument(
        "--views", type=int, default=300, help="the view cap (default 300; 0: the structure's own)"
    )
    ap.add_argument("--set", nargs="*", default=[], help="config overrides for both runs")
    ap.add_argument(
        "--baseline",
        nargs="*",
        default=[],
        help="config overrides of a second run of this checkout to compare with (after --set)",
    )
    a = ap.parse_args()
    rows = compare_on_structure(
        a,
        f"{a.views or 'its own cap of'} views at most, results folder written",
        (
            "peak (end of run)",
            "summary.json's",
            "area cov. @0.05 m",
            "flown",
            "views",
            "realized / expected",
            "first seen / expected",
            "cloud",
            "planning a view",
            "a view",
            "wall",
        ),
        FLY_SNIPPET,
        [a.views or "null", *a.set],
        lambda label, r: f"| {label} | {r['peak_mb'] / 1024:.2f} GB | "
        f"{r['summary_peak_mb'] / 1024:.2f} GB | {100 * r['coverage']:.2f} % | "
        f"{r['distance']:,.0f} m | {r['views']:,} ({r['termination']}) | {r['realized']:.2f} | "
        f"{r['first_seen']:.2f} | {r['cloud_points']:,} points | {r['planning_ms']:.1f} ms | "
        f"{r['ms_per_view']:.1f} ms | {r['wall_s']:.0f} s |",
        a.baseline,
    )
    if len(rows) == 2:
        now, then = rows
        same = all(now[k] == then[k] for k in ("coverage", "distance", "views", "cloud_points"))
        print(
            f"peak ratio (this / {a.against or ' '.join(a.baseline)}): "
            f"{now['peak_mb'] / then['peak_mb']:.2f}; "
            f"the same flight: {'yes' if same else 'NO'}"
        )


if __name__ == "__main__":
    main()
