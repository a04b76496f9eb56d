"""A mission: profiling -> symmetry prediction -> the planner's views -> evaluation and results.

``Mission(config).run(out_dir)`` flies one scenario (nbvkit.scenarios: a row of the paper's Table
2, or one of nbvkit's planners) from one start pose and writes a results folder. The stages are
nbvkit.profiling, nbvkit.symmetry and nbvkit.planning; the world they act on is nbvkit.world;
nbvkit.recorder records the views and writes the results.
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

from .config import Config
from .evaluation import Evaluator
from .planning import Planner
from .planning.terminations.budget import ended_by, view_cap
from .recorder import IterationRecord, Recorder
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
        self._flying = None  # see run_into
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
        there (Recorder.write; with `finish` also nbvkit.report's end-of-run outputs), whole or
        not at all (nbvkit.runfolder: checked before any work; ValueError if it cannot be
        written, another run is writing it, or it holds files and ``overwrite`` is not given).
        A Mission may run again, from a fresh world; one run at a time (RuntimeError)."""
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
                summary, stopped = self.run_into(folder.tmp, finish=finish)
            if stopped is not None:
                raise stopped  # what was flown is in out_dir
            return summary
        finally:
            self._running.release()

    def run_into(self, out, finish: bool = False) -> tuple[dict, BaseException | None]:
        """Runs the mission and writes its results into the folder `out` (see save): (summary,
        None). A flight stopped once its views started, by Ctrl-C or by an error (a planner
        part's), is not lost: what it flew is written (its termination "interrupted" or
        "failed", without the end-of-run outputs) and (summary, the exception) returned, for
        the caller to raise once the folder is in place. Stopped before the views started
        (profile, symmetry), the exception propagates and nothing is written."""
        try:
            summary = self._run()
        except (KeyboardInterrupt, Exception) as e:
            if self._flying is None:
                raise
            why = "interrupted" if isinstance(e, KeyboardInterrupt) else "failed"
            if self.config.progress:
                print(f"{why}: saving what was flown (Ctrl-C again drops it)", file=sys.stderr)
            summary = self.recorder.summary(why, time.perf_counter() - self._flying)
            summary["stopped_by"] = error_line(e)
            return self.save(out, summary), e
        return self.save(out, summary, finish=finish), None

    def save(self, out, summary: dict, finish: bool = False, cache_dir=None) -> dict:
        """Writes this finished mission's results into the folder `out` (Recorder.write);
        returns the summary written."""
        return self.recorder.write(Path(out), summary, finish=finish, cache_dir=cache_dir)

    def _run(self) -> dict:
        if self._ran:  # a second run starts from a fresh world, as a new Mission would
            mesh_path = self.world.mesh_path
            self._start(World(self.config, self.world.mesh))
            self.world.mesh_path = mesh_path
        self._ran = True
        self._flying = None  # the mission's start time, set once its views start (run_into)
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
            self.recorder.open_progress(self.max_views, cfg.progress)
            self._flying = t_start
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


def error_line(e: BaseException) -> str:
    """An exception as one line for a reader: its type, and its message when it has one."""
    message = " ".join(str(e).split())
    return f"{type(e).__name__}: {message}" if message else type(e).__name__
