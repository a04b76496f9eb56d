"""The mission runner: profiling -> symmetry prediction -> next-best-view loop -> evaluation.

``Mission(config).run()`` flies one scenario of the paper's Table 2 from one start pose and writes
a results folder (see ``Mission.run``). Every per-ray and per-voxel loop runs in the C++ core; this
file is the readable sequence of the method.
"""
from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import _core
from .config import Config
from .mesh import default_mesh_path, load_mesh
from .sampling import AdaptiveScale, candidate_poses
from .termination import EntropyTermination, viewable_cells
from .workspace import Workspace, make_workspace, start_poses

#: scenario -> (profiling, symmetry prediction, sampling), as in the paper's Table 2 (the
#: "profile" scenario also reports the symmetry its profile shows, without using it)
SCENARIOS = {
    "profile": (True, False, None),
    "1": (False, False, "cgvs"),
    "2": (True, False, "cgvs"),
    "3": (True, False, "agvs"),
    "4": (True, True, "cgvs"),
    "5": (True, True, "agvs"),
}

STATUS_NAMES = {
    0: "valid",
    1: "out_of_bounds",
    2: "collision",
    3: "path_blocked",
    4: "sees_no_occupied",
}


class MissionError(ValueError):
    """A mission that cannot start: bad start pose, unknown option, missing stage."""


@dataclass
class IterationRecord:
    iteration: int
    x: float
    y: float
    z: float
    yaw: float
    utility: float
    gain: float
    candidates: int
    valid: int
    entropy: float
    entropy_change: float
    delta_ev: float
    alpha: int
    distance_m: float
    cloud_points: int
    coverage_005: float | None = None
    coverage_01: float | None = None
    coverage_05: float | None = None
    t_sampling_ms: float = 0.0
    t_evaluation_ms: float = 0.0
    t_sensing_ms: float = 0.0
    t_integration_ms: float = 0.0
    t_bookkeeping_ms: float = 0.0


@dataclass
class MissionState:
    pose: np.ndarray
    distance_m: float = 0.0
    trajectory: list = field(default_factory=list)  # rows: stage, x, y, z, yaw, distance_m


class CoverageTracker:
    """Cheap coverage for progress reports: the evaluator's ground-truth cell keys per
    resolution, compared with the keys of the cloud's points (numpy set ops) — the same cell
    count as nbvkit.evaluate's coverage, without its distance metrics."""

    RES = (0.05, 0.1, 0.5)

    def __init__(self, gt_points: np.ndarray):
        self.gt_keys = {r: np.unique(_keys(gt_points, r)) for r in self.RES}

    def coverage(self, points: np.ndarray) -> dict:
        out = {}
        for r in self.RES:
            if len(points) == 0:
                out[r] = 0.0
                continue
            ck = np.unique(_keys(points, r))
            out[r] = float(np.isin(self.gt_keys[r], ck, assume_unique=True).mean())
        return out


def _keys(p: np.ndarray, r: float) -> np.ndarray:
    k = np.floor(np.asarray(p) / r).astype(np.int64) + (1 << 20)
    return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]


