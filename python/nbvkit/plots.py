"""Figures of a mission (matplotlib, headless-safe): the trajectory over the structure (the
paper's Fig. 7) and entropy / coverage / distance against iteration."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "module://matplotlib_inline.backend_inline"):
        try:
            matplotlib.use("Agg")
        except Exception:  # pragma: no cover
            pass
    import matplotlib.pyplot as plt

    return plt


STAGE_COLORS = {"start": "k", "profile": "tab:orange", "nbv": "tab:blue"}


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
                m = np.array([s == st for s in stages])
                ax.scatter(xyz[m, i], xyz[m, j], s=6, c=STAGE_COLORS.get(st, "tab:green"), label=st, zorder=3)
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
    """Writes trajectory.png and progress.png for a finished mission; returns their paths."""
    plt = _plt()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    sp = mission.mesh.sample_surface(30000, seed=0)
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 9), gridspec_kw={"height_ratios": [3, 1.2]})
    cfg = mission.config
    plot_trajectory(a, b, sp, mission.state.trajectory, mission.workspace,
                    title=f"scenario {cfg.scenario}, start {cfg.start}: {len(mission.records)} iterations, "
                          f"{mission.state.distance_m:.0f} m")
    fig.tight_layout()
    paths.append(out_dir / "trajectory.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    recs = mission.records
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    it = [r.iteration for r in recs]
    axes[0].plot(it, [r.entropy for r in recs], c="tab:purple")
    axes[0].set_ylabel(f"total entropy ({cfg.map.entropy_unit})")
    for key, lab in (("coverage_005", "0.05 m"), ("coverage_01", "0.10 m"), ("coverage_05", "0.50 m")):
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
    return paths
