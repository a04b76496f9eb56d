"""Figures of a mission (matplotlib, headless-safe): the trajectory over the structure (the
paper's Fig. 7) and entropy / coverage / distance against iteration."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import _plt

STAGE_COLORS = {"profile": "tab:orange", "nbv": "tab:blue"}


def plot_trajectory(ax_top, ax_side, structure_points, trajectory, workspace=None, title=None):
    """Top (x-y) and side (x-z) views of a trajectory over the structure's sampled surface."""
    sp = structure_points
    for ax, (i, j) in ((ax_top, (0, 1)), (ax_side, (0, 2))):
        ax.scatter(sp[:, i], sp[:, j], s=0.2, c="0.6", alpha=0.4, linewidths=0, rasterized=True)
        if len(trajectory):
            xyz = np.array([[r[1], r[2], r[3]] for r in trajectory], float)
            stages = [r[0] for r in trajectory]
            ax.plot(xyz[:, i], xyz[:, j], "-", lw=0.8, c="tab:blue", alpha=0.8)
            for st in dict.fromkeys(stages):
                if st == "start":  # the star below marks it
                    continue
                m = np.array([s == st for s in stages])
                ax.scatter(
                    xyz[m, i],
                    xyz[m, j],
                    s=6,
                    c=STAGE_COLORS.get(st, "tab:green"),
                    label=st,
                    zorder=3,
                )
            ax.scatter(xyz[0, i], xyz[0, j], s=60, marker="*", c="red", zorder=4, label="start")
        if workspace is not None:
            lo, hi = workspace.bounds_min, workspace.bounds_max
            ax.add_patch(_rect(lo[i], lo[j], hi[i] - lo[i], hi[j] - lo[j]))
        ax.set_aspect("equal")
        ax.set_xlabel("xyz"[i] + " (m)")
        ax.set_ylabel("xyz"[j] + " (m)")
    ax_top.legend(loc="upper right", fontsize=7, markerscale=2)
    if title:
        ax_top.set_title(title)


def _rect(x, y, w, h):
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), w, h, fill=False, ls="--", lw=0.8, ec="0.3")


