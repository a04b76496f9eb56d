"""How a mission's cost grows: milliseconds per iteration (by stage) and peak memory against the
map resolution (0.4 / 0.2 / 0.1 m on the airliner) and against the workspace size (the airliner
scaled x1, x2, x4 at 0.2 m). Each point is one Scenario 5 mission from start 0 in a fresh process
(`nbvkit run`), cut at --iterations (0: to termination), so peak memory is that run's own.

Prints one row per mission with the workspace's cell count, and the growth exponents of ms per
iteration and of memory against cells (log-log slope: 1 = linear in cells); writes the figure to
--figure (default docs/figures/scaling.png).

Run: .venv/bin/python bench/bench_scaling.py [--iterations N] [--figure PATH]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
POINTS = [  # (label, map resolution m, mesh scale)
    ("0.4 m", 0.4, 1.0),
    ("0.2 m", 0.2, 1.0),
    ("0.1 m", 0.1, 1.0),
    ("x2, 0.2 m", 0.2, 2.0),
    ("x4, 0.2 m", 0.2, 4.0),
]


def run_one(res: float, scale: float, iterations: int, out: Path) -> dict:
    cmd = [str(Path(sys.executable).parent / "nbvkit"), "run", "--scenario", "5", "--start", "0"]
    cmd += ["--mesh-scale", str(scale), "--out", str(out), "--set", f"map.resolution={res}"]
    cmd += ["progress=false"] + ([f"max_iterations={iterations}"] if iterations else [])
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "summary.json").read_text())


def slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=80, help="iterations per mission (0: all)")
    ap.add_argument("--figure", default=str(ROOT / "docs" / "figures" / "scaling.png"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, res, scale in POINTS:
            s = run_one(res, scale, args.iterations, Path(tmp) / label.replace(" ", "_"))
            ws = s["workspace"]
            extent = np.subtract(ws["bounds_max"], ws["bounds_min"])
            cells = int(np.prod(np.ceil(extent / res - 1e-9)))
            rows.append((label, res, scale, cells, s))
            st = s["ms_per_stage"]
            print(
                f"{label:>10}: {cells:>11,} cells  {s['iterations']:>4} it  "
                f"{s['ms_per_iteration']:6.1f} ms/it (evaluation {st['evaluation']:.1f}, "
                f"sensing {st['sensing']:.1f}, mapping {st['mapping']:.1f})  "
                f"peak {s['peak_memory_mb']:7.0f} MB  wall {s['wall_time_s']:6.1f} s  "
                f"[{s['termination']}]",
                flush=True,
            )
    cells = np.array([r[3] for r in rows], float)
    ms = np.array([r[4]["ms_per_iteration"] for r in rows])
    mem = np.array([r[4]["peak_memory_mb"] for r in rows])
    res_rows = [i for i, r in enumerate(rows) if r[2] == 1.0]
    size_rows = [i for i, r in enumerate(rows) if r[1] == 0.2]
    for name, idx in (("resolution", res_rows), ("workspace size", size_rows)):
        print(
            f"against cells ({name}): ms/iteration ~ cells^{slope(cells[idx], ms[idx]):.2f}, "
            f"peak memory ~ cells^{slope(cells[idx], mem[idx]):.2f}"
        )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for idx, style, name in ((res_rows, "o-", "resolution"), (size_rows, "s--", "size")):
        for ax, y in zip(axes, (ms, mem)):
            ax.loglog(cells[idx], y[idx], style, label=f"{name}")
            for i in idx:
                ax.annotate(
                    rows[i][0],
                    (cells[i], y[i]),
                    fontsize=8,
                    xytext=(4, 4),
                    textcoords="offset points",
                )
    axes[0].set_ylabel("ms per iteration")
    axes[1].set_ylabel("peak memory (MB)")
    for ax in axes:
        ax.set_xlabel("workspace cells")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    n_it = f"first {args.iterations} iterations" if args.iterations else "whole missions"
    fig.suptitle(f"Scenario 5, airliner, start 0 ({n_it})")
    fig.tight_layout()
    Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.figure, dpi=110)
    print(f"figure -> {args.figure}")


if __name__ == "__main__":
    main()
