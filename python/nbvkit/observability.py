"""The observable surface: which part of a structure's surface the configured camera could see at
all from the navigation space, so that coverage can be told apart from geometry (an aircraft's
wing root inside its fuselage can never be seen, whatever the planner).

Method (C++ calls, ``nbvkit._core.observable_samples``, Embree):

1. *Poses.* A lattice of candidate vehicle positions of spacing ``observability.pose_spacing``
   (default 2 m; for a small structure a second, finer lattice searched for what the first left
   unseen: ``nbvkit.work_limits.pose_spacing``) fills the navigation box (the workspace shrunk by
   the collision radius: where a mission's vehicle may be). A lattice point is dropped if the mesh
   comes within ``vehicle.collision_radius`` of it (an Embree point query), or if the vehicle cannot
   fly there from outside: it must be connected, through lattice edges that the mesh does not cross
   and along which the collision sphere fits (checked every half radius), to a free position on the
   navigation box's sides or top that sees out of it (a flood fill; the ground below is not part of
   the mesh). A closed hull's inside is unreachable however large it is, and so is a space behind an
   opening narrower than the vehicle (a camera outside may still see through it: an office's
   windows, a covered rooftop). The yaw is free.
2. *Samples.* The ground-truth samples (``Evaluator.gt_points``: the mesh sampled uniformly at
   ``evaluation.gt_density``) with their triangle's normal (either side).
3. *Visibility.* A sample is observable if, from some kept position (samples in Morton order,
   the previous sample's seeing position first, then nearest first; the first success ends the
   search), with the camera at the position plus its mount height (pitched by its gimbal, within
   camera.gimbal_pitch_deg, to centre the sample vertically), some yaw
   (the one that centres the sample horizontally, and ``yaw_steps`` offsets each side across
   the frustum's half diagonal) puts it inside the pinhole frustum (mount pitch and roll, FOV)
   at a depth along the optical axis in [min_range, max_range], its line of sight is within
   ``max_incidence_deg`` of the normal, and an Embree occlusion ray from the sample to the
   camera hits nothing. The pixel grid is not simulated (at 640 x 480 a pixel spans 1.4 cm at
   8 m, finer than the finest 5 cm coverage cell).

The lattice is the only approximation that a finer setting removes. Each side of the box is
split evenly into the fewest steps of at most the spacing, both faces included: the air just
above a roof and the band under a wing are flown (a lattice about the box's centre left up to a
spacing unflown at each face: the twinjet's undersides, 10 % of its area, counted unobservable).
At 2 m the observable share is within 0.6 points of 0.5 m's on six structures;
``bench/bench_observable.py`` measures it and draws ``docs/figures/observable_convergence.png``.
Results are cached on disk per (mesh, samples, camera, navigation space, options) in a
``cache_dir`` (a run's or a sweep's folder), so a 30-run table computes it once per structure.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _core
from .output_paths import check_output_dir
from .limits import Bound, read_only, require_config, require_type
from .work_limits import pose_spacing
from .locks import FileLock
from .sensors import build_camera
from .settings import cpp_section

__all__ = ["ObservableSurface", "observability_options", "observable_surface", "sample_normals"]

#: bump when the method changes, so old caches are not reused
_METHOD_VERSION = 6


ObservabilityConfig = cpp_section(
    "ObservabilityConfig",
    _core.ObservabilityOptions,
    "The observable surface (nbvkit.observable_surface): what the camera could see at all.",
    only=("pose_spacing", "max_incidence_deg", "yaw_steps"),  # the radius is the vehicle's
    before=[
        (
            "enabled",
            bool,
            True,
            "compute it at the end of a mission (cached under the run/sweep folder)",
        )
    ],
    bounds={
        "pose_spacing": Bound(lo=0, lo_open=True),
        "max_incidence_deg": Bound(lo=0, lo_open=True),
        "yaw_steps": Bound(lo=0, hi=180),
    },
)


@dataclass
class ObservableSurface:
    """What ``observable_surface`` found.

    points: (N, 3) the samples; observable: (N,) bool; poses: (P, 3) the reachable,
    collision-free vehicle positions used; stats: counts, timings (s) and the settings;
    cached: whether it came from the cache.
    """

    points: np.ndarray
    observable: np.ndarray
    poses: np.ndarray
    stats: dict = field(default_factory=dict)
    cached: bool = False

    @property
    def fraction(self) -> float:
        """Observable share of the samples (of the area, for area-uniform samples)."""
        return float(self.observable.mean()) if len(self.observable) else 0.0


def sample_normals(mesh, face_ids) -> np.ndarray:
    """(N, 3) unit normals of the triangles ``face_ids`` (N,) of ``mesh`` (zero if degenerate)."""
    # per triangle once, then gathered, when there are fewer triangles than samples: the same
    # numbers as per sample, without the (N, 3, 3) corners and their differences (3.4 GB
    # transient for 20 million samples); per sample when there are fewer samples (a scanned
    # mesh of millions of triangles)
    v, f, ids = np.asarray(mesh.vertices), np.asarray(mesh.faces), np.asarray(face_ids)
    if len(ids) < len(f):
        f, ids = f[ids], np.arange(len(ids))
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    unit = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    return unit[ids]


def _fine_spacing(config, workspace, mesh_bounds, samples: int) -> float:
    """The spacing of the fine lattice searched beside the configured one (work_limits.pose_spacing;
    the configured spacing when it is no finer)."""
    size = [float(b - a) for a, b in zip(workspace.nav_min, workspace.nav_max)]
    return pose_spacing(config, mesh_bounds, size, samples)


def _settings(config, workspace, mesh_bounds, samples: int) -> dict:
    c, o = config.camera, config.observability
    return {
        "camera": {
            "hfov_deg": c.hfov_deg,
            "vfov_deg": c.vfov_deg,
            "min_range": c.min_range,
            "max_range": c.max_range,
            "mount_xyz": list(map(float, c.mount_xyz)),
            "mount_rpy_deg": list(map(float, c.mount_rpy_deg)),
        },
        "nav_min": [round(float(x), 9) for x in workspace.nav_min],
        "nav_max": [round(float(x), 9) for x in workspace.nav_max],
        "collision_radius": config.vehicle.collision_radius,
        "pose_spacing": o.pose_spacing,
        "fine_pose_spacing": _fine_spacing(config, workspace, mesh_bounds, samples),
        "max_incidence_deg": o.max_incidence_deg,
        "yaw_steps": o.yaw_steps,
        "gimbal_pitch_deg": list(map(float, c.gimbal_pitch_deg)),
    }


def _cache_key(mesh, points, settings) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, np.int32).tobytes())
    h.update(memoryview(np.ascontiguousarray(points, np.float64)))  # (tobytes: a copy)
    h.update(json.dumps([_METHOD_VERSION, settings], sort_keys=True).encode())
    return h.hexdigest()[:20]


def _check_of_mesh(mesh, evaluator, scene) -> None:
    """TypeError/ValueError unless evaluator and scene (each optional) were built of `mesh`
    (another mesh's gave its samples or its walls: 1.0 observable where 0.835 was)."""
    from .evaluation import Evaluator

    if evaluator is not None:
        require_type(evaluator, Evaluator, "evaluator", "an nbvkit.Evaluator or None")
        info = evaluator._core.gt_info
        if info.from_mesh and not math.isclose(info.gt_area, mesh.area, rel_tol=1e-9):
            raise ValueError(
                f"evaluator was built of another mesh: its surface is {info.gt_area:.6g} m^2, "
                f"the mesh's {mesh.area:.6g} m^2"
            )
    if scene is not None:
        require_type(scene, _core.RaycastScene, "scene", "an nbvkit.RaycastScene or None")
        other = scene.mesh
        if other is not mesh and not (
            np.array_equal(other.faces, mesh.faces)
            and np.array_equal(other.vertices, mesh.vertices)
        ):
            raise ValueError("scene was built of another mesh: give a RaycastScene(mesh)")


def _checked_face_ids(face_ids, n: int, triangles: int) -> np.ndarray:
    """face_ids as (n,) int64 of triangles [0, triangles); ValueError naming what is wrong (a
    negative id picked a triangle from the end)."""
    f = np.asarray(face_ids)
    whole = f.dtype.kind == "f" and bool(np.all(np.isfinite(f) & (f == np.round(f))))
    if f.shape != (n,) or (f.size and f.dtype.kind not in "iu" and not whole):
        raise ValueError(
            f"face_ids must be ({n},) integers, one triangle a point, got shape {f.shape} "
            f"of {f.dtype}"
        )
    if f.size and (f.min() < 0 or f.max() >= triangles):
        raise ValueError(
            f"face_ids must be triangles of the mesh, in [0, {triangles}), got "
            f"{int(f.min())}..{int(f.max())}"
        )
    return f.astype(np.int64)


def observable_surface(
    mesh,
    config,
    *,
    points=None,
    face_ids=None,
    evaluator=None,
    cache_dir: str | os.PathLike | None = None,
    scene=None,
) -> ObservableSurface:
    """Which surface samples of ``mesh`` the configured camera could see from some
    collision-free pose of the navigation space (see the module docstring for the method).

    mesh: an ``nbvkit.Mesh`` (need not be closed: the test is geometric, not topological).
    config: an ``nbvkit.Config``: ``camera`` (mount, FOV, range),
    ``workspace`` and ``vehicle.collision_radius`` (the navigation space), ``observability``
    (pose spacing, incidence limit, yaw steps), ``evaluation.gt_density`` and ``seed`` (the
    samples).
    points, face_ids: the samples (N, 3) and their triangles (N,) (normals come from these;
    without face_ids no incidence test is made). Default: the ground-truth samples of
    ``evaluator`` if given (its ``gt_points``), else those of ``nbvkit.Evaluator(mesh,
    gt_density, seed)``, i.e. ``mesh.sample_surface(n, seed, return_faces=True)``.
    cache_dir: folder of the on-disk cache (``observable-<key>.npz``; the key hashes the mesh,
    the samples and every setting above; concurrent processes wait on a file lock, so one
    computes and the others read). None: no cache.
    scene: an ``nbvkit.RaycastScene`` of ``mesh`` to reuse (default: one is built).

    Returns an ``ObservableSurface``; ``.observable`` is the ``(N,)`` bool mask to pass to
    ``Evaluator.set_observable``.
    """
    from .evaluation import Evaluator
    from .workspace import make_workspace

    require_type(mesh, _core.Mesh, "mesh", "an nbvkit.Mesh")
    require_config(config)
    _check_of_mesh(mesh, evaluator, scene)
    cfg = config
    ws = make_workspace(mesh.bounds, cfg)
    ev = None
    if points is None:
        ev = evaluator or Evaluator(mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
        points = ev.gt_points
    else:  # a copy: the result must not change with the caller's array
        points = read_only(points, "points", np.float64)  # (complex refused, not cut)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {points.shape}")
    if face_ids is not None:
        face_ids = _checked_face_ids(face_ids, len(points), mesh.num_triangles)

    def normals():  # only a computation needs them (a cache hit does not)
        fid = face_ids
        if ev is not None and ev._core.gt_info.from_mesh:
            again, f = mesh.sample_surface(
                len(points), int(ev._core.gt_info.seed), return_faces=True
            )
            if np.array_equal(again, points):
                fid = f
        return sample_normals(mesh, fid) if fid is not None else np.zeros_like(points)

    settings = _settings(cfg, ws, mesh.bounds, len(points))
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"observable-{_cache_key(mesh, points, settings)}.npz"
        hit = _load(path, points)  # (a read-only folder serves its hits)
        if hit is not None:
            return hit
        check_output_dir(path.parent, "cache_dir")  # (a file there: FileExistsError from mkdir)
        path.parent.mkdir(parents=True, exist_ok=True)
        with FileLock(path.with_suffix(".lock")):
            hit = _load(path, points)  # another process may have computed it meanwhile
            if hit is not None:
                return hit
            out = _compute(mesh, cfg, points, normals(), ws, settings, scene)
            _save(path, out)
            return out
    return _compute(mesh, cfg, points, normals(), ws, settings, scene)


def observability_options(config, **changes) -> _core.ObservabilityOptions:
    """The C++ options of the observability section with the camera's gimbal range (what a
    pose of this vehicle can see), and `changes` (e.g. pose_spacing=4.0)."""
    pitch = config.camera.gimbal_pitch_deg
    return config.observability.options().copy(
        gimbal_min_deg=pitch[0], gimbal_max_deg=pitch[1], **changes
    )


#: the counts of a lattice search (observable_samples) that a run's stats sum over its lattices
LATTICE_COUNTS = ("lattice_points", "colliding", "unreachable")


def _compute(mesh, cfg, points, normals, ws, settings, scene) -> ObservableSurface:
    t0 = time.perf_counter()
    scene = scene or _core.RaycastScene(mesh)
    # only its field of view, ranges and mount are used
    camera = build_camera(cfg.camera, scene, cfg.seed, width=16, height=12, noise_k=0.0)

    def search(which, spacing):  # which: the samples' indices, or None for all (not copied)
        pts, nrm = (points, normals) if which is None else (points[which], normals[which])
        return _core.observable_samples(
            scene,
            pts,
            nrm,
            camera,
            ws.nav_min,
            ws.nav_max,
            options=observability_options(cfg, pose_spacing=spacing),
            collision_radius=cfg.vehicle.collision_radius,
        )

    # the configured lattice, then a small structure's finer one for what it left unseen: a
    # finer lattice's levels need not hold every position a coarser one does
    runs = [search(None, settings["pose_spacing"])]
    mask = np.asarray(runs[0].observable, bool)
    if settings["fine_pose_spacing"] < settings["pose_spacing"] and not mask.all():
        left = np.flatnonzero(~mask)
        runs.append(search(left, settings["fine_pose_spacing"]))
        mask[left] = np.asarray(runs[1].observable, bool)
    timings: dict = {}
    for r in runs:
        for k, v in r.timings_s:
            timings[k] = timings.get(k, 0.0) + float(v)
    stats = {
        "settings": settings,
        "samples": int(len(mask)),
        "observable_samples": int(mask.sum()),
        **{k: sum(int(getattr(r, k)) for r in runs) for k in LATTICE_COUNTS},
        "poses": sum(len(r.poses) for r in runs),
        "timings_s": timings,
        "wall_time_s": time.perf_counter() - t0,
    }
    poses = np.vstack([np.asarray(r.poses).reshape(-1, 3) for r in runs])
    return ObservableSurface(points, mask, poses, stats)


def _save(path: Path, out: ObservableSurface) -> None:
    """Writes a cache entry whole or not at all: a temporary file beside it, renamed over it
    (OSError, e.g. a full disk, leaves no partial entry)."""
    tmp = path.with_name(path.name + f".tmp{os.getpid()}.npz")
    try:
        with open(tmp, "wb") as f:
            np.savez_compressed(
                f,
                observable=out.observable,
                poses=out.poses,
                stats=np.array(json.dumps(out.stats)),
            )
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _load(path: Path, points) -> ObservableSurface | None:
    """The cache entry at path, or None when there is none or it is damaged (truncated, not a
    zip file, wrong arrays: it is then recomputed and written again)."""
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            mask = z["observable"].astype(bool)
            poses = np.asarray(z["poses"], float).reshape(-1, 3)
            stats = json.loads(str(z["stats"]))
        if not isinstance(stats, dict) or mask.ndim != 1:
            return None
    except Exception:  # noqa: BLE001 - BadZipFile, EOFError, zlib.error, ValueError, ...
        return None
    if len(mask) != len(points):
        return None
    return ObservableSurface(points, mask, poses, stats, cached=True)
