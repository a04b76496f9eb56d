"""Path planning speed: A* through known free space (``_core.plan_path``) against the reference
search it replaced (``plan_path(..., reference=True)``, the first implementation: hash maps and a
sphere test per cell), in the same run, on the same map, starts and goals; the paths must be the
same.

The map is a mission's: ``--run DIR`` reads DIR/map.ot, DIR/summary.json (workspace) and
DIR/trajectory.csv (starts: where the vehicle was); otherwise the recommended planner first flies
``--views`` views on ``--mesh`` (default: the shipped airliner). Goals are random positions in the
navigation space whose collision sphere is free (valid views), reachable or not.

    .venv/bin/python bench/bench_paths.py --mesh ../shared/meshes/office_building.obj
    .venv/bin/python bench/bench_paths.py --run runs/surface --goals 60
"""
from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from _timing import mesh_parser
from nbvkit import _core
from nbvkit.config import Config
from nbvkit.mission import Mission


def fly(mesh: str | None, views: int, out: Path) -> Path:
    over = ["progress=false", f"max_iterations={views}"] + ([f"mesh.path={mesh}"] if mesh else [])
    Mission(Config().with_overrides(over)).run(out)
    return out


def main() -> None:
    ap = mesh_parser(__doc__)
    ap.add_argument("--run", default=None, help="a mission's results folder to take the map from")
    ap.add_argument("--views", type=int, default=60, help="views to fly first (without --run)")
    ap.add_argument("--goals", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(a.run) if a.run else fly(a.mesh, a.views, Path(tmp) / "run")
        summary = json.loads((run / "summary.json").read_text())
        ws = summary["workspace"]
        m = _core.OccupancyMap.load(run / "map.ot", ws["bounds_min"], ws["bounds_max"])
        traj = np.loadtxt(run / "trajectory.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3))
        radius = Config.from_yaml(run / "config.yaml").vehicle.collision_radius  # the mission's
    rng = np.random.default_rng(a.seed)
    lo, hi = np.array(ws["nav_min"]), np.array(ws["nav_max"])
    goals = []
    while len(goals) < a.goals:
        for g in rng.uniform(lo, hi, (1000, 3)):
            if len(goals) < a.goals and _core.sphere_is_free(m, g, radius):
                goals.append(g)
    starts = traj[rng.integers(0, len(traj), a.goals)]
    times, paths = {}, {}
    for ref in (True, False):
        ts, ps = [], []
        for s, g in zip(starts, goals):
            t0 = time.perf_counter()
            ps.append(_core.plan_path(m, s, g, radius, reference=ref))
            ts.append(time.perf_counter() - t0)
        times[ref], paths[ref] = np.array(ts), ps
    same = all(np.array_equal(x, y) for x, y in zip(paths[True], paths[False]))
    found = np.array([len(p) > 0 for p in paths[False]])
    straight = np.array([len(p) == 2 for p in paths[False]])
    print(f"map {m.shape} cells at {m.resolution} m, collision radius {radius} m")
    print(
        f"{a.goals} goals: {int(straight.sum())} straight, {int((found & ~straight).sum())} around "
        f"obstacles, {int((~found).sum())} unreachable; the same paths: {same}"
    )
    for name, sel in (("around obstacles", found & ~straight), ("unreachable", ~found)):
        if sel.any():
            f, r = times[False][sel], times[True][sel]
            print(
                f"  {name:16s}: {1e3 * f.mean():8.1f} ms mean ({1e3 * f.max():7.1f} max) against "
                f"{1e3 * r.mean():8.1f} ms ({1e3 * r.max():7.1f}) -> {r.sum() / f.sum():.1f}x"
            )
    f, r = times[False].sum(), times[True].sum()
    print(f"  all {a.goals}: {f:.2f} s against {r:.2f} s -> {r / f:.1f}x")
    if not same:
        raise SystemExit("the fast search's paths differ from the reference's")


if __name__ == "__main__":
    main()
