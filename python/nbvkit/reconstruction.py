"""The reconstruction as a mesh: ``mesh.ply`` from a mission's final cloud, and its scores
against the ground truth (part of the end-of-run outputs, nbvkit.finish; importable from
nbvkit.report).

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

import math
from pathlib import Path

import numpy as np

from . import _core
from ._open3d import open3d
from .cloud import _is_cloud_list

__all__ = ["MIN_MESH_POINTS", "reconstruct_mesh", "score_mesh", "write_mesh_ply"]

#: fewer cloud points than this: no mesh is reconstructed (a clear message instead)
MIN_MESH_POINTS = 100


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

    points: (N, 3) world-frame cloud, or a list of SurfaceClouds read in place (a mission's
    ``world.clouds``: the same mesh as of their points stacked). It is voxel-thinned to about
    ``max_points`` points, normals are estimated (20 neighbours) and oriented toward the nearest
    of ``viewpoints`` (K, 3; e.g. the trajectory) or, without them, by open3d's tangent-plane
    propagation.
    Poisson at octree ``depth`` on ``threads`` threads (default 1: open3d's OpenMP Poisson
    runs several times slower when its threads outnumber the free cores, as in a sweep's
    worker processes: 22 s on 2 threads against 6 s on 1 for the airliner on the loaded 2-core
    machine); vertices below the ``density_quantile`` of Poisson's
    densities, and vertices farther than ``trim_distance`` (m) from the cloud, are removed.

    Returns ``(mesh, info)``: an ``open3d.geometry.TriangleMesh`` (None when there are fewer
    than ``MIN_MESH_POINTS`` points or nothing is left) and a dict: ``message`` (why not, if
    None), ``vertices``, ``triangles``, ``points_used``, ``voxel_m``, ``area_m2``.
    """
    o3d = open3d()

    if _is_cloud_list(points):  # read in place, never stacked whole (their points are finite)
        clouds = list(points)
        n = sum(len(c) for c in clouds)
        whole = lambda: _core.stack_points(clouds)  # noqa: E731
        thin = lambda voxel: _core.voxelgrid_sampling_of(clouds, voxel)  # noqa: E731
    else:
        pts = np.asarray(points, float).reshape(-1, 3)
        finite = np.isfinite(pts).all(axis=1)
        if not finite.all():  # a copy only then (a 100 m plant's cloud is 0.6 GB)
            pts = pts[finite]
        del finite
        n, whole = len(pts), (lambda: pts)
        thin = lambda voxel: _core.voxelgrid_sampling(pts, voxel)  # noqa: E731
    if n < MIN_MESH_POINTS:
        return None, {
            "message": f"the cloud has {n} points; at least {MIN_MESH_POINTS} are "
            "needed to reconstruct a mesh"
        }
    pts, voxel = (whole(), 0.0) if n <= max_points else _thinned(thin, n, max_points)
    pcd = _oriented_cloud(pts, voxel, viewpoints)
    if threads is None:
        threads = 1
    mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=int(depth), n_threads=max(1, int(threads))
    )
    dens = np.asarray(dens)
    if len(dens) == 0 or len(mesh.triangles) == 0:
        return None, {"message": "Poisson reconstruction produced no surface"}
    _trim(mesh, dens, np.asarray(pcd.points), density_quantile, trim_distance)
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


def _thinned(thin, n: int, max_points: int) -> tuple[np.ndarray, float]:
    """A cloud of n > max_points points voxel-thinned (thin(voxel): its voxel centroids) to at
    most about max_points points, and the voxel (m)."""
    # a surface's voxel count falls with the square of the voxel: the first size from the
    # point count (a camera cloud holds about one point per 0.02 m cell), then refined from
    # the count it gave. (A first pass at the cloud's own 0.02 m, as before, took 5.8 of the
    # 11.2 s on an airliner mission's cloud, 163 s at twice its size: bench/bench_mesh.py.)
    voxel = 0.02 * math.sqrt(n / max_points)
    for _ in range(6):
        out = thin(voxel)
        if len(out) <= max_points:
            break
        voxel *= max(1.05, math.sqrt(len(out) / max_points) * 1.02)
    return out, voxel


def _oriented_cloud(pts: np.ndarray, voxel: float, viewpoints):
    """An open3d PointCloud of pts with normals (20 neighbours) turned toward the nearest of
    the viewpoints, or without them oriented by open3d's tangent-plane propagation."""
    o3d = open3d()

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
    return pcd


def _trim(mesh, dens: np.ndarray, cloud: np.ndarray, density_quantile, trim_distance) -> None:
    """Removes the Poisson surface's bubbles: the vertices below the density_quantile of the
    densities and those farther than trim_distance from the cloud."""
    remove = dens < np.quantile(dens, density_quantile)
    if trim_distance > 0:
        d = _core.nearest_distances(cloud, np.asarray(mesh.vertices))
        remove |= d > trim_distance
    mesh.remove_vertices_by_mask(remove)
    mesh.remove_unreferenced_vertices()


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
    from .evaluation import Evaluator
    from .mesh import mesh_from_open3d

    if not isinstance(mesh, _core.Mesh):
        mesh = mesh_from_open3d(mesh)
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


def write_mesh_ply(path, mesh) -> Path:
    """Writes an open3d TriangleMesh as PLY, whole or not at all: into a temporary file that is
    checked and renamed over ``path``. OSError when it cannot be written (open3d only returns
    False, and on a full disk may leave a short file)."""
    import os

    o3d = open3d()

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
