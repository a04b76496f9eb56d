"""Coverage-tour planning speed: the first tour the recommended planner plans on the airliner (or
--mesh) after its profile - the candidate views' coverage (view_coverage) and the prize-collecting
insertion over them (select_tour, with and without charging the first transit, and both at once
as the tour generator asks for them: select_tours, one inverse of the coverage, the two tours in
parallel), and the rise of the peak resident memory the selections bring.

``--against DIR`` times both, in the same run, with the nbvkit package (and its built extension)
of another checkout, DIR/python or DIR (e.g. a saved copy of the package before a change): each
checkout flies the profile and times view_coverage over the same candidates (alternating, best of
--repeat each), then select_tour on the same coverage; it checks that both give the same coverage
arrays, and choose the same views with the same gains, and prints the ratios.

    .venv/bin/python bench/bench_tour.py
    .venv/bin/python bench/bench_tour.py --against /tmp/main_before --repeat 5
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

import nbvkit
from _timing import alternate, checkouts, median_time, mesh_parser, run_snippet
from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.planning.registry import get_generator
from nbvkit.profiling import run_profiling
from nbvkit.symmetry import run_symmetry_prediction

# Runs in this checkout or, through --against, in another one: only select_tour's array API.
TIME_SNIPPET = r"""
import json, sys, time
import numpy as np
from nbvkit import _core
d = np.load(sys.argv[1])
kw = json.loads(sys.argv[2])
cov = {k: d[k] for k in ("offsets", "elements", "weights", "status")}
positions, start = d["positions"], d["start"]
def hwm():  # the peak resident memory since the last reset, GiB (Linux: VmHWM)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 2**20
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # the peak back to the resident memory now, the coverage loaded
rss0 = hwm()
out, times = [], []
for charge in (True, False):
    args = (cov, positions, start)
    _core.select_tour(*args, charge_transit=charge, **kw)  # warm-up
    best = float("inf")
    for _ in range(int(sys.argv[3])):
        t = time.perf_counter()
        views, gains = _core.select_tour(*args, charge_transit=charge, **kw)
        best = min(best, time.perf_counter() - t)
    times.append(best)
    out.append([list(map(int, views)), [float(g) for g in gains]])
pair = sum(times)  # both tours, as the tour generator asks for them: one call where it can
if hasattr(_core, "select_tours"):
    pair = float("inf")
    for _ in range(int(sys.argv[3])):
        t = time.perf_counter()
        both = _core.select_tours(cov, positions, start, charges=[True, False], **kw)
        pair = min(pair, time.perf_counter() - t)
    assert [[list(map(int, v)), [float(x) for x in g]] for v, g in both] == out
rise = hwm() - rss0
print(json.dumps({"times": times, "choice": out, "pair": pair, "rise": rise}))
"""


# Runs in either checkout: the first plan's view_coverage, timed, and a digest of its arrays.
COVERAGE_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
from bench_tour import arrays, first_plan
cov, cands, pose, sel, t, again = first_plan(sys.argv[2] or None, with_again=True)
cov = arrays(cov)
ts = []
for _ in range(int(sys.argv[3])):
    t0 = time.perf_counter()
    again()
    ts.append(time.perf_counter() - t0)
keys = ("offsets", "elements", "weights", "status")
same = [np.asarray(cov[k], np.int64 if k == "elements" else None) for k in keys]  # by value
digest = hashlib.sha1(b"".join(np.ascontiguousarray(a).tobytes() for a in same))
print(json.dumps({"time": min(ts), "digest": digest.hexdigest()}))
"""


def arrays(coverage) -> dict:
    """The CSR arrays of coverage sets: a CoverageSets, or the dict view_coverage returned
    before it (another checkout, --against)."""
    keys = ("offsets", "elements", "weights", "status")
    if isinstance(coverage, dict):
        return {k: coverage[k] for k in keys}
    return {k: getattr(coverage, k) for k in keys}


