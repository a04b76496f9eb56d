"""Point clouds: the voxel-filtered reconstruction cloud and PLY / PCD / NPY files.

``PointCloud`` accumulates observed surface points (world frame, metres) through an incremental
voxel-grid filter with ground removal (the C++ ``nbv::SurfaceCloud``). ``read_points`` and
``write_points`` move ``(N, 3)`` float64 arrays in and out of ``.ply``, ``.pcd`` and ``.npy``
files; they are plain numpy (no PCL/VTK at import), read what open3d, PCL, CloudCompare and
MeshLab write, and write files those tools read.
"""
from __future__ import annotations

import io
import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from . import _core
from ._open3d import open3d
from .limits import MAX_DATA_FILE_BYTES, check_input_file
from .output_paths import naming_the_file
from .settings import positive

__all__ = [
    "PointCloud",
    "read_points",
    "write_points",
    "DEFAULT_VOXEL_SIZE",
    "NESTED_VOXEL_SIZE",
    "DEFAULT_MIN_Z",
    "LASER_VOXEL_SIZE",
]

_DEFAULTS = _core.SurfaceCloudOptions()
#: Voxel-grid cell of the RGB-D camera's cloud, metres (the authors' 0.02 m).
DEFAULT_VOXEL_SIZE: float = _DEFAULTS.voxel_size
#: The missions' camera voxel, metres: half the finest coverage cell (0.05 m), so that every
#: voxel lies in one cell of each of the paper's resolutions (0.05, 0.1, 0.5 m).
NESTED_VOXEL_SIZE: float = min(_core.EvaluationOptions().resolutions) / 2
#: Voxel-grid cell the authors used for the laser's profile cloud, metres.
LASER_VOXEL_SIZE: float = 0.1
#: Ground removal: points below this height (metres) are not registered.
DEFAULT_MIN_Z: float = _DEFAULTS.min_z

_SUFFIXES = (".ply", ".pcd", ".npy")
#: m: the largest coordinate float32 holds to within 1 mm (its spacing there is 2 mm)
FLOAT32_EXACT_M = 16384.0


_CLOUD = _core.SurfaceCloudOptions()


@dataclass(frozen=True)
class CloudConfig:
    """The reconstructed point clouds."""

    # 0.025 m (NESTED_VOXEL_SIZE) nests in the 0.05 / 0.1 / 0.5 m cells coverage is counted in,
    # so a cell the camera hit keeps a point; the authors' 0.02 m, which the paper's scenarios
    # keep, straddles 0.05 m cells: a centroid can fall in the neighbouring cell (RESULTS.md)
    camera_voxel: float = positive(NESTED_VOXEL_SIZE, 1e3)  # m, nests in 0.05 m coverage cells
    laser_voxel: float = positive(0.1, 1e3)  # m, authors' profile voxel filter
    # the simulated world has no ground plane, so a ground removal drops only the structure's
    # own surface near the ground (an open tank's floor: 82 % of its observable area covered
    # with 0.3 m, 99.5 % without; RESULTS.md); the paper's scenarios keep the authors' 0.3 m
    min_z: Optional[float] = None  # m above the ground: lower dropped; null: none
    # the camera cloud's voxel sums in single precision, as offsets from the voxel's corner: 16
    # bytes a voxel instead of 28 (0.45 GB less on a 100 m plant's 38 M voxels), each centroid
    # within 1e-5 of camera_voxel of its points' mean; null: on a workspace longer than 6
    # camera ranges (workspace.is_large), where the cloud is largest; false: the exact sums
    single_precision: Optional[bool] = None  # single-precision voxel sums; null: by size