def plot_mission(mission, out_dir: Path) -> list[Path]:
    """Writes trajectory.png and progress.png for a finished mission, and symmetry.png (the
    paper's Fig. 3) where its symmetry stage ran; returns their paths."""
    plt = _plt()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    sp = mission.mesh.sample_surface(30000, seed=0)
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 9), gridspec_kw={"height_ratios": [3, 1.2]})
    cfg = mission.config
    plot_trajectory(
        a,
        b,
        sp,
        mission.world.state.trajectory,
        mission.world.workspace,
        title=f"scenario {cfg.scenario}, start {cfg.start}: {len(mission.records)} iterations, "
        f"{mission.world.state.distance_m:.0f} m",
    )
    fig.tight_layout()
    paths.append(out_dir / "trajectory.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    recs = mission.records
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    it = [r.iteration for r in recs]
    axes[0].plot(it, [r.entropy for r in recs], c="tab:purple")
    axes[0].set_ylabel(f"total entropy ({cfg.map.entropy_unit})")
    for key, lab in (
        ("coverage_005", "0.05 m"),
        ("coverage_01", "0.10 m"),
        ("coverage_05", "0.50 m"),
    ):
        pts = [(r.iteration, getattr(r, key)) for r in recs if getattr(r, key) is not None]
        if pts:
            x, y = zip(*pts)
            axes[1].plot(x, np.array(y) * 100, marker=".", label=lab)
    axes[1].set_ylabel("coverage (%)")
    if axes[1].lines:
        axes[1].legend(fontsize=8)
    axes[2].plot(it, [r.distance_m for r in recs], c="tab:green")
    axes[2].set_ylabel("distance (m)")
    axes[2].set_xlabel("iteration")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    paths.append(out_dir / "progress.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    world = mission.world
    if getattr(world, "symmetry_result", None) is not None:
        from .symmetry_figures import plot_symmetry

        paths.append(
            plot_symmetry(
                world.symmetry_profile,
                world.symmetry_result,
                world.symmetry_prediction,
                out_dir / "symmetry.png",
            )
        )
    return paths


# ------------------------------------------------------------------ experiments


def _iterations(run_dir: Path):
    import pandas as pd

    p = Path(run_dir) / "iterations.csv"
    return pd.read_csv(p) if p.exists() and p.stat().st_size else None


def plot_experiment(root, df, out_dir) -> list[Path]:
    """Figures of a finished experiment (a tidy table `df` of runs under `root/runs`):
    coverage vs distance and vs iteration per scenario, the trajectories of one start per
    scenario (paper's Fig. 7), and the final cloud and map of the full method (Fig. 6)."""
    root, out_dir = Path(root), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scen = [s for s in ("1", "2", "3", "4", "5") if (df["scenario"].astype(str) == s).any()]
    # coverage vs distance / iteration (mean over starts is not meaningful per step: draw each run)
    paths = [
        _coverage_of_scenarios(root, df, scen, xkey, xlabel, out_dir / name)
        for xkey, xlabel, name in (
            ("distance_m", "distance (m)", "coverage_vs_distance.png"),
            ("iteration", "iteration", "coverage_vs_iteration.png"),
        )
    ]
    if scen:
        paths.append(_trajectories(root, df, scen, out_dir / "trajectories.png"))
    # final cloud and map of the most complete scenario present (Fig. 6)
    best = scen[-1] if scen else None
    if best is not None:
        r = df[df["scenario"].astype(str) == best].sort_values("start").iloc[0]
        paths.append(
            plot_cloud_and_map(
                root / "runs" / r["run_id"],
                out_dir / "final_cloud_and_map.png",
                title=f"scenario {best}, start {r['start']}",
            )
        )
    return paths


#: colour of each of the paper's scenarios in the experiment's figures
SCENARIO_COLORS = dict(
    zip(
        ("1", "2", "3", "4", "5"),
        ("tab:gray", "tab:blue", "tab:orange", "tab:green", "tab:red"),
    )
)


def _coverage_of_scenarios(root: Path, df, scen, xkey, xlabel, path: Path) -> Path:
    """Coverage at the three resolutions against `xkey` (distance_m or iteration), every run of
    the scenarios `scen` a line in its scenario's colour."""
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4), sharey=True)
    for sc in scen:
        for k, (_, r) in enumerate(df[df["scenario"].astype(str) == sc].iterrows()):
            it = _iterations(root / "runs" / r["run_id"])
            if it is None or not len(it):
                continue
            for ax, col in zip(axes, ("coverage_005", "coverage_01", "coverage_05")):
                d = it.dropna(subset=[col])
                ax.plot(
                    d[xkey],
                    d[col] * 100,
                    c=SCENARIO_COLORS[sc],
                    alpha=0.7,
                    lw=1,
                    marker=".",  # (a table samples coverage every 5 views: a short run's is one)
                    label=f"scenario {sc}" if k == 0 else None,
                )
    for ax, res in zip(axes, ("0.05", "0.10", "0.50")):
        ax.set_title(f"coverage @ {res} m")
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("coverage (%)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _trajectories(root: Path, df, scen, path: Path) -> Path:
    """The trajectories of the first start of each scenario in `scen` (the paper's Fig. 7)."""
    import csv

    plt = _plt()
    mesh = None
    fig, axes = plt.subplots(
        2,
        len(scen),
        figsize=(4.2 * len(scen), 6.5),
        gridspec_kw={"height_ratios": [3, 1.2]},
        squeeze=False,
    )
    for j, sc in enumerate(scen):
        r = df[df["scenario"].astype(str) == sc].sort_values("start").iloc[0]
        d = root / "runs" / r["run_id"]
        if mesh is None:
            mesh = _mesh_of(d)
        traj = [
            (row["stage"], float(row["x"]), float(row["y"]), float(row["z"]))
            for row in csv.DictReader(open(d / "trajectory.csv"))
        ]
        sp = mesh.sample_surface(20000, seed=0)
        plot_trajectory(
            axes[0, j],
            axes[1, j],
            sp,
            traj,
            title=f"scenario {sc} (start {r['start']}): {r['distance_m']:.0f} m",
        )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _mesh_of(run_dir: Path):
    import yaml

    from .mesh import default_mesh_path, load_mesh

    cfg = yaml.safe_load((Path(run_dir) / "config.yaml").read_text())
    m = cfg.get("mesh", {})
    return load_mesh(
        m.get("path") or default_mesh_path(),
        scale=m.get("scale", 1.0),
        up=m.get("up", "z"),  # a record without it: flown as it was
        shift=m.get("shift"),
    )


def plot_cloud_and_map(run_dir, path, title=None) -> Path:
    """The final point cloud (top) and the occupancy map's occupied cells (bottom), side views."""
    plt = _plt()
    from . import _core
    from .cloud import read_points

    run_dir = Path(run_dir)
    pts = read_points(run_dir / "cloud.ply")
    m = _core.OccupancyMap.load(str(run_dir / "map.ot"))
    occ = m.occupied_cells()
    rng = np.random.default_rng(0)
    if len(pts) > 150_000:
        pts = pts[rng.choice(len(pts), 150_000, replace=False)]
    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    for row, (P, c, lab) in enumerate(
        (
            (pts, "tab:blue", f"point cloud ({len(pts):,} shown)"),
            (occ, "tab:green", f"occupied cells ({len(occ):,})"),
        )
    ):
        for col, (i, j) in enumerate(((0, 1), (0, 2))):
            ax = axes[row, col]
            if len(P):
                ax.scatter(
                    P[:, i], P[:, j], s=0.3 if row == 0 else 1.0, c=c, linewidths=0, rasterized=True
                )
            ax.set_aspect("equal")
            ax.set_xlabel("xyz"[i] + " (m)")
            ax.set_ylabel("xyz"[j] + " (m)")
            ax.set_title(lab if col == 0 else "")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_compare(root, df, out_dir) -> list[Path]:
    """coverage_vs_distance.png of a planner comparison: coverage at 0.05 m against distance
    flown, every run as a line (from its iterations.csv) ending in a dot at its final
    evaluation, one colour per planner, and the paper's Scenario 5 (Table 2 mean) as a star."""
    from .experiment_tables import PAPER_SCENARIO5

    plt = _plt()
    root, out_dir = Path(root), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    cmap = plt.get_cmap("tab10")
    for i, planner in enumerate(dict.fromkeys(df["scenario"].astype(str))):
        c = cmap(i % 10)
        sub = df[df["scenario"].astype(str) == planner]
        for k, (_, r) in enumerate(sub.iterrows()):
            it = _iterations(root / "runs" / r["run_id"])
            if it is not None and len(it):
                d = it.dropna(subset=["coverage_005"])
                ax.plot(d["distance_m"], d["coverage_005"] * 100, c=c, alpha=0.6, lw=1)
            ax.scatter(
                [r["distance_m"]],
                [r["coverage_0.05"] * 100],
                color=c,
                s=18,
                zorder=3,
                label=f"{planner} ({len(sub)} starts)" if k == 0 else None,
            )
    ax.scatter(
        [PAPER_SCENARIO5["distance_m"]],
        [PAPER_SCENARIO5["coverage_0.05"] * 100],
        marker="*",
        s=220,
        c="k",
        zorder=4,
        label="paper, Scenario 5 (Table 2)",
    )
    ax.set_xlabel("distance flown (m, profiling included)")
    ax.set_ylabel("coverage @ 0.05 m (%)")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    path = out_dir / "coverage_vs_distance.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [path]
