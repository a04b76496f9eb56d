"""The figures of the symmetry stage (the paper's Fig. 3): :func:`plot_symmetry` (a headless PNG,
top views) and open3d's geometries of it (:func:`symmetry_geometries`,
:func:`show_symmetry_open3d`). Re-exported by nbvkit.symmetry."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ._open3d import open3d
from ._core import SymmetricPrediction, reflect_points
from .figures import _plt  # one headless matplotlib set-up for all figures

__all__ = ["plot_symmetry", "symmetry_geometries", "show_symmetry_open3d"]


def _subsample(p: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    if len(p) <= n:
        return p
    return p[np.random.default_rng(seed).choice(len(p), n, replace=False)]


def _plane_of(result) -> np.ndarray | None:
    if result is None:
        return None
    pl = np.asarray(getattr(result, "plane", result), float).reshape(-1)
    return pl if pl.size == 4 and np.all(np.isfinite(pl)) else None


def _added_points(predicted) -> np.ndarray:
    """(M, 3) the predicted points of a SymmetricPrediction, an (M, 3) array or None."""
    if isinstance(predicted, SymmetricPrediction):
        return np.asarray(predicted.predicted)
    return np.zeros((0, 3)) if predicted is None else np.asarray(predicted, float).reshape(-1, 3)


def plot_symmetry(
    profile, result, predicted, path, max_points: int = 20000, title: str | None = None
):
    """The paper's Fig. 3 as a PNG (headless; top views, x-y): (a) the profile, (b) the detected
    plane over it (blue), (c) the profile mirrored about that plane (green), (d) the mirrored cloud
    aligned by ICP and merged with the profile, (e) the added points (the prediction, red).

    profile: (N, 3); result: a SymmetryResult (or a plane [nx, ny, nz, d], or None); predicted: a
    SymmetricPrediction, an (M, 3) array or None. Clouds are subsampled to max_points. Returns
    the path written.
    """
    plt = _plt()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    prof = np.asarray(profile, float).reshape(-1, 3)
    plane = _plane_of(result)
    corrected = _plane_of(predicted) if isinstance(predicted, SymmetricPrediction) else None
    if corrected is None:
        corrected = plane
    added = _added_points(predicted)
    mirrored = reflect_points(prof, plane) if plane is not None and len(prof) else np.zeros((0, 3))
    aligned = (
        reflect_points(prof, corrected) if corrected is not None and len(prof) else np.zeros((0, 3))
    )
    clouds = tuple(_subsample(x, max_points) for x in (prof, mirrored, aligned, added))

    # Fixed margins: a constrained layout would draw every panel once more to measure it (0.3 s
    # of the 0.45 s this figure took on the airliner's profile).
    fig, axes = plt.subplots(1, 5, figsize=(22, 4.8))
    fig.subplots_adjust(
        left=0.035, right=0.995, bottom=0.1, top=0.86 if title else 0.93, wspace=0.12
    )
    _Fig3(axes, prof, *clouds).draw(result, plane, corrected, len(added))
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


class _Fig3:
    """The five panels of plot_symmetry over the subsampled clouds: P the profile, M mirrored, A
    aligned, E the added points (prof: the whole profile, for the planes' height)."""

    def __init__(self, axes, prof, P, M, A, E):
        self.axes, self.prof, self.P, self.M, self.A, self.E = axes, prof, P, M, A, E
        both = np.vstack([x for x in (P, M, A, E) if len(x)]) if len(P) else np.zeros((1, 3))
        self.lo, self.hi = both[:, :2].min(0) - 1.0, both[:, :2].max(0) + 1.0

    def base(self, ax, alpha=1.0, c="0.25"):
        P = self.P
        if len(P):
            ax.scatter(P[:, 0], P[:, 1], s=0.3, c=c, alpha=alpha, linewidths=0, rasterized=True)

    def plane_line(self, ax, pl, color):
        n, d = pl[:3], pl[3]
        if np.hypot(n[0], n[1]) < 1e-3:  # horizontal plane: no line in a top view
            return
        prof = self.prof
        zc = float(np.mean(prof[:, 2])) if len(prof) else 0.0
        # points of the plane at height zc: n_x x + n_y y = d - n_z zc
        rhs = d - n[2] * zc
        t = np.linspace(-1, 1, 2) * np.linalg.norm(self.hi - self.lo)
        p0 = rhs * n[:2] / (n[0] ** 2 + n[1] ** 2)
        u = np.array([-n[1], n[0]]) / np.hypot(n[0], n[1])
        ax.plot(p0[0] + t * u[0], p0[1] + t * u[1], "-", c=color, lw=1.5)

    def draw(self, result, plane, corrected, n_added: int) -> None:
        axes, M, A, E = self.axes, self.M, self.A, self.E
        ax = axes[0]
        self.base(ax)
        ax.set_title("(a) profile")
        ax = axes[1]
        self.base(ax)
        if plane is not None:
            self.plane_line(ax, plane, "tab:blue")
        conf = getattr(result, "confidence", None)
        verdict = "accepted" if getattr(result, "accepted", None) else "rejected"
        ax.set_title(
            "(b) detected plane" + (f" (conf {conf:.2f}, {verdict})" if conf is not None else "")
        )
        ax = axes[2]
        self.base(ax, 0.5, "0.6")
        if len(M):
            ax.scatter(M[:, 0], M[:, 1], s=0.3, c="tab:green", linewidths=0, rasterized=True)
        ax.set_title("(c) mirrored")
        ax = axes[3]
        self.base(ax)
        if len(A):
            ax.scatter(
                A[:, 0], A[:, 1], s=0.3, c="tab:green", alpha=0.6, linewidths=0, rasterized=True
            )
        if corrected is not None:
            self.plane_line(ax, corrected, "tab:blue")
        ax.set_title("(d) aligned (ICP) and merged")
        ax = axes[4]
        self.base(ax, 0.25, "0.7")
        if len(E):
            ax.scatter(E[:, 0], E[:, 1], s=0.5, c="tab:red", linewidths=0, rasterized=True)
        ax.set_title(f"(e) added points ({n_added})")
        for ax in axes:
            ax.set_xlim(self.lo[0], self.hi[0])
            ax.set_ylim(self.lo[1], self.hi[1])
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
        axes[0].set_ylabel("y (m)")


def symmetry_geometries(profile, result, predicted=None, plane_size: float | None = None):
    """open3d geometries of Fig. 3 (imports open3d lazily): the profile (grey), its reflection
    about the (corrected) plane (green), the prediction (red) and the plane as a thin blue square.
    """
    o3d = open3d()

    prof = np.asarray(profile, float).reshape(-1, 3)
    plane = _plane_of(predicted) if isinstance(predicted, SymmetricPrediction) else None
    if plane is None:
        plane = _plane_of(result)
    added = _added_points(predicted)
    geoms = []

    def cloud(p, color):
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(p)))
        pc.paint_uniform_color(color)
        return pc

    geoms.append(cloud(prof, [0.5, 0.5, 0.5]))
    if plane is not None and len(prof):
        geoms.append(cloud(reflect_points(prof, plane), [0.2, 0.7, 0.2]))
        n, d = plane[:3], plane[3]
        c = prof.mean(0)
        c = c - (n @ c - d) * n
        size = plane_size or float(np.ptp(prof, axis=0).max())
        u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        h = 0.5 * size
        verts = np.array(
            [c - h * u - h * v, c + h * u - h * v, c + h * u + h * v, c - h * u + h * v]
        )
        tri = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]], np.int32)
        m = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(tri)
        )
        m.paint_uniform_color([0.2, 0.4, 0.9])
        geoms.append(m)
    if len(added):
        geoms.append(cloud(added, [0.9, 0.1, 0.1]))
    return geoms


def show_symmetry_open3d(profile, result, predicted=None, window_name: str = "nbvkit symmetry"):
    """Opens an open3d window with :func:`symmetry_geometries` (needs a display; for notebooks).
    Returns the geometries."""
    o3d = open3d()

    geoms = symmetry_geometries(profile, result, predicted)
    o3d.visualization.draw_geometries(geoms, window_name=window_name)
    return geoms
