"""COLMAP's text model of an exported flight's camera poses (cameras.txt, images.txt, an empty
points3D.txt), from COLMAP's documented format (docs/EXPORT.md): what a photogrammetry tool reads
to start from the planned poses."""
from __future__ import annotations

import math
import re
import string

import numpy as np

from ..flight_time import FRAME, VIEW

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


def capture_numbers(capture, flown=None) -> dict:
    """{row: (kind, number of its kind, photo number)} of each capture row of a flight that is
    flown (`capture`: each row's kind, VIEW, FRAME or ''; `flown`: the rows the mission files fly,
    None for all), in flight order; numbers from 1. The number of its kind is the run's (view 7
    stays view 7); the photo number counts the photos taken, as the camera numbers them: the
    mission files' IMAGE_START_CAPTURE number and the CSV's photo. A capture no sortie flies (the
    export's unreachable) takes no photo, and no number after it is skipped."""
    out, count = {}, {VIEW: 0, FRAME: 0}
    for i, c in enumerate(capture):
        if c:
            count[c] += 1
            if flown is None or i in flown:
                out[i] = (c, count[c], len(out) + 1)
    return out


def camera_poses(fl, photo_names=None, flown=None) -> list:
    """(name, T_world_sensor (4, 4)) of every capture of the flight that is flown (`flown`: the
    rows flown, None for all; capture_numbers), in order. Named view_0001.png ..., frame_0001.png
    ... (numbered per kind, as in the run), or, given photo_names (pattern, first), by the
    pattern formatted with each capture's photo number (capture_numbers) plus first - 1
    (photo_name)."""
    from .. import _core

    cfg = fl.config
    cam = _core.mount_transform(cfg.camera.mount_xyz, *cfg.camera.mount_rpy_deg)
    out = []
    for i, (c, n, seq) in capture_numbers(fl.capture, flown).items():
        T_body = _core.pose_to_transform([*fl.xyz[i], fl.yaw[i]])
        T = T_body @ _core.mount_transform([0, 0, 0], 0.0, math.degrees(fl.pitch[i]), 0.0) @ cam
        name = f"{c}_{n:04d}.png" if photo_names is None else photo_name(*photo_names, seq)
        out.append((name, T))
    return out


def check_photo_names(pattern, first) -> tuple | None:
    """(pattern, first) of camera_poses, checked (photo_name; first a whole number >= 0), or
    None for pattern None."""
    if pattern is None:
        return None
    if not isinstance(pattern, str):
        raise ValueError(
            f"photo names must be a string such as 'DJI_{{:04d}}.JPG', got {pattern!r}"
        )
    if isinstance(first, bool) or not isinstance(first, (int, np.integer)) or first < 0:
        raise ValueError(f"the first photo's number must be a whole number >= 0, got {first!r}")
    photo_name(pattern, int(first), 1)
    return pattern, int(first)


def photo_name(pattern: str, first: int, seq: int) -> str:
    """The name of the seq-th photo (1-based) by `pattern`, a file name with one replacement
    field for a whole number ("DJI_{:04d}.JPG"), numbered from `first`. ValueError naming the
    pattern where it has not exactly one such field or makes a name COLMAP cannot read (its
    images.txt separates fields by spaces; a name is a path relative to the image folder)."""
    try:
        fields = [(f, s, c) for _, f, s, c in string.Formatter().parse(pattern) if f is not None]
        if [f for f, _, _ in fields] not in ([""], ["0"]):
            raise ValueError("one replacement field, {} or {:04d}")
        _, spec, conv = fields[0]
        # a whole number's digits, zero-padded to at most 32 (distinct numbers, distinct names:
        # '{:.1e}' named 11 photos IMG_1.6e+02.JPG; '{:>999999999d}' built a gigabyte first)
        if (
            conv is not None
            or not re.fullmatch(r"(0?[1-9]\d?)?d?", spec or "")
            or (spec and int(re.sub(r"\D", "", spec) or 0) > 32)
        ):
            raise ValueError(
                "its field must write the number's digits: {}, {:d} or {:04d}, at most 32 wide"
            )
        name = pattern.format(first + seq - 1)
    except (ValueError, IndexError, KeyError) as e:
        raise ValueError(
            f"photo names {pattern!r}: a file name with one field for the photo's number, such "
            f"as 'DJI_{{:04d}}.JPG' ({e})"
        ) from None
    if (
        not 0 < len(name) <= 255
        or any(ch.isspace() for ch in name)
        or name.startswith("/")
        or ".." in name.split("/")
    ):
        raise ValueError(
            f"photo names {pattern!r} give {name[:80]!r}: COLMAP reads a file name (at most 255 "
            "characters, no spaces) relative to its image folder"
        )
    return name
