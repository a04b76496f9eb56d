"""What a mission leaves for a person: the observable-surface figures, the reconstruction as a
mesh (``mesh.ply``, scored against the ground truth), ``figures/coverage.png`` and a
self-contained ``report.html``; and one ``report.html`` per experiment (table, sweep, compare).

``finish_run(mission, out, summary, cache_dir)`` runs as a mission's folder is written
(``Mission.run(out, finish=True)``, ``Mission.save``); it adds to the summary and
writes the files. Each part is switched by the ``observability`` and ``report`` config sections.

Mesh reconstruction: open3d's screened Poisson reconstruction rather than ball pivoting. The
final cloud mixes the camera's 2 cm voxels with the laser profile's 10 cm voxels and has holes
where nothing was seen; ball pivoting needs radii matched to one point spacing and leaves every
gap open (and grows slow with several radii), while Poisson tolerates uneven density and noise,
closes small gaps, and reports a per-vertex density that tells its extrapolated "bubbles" (far
from any point) from supported surface. Those are trimmed twice: vertices below the
``report.density_quantile`` of the densities, and vertices farther than ``report.trim_distance``
from the cloud. Normals are oriented toward the nearest point of the flown trajectory (the
camera saw each point from its side of the surface), which Poisson needs and which costs far
less than open3d's tangent-plane propagation.
"""
from __future__ import annotations

import base64
import csv
import functools
import html
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .settings import nonneg, within

__all__ = [
    "finish_run",
    "reconstruct_mesh",
    "score_mesh",
    "coverage_classes",
    "plot_coverage",
    "write_run_report",
    "write_experiment_report",
    "plotly_js",
    "run_view",
    "MIN_MESH_POINTS",
]

#: fewer cloud points than this: no mesh is reconstructed (a clear message instead)
MIN_MESH_POINTS = 100

#: colours of the three classes (covered, observable but missed, unobservable)
CLASS_COLOURS = ("#2ca02c", "#d62728", "#9e9e9e")
CLASS_NAMES = ("covered", "observable but missed", "unobservable")


# ---------------------------------------------------------------------------------- the run


@dataclass(frozen=True)
class ReportConfig:
    """End-of-run outputs: mesh.ply (Poisson), figures/coverage.png, report.html."""

    enabled: bool = True  # write them at the end of every mission
    mesh: bool = True  # reconstruct and score mesh.ply from the final cloud
    poisson_depth: int = within(8, 1, 12)  # octree depth of open3d's Poisson (experiments: 7)
    mesh_max_points: int = within(60000, 1, 10**7)  # the cloud is voxel-thinned to ~this many
    density_quantile: float = within(0.05, 0, 1)  # vertices of the lowest Poisson densities trimmed
    trim_distance: float = nonneg(0.3)  # m; vertices farther than this from the cloud are trimmed
    html: bool = True  # write report.html (plotly, self-contained)
    view_points: int = within(50000, 1, 2 * 10**6)  # ground-truth samples in the report's 3D view


