"""What a mission records and writes: one IterationRecord per view (the Recorder observes the
planner's steps), the summary, and the run folder's files, each written once (summary.json
last, after the end-of-run outputs of nbvkit.report when asked for)."""
from __future__ import annotations

import contextvars
import csv
import resource
import sys
import time
import warnings
from dataclasses import dataclass, fields
from pathlib import Path

from . import _core
from .evaluation import SUMMARY_KEYS
from .limits import add_note, require_bool, require_type
from .planning.registry import utility_only_checks
from .planning.selection import nothing_flown
from .planning.terminations.budget import BUDGET_REASONS
from .output_paths import atomic_open, write_text_atomic
from .plugins import error_line
from .runfolder import RunFolder, write_json_atomic
from .vehicle import FLIGHT_COLUMNS
from .interrupts import terminate_as_interrupt

# what stops a flight or its saving and leaves what was flown kept: Ctrl-C (and a `kill` handled
# as it), sys.exit() from a part, any error
STOPS = (KeyboardInterrupt, SystemExit, Exception)

#: (the mission, the RunFolder it is written into) while fly_into flies it: its checkpoints' place
_CHECKPOINTS = contextvars.ContextVar("nbvkit_checkpoints", default=None)

#: a checkpoint's stopped_by: what a run folder left by a killed run says of its end
CHECKPOINT_STOP = (
    "not known: this is the run's last checkpoint, saved while it was still flying (a kill, an "
    "out-of-memory kill or a power loss ended it before it saved its own results)"
)


def stop_kind(e: BaseException) -> str:
    """How `e` (one of STOPS) stopped a flight: "failed" (an error) or "interrupted"."""
    return "failed" if isinstance(e, Exception) else "interrupted"


#: The per-view stages timed in every iteration (ms_per_stage in the summary).
STAGES = ("sampling", "evaluation", "selection", "motion", "sensing", "mapping")


def _stage_times(timers, n_it: int) -> tuple[dict, float]:
    """Per flown view, every ms the per-view stages took: the rows of iterations.csv and the plan
    that ended the mission, which flew no view and so has no row (the second, in ms)."""
    per_stage = {s: timers.total.get(s, 0.0) * 1e3 / n_it if n_it else 0.0 for s in STAGES}
    return per_stage, sum(timers.pending().get(s, 0.0) for s in STAGES) * 1e3


def _refusals(selector, n_it: int) -> dict:
    """The candidates refused in the last planning step, by cause; with no planned view flown
    (n_it 0) a RuntimeWarning says so (a script reads no console note; as ended_by warns
    NOTHING_SEEN)."""
    refused = dict(+selector.refused)
    if not n_it:
        warnings.warn(nothing_flown(refused), RuntimeWarning, stacklevel=5)  # Mission.run's caller
    return refused


def _drop_memos(planner) -> None:
    """Clears the planner parts' memos of walks after the flight, before the end-of-run results
    need the memory: they only save time (the same answers without them), and a large
    structure's hold up to 256 MiB."""
    for part in (planner.score, *planner.generators):
        if getattr(part, "memo", None) is not None:
            part.memo.clear()


@dataclass
class IterationRecord:
    """One row of iterations.csv: a view flown after profiling."""

    iteration: int
    x: float
    y: float
    z: float
    yaw: float
    pitch: float  # the camera gimbal's, radians, > 0 looks down (0: level)
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