class PointCloud(_core.SurfaceCloud):
    """Observed surface points, world frame, metres, with an incremental voxel-grid filter.

    Every point added falls in a voxel ``floor(p / voxel_size)`` (grid anchored at the origin);
    the cloud keeps one point per voxel, the centroid of all points that fell in it — the same as
    PCL's ``VoxelGrid`` over the union of everything added. Points with ``z < min_z`` (ground
    removal) or, with ``crop=True``, outside the box ``[crop_min, crop_max]`` are not registered.
    ``points`` returns them as ``(K, 3)`` float64 in the order their voxels were first seen.

    Args:
        points: optional ``(N, 3)`` array (or a ``Scan``, or another cloud) to add at once.
        options: a ``SurfaceCloudOptions`` (or a dict of its fields, or None for the defaults),
            with keyword overrides of its fields (a keyword set to None keeps the value):

            - ``voxel_size``: voxel-grid cell in metres. Default 0.02 m, the authors' setting for
              the RGB-D camera; use ``LASER_VOXEL_SIZE`` (0.1 m) for a laser profile cloud;
            - ``min_z``: ground-removal height in metres (default 0.3 m as the authors);
              ``float("-inf")`` keeps everything;
            - ``crop``, ``crop_min``, ``crop_max``: register only points inside the box
              ``[crop_min, crop_max]`` (world frame, metres) when ``crop`` is True.

    Raises ValueError for a non-positive voxel size, an unknown option or NaN/inf points.
    """

    def __init__(self, points=None, options=None, **kw):
        super().__init__(options, **kw)
        if points is not None:
            self.add(points)

    def add(self, points) -> int:
        """Register ``(N, 3)`` world-frame points (or a ``Scan``'s hits, or another cloud's points).

        Returns the number of voxels they created. Raises ValueError, registering nothing, if any
        point is NaN or infinite.
        """
        return super().add(_as_points(points))

    @classmethod
    def from_numpy(cls, points, options=None, **kw) -> "PointCloud":
        """A cloud holding ``points`` ``(N, 3)`` after the voxel filter and ground removal."""
        return cls(points, options, **kw)

    @classmethod
    def from_open3d(cls, o3d_cloud, options=None, **kw) -> "PointCloud":
        """A cloud from an ``open3d.geometry.PointCloud`` (its points only)."""
        return cls(np.asarray(o3d_cloud.points, dtype=np.float64), options, **kw)

    @classmethod
    def load(cls, path, options=None, **kw) -> "PointCloud":
        """Read a ``.ply`` / ``.pcd`` / ``.npy`` file (see ``read_points``) into a new cloud.

        The file's points go through the same filter as any other (so loading a cloud this
        class saved, with the same settings, gives back the same points). Pass
        ``min_z=float("-inf")`` to keep points below 0.3 m.
        """
        return cls(read_points(path), options, **kw)

    def save(self, path, ascii: bool = False, dtype=None) -> None:
        """Write the points to ``.ply``, ``.pcd`` or ``.npy`` (see ``write_points``)."""
        write_points(path, self.points, ascii=ascii, dtype=dtype)

    def to_numpy(self) -> np.ndarray:
        """``(K, 3)`` float64 voxel centroids (a copy), same as ``points``."""
        return self.points

    def __array__(self, dtype=None):
        pts = self.points
        return pts if dtype is None else pts.astype(dtype)

    def to_open3d(self):
        """An ``open3d.geometry.PointCloud`` of the points (open3d is imported only here)."""
        o3d = open3d()

        return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))

    def __repr__(self) -> str:
        return (
            f"<nbvkit.PointCloud {len(self)} points, voxel_size={self.voxel_size:g} m, "
            f"min_z={self.min_z:g}>"
        )


def _as_points(points):
    if isinstance(points, _core.SurfaceCloud):
        return points.points
    if isinstance(points, _core.Scan):
        return points.hits
    return points


# ------------------------------------------------------------------------------------ files