def finish_run(mission, out, summary: dict, cache_dir=None) -> dict:
    """The end-of-run outputs of a finished mission: writes ``mesh.ply``,
    ``figures/coverage.png`` and ``report.html`` into its results folder `out` and returns
    `summary` with the observable-surface figures and the mesh scores added (the caller writes
    summary.json once, last: Mission.save / Recorder.write).

    mission: the ``nbvkit.Mission`` that has run (its evaluator, world and records are used);
    cache_dir: the observable-surface cache (default ``out/cache``; a sweep passes its own
    folder's so that every run of a structure shares one entry). Stage timings go into
    ``summary["finish_s"]``.
    """
    out = Path(out)
    cfg = mission.config
    summary = dict(summary)
    timings: dict = {}
    t_all = time.perf_counter()
    cloud = mission.cloud_points()
    ev = mission.evaluator

    mask = None
    if cfg.observability.enabled:
        from .observability import observable_surface

        t0 = time.perf_counter()
        obs = observable_surface(
            mission.mesh,
            cfg,
            evaluator=ev,
            cache_dir=cache_dir if cache_dir is not None else out / "cache",
            scene=mission.world.scene,
        )
        mask = obs.observable
        ev.set_observable(mask)
        cov = ev.coverage(mission.world.clouds)  # of `cloud`, from the mission's kept count
        for k in (
            "coverage_observable",
            "area_coverage_observable",
            "observable_fraction",
            "observable_area_fraction",
        ):
            summary[k] = cov[k]
        summary["observability"] = {
            k: obs.stats[k]
            for k in ("samples", "observable_samples", "poses", "lattice_points")
            if k in obs.stats
        }
        summary["observability"]["cached"] = obs.cached
        summary["observability"]["compute_s"] = obs.stats.get("wall_time_s")
        timings["observable"] = time.perf_counter() - t0

    rep = cfg.report
    if rep.enabled and rep.mesh:
        t0 = time.perf_counter()
        mesh, info = reconstruct_mesh(
            cloud,
            depth=rep.poisson_depth,
            max_points=rep.mesh_max_points,
            density_quantile=rep.density_quantile,
            trim_distance=rep.trim_distance,
            viewpoints=_viewpoints(mission),
        )
        timings["mesh"] = time.perf_counter() - t0
        if mesh is None:
            print(f"mesh.ply not written: {info['message']}")
            summary["reconstructed_mesh"] = {"written": False, "message": info["message"]}
        else:
            write_mesh_ply(out / "mesh.ply", mesh)
            t0 = time.perf_counter()
            scores = score_mesh(mesh, ev, taus=tuple(float(t) for t in summary["completeness"]))
            timings["mesh_score"] = time.perf_counter() - t0
            summary["reconstructed_mesh"] = {"written": True, **info, **scores}

    if rep.enabled:
        t0 = time.perf_counter()
        classes, pts = _view_classes(ev, cloud, mask, rep.view_points, cfg.seed)
        plot_coverage(pts, classes, out / "figures" / "coverage.png")
        timings["coverage_png"] = time.perf_counter() - t0
        if rep.html:
            t0 = time.perf_counter()
            summary["finish_s"] = {**timings, "total": time.perf_counter() - t_all}
            write_run_report(
                out, summary, pts, classes, records=mission.records, occ_map=mission.map
            )
            timings["report_html"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    summary["finish_s"] = timings
    return summary


def write_mesh_ply(path, mesh) -> Path:
    """Writes an open3d TriangleMesh as PLY, whole or not at all: into a temporary file that is
    checked and renamed over ``path``. OSError when it cannot be written (open3d only returns
    False, and on a full disk may leave a short file)."""
    import os

    import open3d as o3d

    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.ply")
    try:
        ok = o3d.io.write_triangle_mesh(str(tmp), mesh)
        if ok:  # read it back: the counts of a short file do not match
            back = o3d.io.read_triangle_mesh(str(tmp))
            ok = len(back.vertices) == len(mesh.vertices) and len(back.triangles) == len(
                mesh.triangles
            )
        if not ok:
            free = _free_bytes(path.parent)
            raise OSError(
                f"cannot write {path}: open3d could not write the mesh whole"
                + (" (the disk is full)" if free is not None and free < (1 << 20) else "")
            )
        os.replace(tmp, path)
    except BaseException:
        if tmp.exists():
            tmp.unlink()
        raise
    return path


def _free_bytes(folder) -> int | None:
    import shutil

    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


def _viewpoints(mission) -> np.ndarray:
    """Where the sensors were: the trajectory's rows and the chosen views, (K, 3)."""
    rows = [r[1:4] for r in mission.world.state.trajectory]
    rows += [(r.x, r.y, r.z) for r in mission.records]
    return np.asarray(rows, float).reshape(-1, 3)


def _view_classes(ev, cloud, mask, n_view, seed):
    """A subsample of the ground-truth samples (at most n_view) and their class: 0 covered
    (its 0.1 m cell holds a cloud point), 1 observable but missed, 2 unobservable."""
    gt = ev.gt_points
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(gt), n_view, replace=False)) if len(gt) > n_view else None
    pts = gt if idx is None else gt[idx]
    m = None if mask is None else (mask if idx is None else mask[idx])
    return coverage_classes(pts, cloud, m), pts


