"""Where the observable surface a mission on a large structure missed lies: flies the structure
(defaults but for the view cap and --set), then sorts the observable ground-truth samples (the
level camera's, nbvkit.observable_surface) it did not see (no cloud point within 5 cm) by what
the map holds at them (unknown, occupied, free) and by their distance to the nearest view flown.
Shares are of the observable samples. Meshes come from bench/large_structures.py.

    .venv/bin/python bench/large_missed.py --seed 2 --views 1000
    .venv/bin/python bench/large_missed.py --seed 1 --views 1000 --set utility.unknown_prior=0.05

The observable surface of a layout is cached in --cache (minutes the first time on a plant).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
from large_structures import structure_parser, write_structure  # noqa: E402

from nbvkit.config import load_config  # noqa: E402
from nbvkit.mission import Mission  # noqa: E402
from nbvkit.observability import observable_surface  # noqa: E402

STATES = {-1: "unknown", 1: "occupied", 0: "free"}
DISTANCES = (0.0, 8.0, 16.0, np.inf)  # m to the nearest view: within the camera's reach, ...


def missed(mission, config, cache: str, seen_within: float = 0.05) -> dict:
    """Shares of the observable samples: covered (area_coverage_observable at 0.05 m), missed,
    and the missed by map state and by distance to the nearest view."""
    ev = mission.evaluator
    points = np.asarray(ev.gt_points)
    observable = observable_surface(mission.mesh, config, evaluator=ev, cache_dir=cache).observable
    ev.set_observable(observable)
    cloud = np.asarray(mission.cloud_points())
    covered = ev.coverage(cloud)["area_coverage_observable"]["0.05"]
    d, _ = cKDTree(cloud).query(points, distance_upper_bound=2 * seen_within, workers=-1)
    miss = observable & (d > seen_within)
    views = np.array([[r.x, r.y, r.z] for r in mission.records])
    to_view = cKDTree(views).query(points[miss], workers=-1)[0]
    state = np.asarray(mission.map.state(points[miss]))
    n = observable.sum()
    out = {
        "observable share": observable.mean(),
        "covered (cells)": covered,
        "missed": miss.sum() / n,
    }
    for s, name in STATES.items():
        out[f"missed, map {name}"] = (state == s).sum() / n
    for lo, hi in zip(DISTANCES[:-1], DISTANCES[1:]):
        out[f"missed, {lo:g}-{hi:g} m from a view"] = ((to_view >= lo) & (to_view < hi)).sum() / n
    return out


def main() -> None:
    ap = structure_parser(__doc__, seed=1)
    ap.add_argument("--views", type=int, default=1000, help="the view cap (default 1000)")
    ap.add_argument("--set", nargs="*", default=[], help="config overrides")
    ap.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "nbvkit-observable"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = write_structure(a.structure, a.seed, tmp)
        over = [f"mesh.path={path}", f"max_iterations={a.views}", "progress=false"]
        over += ["report.enabled=false", "observability.enabled=false", *a.set]
        config = load_config(overrides=over)
        mission = Mission(config)
        s = mission.run()
        print(f"{a.structure} seed {a.seed}, {a.views} views at most {' '.join(a.set)}")
        print(
            f"area cov. @0.05 m {100 * s['area_coverage']['0.05']:.2f} %, "
            f"{s['distance_m']:,.0f} m, {s['views']} views, {len(s['tours'])} plans"
        )
        for key, share in missed(mission, config, a.cache).items():
            print(f"  {key}: {100 * share:.1f} %")


if __name__ == "__main__":
    main()
