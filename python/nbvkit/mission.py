"""A mission: profiling -> symmetry prediction -> the planner's views -> evaluation and results.

``Mission(config).run(out_dir)`` flies one scenario (nbvkit.scenarios: a row of the paper's Table
2, or one of nbvkit's planners) from one start pose and writes a results folder. The stages are
nbvkit.profiling, nbvkit.symmetry and nbvkit.planning; the world they act on is nbvkit.world.
"""
from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import resource
import threading
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from .config import Config
from .evaluation import SUMMARY_KEYS, Evaluator
from .planning import Planner
from .planning.terminations.budget import BUDGET_REASONS, view_cap
from .world import FLIGHT_COLUMNS, MissionError, World

__all__ = ["Mission", "MissionError", "IterationRecord"]

#: The per-view stages timed in every iteration (ms_per_stage in the summary).
STAGES = ("sampling", "evaluation", "selection", "motion", "sensing", "mapping")


@dataclass
class IterationRecord:
    """One row of iterations.csv: a view flown after profiling."""

    iteration: int
    x: float
    y: float
    z: float
    yaw: float
    source: str  # the generator that proposed the view
    utility: float
    gain: float
    candidates: int
    valid: int
    entropy: float
    entropy_change: float
    delta_ev: float
    alpha: int
    expected_m2: float | None  # the new surface the plan expected of the view (surface utility)
    realized_m2: float | None  # how much of it the view brought, as the utility counts it
    new_surface_m2: float
    leg_m: float
    distance_m: float
    cloud_points: int
    coverage_005: float | None = None
    coverage_01: float | None = None
    coverage_05: float | None = None
    t_sampling_ms: float = 0.0
    t_evaluation_ms: float = 0.0
    t_selection_ms: float = 0.0
    t_motion_ms: float = 0.0
    t_sensing_ms: float = 0.0
    t_mapping_ms: float = 0.0