def run_view(run_dir, view_points: int = 60000):
    """The coverage colouring of a finished run folder: ``(points, classes, summary)`` with a
    subsample of the ground-truth samples (N, 3) and their class (0 covered, 1 observable but
    missed, 2 unobservable), rebuilt from its ``config.yaml`` and ``cloud.ply`` (the observable
    surface comes from the run's cache when it is there)."""
    from .cloud import read_points
    from .config import load_config
    from .evaluation import Evaluator
    from .mesh import default_mesh_path, load_mesh
    from .observability import observable_surface

    from .runfolder import require_complete_run

    run_dir = require_complete_run(run_dir)
    cfg = load_config(run_dir / "config.yaml", [])
    m = cfg.mesh
    mesh = load_mesh(m.path or default_mesh_path(), scale=m.scale, up=m.up, shift=m.shift)
    ev = Evaluator(mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
    cache = run_dir / "cache" if (run_dir / "cache").exists() else run_dir.parent.parent / "cache"
    mask = observable_surface(mesh, cfg, evaluator=ev, cache_dir=cache).observable
    classes, pts = _view_classes(
        ev, read_points(run_dir / "cloud.ply"), mask, view_points, cfg.seed
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    return pts, classes, summary


def coverage_classes(points, cloud, observable=None, resolution: float = 0.1) -> np.ndarray:
    """(N,) int8 class of each surface point: 0 covered (its ``resolution`` cell, on the
    origin-anchored grid of ``nbvkit.evaluate``, holds a cloud point), 1 observable but missed,
    2 unobservable (``observable`` False). Without ``observable`` every point is observable."""
    points = np.asarray(points, float).reshape(-1, 3)
    cloud = np.asarray(cloud, float).reshape(-1, 3)

    def keys(p):
        k = np.floor(p / resolution).astype(np.int64) + (1 << 20)
        return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]

    covered = (
        np.isin(keys(points), np.unique(keys(cloud))) if len(cloud) else np.zeros(len(points), bool)
    )
    out = np.where(covered, 0, 1).astype(np.int8)
    if observable is not None:
        out[~np.asarray(observable, bool)] = 2
    return out


# ---------------------------------------------------------------------------------- the mesh


def reconstruct_mesh(
    points,
    depth: int = 8,
    max_points: int = 150000,
    density_quantile: float = 0.05,
    trim_distance: float = 0.3,
    viewpoints=None,
    threads: int | None = None,
):
    """Screened Poisson surface reconstruction of a cloud (open3d), trimmed of its bubbles.

    points: (N, 3) world-frame cloud. It is voxel-thinned to about ``max_points`` points,
    normals are estimated (20 neighbours) and oriented toward the nearest of ``viewpoints``
    (K, 3; e.g. the trajectory) or, without them, by open3d's tangent-plane propagation.
    Poisson at octree ``depth`` on ``threads`` threads (default 1: open3d's OpenMP Poisson
    runs several times slower when its threads outnumber the free cores, as in a sweep's
    worker processes: 22 s on 2 threads against 6 s on 1 for the airliner on the loaded 2-core
    machine); vertices below the ``density_quantile`` of Poisson's
    densities, and vertices farther than ``trim_distance`` (m) from the cloud, are removed.

    Returns ``(mesh, info)``: an ``open3d.geometry.TriangleMesh`` (None when there are fewer
    than ``MIN_MESH_POINTS`` points or nothing is left) and a dict: ``message`` (why not, if
    None), ``vertices``, ``triangles``, ``points_used``, ``voxel_m``, ``area_m2``.
    """
    import open3d as o3d

    from . import _core

    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < MIN_MESH_POINTS:
        return None, {
            "message": f"the cloud has {len(pts)} points; at least {MIN_MESH_POINTS} are "
            "needed to reconstruct a mesh"
        }
    voxel = 0.0
    if len(pts) > max_points:
        # a surface's voxel count falls with the square of the voxel: the first size from the
        # point count (a camera cloud holds about one point per 0.02 m cell), then refined from
        # the count it gave. (A first pass at the cloud's own 0.02 m, as before, took 5.8 of the
        # 11.2 s on an airliner mission's cloud, 163 s at twice its size: bench/bench_mesh.py.)
        voxel = 0.02 * math.sqrt(len(pts) / max_points)
        for _ in range(6):
            thin = _core.voxelgrid_sampling(pts, voxel)
            if len(thin) <= max_points:
                break
            voxel *= max(1.05, math.sqrt(len(thin) / max_points) * 1.02)
        pts = thin
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    spacing = max(voxel, 0.02)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=6 * spacing, max_nn=20))
    vp = None if viewpoints is None else np.asarray(viewpoints, float).reshape(-1, 3)
    if vp is not None and len(vp):
        from scipy.spatial import cKDTree

        p = np.asarray(pcd.points)
        n = np.asarray(pcd.normals)
        _, j = cKDTree(vp).query(p)
        flip = np.einsum("ij,ij->i", n, vp[j] - p) < 0
        n[flip] *= -1
        pcd.normals = o3d.utility.Vector3dVector(n)
    else:
        pcd.orient_normals_consistent_tangent_plane(15)
    if threads is None:
        threads = 1
    mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=int(depth), n_threads=max(1, int(threads))
    )
    dens = np.asarray(dens)
    if len(dens) == 0 or len(mesh.triangles) == 0:
        return None, {"message": "Poisson reconstruction produced no surface"}
    remove = dens < np.quantile(dens, density_quantile)
    if trim_distance > 0:
        d = _core.nearest_distances(np.asarray(pcd.points), np.asarray(mesh.vertices))
        remove |= d > trim_distance
    mesh.remove_vertices_by_mask(remove)
    mesh.remove_unreferenced_vertices()
    if len(mesh.triangles) == 0:
        return None, {"message": "nothing of the Poisson surface is near the cloud"}
    mesh.compute_vertex_normals()
    return mesh, {
        "message": "",
        "vertices": len(mesh.vertices),
        "triangles": len(mesh.triangles),
        "points_used": len(pcd.points),
        "voxel_m": voxel,
        "area_m2": float(mesh.get_surface_area()),
        "poisson_depth": int(depth),
    }