class Mission:
    """One run of the method on one structure from one start.

    config: a nbvkit.Config (defaults: the paper's). mesh: an nbvkit.Mesh to use instead of
    config.mesh. Raises MissionError (a ValueError) before any work for a bad start, scenario or
    configuration.
    """

    def __init__(self, config: Config | None = None, mesh=None):
        self.config = cfg = config or Config()
        if cfg.scenario not in SCENARIOS:
            raise MissionError(f"unknown scenario {cfg.scenario!r}; known: {', '.join(SCENARIOS)}")
        self.profiling, self.symmetry, sampling = SCENARIOS[cfg.scenario]
        if sampling is not None and sampling != cfg.sampling.method:
            self.config = cfg = replace(cfg, sampling=replace(cfg.sampling, method=sampling))
        if mesh is None:
            self.mesh_path = str(cfg.mesh.path or default_mesh_path())
            mesh = load_mesh(self.mesh_path, scale=cfg.mesh.scale, up=cfg.mesh.up)
        else:
            self.mesh_path = "<in-memory mesh>"
        self.mesh = mesh
        self.workspace: Workspace = make_workspace(mesh.bounds, cfg)
        self.scene = _core.RaycastScene(mesh)
        # starts within 3/4 of the camera's range of the structure, seeing it (see start_poses)
        c, la = cfg.camera, cfg.laser
        camera_mount = _core.mount_transform(c.mount_xyz, *c.mount_rpy_deg)
        probe = _core.DepthCamera(
            self.scene,
            width=32,
            height=24,
            hfov_deg=c.hfov_deg,
            vfov_deg=c.vfov_deg,
            min_range=c.min_range,
            max_range=c.max_range,
            mount=camera_mount,
        )
        self.starts = start_poses(
            self.workspace,
            surface=mesh.sample_surface(20000, seed=0),
            reach=0.75 * c.max_range,
            clearance=cfg.vehicle.collision_radius + 1.0,
            sees=lambda pose: len(probe.scan_pose(pose).hits) >= 0.05 * 32 * 24,
        )
        self.start_pose = (
            np.array(cfg.start_pose, float)
            if cfg.start_pose is not None
            else self.starts[cfg.start]
        )
        self._check_start(self.start_pose)
        self.camera = _core.DepthCamera(
            self.scene,
            width=c.width,
            height=c.height,
            hfov_deg=c.hfov_deg,
            vfov_deg=c.vfov_deg,
            min_range=c.min_range,
            max_range=c.max_range,
            noise_k=c.noise_k,
            seed=cfg.seed,
            mount=camera_mount,
        )
        self.laser = _core.LaserScanner(
            self.scene,
            fov_deg=la.fov_deg,
            resolution_deg=la.resolution_deg,
            min_range=la.min_range,
            max_range=la.max_range,
            noise_sigma=la.noise_sigma,
            seed=cfg.seed + 1,
            mount=_core.mount_transform(la.mount_xyz, *la.mount_rpy_deg),
        )
        m = cfg.map
        self.map = _core.OccupancyMap(
            m.resolution,
            self.workspace.bounds_min,
            self.workspace.bounds_max,
            options=_core.OccupancyMapOptions(
                prob_hit=m.prob_hit,
                prob_miss=m.prob_miss,
                clamp_min=m.clamp_min,
                clamp_max=m.clamp_max,
                occupancy_threshold=m.occupancy_threshold,
                entropy_unit=m.entropy_unit,
                clamped_entropy_zero=m.clamped_entropy_zero,
                deduplicate_end_points=m.fast_integration,
                clip_to_workspace=m.clip_to_workspace,
            ),
        )
        cl = cfg.cloud
        self.camera_cloud = _core.SurfaceCloud(voxel_size=cl.camera_voxel, min_z=cl.min_z)
        self.laser_cloud = _core.SurfaceCloud(voxel_size=cl.laser_voxel, min_z=cl.min_z)
        vc = _core.ViewCameraModel.for_resolution(c.hfov_deg, c.vfov_deg, c.max_range, m.resolution)
        self.view_camera = vc.copy(
            rays_x=cfg.utility.rays_x or vc.rays_x,
            rays_y=cfg.utility.rays_y or vc.rays_y,
            mount=camera_mount,
        )
        self.rays = (self.view_camera.rays_x, self.view_camera.rays_y)
        self.c_view = viewable_cells(
            c.hfov_deg,
            c.vfov_deg,
            c.min_range,
            c.max_range,
            m.resolution,
            cfg.termination.count_partial_cells,
        )
        self.state = MissionState(pose=self.start_pose.copy())
        self.records: list[IterationRecord] = []
        self.profile_summary: dict | None = None
        self.coverage_time_s = 0.0  # progress-report coverage refreshes (not a stage of the method)
        self.symmetry_summary: dict | None = None

    # ------------------------------------------------------------------ checks
    def _check_start(self, pose) -> None:
        ws = self.workspace
        if not ws.contains(pose):
            raise MissionError(
                f"start pose {np.round(pose, 3).tolist()} is outside the navigation bounds "
                f"{ws.nav_min.round(3).tolist()} - {ws.nav_max.round(3).tolist()}"
            )
        r = self.config.vehicle.collision_radius
        dirs = _fibonacci_sphere(200)
        t, _ = self.scene.intersect(np.asarray(pose[:3], float)[None], dirs, 0.0, max(r, 1e-6))
        if np.isfinite(t).any():
            raise MissionError(
                f"start pose {np.round(pose, 3).tolist()} is within the collision radius "
                f"({r} m) of the structure"
            )
        # Inside test: from outside, a ray always enters the first surface it meets through a
        # front face (outward-oriented parts, even intersecting ones); from inside, most first
        # hits are back faces. Open shells seen from outside give some back faces, hence a vote.
        t, prim = self.scene.intersect(np.asarray(pose[:3], float)[None], dirs, 0.0, np.inf)
        hit = prim >= 0
        if hit.any():
            v, f = self.mesh.vertices, self.mesh.faces[prim[hit]]
            n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
            back = np.einsum("ij,ij->i", n, dirs[hit]) > 0
            if back.sum() > 0.5 * len(dirs):
                raise MissionError(
                    f"start pose {np.round(pose, 3).tolist()} is inside the structure"
                )

    # ------------------------------------------------------------------ sensing
    def sense_camera(self, pose) -> None:
        scan = self.camera.scan_pose(pose)
        self.map.integrate(scan)
        self.camera_cloud.add(scan.hits)

    def sense_laser(self, pose) -> None:
        scan = self.laser.scan_pose(pose)
        self.map.integrate(scan)
        self.laser_cloud.add(scan.hits)

    def cloud_points(self) -> np.ndarray:
        a, b = self.camera_cloud.points, self.laser_cloud.points
        return np.vstack([a, b]) if len(b) else a

    def fly_to(self, target, stage: str, path=None) -> float:
        """Move the vehicle along `path` (or straight) to `target`; returns the distance flown."""
        cur = self.state.pose
        pts = np.asarray(path if path is not None and len(path) else [cur[:3], target[:3]], float)
        d = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        if self.config.vehicle.clear_swept_volume:
            for a, b in zip(pts[:-1], pts[1:]):
                self.map.mark_free_segment(a, b, self.config.vehicle.collision_radius)
        self.state.distance_m += d
        self.state.pose = np.asarray(target, float).copy()
        p = self.state.pose
        self.state.trajectory.append((stage, *p.tolist(), self.state.distance_m))
        return d

    # ------------------------------------------------------------------ the method
    def run(self, out_dir: str | Path | None = None) -> dict:
        """Runs the mission; with out_dir writes config.yaml, iterations.csv, summary.json,
        cloud.ply, map.ot, trajectory.csv and figures/*.png there. Returns the summary dict."""
        cfg = self.config
        t_start = time.perf_counter()
        self.out_dir = Path(out_dir) if out_dir is not None else None  # stages may save figures
        self.entropy_initial = self.map.total_entropy()  # the empty workspace: cells * ln 2
        p = self.state.pose
        self.state.trajectory.append(("start", *p.tolist(), 0.0))
        if cfg.vehicle.start_clear_radius > 0:
            self.map.mark_free_segment(p[:3], p[:3], cfg.vehicle.start_clear_radius)
        from .evaluation import Evaluator

        self.evaluator = Evaluator(self.mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
        if self.profiling:
            from .profiling import run_profiling  # issue: profiling stage

            self.profile_summary = run_profiling(self)
        if self.symmetry or cfg.scenario == "profile":
            from .symmetry import run_symmetry_prediction

            # the profile scenario reports the plane its profile shows, without predicting
            # into the map
            self.symmetry_summary = run_symmetry_prediction(self, write_map=self.symmetry)
        self.sense_camera(self.state.pose)
        self.tracker = CoverageTracker(self.evaluator.gt_points)
        termination = self._nbv_loop() if cfg.scenario != "profile" else "profile_only"
        wall = time.perf_counter() - t_start
        summary = self._summary(termination, wall)
        if out_dir is not None:
            self.write_results(Path(out_dir), summary)
        return summary

    def _nbv_loop(self) -> str:
        cfg = self.config
        s, u, v = cfg.sampling, cfg.utility, cfg.vehicle
        agvs = AdaptiveScale(
            s.sigma,
            s.alpha_max,
            s.stuck_threshold,
            s.stuck_window,
            s.scale_cap,
            s.oscillation_is_stuck,
            enabled=(s.method == "agvs"),
        )
        term = EntropyTermination(self.c_view, cfg.termination.threshold, cfg.termination.window)
        entropy_prev = self.map.total_entropy()
        bar = _progress(cfg.max_iterations, cfg.progress)
        last_cov = {}
        termination = "max_iterations"
        try:
            for it in range(1, cfg.max_iterations + 1):
                t0 = time.perf_counter()
                pose = self.state.pose
                cands = candidate_poses(pose, s.delta_d, s.delta_theta, agvs.scale)
                t1 = time.perf_counter()
                sc = _core.evaluate_views(
                    self.map,
                    cands,
                    pose,
                    camera=self.view_camera,
                    utility=dict(
                        name=u.name,
                        distance_lambda=u.distance_lambda,
                        require_occupied=True,
                        require_occupied_probability=u.require_occupied_probability or 0.0,
                    ),
                    validity=dict(
                        collision_radius=v.collision_radius,
                        bounds_min=self.workspace.nav_min,
                        bounds_max=self.workspace.nav_max,
                        blocked_path=v.blocked_path,
                    ),
                )
                valid = np.flatnonzero(sc["status"] == 0)
                chosen, path = None, None
                for k in valid[np.argsort(-sc["utility"][valid], kind="stable")]:
                    if v.blocked_path == "plan":
                        path = _core.plan_path(self.map, pose[:3], cands[k, :3], v.collision_radius)
                        if len(path) == 0:
                            continue
                    chosen = k
                    break
                t2 = time.perf_counter()
                if chosen is None:
                    termination = "no_valid_viewpoint"
                    break
                self.fly_to(cands[chosen], "nbv", path)
                scan = self.camera.scan_pose(self.state.pose)
                t3 = time.perf_counter()
                self.map.integrate(scan)
                self.camera_cloud.add(scan.hits)
                t4 = time.perf_counter()
                e_now = self.map.total_entropy()
                dev, done = term.update(entropy_prev, e_now)
                alpha = agvs.update(dev, self.state.pose[:3])
                if cfg.evaluation.coverage_every and it % cfg.evaluation.coverage_every == 0:
                    tc = time.perf_counter()
                    last_cov = self.tracker.coverage(self.cloud_points())
                    self.coverage_time_s += time.perf_counter() - tc
                    t4 += (
                        time.perf_counter() - tc
                    )  # reporting, not the method: kept out of the stages
                p = self.state.pose
                rec = IterationRecord(
                    it,
                    *map(float, p),
                    float(sc["utility"][chosen]),
                    float(sc["gain"][chosen]),
                    len(cands),
                    len(valid),
                    e_now,
                    e_now - entropy_prev,
                    dev,
                    alpha,
                    self.state.distance_m,
                    len(self.camera_cloud) + len(self.laser_cloud),
                    last_cov.get(0.05),
                    last_cov.get(0.1),
                    last_cov.get(0.5),
                    (t1 - t0) * 1e3,
                    (t2 - t1) * 1e3,
                    (t3 - t2) * 1e3,
                    (t4 - t3) * 1e3,
                )
                rec.t_bookkeeping_ms = (time.perf_counter() - t4) * 1e3
                self.records.append(rec)
                entropy_prev = e_now
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix_str(
                        f"H={e_now:,.0f} a={alpha}"
                        + (f" cov0.5={last_cov[0.5]:.1%}" if last_cov else "")
                    )
                if done:
                    termination = "entropy_converged"
                    break
        finally:
            if bar is not None:
                bar.close()
        return termination

    # ------------------------------------------------------------------ results
    def _summary(self, termination: str, wall: float) -> dict:
        cfg = self.config
        ev = self.evaluator(self.cloud_points())
        n_it = len(self.records)
        e_final = self.map.total_entropy()
        stages = ("sampling", "evaluation", "sensing", "integration", "bookkeeping")
        per_stage = {
            s: (float(np.mean([getattr(r, f"t_{s}_ms") for r in self.records])) if n_it else 0.0)
            for s in stages
        }
        out = {
            "scenario": cfg.scenario,
            "start": cfg.start,
            "start_pose": [float(x) for x in self.start_pose],
            "mesh": self.mesh_path,
            "profiling": self.profiling,
            "symmetry_prediction": self.symmetry,
            "sampling": cfg.sampling.method if cfg.scenario != "profile" else None,
            "iterations": n_it,
            "distance_m": self.state.distance_m,
            "entropy_initial": self.entropy_initial,
            "entropy_final": e_final,
            "entropy_reduction": self.entropy_initial - e_final,
            "entropy_unit": cfg.map.entropy_unit,
            "termination": termination,
            "wall_time_s": wall,
            "ms_per_iteration": (
                sum(sum(getattr(r, f"t_{s}_ms") for s in stages) for r in self.records) / n_it
                if n_it
                else 0.0
            ),
            "ms_per_stage": per_stage,
            "coverage_refresh_s": self.coverage_time_s,
            "cloud_points": int(ev["n_points"]),
            "workspace": self.workspace.to_dict(),
            "c_view": self.c_view,
            "seed": cfg.seed,
        }
        for k in (
            "coverage",
            "area_coverage",
            "precision",
            "completeness",
            "accuracy",
            "fscore",
            "chamfer_m",
            "n_points",
            "gt_density",
        ):
            out[k] = ev[k]
        if self.profile_summary is not None:
            out["profile"] = self.profile_summary
        if self.symmetry_summary is not None:
            out["symmetry"] = self.symmetry_summary
        return out

    def write_results(self, out: Path, summary: dict) -> None:
        from .cloud import write_points
        from .plots import plot_mission

        out.mkdir(parents=True, exist_ok=True)
        (out / "config.yaml").write_text(self.config.to_yaml())
        _write_json_atomic(out / "summary.json", summary)
        fields_ = list(IterationRecord.__dataclass_fields__)
        with open(out / "iterations.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(fields_)
            for r in self.records:
                w.writerow(["" if getattr(r, k) is None else getattr(r, k) for k in fields_])
        with open(out / "trajectory.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["stage", "x", "y", "z", "yaw", "distance_m"])
            w.writerows(self.state.trajectory)
        write_points(out / "cloud.ply", self.cloud_points())
        self.map.save(str(out / "map.ot"))
        plot_mission(self, out / "figures")


def _write_json_atomic(path: Path, data: dict) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(_jsonable(data), indent=2, allow_nan=False))
    tmp.replace(path)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def _fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = math.pi * (1 + 5**0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1)


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a Debian package we install
        return None
    # disable=None: no bar when stderr is not a terminal (logs, pipes, CI)
    return tqdm(total=total, desc="NBV", unit="it", dynamic_ncols=True, leave=False, disable=None)