class Mission:
    """One run of a scenario on one structure from one start.

    config: a nbvkit.Config (default: the recommended planner). mesh: an nbvkit.Mesh to use
    instead of config.mesh. Raises MissionError (a ValueError) before any work for a bad start or
    configuration.
    """

    def __init__(self, config: Config | None = None, mesh=None):
        if config is not None and not isinstance(config, Config):
            raise TypeError(f"config must be an nbvkit.Config, got {type(config).__name__}")
        self.config = config or Config()
        self._running = threading.Lock()
        self._ran = False
        self._start(World(self.config, mesh))

    def _start(self, world: World) -> None:
        """Everything a run changes, as a new Mission has it."""
        cfg = self.config
        self.world = world
        self.planner = Planner(cfg, cfg.map.resolution, on_step=self._record)
        self.records: list[IterationRecord] = []
        self.refresh = None
        self._bar = None
        self.profile_summary: dict | None = None
        self.symmetry_summary: dict | None = None
        self.coverage_time_s = 0.0  # progress-report coverage refreshes (not a stage)
        self.termination = "not_run"
        # the cap on views after profiling (max_iterations, or one that follows the structure)
        self.max_views = view_cap(cfg.max_iterations, self.world.mesh.area)

    # the world's parts, for stages and figures
    mesh = property(lambda self: self.world.mesh)
    mesh_path = property(lambda self: self.world.mesh_path)
    map = property(lambda self: self.world.map)
    state = property(lambda self: self.world.state)
    workspace = property(lambda self: self.world.workspace)
    start_pose = property(lambda self: self.world.start_pose)
    starts = property(lambda self: self.world.starts)
    camera_cloud = property(lambda self: self.world.camera_cloud)
    laser_cloud = property(lambda self: self.world.laser_cloud)

    def cloud_points(self) -> np.ndarray:
        return self.world.cloud_points()

    # ------------------------------------------------------------------ the method
    def run(self, out_dir: str | Path | None = None, overwrite: bool = False) -> dict:
        """Runs the mission; with out_dir writes config.yaml, iterations.csv, summary.json,
        cloud.ply, map.ot, trajectory.csv, flight.csv and figures/*.png there. Returns the
        summary dict.

        The folder is written whole or not at all (nbvkit.runfolder): into a temporary folder
        beside it, moved into place with ``manifest.json`` once complete. out_dir is checked
        before any work: ValueError if it cannot be written, if another run is writing it, or
        if it already holds files and ``overwrite`` is not given (an overwrite replaces the old
        run whole, and only a folder holding nothing but nbvkit's outputs).

        A Mission may run again: each run starts from a fresh world (the same results as a new
        Mission of the same configuration and mesh). One run at a time: a second thread calling
        run() on a Mission that is running gets a RuntimeError.
        """
        if not self._running.acquire(blocking=False):
            raise RuntimeError(
                "this Mission is already running (in another thread): a Mission runs one "
                "flight at a time; make one Mission per thread"
            )
        try:
            if out_dir is None:
                return self._run()
            from .runfolder import RunFolder

            # before any work: a mission must not fly and then fail to save
            with RunFolder(out_dir, overwrite=overwrite, what="out_dir") as folder:
                summary = self._run()
                self.write_results(folder.tmp, summary)
            return summary
        finally:
            self._running.release()

    def _run(self) -> dict:
        if self._ran:  # a second run starts from a fresh world, as a new Mission would
            world = self.world
            mesh_path = world.mesh_path
            self._start(World(self.config, world.mesh))
            self.world.mesh_path = mesh_path
        self._ran = True
        cfg, world = self.config, self.world
        t_start = time.perf_counter()
        self.entropy_initial = world.map.total_entropy()  # the empty workspace
        world.take_off()
        self.evaluator = Evaluator(world.mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
        if cfg.profiling.enabled:
            self.profile_summary = self._profile()
        if cfg.symmetry.mode != "none":
            self.symmetry_summary = self._symmetry()
        if cfg.planner.generators:
            world.sense_camera()  # the first view, from where the camera stage starts
            self._bar = _progress(self.max_views, cfg.progress)
            try:
                self.termination = self.planner.run(world, self.max_views)
            finally:
                if self._bar is not None:
                    self._bar.close()
        else:
            self.termination = "profile_only"
        return self._summary(self.termination, time.perf_counter() - t_start)

    def _profile(self) -> dict:
        from .profiling import run_profiling

        world = self.world
        summary = run_profiling(world)
        # laser, and camera frames if taken: the cell figures alone (no distances)
        ev = self.evaluator.coverage(world.clouds)
        summary.update(coverage=ev["coverage"], area_coverage=ev["area_coverage"])
        return summary

    def _symmetry(self) -> dict:
        from .prediction import SymmetryRefresh
        from .symmetry import run_symmetry_prediction

        cfg = self.config.symmetry
        summary = run_symmetry_prediction(self.world, write_map=cfg.mode == "predict")
        plane = summary.get("plane")
        if cfg.mode == "predict" and plane is not None and cfg.refresh_every > 0:
            self.refresh = SymmetryRefresh(self.world, plane, cfg)
            summary["refreshed_cells"] = 0
        return summary

    # ------------------------------------------------------------------ per view
    def _record(self, step) -> None:
        cfg, world = self.config, self.world
        refresh = self.refresh
        if refresh is not None:
            self.symmetry_summary["refreshed_cells"] += refresh.after_view(step)
        cov = {}
        if cfg.evaluation.coverage_every and step.iteration % cfg.evaluation.coverage_every == 0:
            t0 = time.perf_counter()
            c = self.evaluator.coverage(world.clouds)["coverage"]
            cov = {float(k): v for k, v in c.items()}
            self.coverage_time_s += time.perf_counter() - t0
        p, c = world.state.pose, step.choice
        lap = self.planner.timers.lap()
        self.records.append(
            IterationRecord(
                step.iteration,
                *map(float, p),
                step.source,
                c.utility,
                c.gain,
                step.candidates,
                step.valid,
                step.entropy_after,
                step.entropy_after - step.entropy_before,
                step.delta_ev,
                int(step.extra.get("alpha", 0)),
                step.expected_m2,
                step.realized_m2,
                step.new_surface_m2,
                step.extra["leg_m"],
                step.distance_m,
                len(world.camera_cloud) + len(world.laser_cloud),
                cov.get(0.05),
                cov.get(0.1),
                cov.get(0.5),
                *(lap.get(s, 0.0) * 1e3 for s in STAGES),
            )
        )
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix_str(
                f"{step.distance_m:.0f} m H={step.entropy_after:,.0f}"
                + (f" cov0.05={cov[0.05]:.1%}" if cov else "")
            )

    # ------------------------------------------------------------------ results
    def _summary(self, termination: str, wall: float) -> dict:
        cfg, world = self.config, self.world
        ev = self.evaluator(world.cloud_points())
        n_it = len(self.records)
        e_final = world.map.total_entropy()
        # Per flown view, every second the per-view stages took: the rows of iterations.csv and
        # the plan that ended the mission, which flew no view and so has no row (final_plan_ms).
        timers = self.planner.timers
        per_stage = {s: timers.total.get(s, 0.0) * 1e3 / n_it if n_it else 0.0 for s in STAGES}
        final_plan_ms = sum(timers.pending().get(s, 0.0) for s in STAGES) * 1e3
        tour = next((g for g in self.planner.generators if hasattr(g, "plans")), None)
        out = {
            "scenario": cfg.scenario,
            "start": cfg.start,
            "start_pose": [float(x) for x in world.start_pose],
            "mesh": world.mesh_path,
            "profiling": cfg.profiling.enabled,
            "symmetry_prediction": cfg.symmetry.mode == "predict",
            "generators": list(cfg.planner.generators),
            "utility": cfg.utility.name,
            "sampling": cfg.sampling.method if "lattice" in cfg.planner.generators else None,
            "iterations": n_it,
            "views": world.state.views,
            "distance_m": world.state.distance_m,
            "entropy_initial": self.entropy_initial,
            "entropy_final": e_final,
            "entropy_reduction": self.entropy_initial - e_final,
            "entropy_unit": cfg.map.entropy_unit,
            "termination": termination,
            # a budget (view cap, distance, views, time) ended it, not the planner's coverage
            "stopped_by_budget": termination in BUDGET_REASONS,
            "max_views": self.max_views,
            "wall_time_s": wall,
            "ms_per_iteration": sum(per_stage.values()),
            "ms_per_stage": per_stage,
            "final_plan_ms": final_plan_ms,
            "coverage_refresh_s": self.coverage_time_s,
            # the process's peak resident memory so far (Linux ru_maxrss, KiB): in a sweep worker
            # that has flown several runs, the largest of them
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "cloud_points": int(ev["n_points"]),
            "workspace": world.workspace.to_dict(),
            "c_view": self.planner.c_view,
            "seed": cfg.seed,
        }
        out.update(_gain_accounting(self.records))
        for k in SUMMARY_KEYS:
            out[k] = ev[k]
        if self.profile_summary is not None:
            out["profile"] = self.profile_summary
        if self.symmetry_summary is not None:
            out["symmetry"] = self.symmetry_summary
        if tour is not None:
            out["tours"] = tour.plans
        return out

    def write_results(self, out: Path, summary: dict) -> None:
        """Writes the run's files into the folder ``out`` as they are (Mission.run(out_dir) and
        the commands call it on the temporary folder of nbvkit.runfolder.RunFolder, which makes
        the whole folder appear at once). summary.json is written last. Any write error (a full
        disk) raises OSError."""
        from .cloud import write_points
        from .plots import plot_mission

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        _write_text_atomic(out / "config.yaml", self.config.to_yaml())
        names = [f.name for f in fields(IterationRecord)]
        with _atomic_open(out / "iterations.csv", newline="") as f:
            w = csv.writer(f)
            w.writerow(names)
            for r in self.records:
                w.writerow(["" if getattr(r, k) is None else getattr(r, k) for k in names])
        with _atomic_open(out / "trajectory.csv", newline="") as f:
            w = csv.writer(f)
            w.writerow(["stage", "x", "y", "z", "yaw", "distance_m"])
            w.writerows(self.world.state.trajectory)
        with _atomic_open(out / "flight.csv", newline="") as f:  # every point flown (export)
            w = csv.writer(f)
            w.writerow(FLIGHT_COLUMNS)
            w.writerows(self.world.state.flight)
        write_points(out / "cloud.ply", self.world.cloud_points())
        self.world.map.save(str(out / "map.ot"))
        plot_mission(self, out / "figures")
        _write_json_atomic(out / "summary.json", summary)


@contextlib.contextmanager
def _atomic_open(path: Path, mode: str = "w", **kw):
    """A file opened for writing at a temporary name beside `path`, renamed over it once closed
    without error (a write error, e.g. a full disk, raises OSError and leaves `path` as it was)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, mode, **kw) as f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_text_atomic(path: Path, text: str) -> None:
    with _atomic_open(path) as f:
        f.write(text)


def _gain_accounting(records) -> dict:
    """What the views were expected to bring against what they brought (surface utility): the
    sums of expected_m2, realized_m2 (as the utility counts) and new_surface_m2 (cells seen for
    the first time) over the flown views, and the two ratios to the expected; {} otherwise."""
    flown = [r for r in records if r.expected_m2 is not None]
    if not flown:
        return {}
    expected = sum(r.expected_m2 for r in flown)
    realized = sum(r.realized_m2 for r in flown)
    new = sum(r.new_surface_m2 for r in flown)
    return {
        "expected_m2": expected,
        "realized_m2": realized,
        "realized_to_expected": realized / expected if expected > 0 else None,
        "new_surface_to_expected": new / expected if expected > 0 else None,
    }


def _write_json_atomic(path: Path, data: dict) -> None:
    _write_text_atomic(path, json.dumps(_jsonable(data), indent=2, allow_nan=False))


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


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a Debian package we install
        return None
    # disable=None: no bar when stderr is not a terminal (logs, pipes, CI)
    return tqdm(
        total=total, desc="views", unit="view", dynamic_ncols=True, leave=False, disable=None
    )
