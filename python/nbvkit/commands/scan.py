"""nbvkit scan: one simulated scan of a mesh from a vehicle pose, written as a point cloud."""
from __future__ import annotations

import argparse

from pathlib import Path

import numpy as np

from .._core import MAX_COORDINATE, DepthCamera, LaserScanner, RaycastScene
from ..cloud import write_points
from ..mesh import default_mesh_path
from ..output_paths import check_not_input
from ..paths import check_output_file
from .common import add_mesh_options, mesh_from_args, path_arg


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "scan",
        help="scan a mesh from one vehicle pose and write the hit points",
        description="Ray-cast one scan of the structure from a vehicle pose and write the "
        "world-frame "
        "hit points (PLY, PCD or .npy by the file's extension). The sensor is mounted at "
        "the vehicle origin: the camera untilted, the laser pitched 10 deg down (Table 1). "
        "Noise is off unless --noise is given.",
    )
    add_mesh_options(p)
    p.add_argument(
        "--pose",
        nargs="+",
        type=float,
        metavar="X Y Z YAW [PITCH]",
        required=True,
        help="vehicle pose: position in metres (world frame, z up), yaw in radians about +z and "
        "optionally the camera gimbal's pitch in radians (> 0 looks down, |pitch| <= pi/2; "
        "default 0: level; the laser ignores it)",
    )
    p.add_argument(
        "--sensor",
        choices=("camera", "laser"),
        default="camera",
        help="camera: 640x480 RGB-D, 60x45 deg, 0.5-8 m depth; "
        "laser: 721 beams over 180 deg, 0.1-30 m (default camera)",
    )
    p.add_argument(
        "--noise",
        type=float,
        default=0.0,
        metavar="K",
        help="camera depth noise sigma = K z^2 metres (the authors used 0.0025); "
        "laser range noise sigma = K metres (default 0: exact)",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument(
        "--out",
        required=True,
        metavar="FILE",
        type=path_arg,
        help="output cloud: .ply, .pcd or .npy",
    )
    return p


def run(args) -> int:
    pose = np.asarray(args.pose, dtype=np.float64)
    if len(pose) not in (4, 5):
        raise ValueError(
            f"--pose must be 4 numbers (X Y Z YAW) or 5 (X Y Z YAW PITCH), got {len(pose)}"
        )
    if not np.all(np.isfinite(pose)) or np.abs(pose[:3]).max() > MAX_COORDINATE:
        raise ValueError(
            f"--pose must be finite numbers with |x|, |y|, |z| <= {MAX_COORDINATE:g} m, "
            f"got {args.pose}"
        )
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if Path(args.out).suffix.lower() not in (".ply", ".pcd", ".npy"):
        raise ValueError(f"--out {args.out}: unknown extension (use .ply, .pcd or .npy)")
    check_output_file(args.out, "--out")
    check_not_input(args.out, [("the mesh", args.mesh or default_mesh_path())], "--out")
    scene = RaycastScene(mesh_from_args(args))
    if args.sensor == "camera":
        sensor = DepthCamera(scene, noise_k=args.noise, seed=args.seed)
    else:
        sensor = LaserScanner(scene, noise_sigma=args.noise, seed=args.seed)
    scan = sensor.scan_pose(pose)
    write_points(args.out, scan.hits)
    print(
        f"{args.sensor} scan from {tuple(args.pose)}: {len(scan.hits)} hits, "
        f"{len(scan.free_ends)} free rays -> {args.out}"
    )
    return 0
