"""The surface's coverage classes (covered, observable but missed, unobservable) and their
picture, ``figures/coverage.png`` (part of the end-of-run outputs, nbvkit.finish; the report's 3D
view colours the same classes)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from . import _core
from .cloud import _is_cloud_list, _parts
from .figures import _plt

__all__ = ["CLASS_COLOURS", "CLASS_NAMES", "coverage_classes", "view_classes", "plot_coverage"]

#: colours of the three classes (covered, observable but missed, unobservable)
CLASS_COLOURS = ("#2ca02c", "#d62728", "#9e9e9e")
CLASS_NAMES = ("covered", "observable but missed", "unobservable")


#: cloud points whose cells coverage_classes looks up at a time
_SLICE = 1 << 20


def coverage_classes(points, cloud, observable=None, resolution: float = 0.1) -> np.ndarray:
    """(N,) int8 class of each surface point: 0 covered (its ``resolution`` cell, on the
    origin-anchored grid of ``nbvkit.evaluate``, holds a cloud point), 1 observable but missed,
    2 unobservable (``observable`` False). Without ``observable`` every point is observable.
    cloud: (M, 3) points or a list of SurfaceClouds (read in place)."""
    points = np.asarray(points, float).reshape(-1, 3)
    if not _is_cloud_list(cloud):
        cloud = np.asarray(cloud, float).reshape(-1, 3)

    def keys(p):  # the cells as evaluate counts them (a value on a boundary: the cell above)
        return _core.cell_keys(p, resolution)

    # the points' cells, then which of them the cloud's points fall in, a slice of the cloud
    # at a time: a 100 m structure's cloud of 25 M points would take 1.2 GB of keys at once
    cells = np.unique(keys(points))
    hit = np.zeros(len(cells), bool)
    for part in _parts(cloud, _SLICE)[1] if len(cells) else ():
        k = keys(part)
        j = np.minimum(np.searchsorted(cells, k), len(cells) - 1)
        hit[j[cells[j] == k]] = True
    covered = hit[np.searchsorted(cells, keys(points))]
    out = np.where(covered, 0, 1).astype(np.int8)
    if observable is not None:
        out[~np.asarray(observable, bool)] = 2
    return out


def view_classes(ev, cloud, mask, n_view, seed):
    """A subsample of the ground-truth samples (at most n_view) and their class: 0 covered
    (its 0.1 m cell holds a cloud point), 1 observable but missed, 2 unobservable."""
    gt = ev.gt_points
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(gt), n_view, replace=False)) if len(gt) > n_view else None
    pts = gt if idx is None else gt[idx]
    m = None if mask is None else (mask if idx is None else mask[idx])
    return coverage_classes(pts, cloud, m), pts


# ---------------------------------------------------------------------------------- figures


def _views():
    """(name, azimuth deg, elevation deg) of the four viewpoints of coverage.png."""
    return (
        ("above, front left", -60, 35),
        ("above, rear right", 120, 35),
        ("below", -60, -50),
        ("the front", 0, 0),
    )


def _project(pts, az, el):
    a, e = math.radians(az), math.radians(el)
    # camera looking from direction (cos e cos a, cos e sin a, sin e) toward the origin
    view = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    right = np.array([-math.sin(a), math.cos(a), 0.0])
    up = np.cross(view, right)
    return pts @ right, pts @ up, pts @ view


def plot_coverage(points, classes, path, max_points: int = 30000) -> Path:
    """``path`` (PNG): the surface points coloured covered / observable but missed /
    unobservable, seen orthographically from four viewpoints (nearest points drawn last)."""
    plt = _plt()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pts = np.asarray(points, float).reshape(-1, 3)
    cls = np.asarray(classes)
    if len(pts) > max_points:  # a still picture needs fewer points than the 3D view
        keep = np.linspace(0, len(pts) - 1, max_points).astype(int)
        pts, cls = pts[keep], cls[keep]
    c = pts - pts.mean(axis=0) if len(pts) else pts
    colours = np.array(CLASS_COLOURS)[cls] if len(cls) else np.array([])
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    for ax, (name, az, el) in zip(axes.ravel(), _views()):
        if len(c):
            x, y, depth = _project(c, az, el)
            order = np.argsort(depth)
            ax.scatter(x[order], y[order], c=colours[order], s=1.2, linewidths=0)
        ax.set_title(f"from {name}")
        ax.set_aspect("equal")
        ax.axis("off")
    n = max(len(cls), 1)
    handles = [
        plt.Line2D(
            [], [], marker="o", ls="", color=col, label=f"{lab} ({np.sum(cls == k) / n:.1%})"
        )
        for k, (lab, col) in enumerate(zip(CLASS_NAMES, CLASS_COLOURS))
    ]
    fig.legend(handles=handles, loc="lower center", ncol=3, frameon=False)
    fig.suptitle("surface coverage (share of the surface area)")
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