def write_points(path, points, ascii: bool = False, dtype=None) -> None:
    """Write ``(N, 3)`` points to a ``.ply``, ``.pcd`` or ``.npy`` file (by the extension).

    - ``.ply``: binary little-endian (``ascii=True`` for text), ``property double x/y/z`` by
      default — no precision lost; open3d, PCL, MeshLab and CloudCompare read it.
    - ``.pcd``: PCL PCD v0.7, ``DATA binary`` (or ``ascii``), fields ``x y z`` as ``F 4``
      (float32) by default, so ``pcl::io::loadPCDFile<pcl::PointXYZ>`` reads it directly
      (float32 keeps ~4 µm at 35 m); ``dtype=np.float64`` writes ``F 8``, as does a cloud past
      FLOAT32_EXACT_M (with a RuntimeWarning; refused for ``dtype=np.float32``).
    - ``.npy``: the ``(N, 3)`` array as float64 (or ``dtype``).

    ``points`` may also be a list of ``SurfaceCloud`` objects: their points one cloud after the
    other (``_core.stack_points``), written a million at a time rather than copied whole.

    Raises ValueError for a bad shape, NaN/inf points or an unknown extension.
    """
    path = Path(os.fsdecode(path)).expanduser()
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(
            f"cannot write point cloud '{path}': unknown extension "
            f"'{path.suffix}' (use .ply, .pcd or .npy)"
        )
    chosen = dtype is not None
    dtype = np.dtype(dtype if chosen else np.float32 if suffix == ".pcd" else np.float64)
    if dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype must be float32 or float64, got {dtype}")
    # a list of clouds is finite by construction: SurfaceCloud refuses NaN/inf
    if not _is_cloud_list(points):
        points = _check_points(points, "points")
    big = _largest(points) if dtype == np.float32 else 0.0
    if big >= FLOAT32_EXACT_M:
        off = float(np.spacing(np.float32(big))) / 2 if big < 3e38 else math.inf  # its rounding
        if not chosen:  # a georeferenced cloud: F 8, said
            warnings.warn(
                f"point cloud '{path}': a coordinate reaches {big:.6g} m, which float32 (PCD's "
                f"F 4, PCL's PointXYZ) rounds by up to {off * 1000:.3g} mm: written as F 8 "
                "(double); shift the cloud near the origin for F 4",
                RuntimeWarning,
                2,
            )
            dtype = np.dtype(np.float64)
        else:
            raise ValueError(
                f"cannot write point cloud '{path}' in float32: a coordinate reaches {big:.3g} "
                f"m, which float32 rounds by more than 1 mm (from {FLOAT32_EXACT_M:,.0f} m); "
                "write it with dtype=np.float64 or shift it near the origin"
            )
    n, parts = _parts(points, _WRITE_PART)
    with naming_the_file(path), open(path, "wb") as f:
        f.write(_points_header(suffix, n, dtype, ascii))
        for part in parts:
            data = np.ascontiguousarray(part, dtype=dtype.newbyteorder("<"))
            if ascii and suffix != ".npy":
                np.savetxt(f, data, fmt="%.9g" if dtype == np.float32 else "%.17g")
            elif data.size:
                f.write(memoryview(data).cast("B"))  # the array's bytes, not a copy of them


#: Points a list of clouds is written in, a part at a time (24 MB of float64).
_WRITE_PART = 1 << 20


def _parts(points, size: int):
    """(n, parts): the number of points of `points` and an iterator over them in order, `size`
    at a time. points: a list of SurfaceClouds, read in place (rows of their stack,
    ``_core.stack_points``: never the whole stack at once), or an (N, 3) array (its slices)."""
    if _is_cloud_list(points):
        clouds = list(points)
        n = sum(len(c) for c in clouds)
        return n, (_core.stack_points(clouds, b, b + size) for b in range(0, n, size))
    return len(points), (points[b : b + size] for b in range(0, len(points), size))


def _largest(points) -> float:
    """The largest |coordinate| of `points` (an array, or SurfaceClouds read in parts), or 0."""
    _, parts = _parts(points, _WRITE_PART)
    return max((float(np.abs(q).max()) for q in parts if len(q)), default=0.0)


def _is_cloud_list(points) -> bool:
    """Whether `points` is a list (or tuple) of SurfaceClouds, read in place (by write_points,
    the evaluator, the mesh and the coverage classes) rather than as one array."""
    return isinstance(points, (list, tuple)) and all(
        isinstance(c, _core.SurfaceCloud) for c in points
    )


def _points_header(suffix: str, n: int, dtype: np.dtype, ascii: bool) -> bytes:
    """The header of a points file of n points: NPY 1.0, PLY or PCD v0.7."""
    if suffix == ".npy":
        buf = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            buf, {"descr": dtype.newbyteorder("<").str, "fortran_order": False, "shape": (n, 3)}
        )
        return buf.getvalue()
    if suffix == ".ply":
        t = "float" if dtype == np.float32 else "double"
        header = (
            "ply\nformat {} 1.0\ncomment written by nbvkit\nelement vertex {}\n"
            "property {t} x\nproperty {t} y\nproperty {t} z\nend_header\n"
        ).format("ascii" if ascii else "binary_little_endian", n, t=t)
    else:
        header = (
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
            "SIZE {s} {s} {s}\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {d}\n"
        ).format(s=dtype.itemsize, n=n, d="ascii" if ascii else "binary")
    return header.encode("ascii")


