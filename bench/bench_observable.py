"""Convergence and cost of the observable surface (nbvkit.observable_surface) as the lattice of
candidate vehicle positions is refined, on the shipped airliner (or --mesh). Prints, per pose
spacing, the observable share of the surface (area, and cells at 0.05 / 0.1 / 0.5 m) and the
wall time, and draws docs/figures/observable_convergence.png. Asserts nothing.

    .venv/bin/python bench/bench_observable.py
    .venv/bin/python bench/bench_observable.py --spacings 2 1 0.5 --no-figure
    .venv/bin/python bench/bench_observable.py --against /tmp/before [--mesh M] [--rounds 2]

--against DIR: the default spacing only, with this checkout and another one (DIR/python, or a
saved copy of a built package), each in a process of its own, alternating: the least time of
each, their ratio, and whether both found the same observable samples bit for bit.

The default configuration's camera, workspace and vehicle; ground truth at the default density.
Measured (2026-12-07, 2 cores, a mission beside it; the lattice reaching the box's faces):
8 / 4 / 2 / 1 / 0.5 m give 91.79 / 91.79 / 91.81 / 91.81 / 91.81 % of the area (2.4 / 2.0 / 3.8 /
20.7 / 121.8 s). With the lattice about the box's centre (2026-12-05): 89.73 / 91.46 / 91.78 /
91.80 / 91.81 %; on 2026-12-01, before the fine lattice, 8 and 4 m gave 56.81 and 91.25 %.
Compare the time at the default spacing (observability.pose_spacing, 2 m) with a Scenario 5
mission's wall time (``nbvkit run``): the budget is a tenth of it.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from nbvkit import default_mesh_path
from nbvkit.config import load_config
from nbvkit.evaluation import Evaluator
from nbvkit.observability import observable_surface
from _timing import alternate, bench_mesh, mesh_parser

ROOT = Path(__file__).resolve().parent.parent

TIME_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
from nbvkit.config import load_config
from nbvkit.evaluation import Evaluator
from nbvkit.mesh import load_mesh
from nbvkit.observability import observable_surface
mesh = load_mesh(sys.argv[1])
cfg = load_config(None, [])
ev = Evaluator(mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
t = time.perf_counter()
obs = observable_surface(mesh, cfg, evaluator=ev)
dt = time.perf_counter() - t
mask = np.ascontiguousarray(obs.observable, dtype=np.uint8)
print(json.dumps({"time": dt, "observable": int(mask.sum()), "samples": len(mask),
                  "digest": hashlib.sha1(mask.tobytes()).hexdigest()}))
"""


def compare(args) -> None:
    """The default spacing's observable surface with this checkout and --against's."""
    best, same = alternate(
        TIME_SNIPPET,
        [str(Path(args.mesh).resolve()) if args.mesh else str(default_mesh_path())],
        args.against,
        rounds=args.rounds,
    )
    print(
        f"structure: {args.mesh or 'shipped airliner'}, observable surface at the default spacing"
    )
    for label, t in best:
        print(f"{label:>30}: {t:9.2f} s")
    if len(best) == 2:
        print(
            f"ratio {best[1][1] / best[0][1]:.2f}x; the same observable samples bit for bit: {same}"
        )


def main() -> None:
    ap = mesh_parser(__doc__)
    ap.add_argument("--spacings", type=float, nargs="+", default=[8.0, 4.0, 2.0, 1.0, 0.5])
    ap.add_argument("--no-figure", action="store_true")
    ap.add_argument("--against", help="another checkout (or a saved package) to compare with")
    ap.add_argument("--rounds", type=int, default=2, help="alternating runs each (--against)")
    args = ap.parse_args()
    if args.against:
        return compare(args)
    mesh = bench_mesh(args.mesh)[0]
    cfg0 = load_config(None, [])
    ev = Evaluator(mesh, gt_density=cfg0.evaluation.gt_density, seed=cfg0.seed)
    print(
        f"structure: {args.mesh or 'shipped airliner'}, {mesh.area:.0f} m^2, "
        f"{ev.num_gt_points:,} ground-truth samples"
    )
    print(f"{'spacing':>8} {'poses':>7} {'area':>7} {'@0.05':>7} {'@0.1':>7} {'@0.5':>7} {'s':>7}")
    rows = []
    empty = np.zeros((0, 3))
    for s in args.spacings:
        cfg = load_config(None, [f"observability.pose_spacing={s}"])
        t0 = time.perf_counter()
        obs = observable_surface(mesh, cfg, evaluator=ev)
        dt = time.perf_counter() - t0
        ev.set_observable(obs.observable)
        f = ev.coverage(empty)["observable_fraction"]
        rows.append((s, obs.stats["poses"], obs.fraction, f["0.05"], f["0.1"], f["0.5"], dt))
        print(
            f"{s:8.2f} {obs.stats['poses']:7d} {100 * obs.fraction:6.2f}% "
            f"{100 * f['0.05']:6.2f}% {100 * f['0.1']:6.2f}% {100 * f['0.5']:6.2f}% {dt:7.2f}",
            flush=True,
        )
    if args.no_figure:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = np.array(rows)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(r[:, 0], 100 * r[:, 2], "o-", label="area (samples)")
    for j, lab in ((3, "cells @0.05 m"), (4, "cells @0.1 m"), (5, "cells @0.5 m")):
        ax.plot(r[:, 0], 100 * r[:, j], ".--", label=lab)
    ax.set_xscale("log")
    ax.set_xticks(r[:, 0])
    ax.set_xticklabels([f"{v:g}" for v in r[:, 0]])
    ax.minorticks_off()
    ax.invert_xaxis()
    ax.set_xlabel("pose lattice spacing (m), finer to the right")
    ax.set_ylabel("observable share of the surface (%)")
    ax.set_title("observable surface of the airliner vs. pose sampling")
    for s, _, fa, *_, dt in rows:
        ax.annotate(
            f"{dt:.1f} s",
            (s, 100 * fa),
            textcoords="offset points",
            xytext=(0, -14),
            fontsize=8,
            ha="center",
        )
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "observable_convergence.png"
    fig.savefig(out, dpi=110)
    print(f"figure -> {out}")


if __name__ == "__main__":
    main()
