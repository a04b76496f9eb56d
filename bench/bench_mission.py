"""A whole mission's cost per view, by stage, with this checkout and (--against DIR) another one,
alternating, each mission in a process of its own: the `ms_per_stage` of summary.json (tour
planning is `sampling`), wall time and peak memory, and whether both fly the same views (a digest
of the trajectory). Default: what `make` flies (the shipped airliner, the recommended planner,
start 0).

    .venv/bin/python bench/bench_mission.py --against /tmp/before --rounds 2
    .venv/bin/python bench/bench_mission.py --mesh M --set scenario=5 start=1
    .venv/bin/python bench/bench_mission.py --mesh M --against-set planner.frame_novelty=0

DIR is another checkout (DIR/python) or a saved copy of a built package (its folder's parent);
--against-set flies this checkout again with more overrides (a setting against its default).
"""
from __future__ import annotations

from _timing import checkouts, mesh_parser, run_snippet, table_header

FLY_SNIPPET = r"""
import hashlib, json, resource, sys, tempfile, time
from pathlib import Path
from nbvkit.config import load_config
from nbvkit.mission import Mission
over = ["progress=false", "report.enabled=false", "observability.enabled=false", *sys.argv[2:]]
if sys.argv[1]:
    over.append(f"mesh.path={sys.argv[1]}")
t = time.perf_counter()
with tempfile.TemporaryDirectory() as tmp:
    s = Mission(load_config(overrides=over)).run(Path(tmp) / "run")
    digest = hashlib.sha1((Path(tmp) / "run" / "trajectory.csv").read_bytes()).hexdigest()
print(json.dumps({
    "stages": s["ms_per_stage"], "views": s["views"], "wall_s": time.perf_counter() - t,
    "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    "coverage": s["area_coverage"]["0.05"], "distance": s["distance_m"], "digest": digest}))
"""

STAGES = ("sampling", "sensing", "mapping", "selection")


def main() -> None:
    ap = mesh_parser(__doc__)
    ap.add_argument("--against", help="another checkout (or saved package) to fly, alternating")
    ap.add_argument(
        "--against-set", nargs="*", default=[], help="or this checkout with these overrides too"
    )
    ap.add_argument("--rounds", type=int, default=1, help="missions each way (default 1)")
    ap.add_argument("--set", nargs="*", default=[], help="config overrides for every mission")
    a = ap.parse_args()
    arms = [(label, package, []) for label, package in checkouts(a.against)]
    if a.against_set:
        arms.append(("with " + " ".join(a.against_set), None, a.against_set))
    runs = {label: [] for label, _, _ in arms}
    table_header(
        "views",
        "ms per view: " + ", ".join(STAGES),
        "every stage",
        "wall",
        "peak",
        "cov. @0.05 m",
        "flown",
        "digest",
    )
    for _ in range(a.rounds):
        for label, package, extra in arms:
            r = run_snippet(FLY_SNIPPET, [a.mesh or "", *a.set, *extra], package)
            runs[label].append(r)
            ms = ", ".join(f"{r['stages'].get(s, 0.0):.1f}" for s in STAGES)
            print(
                f"| {label} | {r['views']} | {ms} | {sum(r['stages'].values()):.1f} | "
                f"{r['wall_s']:.1f} s | "
                f"{r['peak_mb']:.0f} MB | {100 * r['coverage']:.2f} % | {r['distance']:.1f} m | "
                f"{r['digest'][:12]} |",
                flush=True,
            )
    if len(runs) == 2:
        (la, ra), (lb, rb) = runs.items()
        same = len({r["digest"] for rr in runs.values() for r in rr}) == 1
        for stage in ("sampling", "view", "every stage", "wall_s"):
            get = {
                "wall_s": lambda r: r["wall_s"],
                "view": lambda r: sum(r["stages"].get(s, 0.0) for s in STAGES),
                "every stage": lambda r: sum(r["stages"].values()),
            }.get(stage, lambda r: r["stages"][stage])
            best_a, best_b = min(map(get, ra)), min(map(get, rb))
            print(f"{stage}: best {best_a:.2f} against {best_b:.2f} -> {best_b / best_a:.2f}x")
        print(f"the same flight in every mission: {same}")


if __name__ == "__main__":
    main()