def read_points(path, drop_nonfinite: bool = True) -> np.ndarray:
    """Read the x, y, z of every point of a ``.ply``, ``.pcd`` or ``.npy`` file.

    Returns ``(N, 3)`` float64; ``(0, 3)`` for a valid file holding no points.

    - ``.ply``: ``ascii``, ``binary_little_endian`` or ``binary_big_endian``; the ``vertex``
      element's ``x y z`` properties of any numeric type; other properties and elements (normals,
      colours, faces) are ignored.
    - ``.pcd``: PCL PCD v0.5–0.7, ``DATA ascii``, ``binary`` or ``binary_compressed``; fields
      ``x y z`` of type ``F`` (size 4 or 8, or any ``I``/``U``); other fields are ignored.
    - ``.npy``: an ``(N, 3)`` numeric array.

    Points with a NaN or infinite coordinate (PCL marks invalid pixels of organised clouds so)
    are dropped with a warning unless ``drop_nonfinite=False``.

    Raises FileNotFoundError (with the path) for a missing file, and ValueError naming the file
    and the reason for anything but a regular file of at most 2 GiB (a directory, a FIFO, a
    device), an unknown extension or a file that cannot be parsed.
    """
    path = check_input_file(path, "point cloud", MAX_DATA_FILE_BYTES)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(
            f"cannot read point cloud '{path}': unknown extension '{path.suffix}' "
            f"(use .ply, .pcd or .npy)"
        )
    try:
        if suffix == ".npy":
            pts = _read_npy(path)
        else:
            data = path.read_bytes()
            pts = _read_ply(data) if suffix == ".ply" else _read_pcd(data)
    except _FormatError as e:
        raise ValueError(f"cannot read point cloud '{path}': {e}") from None
    pts = np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 3)
    if drop_nonfinite:
        ok = np.isfinite(pts).all(axis=1)
        if not ok.all():
            warnings.warn(
                f"{path}: dropped {int((~ok).sum())} points with NaN or infinite " f"coordinates",
                RuntimeWarning,
                stacklevel=2,
            )
            pts = pts[ok]
    return pts


class _FormatError(Exception):
    pass


