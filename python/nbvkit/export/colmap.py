"""COLMAP's text model of an exported flight's camera poses (cameras.txt, images.txt, an empty
points3D.txt), from COLMAP's documented format (docs/EXPORT.md): what a photogrammetry tool reads
to start from the planned poses."""
from __future__ import annotations

import math

import numpy as np

#: COLMAP's camera axes in nbvkit's sensor frame (x forward, y left, z up): x right = -y,
#: y down = -z, z forward = +x.
R_COLMAP_SENSOR = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def colmap_pose(T_world_sensor: np.ndarray):
    """(qw, qx, qy, qz), (tx, ty, tz): COLMAP's world-to-camera pose of a sensor pose (4, 4)."""
    from scipy.spatial.transform import Rotation

    R_ws, t = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
    R_cw = R_COLMAP_SENSOR @ R_ws.T
    t_cw = -R_cw @ t
    x, y, z, w = Rotation.from_matrix(R_cw).as_quat()
    q = np.array([w, x, y, z])
    if q[0] < 0:
        q = -q
    return q, t_cw


def write_colmap(folder, camera: dict, images: list) -> None:
    """COLMAP text model: cameras.txt (one PINHOLE camera), images.txt (a pose per image, no 2D
    points) and an empty points3D.txt. camera: width, height, fx, fy, cx, cy; images: (name,
    T_world_sensor (4, 4)) in order."""
    c = camera
    with open(folder / "cameras.txt", "w") as f:
        f.write("# Camera list with one line of data per camera:\n")
        f.write("#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n")
        f.write("# Number of cameras: 1\n")
        f.write(
            f"1 PINHOLE {c['width']} {c['height']} {c['fx']!r} {c['fy']!r} "
            f"{c['cx']!r} {c['cy']!r}\n"
        )
    with open(folder / "images.txt", "w") as f:
        f.write("# Image list with two lines of data per image:\n")
        f.write("#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n")
        f.write("#   POINTS2D[] as (X, Y, POINT3D_ID)\n")
        f.write(f"# Number of images: {len(images)}, mean observations per image: 0\n")
        for i, (name, T) in enumerate(images, start=1):
            q, t = colmap_pose(np.asarray(T, float))
            f.write(" ".join([str(i), *(repr(float(v)) for v in (*q, *t)), "1", name]) + "\n\n")
    with open(folder / "points3D.txt", "w") as f:
        f.write("# 3D point list with one line of data per point:\n")
        f.write("#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n")
        f.write("# Number of points: 0, mean track length: 0\n")


def camera_intrinsics(config) -> dict:
    """PINHOLE intrinsics of the run's DepthCamera (cpp/src/sensors.cpp: fx = (W/2) /
    tan(hfov/2), fy = (H/2) / tan(vfov/2); pixel (u, v) looks through its centre, (u + 0.5,
    v + 0.5) in COLMAP's image coordinates, so cx = W/2, cy = H/2)."""
    c = config.camera
    w, h = int(c.width), int(c.height)
    return {
        "width": w,
        "height": h,
        "fx": (w / 2.0) / math.tan(math.radians(c.hfov_deg) / 2.0),
        "fy": (h / 2.0) / math.tan(math.radians(c.vfov_deg) / 2.0),
        "cx": w / 2.0,
        "cy": h / 2.0,
    }