class Recorder:
    """Observes a mission's planner: after every view (``on_step``, a planner hook) a row of
    iterations.csv, the progress bar and, every evaluation.coverage_every views, the coverage so
    far. ``summary`` and ``write`` turn a finished mission into its results."""

    def __init__(self, mission):
        self.mission = mission
        self.records: list[IterationRecord] = []
        self.coverage_time_s = 0.0  # progress-report coverage refreshes (not a stage)
        self.bar = None
        self.flying_since = None  # the mission's start, once its views started (open_progress)
        self.checkpoints, self.checkpoint_time_s = 0, 0.0  # checkpoints put in place, their time
        self.checkpoint_iterations: int | None = None  # the last one's views (None: none)
        self._last_checkpoint = None

    def open_progress(self, total: int, enabled: bool, since: float | None = None) -> None:
        """The progress bar of the views; `since`: the mission's start (perf_counter), from
        when a stopped flight is kept (fly_into)."""
        self.bar = _progress(total, enabled)
        self.flying_since = since

    def close_progress(self) -> None:
        if self.bar is not None:
            self.bar.close()

    def on_step(self, world, step) -> None:
        m = self.mission
        cfg = m.config
        cov = {}
        if cfg.evaluation.coverage_every and step.iteration % cfg.evaluation.coverage_every == 0:
            t0 = time.perf_counter()
            c = m.evaluator.coverage(world.clouds)["coverage"]
            cov = {float(k): v for k, v in c.items()}
            self.coverage_time_s += time.perf_counter() - t0
        p, c = world.state.pose, step.choice
        lap = m.planner.timers.lap()
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
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(
                f"{step.distance_m:.0f} m H={step.entropy_after:,.0f}"
                + (f" cov0.05={cov[0.05]:.1%}" if cov else "")
            )
        self._checkpoint()

    def _checkpoint(self) -> None:
        """Every config.checkpoint_minutes of the mission, what was flown so far put in place as
        its run folder (RunFolder.checkpoint) when fly_into flies it: a complete run whose
        summary says it is a checkpoint (`checkpoint`, `stopped_by`), for a kill to leave. A
        write error (a full disk) skips it, with a warning: the flight goes on."""
        flying, minutes = _CHECKPOINTS.get(), self.mission.config.checkpoint_minutes
        if flying is None or flying[0] is not self.mission or minutes <= 0:
            return
        now = time.perf_counter()
        if now - (self._last_checkpoint or self.flying_since) < 60.0 * minutes:
            return
        try:
            flying[1].checkpoint(lambda out: self._write_checkpoint(out, now - self.flying_since))
            self.checkpoints += 1
            self.checkpoint_iterations = len(self.records)
        except OSError as e:
            warnings.warn(f"checkpoint not saved, the flight goes on: {e}", RuntimeWarning)
        self._last_checkpoint = time.perf_counter()
        self.checkpoint_time_s += self._last_checkpoint - now

    def _write_checkpoint(self, out: Path, wall: float) -> None:
        summary = {
            **self.kept_flight("interrupted", CHECKPOINT_STOP, wall, True),
            "checkpoint": True,
        }
        self._write_flight(out)
        _write_summary(out, summary)

    def kept_flight(self, why: str, stopped_by: str, wall: float, checkpoint=False) -> dict:
        """The summary of a flight kept before it ended (`why`: its termination)."""
        s = self.summary(why, wall, checkpoint)
        return {**s, "stopped_by": stopped_by, "stopped_during": "flight"}

    def _end_curve(self, coverage: dict) -> None:
        """The last row's coverage columns (with evaluation.coverage_every): the run's own
        `coverage` (the summary's), where curves of coverage end (fewer views: they had none;
        a flight stopped on a leg: its frames since counted)."""
        last = self.records[-1] if self.records else None
        if last is not None and self.mission.config.evaluation.coverage_every:
            c = {float(k): float(v) for k, v in coverage.items()}
            last.coverage_005, last.coverage_01, last.coverage_05 = c[0.05], c[0.1], c[0.5]

    def stopped_flight(self, e: BaseException) -> dict:
        """kept_flight of a flight `e` (one of STOPS) stopped once its views started."""
        wall = time.perf_counter() - self.flying_since
        return self.kept_flight(stop_kind(e), error_line(e), wall)

    def summary(self, termination: str, wall: float, checkpoint: bool = False) -> dict:
        """The summary of the flight so far, ended by `termination` after `wall` s; the last row
        of iterations.csv then gets the run's coverage (_end_curve), but at a `checkpoint`."""
        m = self.mission
        cfg, world = m.config, m.world
        m.evaluator.forget_clouds()  # the progress refreshes' state: not needed from here
        _drop_memos(m.planner)
        _core.release_free_memory()  # the flight's freed heap, before the cloud is scored
        ev = m.evaluator(world.clouds)  # read in place: no stacked copy held while scoring
        n_it = len(self.records)
        if not checkpoint:
            self._end_curve(ev["coverage"])
        e_final = world.map.total_entropy()
        per_stage, final_plan_ms = _stage_times(m.planner.timers, n_it)
        tour = next((g for g in m.planner.generators if hasattr(g, "plans")), None)
        out = {
            "scenario": cfg.scenario,
            "start": cfg.start,
            "start_pose": [float(x) for x in world.start_pose],
            "mesh": world.mesh_path,
            "mesh_sha1": world.mesh_sha1,
            "profiling": cfg.profiling.enabled,
            "symmetry_prediction": cfg.symmetry.mode == "predict",
            "generators": list(cfg.planner.generators),
            "terminations": list(cfg.planner.terminations),
            "utility": cfg.utility.name,
            # generators whose views the utility only checks (valid, worth min_gain), not ranks
            "utility_only_checks": utility_only_checks(cfg),
            "sampling": cfg.lattice.method if "lattice" in cfg.planner.generators else None,
            "iterations": n_it,
            "views": world.state.views,
            # camera frames taken in flight: the profile's and those along the legs to views
            "camera_frames": sum(row[6] == "frame" for row in world.state.flight),
            # leg frames whose previews found less than planner.frame_novelty new (not taken)
            "frames_skipped": world.state.frames_skipped,
            "distance_m": world.state.distance_m,
            "entropy_initial": m.entropy_initial,
            "entropy_final": e_final,
            "entropy_reduction": m.entropy_initial - e_final,
            "entropy_unit": cfg.map.entropy_unit,
            "termination": termination,
            "termination_part": m.planner.ended_by,  # the termination whose reason it is, or null
            "stopped_by_budget": termination in BUDGET_REASONS,  # a budget, not coverage, ended it
            "max_views": m.max_views,
            "wall_time_s": wall,
            "ms_per_iteration": sum(per_stage.values()),
            "ms_per_stage": per_stage,
            "final_plan_ms": final_plan_ms,
            "coverage_refresh_s": self.coverage_time_s,
            # checkpoints of the run folder put in place while it flew, and the seconds they took
            "checkpoints": self.checkpoints,
            "checkpoint_s": self.checkpoint_time_s,
            # the process's peak resident memory (ru_maxrss), taken again as summary.json is written
            # (end-of-run outputs included); in a sweep worker, the largest of its runs
            "peak_memory_mb": _peak_mb(),
            "cloud_points": int(ev["n_points"]),
            "workspace": world.workspace.to_dict(),
            "c_view": m.planner.c_view,
            "seed": cfg.seed,
        }
        if termination in ("no_valid_viewpoint", "no_reachable_view"):  # why, by cause
            out["refused_views"] = _refusals(m.planner.selector, n_it)
        out.update(_gain_accounting(self.records))
        for k in SUMMARY_KEYS:
            out[k] = ev[k]
        if m.profile_summary is not None:
            out["profile"] = m.profile_summary
        if m.symmetry_summary is not None:
            out["symmetry"] = m.symmetry_summary
        if tour is not None:
            out["tours"] = tour.plans
        from .planning.registry import part_sources
        from .plugins import loaded_files

        if parts := part_sources(cfg):  # where the parts flown that are not nbvkit's came from
            out["parts_from"] = parts
            # every plugin file loaded, each one's SHA-256 (one file may hold another's code)
            if files := loaded_files():
                out["plugins"] = files
        return out

    def write(self, out: Path, summary: dict, finish: bool = False, cache_dir=None) -> dict:
        """Writes the run's files into the folder ``out``: config.yaml, iterations.csv,
        trajectory.csv, flight.csv, cloud.ply, map.ot, figures/*.png; with `finish` the
        end-of-run outputs (nbvkit.report.finish_run: observable surface, mesh.ply, report.html,
        whose figures join the summary); summary.json last, once. Returns the summary written.
        Any write error (a full disk) raises OSError. The end-of-run outputs stopped (Ctrl-C,
        a `kill`, an error) do not lose the flight: its files and a summary.json naming the
        cause (`stopped_by`, `stopped_during`) are written without them, then the exception is
        raised (write_keeping returns it instead)."""
        if self.mission.termination == "not_run":  # (an empty folder that looked complete)
            raise RuntimeError("save writes a flown mission: run() it first, or run(out_dir)")
        require_type(summary, dict, "summary", "the dict run() returned")
        finish = require_bool(finish, "finish")
        summary, stop = self.write_keeping(out, summary, finish, cache_dir)
        if stop is not None:
            raise stop
        return summary

    def write_keeping(
        self, out: Path, summary: dict, finish: bool = False, cache_dir=None
    ) -> tuple[dict, BaseException | None]:
        """write, returning (summary written, the exception that stopped the end-of-run
        outputs or None) rather than raising it. Ctrl-C (or a `kill`) while the flight's own
        files are written finishes them (once more, whole) without the end-of-run outputs;
        a second one, or one when the flight itself was stopped, drops them."""
        out = Path(out)
        try:
            self._write_flight(out)
        except KeyboardInterrupt as e:
            if "stopped_by" in summary:  # the flight's stop was the first Ctrl-C
                raise
            self._say("interrupted while saving", e, "finishing the flight's files")
            self._write_flight(out)
            return self._stopped(out, summary, e), e
        if not finish:
            return _write_summary(out, summary), None
        from .report import finish_run

        try:
            summary = finish_run(self.mission, out, summary, cache_dir=cache_dir)
        except STOPS as e:
            self._say(f"end-of-run outputs {stop_kind(e)}", e, "saving the flight without them")
            for name in FINISH_OUTPUTS:  # a part of them would read as all of them
                (out / name).unlink(missing_ok=True)
            return self._stopped(out, summary, e), e
        return _write_summary(out, summary), None

    def _write_flight(self, out: Path) -> None:
        """The flight's files, each whole (atomic): all but summary.json and the end-of-run
        outputs."""
        from .cloud import write_points
        from .plots import plot_mission

        m = self.mission
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out / "config.yaml", m.config.to_yaml())
        names = [f.name for f in fields(IterationRecord)]
        with atomic_open(out / "iterations.csv", newline="") as f:
            w = csv.writer(f)
            w.writerow(names)
            for r in self.records:
                w.writerow(["" if getattr(r, k) is None else getattr(r, k) for k in names])
        with atomic_open(out / "trajectory.csv", newline="") as f:
            w = csv.writer(f)
            w.writerow(["stage", "x", "y", "z", "yaw", "pitch", "distance_m"])
            w.writerows(m.world.state.trajectory)
        with atomic_open(out / "flight.csv", newline="") as f:  # every point flown (export)
            w = csv.writer(f)
            w.writerow(FLIGHT_COLUMNS)
            w.writerows(m.world.state.flight)
        write_points(out / "cloud.ply", m.world.clouds)  # streamed: no stacked copy
        m.world.map.save(str(out / "map.ot"))
        plot_mission(m, out / "figures")

    def _stopped(self, out: Path, summary: dict, e: BaseException) -> dict:
        """summary.json of a whole flight whose saving was stopped after it, by `e`."""
        return _write_summary(
            out, {**summary, "stopped_by": error_line(e), "stopped_during": "saving"}
        )

    def _say(self, what: str, e: BaseException, doing: str) -> None:
        """The console's word that `e` stopped `what` and nbvkit is `doing` (saving): the cause
        named unless it was a Ctrl-C, which alone makes a further one "again"."""
        if self.mission.config.progress:
            ctrl_c = type(e) is KeyboardInterrupt
            cause = "" if ctrl_c else f" ({error_line(e)})"
            again = "again " if ctrl_c else ""
            print(f"{what}{cause}: {doing} (Ctrl-C {again}drops it)", file=sys.stderr)


