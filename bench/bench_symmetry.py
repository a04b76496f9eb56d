"""Benchmark of symmetry detection and prediction (paper sec. 3.2.2) on simulated laser profiles.
Prints the time per stage, the plane's error from the true mirror plane y = 0 and the
confidence; asserts nothing.

First the mission's own case: the airliner profile of Scenario 5, start 0 (profiled once), and
detection + prediction with the mission's symmetry config, timed (best of --repeats) with a
fingerprint of the plane and the predicted points (equal fingerprints: identical results).
``--against DIR`` times the same profile, in the same run, with the nbvkit package (and its
built extension) of another checkout, DIR/python or DIR (e.g. ../main, or a saved copy of the
package before a change), and prints the ratio.

    .venv/bin/python bench/bench_symmetry.py --against ../main  # mission profile vs main
    .venv/bin/python bench/bench_symmetry.py --mission-only     # only the mission profile
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
import tempfile
import time
from pathlib import Path

import numpy as np

import nbvkit
from _timing import checkouts, run_snippet
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
    """A uniformly random 3 x 3 rotation."""
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=rng).as_matrix()


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


# Runs in this checkout or, through --against, in another one (its own nbvkit): keep it to the
# API both have.
TIME_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
import nbvkit
from nbvkit import symmetry as sym
from nbvkit.config import Config
nbvkit.set_num_threads(int(sys.argv[3]))
pts = np.load(sys.argv[1])
cfg = Config().symmetry
best = None
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    res = sym.detect_symmetry(pts, **sym.detection_options(cfg))
    t1 = time.perf_counter()
    pred = sym.predict_symmetric(pts, res.plane, **sym.prediction_options(cfg))
    t2 = time.perf_counter()
    if best is None or t2 - t0 < best[0]:
        best = (t2 - t0, t1 - t0, t2 - t1, res, pred)
total, det, prd, res, pred = best
h = hashlib.sha1(np.ascontiguousarray(res.plane).tobytes())
h.update(np.ascontiguousarray(pred.plane).tobytes())
h.update(np.ascontiguousarray(pred.predicted).tobytes())
stages = {"detect_" + k: v for k, v in res.timings.items() if k != "total"}
stages.update({"predict_" + k: v for k, v in pred.timings.items() if k != "total"})
print(json.dumps(dict(total=total, detect=det, predict=prd, accepted=bool(res.accepted),
                      plane=[float(v) for v in pred.plane], predicted=int(len(pred.predicted)),
                      num_points=int(res.num_points), keypoints=int(len(res.keypoints)),
                      fingerprint=h.hexdigest()[:16], stages=stages)))
"""


def mission_profile():
    """The laser profile of the default mission (Scenario 5, start 0, airliner)."""
    from nbvkit.config import Config
    from nbvkit.mission import Mission
    from nbvkit.profiling import run_profiling

    cfg = Config.from_dict({"scenario": "5", "progress": False})
    m = Mission(cfg)
    m.world.take_off()
    run_profiling(m.world)
    return np.asarray(m.world.laser_cloud.points, float)


def mission_case(args):
    t0 = time.perf_counter()
    pts = mission_profile()
    print(
        f"\n[mission] airliner Scenario 5 start 0 profile: {len(pts)} points "
        f"({time.perf_counter() - t0:.1f} s to fly)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "profile.npy"
        np.save(f, pts)
        rows = [
            (label, run_snippet(TIME_SNIPPET, (f, args.repeats, args.threads), py))
            for label, py in checkouts(args.against)
        ]
    for label, r in rows:
        print(
            f"  {label}: detect {r['detect']:.3f} s + predict {r['predict']:.3f} s = "
            f"{r['total']:.3f} s (best of {args.repeats}); {r['num_points']} points after "
            f"downsampling, {r['keypoints']} keypoints, {r['predicted']} predicted points, "
            f"fingerprint {r['fingerprint']}"
        )
        print("    " + "  ".join(f"{k} {v * 1000:.0f} ms" for k, v in r["stages"].items()))
    if len(rows) == 2:
        a, b = rows[0][1], rows[1][1]
        same = "identical" if a["fingerprint"] == b["fingerprint"] else "DIFFERENT"
        print(f"  speed-up vs {rows[1][0]}: {b['total'] / a['total']:.2f}x; results {same}")


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--poses", type=int, default=0, help="random poses per structure (default 0)")
    ap.add_argument("--keypoints", default="sift", choices=["sift", "iss", "uniform"])
    ap.add_argument("--threads", type=int, default=0, help="core threads (0: all)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--against", help="another checkout (with its .venv) to time in the same run")
    ap.add_argument("--mission-only", action="store_true", help="only the mission's profile")
    args = ap.parse_args()
    nbvkit.set_num_threads(args.threads)
    print(f"threads: {nbvkit.get_num_threads()}, keypoints: {args.keypoints}")
    mission_case(args)
    if args.mission_only:
        return
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