def _check_points(points, what):
    a = np.asarray(_as_points(points), dtype=np.float64)
    if a.ndim == 1 and a.size == 0:
        a = a.reshape(0, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{what} must have shape (N, 3), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{what} contains NaN or infinite values")
    return a


def _read_npy(path):
    try:
        a = np.load(path, allow_pickle=False)
    except ValueError as e:  # pickled object arrays, bad headers
        raise _FormatError(f"not a plain numpy array file ({e})") from None
    except (OSError, EOFError) as e:
        raise _FormatError(f"not a numpy .npy file ({e})") from None
    if not isinstance(a, np.ndarray) or a.dtype.kind not in "fiu":
        raise _FormatError(f"expected a numeric (N, 3) array, got dtype {getattr(a, 'dtype', '?')}")
    if a.ndim == 1 and a.size == 0:
        return a.reshape(0, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise _FormatError(f"expected an (N, 3) array, got shape {a.shape}")
    return a


# ---- PLY (split_header: also the PCD reader's)


def _split_header(data: bytes, end_marker: bytes, what: str):
    """(header lines, offset of the body) for a text header ending with the line end_marker."""
    m = re.search(rb"^" + re.escape(end_marker) + rb"[^\n]*\n", data, re.M)
    if m is None:
        # A file whose body is empty may end right after the marker without a newline.
        m = re.search(rb"^" + re.escape(end_marker) + rb"[^\n]*\Z", data, re.M)
        if m is None:
            raise _FormatError(f"no '{end_marker.decode()}' line: not a {what} file or truncated")
    try:
        header = data[: m.end()].decode("ascii")
    except UnicodeDecodeError:
        raise _FormatError(f"the {what} header is not ASCII text") from None
    return header.splitlines(), m.end()


def _read_ply(data: bytes) -> np.ndarray:
    """The vertices of a PLY file, read by the C++ reader meshes use too (nbv/ply.hpp)."""
    try:
        vertices, _ = _core._parse_ply(data, faces=False)
    except ValueError as e:
        raise _FormatError(str(e)) from None
    return vertices


# ---- PCD

_PCD_KINDS = {"F": "f", "I": "i", "U": "u"}


def _read_pcd(data: bytes) -> np.ndarray:
    lines, body = _split_header(data, b"DATA", "PCD")
    h = _pcd_header(lines)
    fields, sizes, types, counts, n = _pcd_layout(h)
    dts = []
    for f, s, t in zip(fields, sizes, types):
        if t not in _PCD_KINDS or s not in (1, 2, 4, 8) or (t == "F" and s not in (4, 8)):
            raise _FormatError(f"unsupported PCD field '{f}': TYPE {t} SIZE {s}")
        dts.append("<" + _PCD_KINDS[t] + str(s))
    mode = h["DATA"][0].lower() if h["DATA"] else ""
    cols = [fields.index(a) for a in "xyz"]
    if n == 0:
        return np.zeros((0, 3))
    if mode == "ascii":
        return _pcd_ascii(data[body:], n, counts, cols)
    if mode == "binary":
        return _pcd_binary(data, body, n, dts, counts, cols)
    if mode == "binary_compressed":
        return _pcd_compressed(data, body, n, dts, sizes, counts, cols)
    raise _FormatError(f"unknown PCD DATA type '{' '.join(h['DATA'])}'")


def _pcd_header(lines) -> dict:
    """A PCD header's lines as {KEY: [values]}; _FormatError without FIELDS, SIZE, TYPE, DATA."""
    h = {}
    for raw in lines:
        s = raw.split("#", 1)[0].strip()
        if not s:
            continue
        key, *vals = s.split()
        h[key.upper()] = vals
    for key in ("FIELDS", "SIZE", "TYPE", "DATA"):
        if key not in h:
            raise _FormatError(f"the PCD header has no {key} line")
    return h


def _pcd_layout(h: dict):
    """fields, sizes, types, counts (per field) and the number of points of a PCD header."""
    fields, sizes, types = h["FIELDS"], h["SIZE"], h["TYPE"]
    counts = h.get("COUNT", ["1"] * len(fields))
    if not (len(fields) == len(sizes) == len(types) == len(counts)):
        raise _FormatError("PCD FIELDS, SIZE, TYPE and COUNT have different lengths")
    try:
        sizes = [int(s) for s in sizes]
        counts = [int(c) for c in counts]
        if "POINTS" in h:
            n = int(h["POINTS"][0])
        else:
            n = int(h["WIDTH"][0]) * int(h.get("HEIGHT", ["1"])[0])
    except (ValueError, KeyError, IndexError):
        raise _FormatError("bad SIZE, COUNT, WIDTH, HEIGHT or POINTS in the PCD header") from None
    for axis in "xyz":
        if axis not in fields:
            raise _FormatError(f"the PCD file has no '{axis}' field")
    return fields, sizes, types, counts, n


def _pcd_ascii(body: bytes, n: int, counts, cols) -> np.ndarray:
    text = body.decode("ascii", errors="replace").split()
    per = sum(counts)
    if len(text) < n * per:
        raise _FormatError(f"truncated: expected {n} points of {per} values")
    try:
        vals = np.array(text[: n * per], dtype=np.float64).reshape(n, per)
    except ValueError:
        raise _FormatError("non-numeric value in the point data") from None
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return vals[:, [starts[c] for c in cols]]


def _pcd_binary(data: bytes, body: int, n: int, dts, counts, cols) -> np.ndarray:
    dtype = np.dtype(
        [
            (f"f{i}", dt, (c,)) if c > 1 else (f"f{i}", dt)
            for i, (dt, c) in enumerate(zip(dts, counts))
        ]
    )
    if body + n * dtype.itemsize > len(data):
        raise _FormatError(f"truncated: {n} points of {dtype.itemsize} bytes do not fit")
    rec = np.frombuffer(data, dtype=dtype, count=n, offset=body)
    return np.stack([_first(rec[f"f{c}"]).astype(np.float64) for c in cols], axis=1)


def _pcd_compressed(data: bytes, body: int, n: int, dts, sizes, counts, cols) -> np.ndarray:
    if body + 8 > len(data):
        raise _FormatError("truncated: no compressed block sizes")
    csize, usize = (int(v) for v in np.frombuffer(data, "<u4", 2, body))
    if body + 8 + csize > len(data):
        raise _FormatError("truncated compressed data")
    try:
        raw = _core._lzf_decompress(data[body + 8 : body + 8 + csize], usize)
    except ValueError as e:
        raise _FormatError(str(e)) from None
    # Fields are stored one after another (all points' x, then all y, ...).
    out, off = [], 0
    per_field = [n * s * c for s, c in zip(sizes, counts)]
    if sum(per_field) > usize:
        raise _FormatError("compressed block smaller than the header's points")
    for i, (dt, c) in enumerate(zip(dts, counts)):
        if i in cols:
            arr = np.frombuffer(raw, dt, n * c, off).reshape(n, c)[:, 0]
            out.append((cols.index(i), arr.astype(np.float64)))
        off += per_field[i]
    out.sort(key=lambda t: t[0])
    return np.stack([a for _, a in out], axis=1)


def _first(a):
    return a[:, 0] if a.ndim == 2 else a
