"""Why symmetry prediction writes so few cells (docs/SYMMETRY.md): follows the mirrored laser
profile of a mission into the occupancy map and counts where it lands.

    .venv/bin/python bench/symmetry_cells.py                 # airliner, Scenario 5, start 0
    .venv/bin/python bench/symmetry_cells.py --start 2 --no-figures

Flies the mission's profiling stage (Algorithm 1), detects the plane and predicts as the mission
does, then counts at the map's resolution:
- the profile's points, their reflections, and the reflections the point-level test keeps
  (farther than explained_tolerance from every profile point: "predicted points");
- the distinct cells these fall in, by the state the profile left them in (occupied, free,
  unknown, outside the workspace): only unknown cells can be predicted;
- the same for the ground truth (mesh samples): how much of the true surface is still unknown
  after profiling, and how much of that the mirror reaches;
- the plane's error against the true mirror plane y = 0 (the generated airliner).
Prints a table and writes docs/figures/symmetry_cells.png and symmetry_cells_topview.png.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from nbvkit import symmetry as sym
from nbvkit.config import Config
from nbvkit.evaluation import Evaluator
from nbvkit.mission import Mission
from nbvkit.profiling import run_profiling

ROOT = Path(__file__).resolve().parent.parent
STATES = {1: "occupied", 0: "free", -1: "unknown"}


def cell_keys(points, res):
    return np.unique(np.floor(np.asarray(points) / res).astype(np.int64), axis=0)


def breakdown(m, points, res):
    """Distinct cells of points (N, 3) by map state: dict name -> count, and the cell centres."""
    keys = cell_keys(points, res)
    centres = (keys + 0.5) * res
    inside = np.asarray(m.in_workspace(centres), bool)
    state = np.asarray(m.state(centres))
    out = {"cells": int(len(keys)), "outside": int((~inside).sum())}
    for v, name in STATES.items():
        out[name] = int(((state == v) & inside).sum())
    return out, centres, state, inside


def plane_error(plane, truth=np.array([0.0, 1.0, 0.0, 0.0]), at=np.zeros(3)):
    n, d = plane[:3], plane[3]
    if n @ truth[:3] < 0:
        n, d = -n, -d
    ang = math.degrees(math.acos(min(1.0, abs(float(n @ truth[:3])))))
    return ang, abs(float(n @ at - d))


def analyse(start: int, figures: bool):
    cfg = Config.from_dict({"scenario": "5", "start": start, "progress": False})
    mission = Mission(cfg)
    world = mission.world
    world.take_off()
    run_profiling(world)
    m, res = world.map, cfg.map.resolution
    profile = np.asarray(world.laser_cloud.points, float)
    scfg = cfg.symmetry
    det = sym.detect_symmetry(profile, **sym.detection_options(scfg))
    pred = sym.predict_symmetric(profile, det.plane, **sym.prediction_options(scfg))
    plane = np.asarray(pred.plane)
    mirrored = sym.reflect_points(profile, plane)
    rows = {}
    rows["profile points"] = breakdown(m, profile, res)[0]
    rows["mirrored points"], mc, mstate, minside = breakdown(m, mirrored, res)
    rows["predicted points (point-level novelty)"] = breakdown(m, pred.predicted, res)[0]
    gt = Evaluator(world.mesh, seed=cfg.seed).gt_points
    rows["ground-truth surface"], gc, gstate, ginside = breakdown(m, gt, res)
    gt_keys = {tuple(k) for k in cell_keys(gt, res)}
    mk = cell_keys(mirrored, res)
    on_gt = np.array([tuple(k) in gt_keys for k in mk])
    unknown_gt = gstate[ginside] == -1
    mirrored_keys = {tuple(k) for k in mk}
    gk = cell_keys(gt, res)[ginside]
    reached = np.array([tuple(k) in mirrored_keys for k in gk])
    # The unknown surface cells' mirror cells: an unknown cell is predictable only if its mirror
    # image was observed (occupied); if the mirror is unknown too, neither side was seen.
    ucent = gc[ginside][unknown_gt]
    mirror_state = np.asarray(m.state(sym.reflect_points(ucent, plane)))
    mirror_of_unknown = {name: int((mirror_state == v).sum()) for v, name in STATES.items()}
    pk = cell_keys(pred.predicted, res)
    extra = {
        "workspace_cells_after_profiling": {k: int(v) for k, v in m.counts().items()},
        "plane": [round(float(v), 5) for v in plane],
        "plane_error_deg_m": [round(v, 4) for v in plane_error(plane)],
        "detected_plane_error_deg_m": [round(v, 4) for v in plane_error(np.asarray(det.plane))],
        "mirrored_cells_on_true_surface": int(on_gt.sum()),
        "mirrored_unknown_cells_on_true_surface": int((on_gt & minside & (mstate == -1)).sum()),
        "mirrored_free_cells_on_true_surface": int((on_gt & minside & (mstate == 0)).sum()),
        "true_surface_cells_unknown_after_profiling": int(unknown_gt.sum()),
        "of_which_reached_by_the_mirror": int((unknown_gt & reached).sum()),
        "state_of_the_mirror_cell_of_each_unknown_surface_cell": mirror_of_unknown,
        "unknown_surface_cells_by_height_m": {
            f"{lo:.0f}-{lo + 2:.0f}": int(((ucent[:, 2] >= lo) & (ucent[:, 2] < lo + 2)).sum())
            for lo in range(0, 10, 2)
        },
        "predicted_point_cells": int(len(pk)),
        "cells_written": int(m.set_unknown_cells(pred.predicted, scfg.prediction_probability)),
        # every mirrored point written (cell-level novelty only): its unknown cells
        "cells_written_without_point_filter": int(((mstate == -1) & minside).sum()),
    }
    if figures:
        plot(profile, mc, mstate, minside, ucent, mirror_state, rows, start)
    return rows, extra


def plot(profile, mc, mstate, minside, ucent, mirror_state, rows, start):
    from nbvkit.plots import _plt

    plt = _plt()
    out = ROOT / "docs" / "figures"
    out.mkdir(parents=True, exist_ok=True)
    names = ["occupied", "free", "unknown", "outside"]
    colors = ["tab:green", "tab:blue", "tab:red", "0.6"]
    labels = list(rows)
    fig, ax = plt.subplots(figsize=(9, 3.8), constrained_layout=True)
    left = np.zeros(len(labels))
    for name, c in zip(names, colors):
        vals = np.array([rows[k][name] for k in labels], float)
        ax.barh(labels, vals, left=left, color=c, label=name)
        left += vals
    for i, k in enumerate(labels):
        ax.text(
            left[i],
            i,
            f" {rows[k]['cells']:,} cells ({rows[k]['unknown']:,} unknown)",
            va="center",
            fontsize=8,
        )
    ax.invert_yaxis()
    ax.set_xlim(0, left.max() * 1.45)
    ax.set_xlabel(f"distinct map cells (0.2 m) by state after profiling - airliner, start {start}")
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(out / "symmetry_cells.png", dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 3, figsize=(20, 6.5), constrained_layout=True)
    axes[0].scatter(profile[:, 0], profile[:, 1], s=0.2, c="0.3", linewidths=0, rasterized=True)
    axes[0].set_title(f"laser profile ({len(profile):,} points), top view")
    for v, name, c in (
        (1, "occupied", "tab:green"),
        (0, "free", "tab:blue"),
        (-1, "unknown", "tab:red"),
    ):
        sel = (mstate == v) & minside
        axes[1].scatter(
            mc[sel, 0],
            mc[sel, 1],
            s=0.5 if v != -1 else 3,
            c=c,
            linewidths=0,
            label=f"{name} ({sel.sum():,})",
            rasterized=True,
        )
    axes[1].set_title("cells of the mirrored profile, by state after profiling")
    axes[1].legend(loc="upper right", markerscale=6, fontsize=8)
    for v, name, c in (
        (1, "occupied", "tab:green"),
        (0, "free", "tab:blue"),
        (-1, "unknown: both sides unseen", "tab:red"),
    ):
        sel = mirror_state == v
        axes[2].scatter(
            ucent[sel, 0],
            ucent[sel, 1],
            s=2,
            c=c,
            linewidths=0,
            label=f"mirror {name} ({sel.sum():,})",
            rasterized=True,
        )
    axes[2].set_title("true-surface cells still unknown, by the state of their mirror cell")
    axes[2].legend(loc="upper right", markerscale=4, fontsize=8)
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    fig.savefig(out / "symmetry_cells_topview.png", dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args()
    rows, extra = analyse(args.start, not args.no_figures)
    print(f"{'':42s} {'cells':>8s} {'occupied':>9s} {'free':>8s} {'unknown':>8s} {'outside':>8s}")
    for k, r in rows.items():
        print(
            f"{k:42s} {r['cells']:8d} {r['occupied']:9d} {r['free']:8d} {r['unknown']:8d} "
            f"{r['outside']:8d}"
        )
    print(json.dumps(extra, indent=1))


if __name__ == "__main__":
    main()
