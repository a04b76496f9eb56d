"""Benchmark of the camera cloud's registration (SurfaceCloud.add, the 0.02 m voxel centroids a
mission keeps): the camera frames of a mission are recorded, then added again, frame after frame,
to a fresh cloud, on 1 thread and on all, best of --repeat. Prints ms per frame and a digest of
the resulting centroids and counts.

    .venv/bin/python bench/bench_cloud.py [--iterations 250] [--mesh M] [--against DIR]
    .venv/bin/python bench/bench_cloud.py --scenario surface --iterations 40 --mesh PLANT.obj

``--scenario`` flies another scenario (default 5); its in-flight frames are recorded too.

``--against DIR`` replays the same frames, in the same run, with the nbvkit package of another
checkout (DIR/python or DIR) and prints the ratio and whether the clouds are the same bit for bit.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import checkouts, mesh_parser, run_snippet

import nbvkit
from nbvkit.config import Config
from nbvkit.mission import Mission

# Runs in this checkout or, through --against, in another one.
REPLAY_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
import nbvkit
from nbvkit import _core
z = np.load(sys.argv[1])
frames = [z[f"arr_{i}"] for i in range(len(z.files))]
out = {}
for threads in (1, 0):
    nbvkit.set_num_threads(threads)
    best = float("inf")
    for _ in range(int(sys.argv[2])):
        cloud = _core.SurfaceCloud(voxel_size=0.02, min_z=0.3)
        t = 0.0
        for f in frames:
            t0 = time.perf_counter()
            cloud.add(f)
            t += time.perf_counter() - t0
        best = min(best, t)
    out[str(nbvkit.get_num_threads())] = best / len(frames)
digest = hashlib.sha1(cloud.points.tobytes() + cloud.counts.tobytes()).hexdigest()[:16]
print(json.dumps({"ms": out, "voxels": len(cloud), "digest": digest}))
"""


def record_frames(args, path: Path) -> int:
    """Flies --scenario for --iterations views and saves every camera frame's hits (views and
    in-flight frames); returns the number of frames."""
    over = [f"scenario={args.scenario}", "progress=false", "report.enabled=false"]
    over += [f"max_iterations={args.iterations}"]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    m = Mission(Config().with_overrides(over))
    frames = []

    class Recording:  # a camera of the world, keeping a copy of each frame's hits
        def __init__(self, camera):
            self.camera = camera

        def scan_pose(self, pose):
            scan = self.camera.scan_pose(pose)
            frames.append(np.array(scan.hits, copy=True))
            return scan

        def __getattr__(self, name):
            return getattr(self.camera, name)

    m.world.camera = Recording(m.world.camera)
    m.world.frame_camera = Recording(m.world.frame_camera)
    m.run()
    np.savez(path, *frames)
    return len(frames)


def main():
    ap = mesh_parser(__doc__, repeat=3)
    ap.add_argument("--iterations", type=int, default=250, help="views recorded")
    ap.add_argument("--scenario", default="5", help="the scenario flown (default 5)")
    ap.add_argument("--against", help="another checkout to replay the frames in, in the same run")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.npz"
        n = record_frames(args, path)
        print(
            f"{n} camera frames of scenario {args.scenario} (start 0), replayed into a fresh "
            "camera cloud:"
        )
        rows = [
            (label, run_snippet(REPLAY_SNIPPET, (path, args.repeat), py))
            for label, py in checkouts(args.against)
        ]
    for label, r in rows:
        ms = ", ".join(f"{v * 1e3:.2f} ms on {k} thread(s)" for k, v in r["ms"].items())
        print(f"  {label}: {ms} per frame; {r['voxels']:,} voxels, digest {r['digest']}")
    if len(rows) == 2:
        (_, a), (_, b) = rows
        ratios = ", ".join(f"{b['ms'][k] / a['ms'][k]:.2f}x on {k}" for k in a["ms"])
        print(f"  faster than {rows[1][0]}: {ratios}; same cloud: {a['digest'] == b['digest']}")
    print(f"  (threads available: {nbvkit.get_num_threads()})")


if __name__ == "__main__":
    main()
