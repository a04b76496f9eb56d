"""A mission: profiling -> symmetry prediction -> the planner's views -> evaluation and results.

``Mission(config).run(out_dir)`` flies one scenario (nbvkit.scenarios: a row of the paper's Table
2, or one of nbvkit's planners) from one start pose and writes a results folder. The stages are
nbvkit.profiling, nbvkit.symmetry and nbvkit.planning; the world they act on is nbvkit.world;
nbvkit.recorder records the views and writes the results."""
from __future__ import annotations

import threading
import time
from pathlib import Path

from .config import Config
from .evaluation import Evaluator
from .planning import Planner
from .planning.terminations.budget import ended_by, view_cap
from .recorder import IterationRecord, Recorder, fly_into, raise_stop
from .runfolder import RunFolder
from .world import MissionError, World

__all__ = ["Mission", "MissionError", "IterationRecord"]


class Mission:
    """One run of a scenario on one structure from one start. config: a nbvkit.Config (default:
    the recommended planner); mesh: an nbvkit.Mesh instead of config.mesh. MissionError (a
    ValueError) before any work for a bad start or configuration."""

    def __init__(self, config: Config | None = None, mesh=None):
        if config is not None and not isinstance(config, Config):
            raise TypeError(f"config must be an nbvkit.Config, got {type(config).__name__}")
        self.config = config or Config()
        self._running = threading.Lock()
        self._ran = False
        self._start(World(self.config, mesh))

    def _start(self, world: World) -> None:
        """Everything a run changes, as a new Mission has it."""
        self.world = world
        self.planner = Planner(self.config)
        self.recorder = Recorder(self)
        self.profile_summary = self.symmetry_summary = None
        self.termination = "not_run"
        # the cap on views after profiling (max_iterations, or one that follows the structure)
        self.max_views = view_cap(self.config.max_iterations, world.mesh.area)

    # the world's parts and the records, for stages and figures
    mesh = property(lambda self: self.world.mesh)
    map = property(lambda self: self.world.map)
    records = property(lambda self: self.recorder.records)

    def cloud_points(self):
        return self.world.cloud_points()

    # ------------------------------------------------------------------ the method
    def run(self, out_dir: str | Path | None = None, overwrite: bool = False, finish=False) -> dict:
        """Runs the mission and returns its summary; with out_dir writes its results folder
        there (`finish`: with the end-of-run outputs) whole or not at all (nbvkit.runfolder);
        stopped once its views started, what it flew (fly_into), then the error. Reruns afresh;
        one at a time (RuntimeError)."""
        if not self._running.acquire(blocking=False):
            raise RuntimeError(
                "this Mission is already running (in another thread): a Mission runs one "
                "flight at a time; make one Mission per thread"
            )
        try:
            if out_dir is None:
                return self._run()
            # before any work: a mission must not fly and then fail to save
            inputs = (self.config.mesh.path,)  # which an overwrite may not replace
            with RunFolder(out_dir, overwrite=overwrite, what="out_dir", inputs=inputs) as folder:
                flown = fly_into(self, folder, finish)
            return raise_stop(*flown, folder)  # once the folder is in place
        finally:
            self._running.release()

    def save(self, out, summary: dict, finish=False, cache_dir=None, overwrite=False) -> dict:
        """Writes this finished mission's results (Recorder.write) as the run folder `out`, whole
        or not at all, as run(out_dir) does (manifest last: export and evaluate read it);
        ValueError as run's. Returns the summary written."""
        with RunFolder(out, overwrite=overwrite, what="out") as folder:
            return self.recorder.write(folder.tmp, summary, finish=finish, cache_dir=cache_dir)

    def _run(self) -> dict:
        if self._ran:  # a second run starts from a fresh world, as a new Mission would
            mesh_path = self.world.mesh_path
            self._start(World(self.config, self.world.mesh))
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
        self.termination = "profile_only"
        if cfg.planner.generators:
            world.sense("view")  # the first view, from where the camera stage starts
            self.planner.hooks["record"] = self.recorder.on_step  # the last hook
            self.recorder.open_progress(self.max_views, cfg.progress, since=t_start)
            try:
                self.termination = self.planner.run(world, self.max_views)
            finally:
                self.recorder.close_progress()
            self.termination = ended_by(self.termination, world)  # or "nothing_seen"
        return self.recorder.summary(self.termination, time.perf_counter() - t_start)

    def _profile(self) -> dict:
        from .profiling import run_profiling

        summary = run_profiling(self.world)
        # laser, and camera frames if taken: the cell figures alone (no distances)
        ev = self.evaluator.coverage(self.world.clouds)
        summary.update(coverage=ev["coverage"], area_coverage=ev["area_coverage"])
        return summary

    def _symmetry(self) -> dict:
        """Symmetry prediction; with symmetry.refresh_every, the after-view hook
        "symmetry_refresh" re-predicts from the camera cloud."""
        from .prediction import SymmetryRefresh
        from .symmetry import run_symmetry_prediction

        cfg = self.config.symmetry
        summary = run_symmetry_prediction(self.world, write_map=cfg.mode == "predict")
        plane = summary.get("plane")
        if cfg.mode == "predict" and plane is not None and cfg.refresh_every > 0:
            refresh = SymmetryRefresh(self.world, plane, cfg)
            summary["refreshed_cells"] = 0

            def symmetry_refresh(world, step):
                summary["refreshed_cells"] += refresh.after_view(step)

            self.planner.hooks["symmetry_refresh"] = symmetry_refresh
        return summary
