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

--threads N [N ...] flies each code at each thread count (nbvkit.set_num_threads), alternating,
and prints how each stage scales from the fewest threads to the most: the speed-up, the share of
the stage that ran in parallel (Amdahl's p from the two), and what that share would make of the
stage on 8 and 16 cores (a projection: measured only up to this machine's cores).

    .venv/bin/python bench/bench_mission.py --mesh M --set max_iterations=150 --threads 1 2
"""
from __future__ import annotations

from _timing import checkouts, mesh_parser, run_snippet, table_header

FLY_SNIPPET = r"""
import hashlib, json, resource, sys, tempfile, time
from pathlib import Path
from nbvkit.config import load_config
from nbvkit.mission import Mission
args = [a for a in sys.argv[2:] if not a.startswith("--threads=")]
for a in sys.argv[2:]:
    if a.startswith("--threads="):
        import nbvkit
        nbvkit.set_num_threads(int(a.split("=", 1)[1]))
over = ["progress=false", "report.enabled=false", "observability.enabled=false", *args]
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
    ap.add_argument(
        "--threads", nargs="*", type=int, default=[], help="thread counts to fly each code at"
    )
    a = ap.parse_args()
    if any(n < 1 for n in a.threads):
        ap.error("--threads: counts of 1 or more")
    arms = [(label, package, []) for label, package in checkouts(a.against)]
    if a.against_set:
        arms.append(("with " + " ".join(a.against_set), None, a.against_set))
    if a.threads:
        arms = [
            (f"{label}, {n} thread{'s' if n > 1 else ''}", package, [*extra, f"--threads={n}"])
            for label, package, extra in arms
            for n in sorted(set(a.threads))
        ]
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
    if len(set(a.threads)) > 1:
        scaling(runs, sorted(set(a.threads)))
    elif len(runs) == 2:
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


def scaling(runs: dict, counts: list) -> None:
    """Per code, each stage's best time at the fewest threads (t1) and the most (tn): speed-up,
    Amdahl's parallel share p = (1 - tn / t1) / (1 - 1 / n) (at most 1; n the ratio of the two
    counts), and t1 * ((1 - p) + p * fewest / c) for c = 8 and 16 threads."""
    lo, hi = counts[0], counts[-1]
    n = hi / lo
    print(f"\nscaling from {lo} to {hi} threads (best of the rounds; 8 and 16: projected)")
    print("| code | stage | ms a view | speed-up | parallel share | 8 cores | 16 cores |")
    print("|---|---|---|---|---|---|---|")
    codes = {}
    for label, rr in runs.items():
        code, count = label.rsplit(", ", 1)
        codes.setdefault(code, {})[int(count.split()[0])] = rr
    for code, by in codes.items():
        for stage in (*STAGES, "every stage"):

            def best(rr):
                if stage == "every stage":
                    return min(sum(r["stages"].values()) for r in rr)
                return min(r["stages"].get(stage, 0.0) for r in rr)

            t1, tn = best(by[lo]), best(by[hi])
            if t1 <= 0:
                continue
            p = min(1.0, max(0.0, (1 - tn / t1) / (1 - 1 / n)))
            at = [t1 * ((1 - p) + p / (c / lo)) for c in (8, 16)]
            print(
                f"| {code} | {stage} | {t1:.1f} / {tn:.1f} | {t1 / tn:.2f} x | {p:.3f} | "
                f"{at[0]:.1f} | {at[1]:.1f} |"
            )


if __name__ == "__main__":
    main()
