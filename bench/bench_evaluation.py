"""Benchmark of nbvkit.evaluate: a 1-million-point cloud against the twinjet, and the same
computation through scipy.spatial.cKDTree + numpy in the same run (a ratio). Prints figures;
asserts nothing.

    .venv/bin/python bench/bench_evaluation.py                # timing, ours vs scipy
    .venv/bin/python bench/bench_evaluation.py --stability    # how the GT density was chosen

The structure is ../shared/meshes/twinjet.obj (727 m^2), or the shipped airliner when that is
absent. The 1M-point cloud is a noisy (sigma 5 mm) sample of the surface with the front 8 m
(nose) missing, as a reconstruction that left part of the structure unseen: ~20 % of the ground
truth is then metres away from the cloud, which is the expensive case for nearest neighbours.

--stability scans the structure with the RGB-D camera from 60 random views (0.02 m voxel filter),
then evaluates that cloud with 8 ground-truth seeds at several densities and prints the spread of
coverage at each resolution: the figures quoted in nbvkit.evaluate's docstring.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import nbvkit
from nbvkit.evaluation import DEFAULT_GT_DENSITY, Evaluator, evaluate

ROOT = Path(__file__).resolve().parent.parent
TWINJET = ROOT.parent / "shared" / "meshes" / "twinjet.obj"


def load_structure(path):
    if path:
        return Path(path), nbvkit.load_mesh(path)
    p = TWINJET if TWINJET.exists() else nbvkit.default_mesh_path()
    return p, nbvkit.load_mesh(p)


def million_cloud(mesh, n=1_000_000, seed=12345):
    rng = np.random.default_rng(seed)
    pts = mesh.sample_surface(int(n * 1.5), seed)
    x0 = mesh.bounds[0, 0]
    pts = pts[pts[:, 0] > x0 + 8.0][:n]
    return pts + rng.normal(scale=0.005, size=pts.shape)


def scipy_evaluate(mesh, cloud, resolutions, taus, density, seed):
    """The same metrics with numpy (np.unique cell sets) and scipy's cKDTree (all cores)."""
    from scipy.spatial import cKDTree

    gt = mesh.sample_surface(int(round(mesh.area * density)), seed)
    out = {"coverage": {}, "area_coverage": {}, "precision": {}, "completeness": {}, "accuracy": {}}
    for r in resolutions:
        kg = np.floor(gt / r).astype(np.int64)
        kc = np.floor(cloud / r).astype(np.int64)
        cells_g, inv_g = np.unique(kg, axis=0, return_inverse=True)
        cells_c = np.unique(kc, axis=0)
        # rows -> void scalars for set membership
        vg = np.ascontiguousarray(cells_g).view([("", np.int64)] * 3).ravel()
        vc = np.ascontiguousarray(cells_c).view([("", np.int64)] * 3).ravel()
        cov_g = np.isin(vg, vc)
        key = f"{r:g}"
        out["coverage"][key] = float(cov_g.mean())
        out["area_coverage"][key] = float(cov_g[inv_g.ravel()].mean())
        out["precision"][key] = float(np.isin(vc, vg).mean())
    d_c, _ = cKDTree(gt).query(cloud, workers=-1)
    d_g, _ = cKDTree(cloud).query(gt, workers=-1)
    for t in taus:
        out["accuracy"][f"{t:g}"] = float((d_c <= t).mean())
        out["completeness"][f"{t:g}"] = float((d_g <= t).mean())
    out["chamfer_m"] = 0.5 * (d_c.mean() + d_g.mean())
    return out


def timed(fn, repeat):
    times, result = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), times, result


def bench_timing(args):
    path, mesh = load_structure(args.mesh)
    cloud = million_cloud(mesh)
    print(
        f"structure: {path.name}, {mesh.area:.1f} m^2; cloud: {len(cloud):,} points; "
        f"GT density {args.density:g} /m^2 ({mesh.area * args.density:,.0f} samples); "
        f"threads: {nbvkit.get_num_threads()}"
    )
    res, taus = (0.05, 0.1, 0.5), (0.05, 0.1)
    med, times, ours = timed(
        lambda: evaluate(mesh, cloud, resolutions=res, taus=taus, gt_density=args.density),
        args.repeat,
    )
    print(
        f"nbvkit.evaluate: median {med:.2f} s of {args.repeat} "
        f"({', '.join(f'{t:.2f}' for t in times)})"
    )
    t = time.perf_counter()
    ev = Evaluator(mesh, resolutions=res, taus=taus, gt_density=args.density)
    t_prep = time.perf_counter() - t
    raw = ev._core.evaluate(cloud)
    phases = dict(ev._core.gt_info.timings_s)
    print(
        f"  ground truth prepared once: {t_prep:.2f} s (sampling {phases['sample']:.2f} s, "
        f"GT cells {phases['prepare_gt']:.2f} s, the rest the GT kd-tree)"
    )
    print(
        "  per cloud: " + ", ".join(f"{k} {v:.2f} s" for k, v in raw.timings_s if k not in phases)
    )
    med_e, _, _ = timed(lambda: ev(cloud), args.repeat)
    print(f"  Evaluator(mesh) reused, per cloud: median {med_e:.2f} s")
    print(
        f"  coverage {fmt(ours['coverage'])}  completeness {fmt(ours['completeness'])}  "
        f"chamfer {ours['chamfer_m']:.4f} m"
    )
    if args.no_scipy:
        return
    try:
        import scipy  # noqa: F401
    except ImportError:
        print("scipy not installed: no comparison")
        return
    med_s, times_s, ref = timed(
        lambda: scipy_evaluate(mesh, cloud, res, taus, args.density, 0), args.scipy_repeat
    )
    print(
        f"scipy cKDTree + numpy: median {med_s:.2f} s of {args.scipy_repeat} "
        f"({', '.join(f'{t:.2f}' for t in times_s)})"
    )
    print(f"ratio scipy / nbvkit: {med_s / med:.1f}x")
    diff = max(
        max(abs(ours[k][r] - ref[k][r]) for r in ref[k])
        for k in ("coverage", "area_coverage", "precision", "completeness", "accuracy")
    )
    print(
        f"largest difference between the two: {diff:.2e} (fractions), "
        f"chamfer {abs(ours['chamfer_m'] - ref['chamfer_m']):.2e} m"
    )