def first_plan(mesh: str | None, with_again: bool = False, level: float = 1.0):
    """The coverage of the first tour's candidates, its positions and start, the rate and minimum
    gain in the units select_tour takes, and view_coverage's time, as the tour generator computes
    them after the mission's profile and symmetry prediction (with_again: and a function that
    computes the coverage again); level: the gain level of the minimum gain (tour.gain_levels:
    a large workspace's first plan is at 8)."""
    over = ["progress=false"] + ([f"mesh.path={mesh}"] if mesh else [])
    m = Mission(Config().with_overrides(over))
    w, cfg = m.world, m.config
    w.take_off()
    run_profiling(w)
    run_symmetry_prediction(w, write_map=cfg.symmetry.mode == "predict")
    w.sense("view")
    tour = get_generator("tour", cfg)
    cands = tour.candidates(w)[2]
    cov = tour.coverage(w, cands)
    t_cov = median_time(lambda: tour.coverage(w, cands), 1)
    cell = w.map.resolution**2
    sel = {"rate": cfg.tour.rate / cell, "min_gain": level * cfg.tour.min_gain / cell}
    if with_again:
        return cov, cands, w.state.pose, sel, t_cov, lambda: tour.coverage(w, cands)
    return cov, cands, w.state.pose, sel, t_cov


def main():
    ap = mesh_parser(__doc__, repeat=3)
    ap.add_argument("--against", help="another checkout to time select_tour in, in the same run")
    ap.add_argument("--level", type=float, default=1.0, help="multiple of tour.min_gain kept")
    args = ap.parse_args()
    cov, cands, pose, sel, t_cov = first_plan(args.mesh, level=args.level)
    cov = arrays(cov)
    valid = int((cov["status"] == 0).sum())
    print(
        f"first tour: {len(cands)} candidate views ({valid} valid), "
        f"{len(cov['elements']):,} (view, surface element) pairs; "
        f"view_coverage {t_cov * 1e3:.0f} ms on {nbvkit.get_num_threads()} threads"
    )
    with tempfile.TemporaryDirectory() as tmp:
        data = str(Path(tmp) / "coverage.npz")
        np.savez(data, positions=cands[:, :3], start=pose[:3], **cov)
        rows = [
            (label, run_snippet(TIME_SNIPPET, (data, json.dumps(sel), args.repeat), py))
            for label, py in checkouts(args.against)
        ]
    if args.against:  # view_coverage in both checkouts, alternating
        bench = str(Path(__file__).resolve().parent)
        snippet_args = (bench, args.mesh or "", args.repeat)
        ((la, ta), (lb, tb)), same = alternate(COVERAGE_SNIPPET, snippet_args, args.against, 2)
        print(
            f"  view_coverage: {la} {ta * 1e3:.0f} ms, {lb} {tb * 1e3:.0f} ms -> {tb / ta:.2f}x; "
            f"the same arrays: {same}"
        )
    for label, r in rows:
        t = r["times"]
        n = [len(c[0]) for c in r["choice"]]
        print(
            f"  {label}: select_tour {t[0] * 1e3:.0f} ms (transit charged, {n[0]} views) + "
            f"{t[1] * 1e3:.0f} ms (first transit free, {n[1]} views), best of {args.repeat}"
        )
        print(
            f"    both tours as the generator asks for them: {r['pair'] * 1e3:.0f} ms; "
            f"peak resident memory up {r.get('rise', float('nan')):.2f} GiB"
        )
    if len(rows) == 2:
        (_, a), (_, b) = rows
        same = a["choice"] == b["choice"]
        ratio = sum(b["times"]) / sum(a["times"])
        print(f"  {ratio:.2f}x faster than {rows[1][0]}; same views, order and gains: {same}")
        print(f"  both tours: {b['pair'] / a['pair']:.2f}x faster than {rows[1][0]}")


if __name__ == "__main__":
    main()
