"""Benchmark of symmetry detection and prediction (paper sec. 3.2.2) on simulated laser profiles.
Prints the time per stage, the plane's error from the true mirror plane y = 0 and the
confidence; asserts nothing.

    .venv/bin/python bench/bench_symmetry.py                  # airliner (+ twinjet if present)
    .venv/bin/python bench/bench_symmetry.py --poses 5        # also 5 random poses of each
    .venv/bin/python bench/bench_symmetry.py --keypoints iss  # another keypoint detector
    .venv/bin/python bench/bench_symmetry.py --threads 1

The profile is flown as in tests/test_symmetry.py: 10 waypoints on a circle of radius 25 m
(28 m in the posed runs) around the structure's centre, each sweeping z from 0.5 to 10 m in
0.5 m steps facing the centre; laser hits voxelised at 0.1 m, ground below 0.3 m removed. In a
posed run the structure is yawed and moved before the flight (the scan pattern is then not
mirror-symmetric) and the profile is then moved rigidly in 3D.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

import nbvkit
from nbvkit import _core

ROOT = Path(__file__).resolve().parent.parent
TWINJET = ROOT.parent / "shared" / "meshes" / "twinjet.obj"
Y0 = np.array([0.0, 1.0, 0.0, 0.0])


def profile(mesh, waypoints=10, radius=25.0):
    lo, hi = mesh.bounds
    c = (lo + hi) / 2
    laser = nbvkit.LaserScanner(mesh)
    cloud = _core.SurfaceCloud(voxel_size=0.1, min_z=0.3)
    for k in range(waypoints):
        th = 2 * math.pi * k / waypoints
        x, y = c[0] + radius * math.cos(th), c[1] + radius * math.sin(th)
        yaw = math.atan2(c[1] - y, c[0] - x)
        for z in np.arange(0.5, 10.0001, 0.5):
            cloud.add(laser.scan_pose([x, y, z, yaw]).hits)
    return cloud.points


def rot_z(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def errors(plane, true, at):
    n, nt = plane[:3], true[:3]
    d, dt = plane[3], true[3]
    if n @ nt < 0:
        n, d = -n, -d
    ang = math.degrees(math.acos(min(1.0, abs(float(n @ nt)))))
    q = at - (nt @ at - dt) * nt
    return ang, abs(float(n @ q - d))


def run(name, points, true, opts, repeats):
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = nbvkit.detect_symmetry(points, **opts)
        t1 = time.perf_counter()
        pred = nbvkit.predict_symmetric(points, res.plane) if res.accepted else None
        t2 = time.perf_counter()
        if best is None or (t2 - t0) < best[0]:
            best = (t2 - t0, t1 - t0, res, pred)
    total, t_det, res, pred = best
    ang, off = errors(res.plane, true, points.mean(0))
    print(
        f"\n{name}: {len(points)} points -> {res.num_points} after downsampling, "
        f"{len(res.keypoints)} keypoints, {len(res.pairs)} pairs, support {res.support}, "
        f"confidence {res.confidence:.3f}, accepted {res.accepted}"
    )
    print(
        f"  detected plane {np.round(res.plane, 4).tolist()}: "
        f"{ang:.3f} deg, {off:.3f} m from the truth"
    )
    if pred is not None:
        ang2, off2 = errors(pred.plane, true, points.mean(0))
        print(
            f"  after ICP     {np.round(pred.plane, 4).tolist()}: {ang2:.3f} deg, {off2:.3f} m; "
            f"{len(pred.predicted)} predicted points"
        )
    print(
        "  detect  "
        + "  ".join(f"{k} {v * 1000:.0f} ms" for k, v in res.timings.items() if k != "total")
    )
    if pred is not None:
        print(
            "  predict "
            + "  ".join(f"{k} {v * 1000:.0f} ms" for k, v in pred.timings.items() if k != "total")
        )
    print(
        f"  total: detect {t_det:.3f} s + predict {total - t_det:.3f} s = {total:.3f} s "
        f"(best of {repeats})"
    )
    return ang, off, res.confidence, total


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--poses", type=int, default=0, help="random poses per structure (default 0)")
    ap.add_argument("--keypoints", default="sift", choices=["sift", "iss", "uniform"])
    ap.add_argument("--threads", type=int, default=0, help="core threads (0: all)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    nbvkit.set_num_threads(args.threads)
    print(f"threads: {nbvkit.get_num_threads()}, keypoints: {args.keypoints}")
    opts = {"keypoints": args.keypoints}
    structures = [("airliner", nbvkit.load_mesh(nbvkit.default_mesh_path()))]
    if TWINJET.exists():
        structures.append(("twinjet", nbvkit.load_mesh(str(TWINJET))))
    rng = np.random.default_rng(0)
    rows = []
    for name, mesh in structures:
        t0 = time.perf_counter()
        pts = profile(mesh)
        print(f"\n[{name}] profile simulated in {time.perf_counter() - t0:.2f} s")
        rows.append((name, "axis-aligned") + run(name, pts, Y0, opts, args.repeats))
        for k in range(args.poses):
            yaw = float(rng.uniform(0, 360))
            R, t = rot_z(yaw), np.r_[rng.uniform(-10, 10, 2), 0.0]
            posed = profile(nbvkit.Mesh(mesh.vertices @ R.T + t, mesh.faces), radius=28.0)
            R3, t3 = random_rotation(rng), rng.uniform(-100, 100, 3)
            n = R3 @ (R @ Y0[:3])
            true = np.r_[n, (R @ Y0[:3]) @ t + n @ t3]
            label = f"{name} yaw {yaw:.0f} deg + 3D pose"
            rows.append(
                (name, f"yaw {yaw:.0f} + 3D") + run(label, posed @ R3.T + t3, true, opts, 1)
            )
    print("\nsummary: structure, pose, angle error (deg), offset error (m), confidence, time (s)")
    for r in rows:
        print(f"  {r[0]:9s} {r[1]:18s} {r[2]:7.3f} {r[3]:7.3f} {r[4]:7.3f} {r[5]:7.3f}")


if __name__ == "__main__":
    main()
