"""Camera and laser ray-casting speed on the default airliner (or --mesh).

Prints, for a 640x480 frame: ms per frame and rays/s with Embree 16-wide packets over 4x4 tiles
(the sensor path) on 1 thread and on all threads, and the same rays cast one at a time with
rtcIntersect1 (RaycastScene.intersect) in the same run, as the baseline ratio; plus the laser scan.
Run: .venv/bin/python bench/bench_sensors.py [--mesh PATH] [--repeat N]
"""
from __future__ import annotations

import time

import numpy as np

import nbvkit
from _timing import bench_mesh, median_time, mesh_parser


def main():
    args = mesh_parser(__doc__, repeat=20).parse_args()
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