def score_mesh(mesh, gt_points, taus=(0.05, 0.1), density: float | None = None, seed: int = 0):
    """Scores a reconstructed mesh (an open3d TriangleMesh or an nbvkit.Mesh) against the
    ground-truth samples ``gt_points`` (M, 3), or against an ``nbvkit.Evaluator``'s (whose
    kd-tree is then used as it is: the same distances).

    The mesh's surface is sampled uniformly at ``density`` points per m² (default 1000, the
    ground truth's default) with ``seed``; with exact nearest distances
    (``nbvkit.nearest_distances``): ``mesh_accuracy`` (mesh samples within tau of a
    ground-truth sample) and ``mesh_completeness`` (ground-truth samples within tau of a mesh
    sample), keyed by tau; ``hausdorff95_m``, the 95th-percentile Hausdorff distance (the
    larger of the two directions' 95th percentiles); ``mean_dist_mesh_to_gt_m``,
    ``mean_dist_gt_to_mesh_m`` and ``mesh_samples``.
    """
    from . import _core
    from .mesh import mesh_from_open3d

    if not isinstance(mesh, _core.Mesh):
        mesh = mesh_from_open3d(mesh)
    from .evaluation import Evaluator

    if isinstance(gt_points, Evaluator):
        gt = gt_points.gt_points
        to_gt = gt_points._core.nearest_to_gt
    else:
        gt = np.asarray(gt_points, float)
        to_gt = lambda q: _core.nearest_distances(gt, q)  # noqa: E731
    dens = density or 1000.0
    n = int(min(max(round(mesh.area * dens), 1), 5_000_000))
    ms = mesh.sample_surface(n, seed)
    # the fractions from at most ~200k queries each way (every k-th point: a statistical error
    # under 0.2 points), against the full sets
    d_m = to_gt(ms[:: max(1, n // 200_000)])
    d_g = _core.nearest_distances(ms, gt[:: max(1, len(gt) // 200_000)])
    out = {
        "mesh_accuracy": {f"{t:g}": float(np.mean(d_m <= t)) for t in taus},
        "mesh_completeness": {f"{t:g}": float(np.mean(d_g <= t)) for t in taus},
        "hausdorff95_m": float(max(np.percentile(d_m, 95), np.percentile(d_g, 95))),
        "mean_dist_mesh_to_gt_m": float(d_m.mean()),
        "mean_dist_gt_to_mesh_m": float(d_g.mean()),
        "mesh_samples": n,
    }
    return out


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
    from .figures import _plt

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


# ---------------------------------------------------------------------------------- HTML


@functools.lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js, from the plotly package (Debian's python3-plotly reads it from
    /usr/share/python3-plotly/plotly.js), read once per process (3.6 MB: a sweep's worker writes
    a report per run). Raises RuntimeError if plotly is not installed."""
    try:
        from plotly.offline import get_plotlyjs

        return get_plotlyjs()
    except Exception:  # noqa: BLE001 - fall back to Debian's file
        p = Path("/usr/share/python3-plotly/plotly.js")
        if p.exists():
            return p.read_text()
        raise RuntimeError(
            "report.html needs plotly.js: install Debian's python3-plotly (make deps)"
        ) from None


@functools.lru_cache(maxsize=1)
def _plotly_in_script() -> str:
    """plotly_js() as the body of an HTML script element."""
    return plotly_js().replace("</script", "<\\/script")


_STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1250px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f2f2f2; } td:first-child, th:first-child { text-align: left; }
img { max-width: 100%; border: 1px solid #eee; } h2 { margin-top: 1.5em; }
.plot { width: 100%; height: 700px; } .small { height: 380px; }
"""


def _page(title: str, body: str, plotly: bool = True) -> str:
    js = _plotly_in_script() if plotly else ""
    script = f"<script type='text/javascript'>{js}</script>" if plotly else ""
    return (
        "<!DOCTYPE html>\n<html><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style>"
        f"{script}</head><body>\n{body}\n</body></html>\n"
    )


def _plot(div: str, traces: list, layout: dict, cls: str = "plot") -> str:
    data = json.dumps(traces, separators=(",", ":"), allow_nan=False)
    lay = json.dumps(layout, separators=(",", ":"), allow_nan=False)
    return (
        f"<div id='{div}' class='{cls}'></div><script>Plotly.newPlot('{div}', {data}, {lay}, "
        "{responsive: true});</script>"
    )


def _img(path: Path) -> str:
    b = base64.b64encode(Path(path).read_bytes()).decode()
    return f"<p><img alt='{html.escape(Path(path).name)}' src='data:image/png;base64,{b}'></p>"


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return html.escape(str(v))


def _table(rows: list[tuple]) -> str:
    out = ["<table>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{_fmt(x)}</td>" for x in r) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _per_res_table(summary: dict) -> str:
    keys = [
        ("coverage", "coverage"),
        ("coverage_observable", "coverage of the observable surface"),
        ("area_coverage", "area coverage"),
        ("area_coverage_observable", "area coverage of the observable surface"),
        ("observable_fraction", "observable share of the surface (cells)"),
        ("precision", "precision"),
    ]
    res = list(summary.get("coverage", {}))
    head = "<tr><th>per resolution</th>" + "".join(f"<th>{r} m</th>" for r in res) + "</tr>"
    rows = []
    for k, label in keys:
        if k in summary:
            rows.append(
                f"<tr><td>{label}</td>"
                + "".join(f"<td>{100 * summary[k][r]:.2f} %</td>" for r in res)
                + "</tr>"
            )
    return "<table>" + head + "".join(rows) + "</table>"


def _r(a, nd=3):
    return np.round(np.asarray(a, float), nd).tolist()


def write_run_report(out, summary: dict, points, classes, records=None, occ_map=None) -> Path:
    """``out/report.html``: the summary figures, an interactive 3D view of the surface
    (``points`` (N, 3) coloured by ``classes`` (N,): covered / observable but missed /
    unobservable) with the trajectory (``out/trajectory.csv``) and the chosen views
    (``records`` or ``out/iterations.csv``), the progress plots, the estimated flight time
    (``occ_map``: the run's final map, else read from map.ot) and the run's PNG figures.
    Self-contained: plotly.js is inlined; it opens offline."""
    out = Path(out)
    pts = np.asarray(points, float).reshape(-1, 3)
    cls = np.asarray(classes)
    traces = []
    for k, (name, col) in enumerate(zip(CLASS_NAMES, CLASS_COLOURS)):
        p = pts[cls == k]
        traces.append(
            {
                "type": "scatter3d",
                "mode": "markers",
                "name": f"{name} ({len(p) / max(len(pts), 1):.1%})",
                "x": _r(p[:, 0], 2),
                "y": _r(p[:, 1], 2),
                "z": _r(p[:, 2], 2),
                "marker": {"size": 1.6, "color": col},
                "hoverinfo": "skip",
            }
        )
    traj = _read_csv(out / "trajectory.csv")
    if traj:
        traces.append(
            {
                "type": "scatter3d",
                "mode": "lines",
                "name": "trajectory",
                "x": _r([float(r["x"]) for r in traj]),
                "y": _r([float(r["y"]) for r in traj]),
                "z": _r([float(r["z"]) for r in traj]),
                "line": {"color": "#1f77b4", "width": 3},
            }
        )
    its = _records(out, records)
    if its:
        x = np.array([r["x"] for r in its])
        y = np.array([r["y"] for r in its])
        z = np.array([r["z"] for r in its])
        yaw = np.array([r["yaw"] for r in its])
        # the camera's axis: body yaw, then the gimbal's pitch (> 0 looks down)
        pitch = np.array([r.get("pitch", 0.0) for r in its])
        traces.append(
            {
                "type": "scatter3d",
                "mode": "markers",
                "name": "chosen views",
                "x": _r(x),
                "y": _r(y),
                "z": _r(z),
                "text": [f"view {r['iteration']} ({r['source']})" for r in its],
                "marker": {"size": 2.5, "color": "#ff7f0e"},
            }
        )
        traces.append(
            {
                "type": "cone",
                "name": "view directions",
                "x": _r(x),
                "y": _r(y),
                "z": _r(z),
                "u": _r(np.cos(yaw) * np.cos(pitch)),
                "v": _r(np.sin(yaw) * np.cos(pitch)),
                "w": _r(-np.sin(pitch)),
                "sizemode": "absolute",
                "sizeref": 0.5,
                "anchor": "tail",
                "visible": "legendonly",
                "showscale": False,
                "colorscale": [[0, "#ff7f0e"], [1, "#ff7f0e"]],
                "showlegend": True,
            }
        )
    layout3d = {
        "title": "surface coverage, trajectory and chosen views",
        "scene": {"aspectmode": "data"},
        "legend": {"itemsizing": "constant"},
        "margin": {"l": 0, "r": 0, "t": 40, "b": 0},
    }
    from .runfolder import run_name

    name = run_name(out)  # the folder's name once in place (not its temporary name)
    body = [f"<h1>nbvkit run: {html.escape(name)}</h1>"]
    body.append(
        _table(
            [
                ("scenario", summary.get("scenario")),
                ("start", summary.get("start")),
                ("mesh", summary.get("mesh")),
                ("iterations", summary.get("iterations")),
                ("distance flown (m)", summary.get("distance_m")),
                ("termination", summary.get("termination")),
                ("wall time (s)", summary.get("wall_time_s")),
                ("cloud points", summary.get("cloud_points")),
                ("Chamfer distance (m)", summary.get("chamfer_m")),
                (
                    "observable share of the area",
                    f"{100 * summary['observable_area_fraction']:.2f} %"
                    if "observable_area_fraction" in summary
                    else "not computed",
                ),
            ]
        )
    )
    body.append(_per_res_table(summary))
    body.append(flight_section(out, occ_map=occ_map))
    m = summary.get("reconstructed_mesh")
    if m:
        if m.get("written"):
            body.append("<h2>Reconstructed mesh (mesh.ply)</h2>")
            rows = [("triangles", m["triangles"]), ("area (m²)", m["area_m2"])]
            rows += [(f"mesh accuracy @ {t} m", v) for t, v in m["mesh_accuracy"].items()]
            rows += [(f"mesh completeness @ {t} m", v) for t, v in m["mesh_completeness"].items()]
            rows += [("Hausdorff 95th percentile (m)", m["hausdorff95_m"])]
            body.append(_table(rows))
        else:
            body.append(f"<p>No mesh.ply: {html.escape(m.get('message', ''))}</p>")
    body.append("<h2>3D view</h2>")
    body.append(
        "<p>Ground-truth surface samples (decimated): green covered (their 0.1 m cell holds a "
        "reconstructed point), red observable but missed, grey unobservable from any "
        "collision-free pose. Click the legend to hide a class.</p>"
    )
    body.append(_plot("view3d", traces, layout3d))
    if its:
        body.append("<h2>Progress</h2>")
        it = [r["iteration"] for r in its]
        cov_tr = []
        for key, lab in (
            ("coverage_005", "0.05 m"),
            ("coverage_01", "0.1 m"),
            ("coverage_05", "0.5 m"),
        ):
            xs = [r["iteration"] for r in its if r.get(key) not in (None, "")]
            ys = [float(r[key]) for r in its if r.get(key) not in (None, "")]
            if xs:
                cov_tr.append(
                    {"type": "scatter", "x": xs, "y": _r(ys, 4), "name": f"coverage @ {lab}"}
                )
        if cov_tr:
            body.append(
                _plot(
                    "progress_cov",
                    cov_tr,
                    {"title": "coverage", "xaxis": {"title": "iteration"}},
                    "plot small",
                )
            )
        body.append(
            _plot(
                "progress_ent",
                [
                    {
                        "type": "scatter",
                        "x": it,
                        "y": _r([r["entropy"] for r in its], 1),
                        "name": "entropy",
                    },
                    {
                        "type": "scatter",
                        "x": it,
                        "y": _r([r["distance_m"] for r in its], 2),
                        "name": "distance (m)",
                        "yaxis": "y2",
                    },
                ],
                {
                    "title": "map entropy and distance flown",
                    "xaxis": {"title": "iteration"},
                    "yaxis": {"title": "entropy"},
                    "yaxis2": {"title": "distance (m)", "overlaying": "y", "side": "right"},
                },
                "plot small",
            )
        )
    figs = sorted((out / "figures").glob("*.png")) if (out / "figures").exists() else []
    if figs:
        body.append("<h2>Figures</h2>")
        body.extend(_img(f) for f in figs)
    body.append(
        "<h2>summary.json</h2><pre>"
        + html.escape(json.dumps(summary, indent=1, default=str)[:20000])
        + "</pre>"
    )
    path = out / "report.html"
    _write_text_atomic(path, _page(f"nbvkit run {name}", "\n".join(body)))
    return path


FLIGHT_BEGIN, FLIGHT_END = "<!-- nbvkit:flight -->", "<!-- /nbvkit:flight -->"
#: colours of the sorties in the report's flight view (cycled)
SORTIE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")


def flight_section(out, export: dict | None = None, paths=None, occ_map=None) -> str:
    """The report's "Flight" section (between FLIGHT_BEGIN and FLIGHT_END): the whole mission's
    estimated flight time (nbvkit.export's flight-time model; ``export``: the summary of an
    export_mission, else its default speeds) and, with a budget, the sorties: a table, and
    ``paths`` ((N, 3) mesh-frame waypoints per sortie) drawn in colour. occ_map: the run's
    final map when at hand (else read from map.ot)."""
    out = Path(out)
    try:
        if export is None:
            from .export import estimate_flight

            e = estimate_flight(out, occ_map=occ_map)
            model = e["model"]
            mission = {"time_s": e["time_s"], "distance_m": e["distance_m"], "views": e["views"]}
        else:
            mission, model = export["mission"], export["model"]
    except (OSError, ValueError, RuntimeError) as err:
        body = f"<p>Flight time not estimated: {html.escape(str(err))}</p>"
        return f"{FLIGHT_BEGIN}<h2>Flight</h2>{body}{FLIGHT_END}"
    speed = model.get("speed", model.get("speed_m_s"))
    climb = model.get("climb_rate", model.get("climb_rate_m_s"))
    rows = [
        ("estimated flight time (min)", f"{mission['time_s'] / 60:.1f}"),
        ("flight distance with take-off and return (m)", f"{mission['distance_m']:.1f}"),
        ("views", mission["views"]),
        ("model", f"{speed:g} m/s, climb {climb:g} m/s, hover {model['hover_s']:g} s per view"),
    ]
    body = [f"<h2>Flight</h2>{_table(rows)}"]
    if export is not None and export.get("budget"):
        b = export["budget"]
        body.append(
            f"<p>Sorties for a {b['flight_time_min']:g} min battery ({b['reserve_pct']:g}% "
            f"reserve): {len(export['sorties'])}"
            + (f"; not flown: {len(export['unreachable'])} points" if export["unreachable"] else "")
            + "</p>"
        )
        body.append(
            _table(
                [("sortie", "views / distance (m) / time (min)")]
                + [
                    (s["sortie"], f"{s['views']} / {s['distance_m']:.1f} / {s['time_min']:.2f}")
                    for s in export["sorties"]
                ]
            )
        )
        if paths:
            traces = [
                {
                    "type": "scatter3d",
                    "mode": "lines",
                    "name": f"sortie {k + 1}",
                    "x": _r(p[:, 0]),
                    "y": _r(p[:, 1]),
                    "z": _r(p[:, 2]),
                    "line": {"color": SORTIE_COLOURS[k % len(SORTIE_COLOURS)], "width": 4},
                }
                for k, p in enumerate(paths)
            ]
            layout = {"title": "sorties", "scene": {"aspectmode": "data"}}
            body.append(_plot("sorties3d", traces, layout))
    return FLIGHT_BEGIN + "\n".join(body) + FLIGHT_END


def update_flight_section(out, export: dict, paths=None) -> bool:
    """Replaces the flight section of ``out/report.html`` (if there) with one for ``export``;
    True if the report was updated."""
    path = Path(out) / "report.html"
    if not path.is_file():
        return False
    text = path.read_text()
    a, b = text.find(FLIGHT_BEGIN), text.find(FLIGHT_END)
    if a < 0 or b < a:
        return False
    new = text[:a] + flight_section(out, export, paths) + text[b + len(FLIGHT_END) :]
    from .runfolder import mark_incomplete, write_manifest

    was_complete = mark_incomplete(out)  # the manifest lists report.html's size
    tmp = path.with_suffix(".html.tmp")
    tmp.write_text(new)
    tmp.replace(path)
    if was_complete:
        write_manifest(out)
    return True


def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _records(out: Path, records) -> list[dict]:
    if records is not None:
        return [
            {
                "iteration": r.iteration,
                "x": r.x,
                "y": r.y,
                "z": r.z,
                "yaw": r.yaw,
                "pitch": r.pitch,
                "source": r.source,
                "entropy": r.entropy,
                "distance_m": r.distance_m,
                "coverage_005": r.coverage_005,
                "coverage_01": r.coverage_01,
                "coverage_05": r.coverage_05,
            }
            for r in records
        ]
    rows = _read_csv(out / "iterations.csv")
    num = ("x", "y", "z", "yaw", "entropy", "distance_m")
    return [
        {
            **r,
            "iteration": int(r["iteration"]),
            **{k: float(r[k]) for k in num},
            "pitch": float(r.get("pitch") or 0.0),  # runs written before views had a pitch: level
        }
        for r in rows
    ]


# ---------------------------------------------------------------------------------- experiments


def write_experiment_report(root, df, title: str, markdown: str | None = None) -> Path:
    """``root/report.html`` of an experiment (table, sweep, compare): the summary table
    (``markdown``, e.g. Table 2, shown as preformatted text), one row per run of ``df`` (the
    tidy runs table) with a link to its ``runs/<run_id>/report.html``, and every PNG of
    ``root/figures``. Self-contained except for the links."""
    root = Path(root)
    body = [f"<h1>{html.escape(title)}</h1>"]
    if markdown:
        body.append("<h2>Summary</h2><pre>" + html.escape(markdown) + "</pre>")
    cols = [
        c
        for c in (
            "scenario",
            "start",
            "mesh",
            "iterations",
            "distance_m",
            "coverage_0.05",
            "coverage_observable_0.05",
            "coverage_0.1",
            "coverage_0.5",
            "observable_fraction_0.05",
            "chamfer_m",
            "mesh_hausdorff95_m",
            "wall_time_s",
            "termination",
        )
        if c in df.columns
    ]
    head = "<tr><th>run</th>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols) + "</tr>"
    rows = []
    for _, r in df.iterrows():
        rid = str(r["run_id"])
        link = f"runs/{rid}/report.html"
        cell = (
            f"<a href='{html.escape(link)}'>{html.escape(rid)}</a>"
            if (root / link).exists()
            else html.escape(rid)
        )
        vals = "".join(f"<td>{_fmt(_plain(r[c]))}</td>" for c in cols)
        rows.append(f"<tr><td>{cell}</td>{vals}</tr>")
    body.append("<h2>Runs</h2><table>" + head + "".join(rows) + "</table>")
    figs = sorted((root / "figures").glob("*.png")) if (root / "figures").exists() else []
    if figs:
        body.append("<h2>Figures</h2>")
        body.extend(_img(f) for f in figs)
    path = root / "report.html"
    _write_text_atomic(path, _page(title, "\n".join(body), plotly=False))
    return path


def _write_text_atomic(path, text: str) -> None:
    from .runfolder import write_text_atomic as write

    write(Path(path), text)


def _plain(v):
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    return v
