"""A large structure flown with one tour over the map (tour.gain_levels=0, the code before issue
37's second session) and with the larger gains first (the default on a large workspace), in the
same run: area coverage at 0.05 m, distance, plans, planning per view and peak memory, and the
ratios. Meshes come from bench/large_structures.py (a layout per seed, never tuned on).

    .venv/bin/python bench/large_gain_levels.py --seed 2 --views 1000      # ~25 min on 2 cores
    .venv/bin/python bench/large_gain_levels.py --structure bridge --views 300
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from nbvkit.config import load_config
from nbvkit.mesh import load_mesh
from nbvkit.mission import Mission

sys.path.insert(0, str(Path(__file__).resolve().parent))
from large_structures import STRUCTURES  # noqa: E402

SETTINGS = {"one tour (before)": ["tour.gain_levels=0"], "larger gains first": []}


def fly(mesh, views: int, over: list) -> dict:
    cfg = load_config(
        overrides=[
            f"max_iterations={views}",
            "progress=false",
            "report.enabled=false",
            "observability.enabled=false",
            *over,
        ]
    )
    with tempfile.TemporaryDirectory() as tmp:
        s = Mission(cfg, mesh=mesh).run(Path(tmp) / "run")
    return {
        "coverage": s["area_coverage"]["0.05"],
        "distance": s["distance_m"],
        "views": s["views"],
        "plans": len(s.get("tours", [])),
        "planning_ms": s["ms_per_stage"]["sampling"],
        "peak_gb": s["peak_memory_mb"] / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--structure", default="plant", choices=list(STRUCTURES))
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--views", type=int, default=1000, help="the view cap (default 1000)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mesh.obj"
        STRUCTURES[a.structure](np.random.default_rng(a.seed)).write(path)
        mesh = load_mesh(path)
    print(f"{a.structure} seed {a.seed}: {mesh.area:,.0f} m^2, {a.views} views at most")
    print("| setting | area cov. @0.05 m | flown | views | plans | planning / view | peak |")
    print("|---|---|---|---|---|---|---|")
    rows = {}
    for name, over in SETTINGS.items():
        r = rows[name] = fly(mesh, a.views, over)
        print(
            f"| {name} | {100 * r['coverage']:.1f} % | {r['distance']:,.0f} m | {r['views']} | "
            f"{r['plans']} | {r['planning_ms']:.0f} ms | {r['peak_gb']:.1f} GB |",
            flush=True,
        )
    before, after = rows.values()
    print(
        f"ratios (after / before): coverage {after['coverage'] / before['coverage']:.2f}, "
        f"distance {after['distance'] / before['distance']:.2f}, "
        f"planning per view {after['planning_ms'] / before['planning_ms']:.2f}"
    )


if __name__ == "__main__":
    main()