def _peak_mb() -> float:
    """The process's peak resident memory so far, MB (Linux ru_maxrss, KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _write_summary(out: Path, summary: dict) -> dict:
    """Write out/summary.json whole, its peak memory taken again as it is written (the end-of-run
    outputs, e.g. the observable surface: 0.6 GB more on a 100 m structure, and the flight's
    files come after the summary was made); returns what was written."""
    summary = {**summary, "peak_memory_mb": _peak_mb()}
    write_json_atomic(out / "summary.json", summary)
    return summary


# what finish_run writes beside the flight's files (its cache of the observable surface stays:
# a cache, valid whole or absent)
FINISH_OUTPUTS = ("mesh.ply", "figures/coverage.png", "report.html")


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


def fly_into(mission, folder: RunFolder, finish: bool = False) -> tuple[dict, BaseException | None]:
    """Flies `mission` and writes its results into the run folder being written, `folder`
    (Recorder.write into its temporary folder): (summary, None); its checkpoints are put in
    place as the mission flies (every config.checkpoint_minutes: Recorder._checkpoint). A
    flight stopped once its views started, by Ctrl-C, sys.exit() or an error (a part's), is not
    lost: what it flew is written (termination "interrupted" or "failed", `stopped_by` the
    cause, without the end-of-run outputs) and (summary, the exception) returned, for the caller
    to raise once the folder is in place (raise_stop); so is a whole flight whose saving was
    stopped (its end-of-run outputs: Recorder.write_keeping, `stopped_during` "saving").
    Stopped before the views (profile, symmetry), the exception propagates and nothing is
    written. TypeError for a `finish` not True or False, before any flight. A `kill` or a
    hang-up stops it as Ctrl-C does (interrupts.terminate_as_interrupt) where the signal has
    no handler of its own: from a script too (the command line's takes them already)."""
    finish = require_bool(finish, "finish")
    with terminate_as_interrupt(only_default=True):
        return _fly_into(mission, folder, finish)


def _fly_into(mission, folder: RunFolder, finish: bool) -> tuple[dict, BaseException | None]:
    out = Path(folder.tmp)
    token = _CHECKPOINTS.set((mission, folder))
    try:
        summary = mission._run()
    except STOPS as e:
        rec = mission.recorder  # this run's (a Mission run again makes a new one)
        if rec.flying_since is None:
            raise
        why = stop_kind(e)
        rec._say(why, e, "saving what was flown")
        folder.partial = True  # (beside a complete run an overwrite keeps)
        folder.saving(len(rec.records), rec.checkpoint_iterations)
        return rec.write(out, rec.stopped_flight(e)), e
    finally:
        _CHECKPOINTS.reset(token)
    # stopped during the end-of-run outputs, the whole flight is kept without them
    rec = mission.recorder
    folder.saving(len(rec.records), rec.checkpoint_iterations)
    summary, e = rec.write_keeping(out, summary, finish=finish)
    folder.partial = e is not None
    return summary, e


def raise_stop(summary: dict, stop: BaseException | None, folder: RunFolder | None = None):
    """fly_into's result: raises the exception that stopped the flight, if any, else returns the
    summary. With the run `folder`, once in place: the exception notes where what was flown is
    saved when that is not the target (RunFolder.placed: beside a complete run kept)."""
    if stop is not None:
        if folder is not None and folder.placed not in (None, folder.path):
            add_note(stop, f"what was flown is saved in {folder.placed} ({folder.path} kept)")
        raise stop
    return summary
