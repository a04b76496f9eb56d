"""The simulated world of a mission: the structure, the vehicle and its sensors, and what has been
mapped so far (occupancy map, point clouds, camera observations).

Planners read it and move the vehicle through it; they never reach past it. Every per-ray and
per-cell loop runs in the C++ core (``nbvkit._core``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

from . import _core
from ._core import MAX_COORDINATE
from .limits import Bound, require_config, require_type
from .work_limits import MissionError, check_work
from .mapping import new_map
from .mesh import check_path_clear, default_mesh_path, fibonacci_sphere, load_mesh
from .mesh import IN_MEMORY_MESH, mesh_file_sha1, surface_crossings
from .sensors import (
    build_camera,
    build_frame_camera,
    build_laser,
    build_preview_camera,
    build_view_camera,
)
from .settings import cpp_section
from .vehicle import FLIGHT_COLUMNS, VehicleState, as_positions, as_view, check_stage  # noqa: F401
from .workspace import Workspace, ground_height, is_large, make_workspace, start_poses
from .workspace import structure_hint, unplaced_start, warn_coarse, warn_floating


VehicleConfig = cpp_section(
    "VehicleConfig",
    _core.ValidityOptions,
    "The UAV: collision sphere and how it flies between views.",
    only=("collision_radius", "blocked_path", "keep_off_hits"),
    after=[
        (
            "start_clear_radius",
            float,
            3.0,
            "m; unknown cells this near the start are known free before the first scan: the "
            "vehicle took off there (with less than ~2 m the strict collision rule leaves a "
            "camera-only start only yaw turns: every 1 m step's sphere reaches outside the "
            "camera's 45 deg vertical FOV); never past the structure's surface (a map cell "
            "short of it); 0 disables",
        ),
        (
            "clear_swept_volume",
            bool,
            True,
            "the vehicle's own swept volume (collision radius along the flown path) is known free",
        ),
        (
            "widen_swept_volume",
            bool,
            True,
            "the swept volume made known free reaches half a cell diagonal past the collision "
            "radius, so the cells the flown path crosses pass A*'s test (the sphere at each cell's "
            "centre) and the vehicle can always plan its way back along its own flight; false: "
            "the radius alone (the paper's scenarios)",
        ),
        (
            "path_expansions",
            int,
            _core.DEFAULT_PATH_EXPANSIONS,
            "cells an A* search to a view expands at most; a view the vehicle's free component "
            "holds is searched again without the cap",
        ),
        (
            "min_altitude",
            Optional[float],
            None,
            "m; the ground clearance: the lowest the vehicle's centre flies above the workspace "
            "floor (the ground; its A* paths between views to within half a map cell); null: "
            "its collision radius + 0.1 m",
        ),
    ],
    choices={"blocked_path": ("reject", "plan")},
    bounds={
        "collision_radius": Bound(lo=0, lo_open=True),
        "start_clear_radius": Bound(lo=0, hi=1000),
        "path_expansions": Bound(lo=1, hi=400_000_000),
        "min_altitude": Bound(lo=0, hi=10_000),
    },
)


def cloud_floor(config, mesh_bounds) -> float:
    """The height below which the clouds drop points: cloud.min_z above the structure's ground
    (workspace.ground_height); -inf (none dropped) where cloud.min_z is null."""
    if config.cloud.min_z is None:
        return -math.inf
    return ground_height(mesh_bounds) + config.cloud.min_z


def surface_clouds(config, mesh_bounds, large: bool = False):
    """(camera, laser) empty SurfaceClouds as a mission keeps them: each voxel-filtered at its
    cloud.*_voxel, dropping points below cloud_floor; the camera cloud's sums in single
    precision with cloud.single_precision (null: when the workspace is large)."""
    cl = config.cloud
    min_z = cloud_floor(config, mesh_bounds)
    single = large if cl.single_precision is None else cl.single_precision
    return (
        _core.SurfaceCloud(voxel_size=cl.camera_voxel, min_z=min_z, single_precision=single),
        _core.SurfaceCloud(voxel_size=cl.laser_voxel, min_z=min_z),
    )


def _check_above_ground_removal(config, mesh_bounds) -> None:
    """Raises MissionError for a structure that lies wholly within the clouds' ground removal
    (below cloud_floor): every point of it would be dropped, and a mission would end at once
    with nothing covered."""
    top = float(np.asarray(mesh_bounds, float)[1][2])
    if top <= cloud_floor(config, mesh_bounds):  # never without a ground removal (null)
        raise MissionError(
            f"the structure's top (z = {top:g} m) is not above the clouds' ground removal "
            f"(cloud.min_z = {config.cloud.min_z:g} m above the ground at z = "
            f"{ground_height(mesh_bounds):g} m): every point of it "
            "would be dropped as ground; lower cloud.min_z (e.g. --set cloud.min_z=-1 keeps "
            "everything) or lift the structure (mesh.shift)"
        )


class World:
    """The structure (mesh, Embree scene), the workspace, the vehicle and its sensors, and the
    maps they build: ``map`` (OccupancyMap), ``camera_cloud`` / ``laser_cloud`` (SurfaceCloud),
    ``surface`` (SurfaceObservations of the camera).

    config: a nbvkit.Config. mesh: an nbvkit.Mesh to use instead of config.mesh. Raises
    MissionError before any work for a bad start or a start inside the structure.
    """

    def __init__(self, config, mesh=None):
        require_config(config)
        self.config = cfg = config
        if mesh is None:
            self.mesh_path = str(cfg.mesh.path or default_mesh_path())
            self.mesh_sha1 = mesh_file_sha1(self.mesh_path)  # evaluate checks it is the same
            mesh = load_mesh(
                self.mesh_path, scale=cfg.mesh.scale, up=cfg.mesh.up, shift=cfg.mesh.shift
            )
        else:
            require_type(mesh, _core.Mesh, "mesh", "an nbvkit.Mesh")
            self.mesh_path, self.mesh_sha1 = IN_MEMORY_MESH, None
        self.mesh = mesh
        try:
            _check_above_ground_removal(cfg, mesh.bounds)
            self.workspace: Workspace = make_workspace(mesh.bounds, cfg)
            # What the configuration asks of this structure (map memory, profile scans and legs,
            # ground-truth samples, observability lattice): refused before any work (limits).
            check_work(cfg, mesh, self.workspace)
            # The map first: its size check (cells, OctoMap's range) comes before any search.
            self.map = new_map(cfg, mesh.bounds, self.workspace)
            warn_floating(mesh.bounds, cfg)  # a structure given in altitudes
            warn_coarse(mesh.bounds, cfg)  # a structure a few cells across
        except ValueError as e:  # a structure of a size or height the metre makes unlikely
            if not (hint := structure_hint(mesh.bounds, cfg)):
                raise
            raise (MissionError if isinstance(e, MissionError) else ValueError)(
                f"{e}{hint}"
            ) from None
        self.scene = _core.RaycastScene(mesh)
        self.camera = build_camera(cfg.camera, self.scene, cfg.seed)
        self.frame_camera = build_frame_camera(cfg.camera, self.scene, cfg.seed + 2) or self.camera
        self._refine = cfg.camera.frame_refine
        self.preview_camera = build_preview_camera(cfg.camera, self.scene)
        self.laser = build_laser(cfg.laser, self.scene, cfg.seed + 1)
        self._ahead = None  # (kind, pose, Scan) of a capture integrate took ahead
        self.starts = self._start_poses()
        start = np.array(cfg.start_pose, float) if cfg.start_pose is not None else None
        self.start_pose = start if start is not None else self.starts[cfg.start]
        if not np.all(np.isfinite(self.start_pose)):  # (another start's failing is no matter)
            raise MissionError(unplaced_start(cfg.start, self._start_space(), cfg.workspace))
        self._check_start(self.start_pose)
        large = is_large(self.workspace, cfg.camera)
        self.camera_cloud, self.laser_cloud = surface_clouds(cfg, mesh.bounds, large)
        self.surface = _core.SurfaceObservations(self.map, cfg.utility.saturation_hits)
        self.view_camera = build_view_camera(cfg.camera, cfg.utility, cfg.map.resolution)
        self.state = VehicleState(pose=as_view(self.start_pose))
        self.state.trajectory.append(("start", *self.state.pose.tolist(), 0.0))
        self.state.record_leg("start", self.start_pose[None, :3], 0.0)
        # the symmetry stage's results, for the mission's figures (nbvkit.symmetry)
        self.symmetry_result = self.symmetry_prediction = self.symmetry_profile = None

    def take_off(self) -> None:
        """Unknown cells within vehicle.start_clear_radius of the start become known free: the
        vehicle took off there (no sensor sees its own surroundings). The sphere stops a map
        cell short of the structure's nearest surface (2,000 rays): reaching it, it would mark
        the cells inside the structure free."""
        r = self.config.vehicle.start_clear_radius
        if r > 0:
            p = self.start_pose[:3]
            _, first = surface_crossings(self.scene, self.mesh.bounds, p, fibonacci_sphere(2000))
            r = min(r, float(np.min(first)) - self.config.map.resolution)
        if r > 0:
            self.map.mark_free_segment(p, p, r)

    # ------------------------------------------------------------------ starts
    def _start_poses(self) -> np.ndarray:
        """The five predefined starts (see workspace.start_poses): within 3/4 of the camera's
        range of the structure, seeing it; a row of NaN for one with no clear place."""
        c, v = self.config.camera, self.config.vehicle
        # a coarse, noise-free copy of the camera
        probe = build_camera(c, self.scene, self.config.seed, width=32, height=24, noise_k=0.0)
        return start_poses(
            self._start_space(),
            surface=self.mesh.sample_surface(20000, seed=0),
            reach=0.75 * c.max_range,
            clearance=v.collision_radius + 1.0,
            sees=lambda pose: len(probe.scan_pose(pose).hits) >= 0.05 * 32 * 24,
            collides=self._collides,
        )

    def _start_space(self) -> Workspace:
        """The workspace the starts keep to: the structure's height, whatever the flight
        envelope above it."""
        return dataclasses.replace(self.workspace, nav_max=self.workspace.structure_nav_max)

    def _collides(self, point) -> bool:
        """Whether a vehicle at `point` would be in collision with or inside the structure."""
        return self._start_problem(point) is not None

    def _check_start(self, pose) -> None:
        problem = self._start_problem(pose)
        if problem:
            raise MissionError(f"start pose {np.round(pose, 3).tolist()} {problem}")

    def _start_problem(self, pose) -> str | None:
        """Why `pose` cannot be a start (outside the bounds, within the collision radius of the
        structure, or inside it), or None."""
        ws = self.workspace
        if not ws.contains(pose):
            return (
                f"is outside the navigation bounds "
                f"{ws.nav_min.round(3).tolist()} - {ws.nav_max.round(3).tolist()}"
            )
        r = self.config.vehicle.collision_radius
        dirs = fibonacci_sphere(200)
        count, first = surface_crossings(self.scene, self.mesh.bounds, pose[:3], dirs)
        if np.any(first <= max(r, 1e-6)):
            return f"is within the collision radius ({r} m) of the structure"
        # Inside test, by the parity of each ray's crossings: a ray from inside a closed surface
        # crosses it an odd number of times, from outside an even number, whichever way the
        # faces are wound (reversed, mixed, or doubled back to back). Holes and open shells make
        # some rays wrong, hence a vote over all of them.
        if (count % 2 == 1).sum() > 0.5 * len(dirs):
            return "is inside the structure"
        return None

    # ------------------------------------------------------------------ sensing
    #: what a capture is: the sensor that takes it
    SENSOR_OF = {"view": "camera", "frame": "camera", "laser": "laser"}

    def sense(self, kind: str = "view", pose=None):
        """One capture where the vehicle is, scanned and integrated (scan, then integrate);
        `pose`, if given, must be the vehicle's (fly_to it first; scan(kind, pose) looks from
        elsewhere without recording). kind: "view" (a camera frame that counts as a view),
        "frame" (a camera frame taken in flight, the profile's or a leg's, by frame_camera at
        camera.frame_stride, refined where it could add: camera.frame_refine) or "laser".
        Returns the Scan."""
        if pose is not None and not np.allclose(as_view(pose), self.state.pose, rtol=0, atol=1e-9):
            raise ValueError(
                f"sense records a capture where the vehicle is, {self.state.pose.tolist()}, not "
                f"at {as_view(pose).tolist()}: fly_to that pose first, or scan(kind, pose) to look "
                "from it without recording anything"
            )
        scan = self.scan(kind, pose)
        self.integrate(scan, kind)
        return scan

    def scan(self, kind: str = "view", pose=None):
        """The Scan of a capture (see sense) from `pose` (default: the vehicle's); nothing is
        integrated. The capture that integrate(then=...) took ahead is returned where it is the
        one asked for (the same kind and pose); asked for another, it is dropped. A frame at
        camera.frame_stride is refined against the camera observations as they are now
        (_core.refine_frame, with camera.frame_refine)."""
        if kind not in self.SENSOR_OF:
            raise ValueError(f"unknown capture {kind!r}; known: {', '.join(self.SENSOR_OF)}")
        pose = self.state.pose if pose is None else as_view(pose)
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead[0] == kind and np.array_equal(ahead[1], pose):
            scan = ahead[2]
        else:
            scan = self._sensor(kind).scan_pose(pose)
        if kind == "frame" and self.frame_camera is not self.camera and self._refine:
            cone = self.config.utility.coverage_cone_deg
            scan = _core.refine_frame(self.camera, scan, pose, self.surface, cone)
        return scan

    def _sensor(self, kind: str):
        return (
            self.laser if kind == "laser" else self.frame_camera if kind == "frame" else self.camera
        )

    def novelty(self, pose) -> float:
        """The share of a coarse, noise-free preview of a camera frame from `pose`
        (preview_camera) whose rays would add to what is known: hits the camera observations
        lack (a side unseen within utility.coverage_cone_deg, or a square no hit has marked:
        SurfaceObservations.novel_hits) and rays ending at max range in an unknown workspace
        cell. Nothing is integrated."""
        scan = self.preview_camera.scan_pose(pose)
        cone = self.config.utility.coverage_cone_deg
        novel = self.surface.novel_hits(scan.origin, scan.hits, cone)
        ends = scan.free_ends
        if len(ends):
            ends = ends[np.asarray(self.map.in_workspace(ends), bool)]
            novel += int(np.count_nonzero(self.map.state(ends) == -1))
        rays = scan.depth.size
        return novel / rays if rays else 0.0

    def integrate(self, scan, kind: str = "view", then=None) -> int:
        """Integrates a capture's Scan (see sense): into the map, and the camera cloud and
        camera observations (a camera frame, also marked on the flight) or the laser cloud.
        Returns the surface cells the camera saw for the first time (0 for a laser scan). A camera
        frame goes into all three at once (_core.integrate_frame: the same as one after the
        other, the map's update beside the other two). then: (kind, pose) of the camera capture
        to come next, where it is known (a leg's next frame, or its view): taken meanwhile, and
        returned by the scan that asks for it. The scan is of the sensor `kind` names, taken
        where the vehicle is (scan(kind)): the capture is recorded there."""
        self._check_sensor(scan, kind)
        if self.SENSOR_OF[kind] == "laser":
            self.map.integrate(scan)
            self.laser_cloud.add(scan.hits)
            return 0
        ahead = {}
        if then is not None:
            if self.SENSOR_OF.get(then[0]) != "camera":
                raise ValueError(f"then must be a camera capture (view, frame), not {then[0]!r}")
            ahead = {"next_camera": self._sensor(then[0]), "next_pose": as_view(then[1])}
        done = _core.integrate_frame(self.map, self.camera_cloud, self.surface, scan, **ahead)
        if then is not None:
            self._ahead = (then[0], ahead["next_pose"], done.next_scan)
        self.state.capture(kind)
        return done.new_cells

    def _check_sensor(self, scan, kind: str) -> None:
        """ValueError unless `scan` is an image of the sensor `kind` names (a laser scan
        integrated as a view went into the camera cloud and counted as a photo)."""
        if kind not in self.SENSOR_OF:
            raise ValueError(f"unknown capture {kind!r}; known: {', '.join(self.SENSOR_OF)}")
        shape = tuple(np.shape(scan.depth))
        if self.SENSOR_OF[kind] == "laser":
            fits = shape == (1, self.laser.num_beams)
        else:
            fits = shape in {(c.height, c.width) for c in (self.camera, self.frame_camera)}
        if not fits:
            raise ValueError(
                f"a {kind!r} capture must be a {self.SENSOR_OF[kind]} scan; this one holds "
                f"{' x '.join(map(str, shape))} rays"
            )

    @property
    def clouds(self) -> list:
        """The reconstruction's clouds, camera then laser (to read in place, e.g. by
        ``Evaluator.coverage``, which keeps its count of them between calls)."""
        return [self.camera_cloud, self.laser_cloud]

    def cloud_points(self) -> np.ndarray:
        """(N, 3) the reconstruction: camera and laser clouds together."""
        return _core.stack_points(self.clouds)

    # ------------------------------------------------------------------ motion
    def fly_to(self, target, stage: str, path=None) -> float:
        """Move the vehicle along `path` ((P, 3) waypoints, first = here; default straight) to
        `target` (x, y, z, yaw) or (x, y, z, yaw, pitch) (4 numbers: the camera level); returns
        the distance flown. The swept volume becomes known free (vehicle.clear_swept_volume).
        Raises ValueError for a stage not in vehicle.STAGES, a non-finite target, a pitch outside
        camera.gimbal_pitch_deg, a path that does not start here and end at the target, or one
        that passes through the structure's surface (the vehicle would crash; nothing moves).
        Nothing checks the collision radius or the workspace: that is the planner's part
        (can_hold)."""
        check_stage(stage)
        target = as_view(target)
        if not np.isfinite(target).all() or np.abs(target[:3]).max() > MAX_COORDINATE:
            raise ValueError(
                f"fly_to target must be finite coordinates within +-{MAX_COORDINATE:g} m, got "
                f"{target.tolist()}"
            )
        self._check_pitch(target[4])
        cur = self.state.pose
        pts = np.asarray(path if path is not None and len(path) else [cur[:3], target[:3]], float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
            raise ValueError(f"fly_to path must be (P, 3) finite waypoints, got shape {pts.shape}")
        for end, where, what in (
            (pts[0], cur, "start where the vehicle is"),
            (pts[-1], target, "end at the target"),
        ):
            if not np.allclose(end, where[:3], rtol=0, atol=1e-6):
                raise ValueError(
                    f"fly_to path must {what}, {where[:3].tolist()}; it gives {end.tolist()}"
                )
        check_path_clear(self.scene, pts, "fly_to path")
        d = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        v = self.config.vehicle
        if v.clear_swept_volume:
            r = v.collision_radius
            if v.widen_swept_volume:
                r += 0.5 * math.sqrt(3.0) * self.map.resolution
            for a, b in zip(pts[:-1], pts[1:]):
                self.map.mark_free_segment(a, b, r)
        d0 = self.state.distance_m
        self.state.distance_m += d
        self.state.pose = target
        self.state.trajectory.append((stage, *self.state.pose.tolist(), self.state.distance_m))
        self.state.record_leg(stage, pts, d0)
        return d

    def _check_pitch(self, pitch: float) -> None:
        lo, hi = self.config.camera.gimbal_pitch_deg
        deg = math.degrees(pitch)
        within = lo - 1e-9 <= deg <= hi + 1e-9 and abs(pitch) <= math.pi / 2  # the camera's
        if not (math.isfinite(pitch) and within):
            raise ValueError(
                f"view pitch {pitch!r} rad ({deg:g} deg) is outside camera.gimbal_pitch_deg "
                f"[{lo:g}, {hi:g}] deg"
            )

    def validity(self, blocked_path: str | None = None):
        """ValidityOptions of a candidate view here: the navigation bounds, the vehicle's
        collision radius and (unless given) its blocked_path rule."""
        ws, v = self.workspace, self.config.vehicle
        return _core.ValidityOptions(
            collision_radius=v.collision_radius,
            bounds_min=ws.nav_min,
            bounds_max=ws.nav_max,
            blocked_path=blocked_path or v.blocked_path,
            keep_off_hits=v.keep_off_hits,
        )

    def can_hold(self, positions) -> np.ndarray:
        """(K,) bool per position (K, 3): within the navigation space, with the vehicle's
        collision sphere in known free space (what a view there needs to be flown)."""
        p = as_positions(positions, "can_hold's positions")
        inside = self.workspace.contains_each(p)
        ok = np.zeros(len(p), bool)
        if inside.any():
            ok[inside] = self.spheres_are_free(p[inside])
        return ok

    def spheres_are_free(self, centres) -> np.ndarray:
        """(K,) bool per centre (K, 3): the vehicle's collision sphere there touches only known
        free cells, none holding a camera hit (vehicle.keep_off_hits: the map alone may call a
        cell free through which a surface cuts; the checks keep off every surface point seen)."""
        radius = self.config.vehicle.collision_radius
        return _core.spheres_are_free(self.map, centres, radius, surface=self.hits_to_avoid)

    def free_component(self):
        """The cells A* can reach from the vehicle (a _core.FreeComponent, by the collision
        checks' rule of spheres_are_free), valid until the map or the observations change."""
        radius = self.config.vehicle.collision_radius
        start = self.state.pose[:3]
        floor = self.workspace.path_floor
        return _core.FreeComponent(self.map, start, radius, self.hits_to_avoid, floor)

    @property
    def hits_to_avoid(self):
        """The camera observations the collision checks keep off (vehicle.keep_off_hits), or
        None: the map alone."""
        return self.surface if self.config.vehicle.keep_off_hits else None

    def plan_path(self, target, max_expansions: int | None = None):
        """A* path (P, 3) from the vehicle to target's position through known free space, or
        None when there is none within max_expansions expanded cells (default
        vehicle.path_expansions)."""
        path = self.search_path(target, max_expansions).path
        return path if len(path) else None

    def search_path(self, target, max_expansions: int | None = None):
        """plan_path's search as a _core.PathSearch: its path ((0, 3) when none was found) and
        whether it stopped at its cap (`capped`: only then may a longer search find a way)."""
        if max_expansions is None:
            max_expansions = self.config.vehicle.path_expansions
        return _core.search_path(
            self.map,
            self.state.pose[:3],
            np.asarray(target, float)[:3],
            self.config.vehicle.collision_radius,
            max_expansions=max_expansions,
            surface=self.hits_to_avoid,
            floor=self.workspace.path_floor,
        )

    def enter_navigation_space(self, stage: str) -> float:
        """After a flight outside the navigation bounds (a wide profiling circle), fly straight
        to the nearest point inside them; returns the distance flown (0 when already inside)."""
        ws = self.workspace
        p = self.state.pose
        q = np.clip(p[:3], ws.nav_min + 1e-6, ws.nav_max - 1e-6)
        if np.allclose(q, p[:3]):
            return 0.0
        return self.fly_to(np.array([*q, *p[3:]]), stage)
