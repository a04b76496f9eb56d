"""Camera and laser ray-casting speed on the default airliner (or --mesh).

Prints, for a 640x480 frame: ms per frame and rays/s with Embree 16-wide packets over 4x4 tiles
(the sensor path) on 1 thread and on all threads, and the same rays cast one at a time with
rtcIntersect1 (RaycastScene.intersect) in the same run, as the baseline ratio; plus the laser scan.

--against DIR times whole camera frames (DepthCamera.scan: the cast and the hits and free ray
ends it returns) in this checkout and in another one (DIR/python, or a saved package),
alternating, in the same run: 48 frames from rings round the structure (3 heights, 16 headings,
5 m outside its bounding box, each facing its centre), on one thread and on all; and checks both
return the same scans bit for bit.

A frame's result (about 12 MB of arrays) is allocated anew by every scan. Where glibc hands such
blocks back to the system between scans, their pages are faulted in again each time, and on
some virtual machines that dominates: on 2026-12-05 on this 2-core machine, 43.5 ms a frame
(1 thread) against 5.3 ms with MALLOC_MMAP_THRESHOLD_=268435456 MALLOC_TRIM_THRESHOLD_=536870912
in the environment (3.4 ms facing away, no hits, either way). A mission keeps its memory and
sees no such gain (plant, 150 views: 134.7-146.6 against 136.6-137.7 ms a view).

Run: .venv/bin/python bench/bench_sensors.py [--mesh PATH] [--repeat N]
     .venv/bin/python bench/bench_sensors.py --against /tmp/before [--mesh PATH] [--rounds N]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import nbvkit
from _timing import alternate, bench_mesh, median_time, mesh_parser

# Runs in either checkout: the least ms per frame over `repeat` passes of the ring's frames on
# 1 thread and on all, and a digest of every scan.
RING_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
import nbvkit
sys.path.insert(0, sys.argv[1])
from _timing import bench_mesh
mesh, lo, hi, c = bench_mesh(sys.argv[2] or None)
cam = nbvkit.DepthCamera(nbvkit.RaycastScene(mesh))
r = 0.5 * np.linalg.norm(hi[:2] - lo[:2]) + 5.0
poses = [(c[0] + r * np.cos(a), c[1] + r * np.sin(a), z, a + np.pi, 0.0)
         for z in np.linspace(lo[2], hi[2], 3) for a in np.arange(16) * np.pi / 8]
h = hashlib.sha1()
for p in poses:
    s = cam.scan_pose(p)
    for a in (s.hits, s.free_ends, s.depth, s.hit_rays, s.free_rays):
        h.update(np.ascontiguousarray(a).tobytes())
out = {"digest": h.hexdigest()}
for label, threads in (("one", 1), ("all", 0)):
    nbvkit.set_num_threads(threads)
    best = np.inf
    for _ in range(int(sys.argv[3])):
        t = time.perf_counter()
        for p in poses:
            cam.scan_pose(p)
        best = min(best, (time.perf_counter() - t) * 1e3 / len(poses))
    out[label] = best
print(json.dumps(out))
"""


def against(args):
    """This checkout's frames against --against's, alternating (see the module's doc)."""
    snippet_args = [Path(__file__).resolve().parent, args.mesh or "", args.repeat]
    best, same = alternate(RING_SNIPPET, snippet_args, args.against, args.rounds, ("one", "all"))
    print("camera frames, 640x480, 48 poses on rings round the structure (least ms a frame)")
    print(f"{'code':>40} {'1 thread':>9} {'all threads':>12}")
    for label, one, every in best:
        print(f"{label:>40} {one:>9.2f} {every:>12.2f}")
    if len(best) == 2:
        (_, one_a, all_a), (_, one_b, all_b) = best
        print(f"ratio (other / this): 1 thread {one_b / one_a:.2f}x, all {all_b / all_a:.2f}x")
    print("scans bit for bit the same in both:", same)


def main():
    ap = mesh_parser(__doc__, repeat=20)
    ap.add_argument("--against", default=None, help="another checkout or saved package")
    ap.add_argument("--rounds", type=int, default=2, help="with --against: runs of each")
    args = ap.parse_args()
    if args.against:
        return against(args)
    mesh, lo, hi, c = bench_mesh(args.mesh)
    t0 = time.perf_counter()
    scene = nbvkit.RaycastScene(mesh)
    build_ms = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    scene_hq = nbvkit.RaycastScene(mesh, high_quality_bvh=True)
    build_hq_ms = (time.perf_counter() - t0) * 1e3
    # a view of the structure from 6 m in front of its +x end, facing it (nose-on for an aircraft)
    pose = [hi[0] + 6.0, c[1], c[2], np.pi]
    cam = nbvkit.DepthCamera(scene)
    cam_hq = nbvkit.DepthCamera(scene_hq)
    T = nbvkit.pose_to_transform(pose) @ cam.mount
    n_rays = cam.width * cam.height
    hits = len(cam.scan(T).hits)
    print(
        f"mesh: {mesh.num_triangles} triangles; BVH build "
        f"{build_ms:.1f} ms (high quality {build_hq_ms:.1f} ms)"
    )
    print(f"camera frame {cam.width}x{cam.height} from 6 m: {hits} hits ({hits / n_rays:.0%})")
    dirs_world = cam.directions @ T[:3, :3].T
    origin = T[:3, 3][None]
    threads = nbvkit.get_num_threads()
    rows = []
    for nt in (1, threads):
        nbvkit.set_num_threads(nt)
        t_pk = median_time(lambda: cam.scan(T), args.repeat)
        t_hq = median_time(lambda: cam_hq.scan(T), args.repeat)
        t_1 = median_time(
            lambda: scene.intersect(origin, dirs_world, 0.0, 8.0 / 0.7), max(3, args.repeat // 4)
        )
        rows.append((nt, t_pk, t_hq, t_1))
    nbvkit.set_num_threads(0)
    print(
        f"{'threads':>7} {'packets ms':>11} {'Mrays/s':>8} {'HQ BVH ms':>10} "
        f"{'rtcIntersect1 ms':>17} {'speed-up':>9}"
    )
    for nt, t_pk, t_hq, t_1 in rows:
        print(
            f"{nt:>7} {t_pk * 1e3:>11.2f} {n_rays / t_pk / 1e6:>8.1f} {t_hq * 1e3:>10.2f} "
            f"{t_1 * 1e3:>17.2f} {t_1 / t_pk:>8.1f}x"
        )
    las = nbvkit.LaserScanner(scene)
    t_las = median_time(lambda: las.scan_pose(pose), 200)
    print(f"laser scan ({las.num_beams} beams, 1 thread): {t_las * 1e6:.0f} us")


if __name__ == "__main__":
    main()