def fmt(d):
    return " ".join(f"{k}:{100 * v:.2f}%" for k, v in d.items())


def camera_cloud(mesh, views=60, seed=7, voxel=0.02):
    """A reconstruction as the RGB-D camera would leave it: 60 random views 3-7 m from the
    surface, `voxel` m voxel filter, no ground removal."""
    rng = np.random.default_rng(seed)
    scene = nbvkit.RaycastScene(mesh)
    cam = nbvkit.DepthCamera(scene)
    cloud = nbvkit.PointCloud(voxel_size=voxel, min_z=float("-inf"))
    targets = mesh.sample_surface(views, seed)
    for p in targets:
        d = rng.normal(size=3)
        d[2] = abs(d[2]) * 0.5
        d /= np.linalg.norm(d)
        c = p + rng.uniform(3, 7) * d
        c[2] = max(c[2], 0.5)
        yaw = np.arctan2(p[1] - c[1], p[0] - c[0])
        cloud.add(cam.scan_pose([c[0], c[1], c[2], yaw]).hits)
    return cloud.points


def bench_stability(args):
    path, mesh = load_structure(args.mesh)
    cloud = camera_cloud(mesh, voxel=args.cloud_voxel)
    print(
        f"structure: {path.name}, {mesh.area:.1f} m^2; camera cloud: {len(cloud):,} points "
        f"(60 views, {args.cloud_voxel:g} m voxels); seeds 0-{args.seeds - 1}"
    )
    print(
        "density  samples   | coverage 0.05 m: mean  spread   std  | 0.1 m: spread | "
        "0.5 m: spread | area cov. 0.05: mean  spread | s/eval"
    )
    for density in args.densities:
        rows = []
        t = time.perf_counter()
        for seed in range(args.seeds):
            rows.append(evaluate(mesh, cloud, gt_density=density, seed=seed))
        dt = (time.perf_counter() - t) / args.seeds
        c = {k: np.array([r["coverage"][k] for r in rows]) * 100 for k in ("0.05", "0.1", "0.5")}
        a = np.array([r["area_coverage"]["0.05"] for r in rows]) * 100
        again = evaluate(mesh, cloud, gt_density=density, seed=0)
        same = "same" if again == rows[0] else "DIFFERENT"
        print(
            f"{density:7.0f}  {rows[0]['n_gt_points']:>9,} "
            f"| {c['0.05'].mean():6.2f} %  "
            f"{np.ptp(c['0.05']):5.2f} pp {c['0.05'].std():5.2f} | "
            f"{np.ptp(c['0.1']):5.2f} pp     | "
            f"{np.ptp(c['0.5']):5.2f} pp     | {a.mean():6.2f} %  {np.ptp(a):5.2f} pp    | "
            f"{dt:5.2f}  (seed 0 again: {same})"
        )


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--mesh", help="structure (default: ../shared/meshes/twinjet.obj or the airliner)"
    )
    p.add_argument(
        "--density",
        type=float,
        default=DEFAULT_GT_DENSITY,
        help=f"GT samples per m^2 (default {DEFAULT_GT_DENSITY:g})",
    )
    p.add_argument("--repeat", type=int, default=3, help="runs of nbvkit.evaluate (median)")
    p.add_argument("--scipy-repeat", type=int, default=1, help="runs of the scipy version (median)")
    p.add_argument("--no-scipy", action="store_true", help="skip the scipy comparison")
    p.add_argument("--threads", type=int, default=0, help="core threads (0 = all)")
    p.add_argument(
        "--stability",
        action="store_true",
        help="measure coverage spread over GT seeds at several densities instead",
    )
    p.add_argument("--densities", type=float, nargs="+", default=[1000, 2000, 4000, 8000, 16000])
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument(
        "--cloud-voxel",
        type=float,
        default=0.02,
        help="voxel filter of the --stability camera cloud, metres (default 0.02)",
    )
    args = p.parse_args(argv)
    nbvkit.set_num_threads(args.threads)
    if args.stability:
        bench_stability(args)
    else:
        bench_timing(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
