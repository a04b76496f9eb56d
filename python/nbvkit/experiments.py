"""Experiments: many missions (scenarios x starts x structures x parameter grids), run in
parallel, resumable, collected into one tidy table; and the paper's Table 2 from it.

Each run writes its own folder ``<out>/runs/<run id>/`` (the Mission results) atomically
(nbvkit.runfolder: into a temporary folder renamed into place once complete, ``manifest.json``
last, under a lock that two workers given the same run share by turns), so an interrupted sweep
restarted with the same arguments skips every run whose folder is complete and of the same
configuration, flies the others again, and loses no finished result. Runs execute in a
local process pool by default, or on a Dask distributed cluster given its scheduler address.

This module runs the specs (run_one, run_specs: the pools, Dask, Ctrl-C); what runs is
nbvkit.experiment_specs (RunSpec, sweep_specs, ...) and the tables are nbvkit.experiment_tables
(row_of, table2, compare_table, ...), both importable from here.
"""
from __future__ import annotations

import json
import operator
import os
import shutil
import time
from pathlib import Path

from .experiment_specs import (  # noqa: F401  (re-exported: what runs)
    MAX_SWEEP_RUNS,
    SWEEP_KEYS,
    RunSpec,
    _spec_dict,
    compare_specs,
    sweep_specs,
    table2_specs,
    validate_specs,
)
from .experiment_tables import (  # noqa: F401  (re-exported: the tables)
    COMPARE_COLUMNS,
    PAPER_SCENARIO5,
    TABLE2_ROWS,
    compare_markdown,
    compare_table,
    compare_with_paper,
    read_table,
    row_of,
    table2,
    table2_markdown,
    write_compare,
    write_results,
    write_table,
    write_table2,
)
from . import console
from .limits import add_note, check_input_file
from .plugins import (
    check_unchanged,
    error_line,
    flown_files,
    load_plugins,
    loaded_files,
    plugin_frame,
    script_only,
)
from .interrupts import terminate_as_interrupt

#: Poisson depth of each run's mesh.ply in experiments (table, sweep, compare) unless the
#: configuration sets report.poisson_depth: 7 costs about a third of the default 8
SWEEP_POISSON_DEPTH = 7


def run_one(spec: RunSpec, root: str | os.PathLike, threads: int = 0, plugins=()) -> dict:
    """Runs one spec into ``root/runs/<run_id>`` unless it is already there; returns its row.
    plugins: plugin files to load first (a worker process has not loaded them), as paths or as
    plugins.loaded_files() entries, whose content must then be the same (a file changed in the
    meantime is a ValueError: this run fails, naming it)."""
    load_plugins(plugins)
    try:
        with console.for_run(spec.run_id):
            return _run_one(spec, Path(root), threads)
    except Exception as e:
        _note_plugin_frame(e)  # the traceback does not cross to the parent process
        raise


def _note_plugin_frame(e: BaseException) -> None:
    """Notes on `e` where in a plugin file it was raised (plugins.error_line then names it in
    the failed run's record, in whichever process it is read)."""
    where = plugin_frame(e)
    if where is not None:
        add_note(e, where)


def _run_one(spec: RunSpec, root: Path, threads: int) -> dict:
    from ._core import set_num_threads
    from .mission import Mission
    from .runfolder import write_json_atomic as _write_json_atomic
    from .runfolder import RunFolder

    final = root / "runs" / spec.run_id
    cfg, mesh_sha1 = _resolved(spec)
    if (row := _kept_row(final, cfg, mesh_sha1)) is not None:
        return row
    # A kept folder that is incomplete, of another configuration or damaged is replaced whole;
    # another worker flying the same run holds its lock: wait for it, then reuse what it wrote.
    with RunFolder(final, overwrite=True, wait=True, carry=(), own=True) as folder:
        if _kept_row(final, cfg, mesh_sha1) is not None:
            folder.cancel()
        else:
            set_num_threads(threads)
            mission = Mission(cfg)
            failed = root / "failed" / spec.run_id
            try:
                summary = mission.run()
            except Exception as e:
                _keep_failed(mission, e, failed)
                raise
            # one observable-surface cache for the whole experiment: once per structure
            rec = mission.recorder
            summary, stop = rec.write_keeping(folder.tmp, summary, True, root / "cache")
            if stop is not None:  # the whole flight, its end-of-run outputs stopped
                if isinstance(stop, Exception):
                    _keep_failed(mission, stop, failed, summary)
                raise stop
            # the plugin files loaded (their content's SHA-256) where it flies a part of the
            # user's: none for nbvkit's own, which keep their spec.json (and resume) as before
            plugins = {"plugins": files} if (files := flown_files(cfg)) else {}
            _write_json_atomic(
                folder.tmp / "spec.json", {**_spec_dict(spec), "mesh_sha1": mesh_sha1, **plugins}
            )
    shutil.rmtree(root / "failed" / spec.run_id, ignore_errors=True)  # (an earlier failure's)
    return row_of(final)


def _keep_failed(mission, e: Exception, path: Path, summary: dict | None = None) -> None:
    """What a run that raised once its views started had flown, written to `path` (termination
    "failed", stopped_by the error, without the end-of-run outputs, as Mission.run(out_dir)
    keeps it; `summary`: the whole flight's, its end-of-run outputs stopped) and named in a note
    on `e`. Not in runs/: the next start flies the run again (and removes it once flown)."""
    from .runfolder import RunFolder

    rec = getattr(mission, "recorder", None)
    if rec is None or rec.flying_since is None:  # stopped before its views: nothing flown
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with RunFolder(path, overwrite=True, own=True) as folder:
            rec.write(folder.tmp, summary or rec.stopped_flight(e))
            path = folder.path
    except Exception as why:  # (a full disk): the run's own error is the one raised
        add_note(e, f"what was flown could not be saved in {path}: {why}")
        return
    add_note(e, f"what was flown is saved in {path}")


def _kept_row(run_dir: Path, cfg, mesh_sha1: str | None) -> dict | None:
    """The row of the finished run of this configuration kept at run_dir (_finished_with), or
    None: none, another, or one whose summary no longer reads (changed at its size since, which
    its manifest cannot tell): that one is flown again, not refused at every start."""
    if not _finished_with(run_dir, cfg, mesh_sha1):
        return None
    try:
        return row_of(run_dir)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _resolved(spec: RunSpec):
    """The configuration a spec runs with, and the SHA-1 of its mesh file (see _finished_with)."""
    from .config import _has_dotted

    cfg = spec.config()
    over = []
    if not _has_dotted(cfg._user, "report.poisson_depth"):
        # sweeps: a cheaper mesh per run (a look, not a result) unless the user set it
        over.append(f"report.poisson_depth={SWEEP_POISSON_DEPTH}")
    if cfg.mesh.up == "auto" and (up := spec.flown_mesh[2]) != "auto":
        over.append(f"mesh.up={up}")  # recorded as flown: the same run whichever is given
    cfg = cfg.with_overrides(over) if over else cfg
    return cfg, _mesh_digest(cfg)


def _finished_rows(specs: list[RunSpec], root: Path, rows: list) -> None:
    """Fills the rows still missing from the run folders already finished on disk: a worker can
    finish a run (its folder renamed into place) just before Ctrl-C reaches the parent, which
    has then not yet received its row."""
    for i, spec in enumerate(specs):
        final = root / "runs" / spec.run_id
        if rows[i] is None and final.is_dir():
            try:
                rows[i] = _kept_row(final, *_resolved(spec))
            except (OSError, ValueError, KeyError):
                pass  # unreadable: left for the next start to run again


def _finished_with(run_dir: Path, cfg, mesh_sha1: str | None) -> bool:
    """Whether run_dir holds a finished run of exactly this resolved configuration on the mesh
    file whose content has this SHA-1 (_mesh_digest), with the plugin files loaded in this
    process of the same content where it flies a part of the user's (plugins.flown_files; none
    for a run of nbvkit's own parts, which a changed plugin file leaves kept). The
    run id hashes the mesh flown (path, scale, up of the resolved configuration), the overrides
    and the config file's name, not the other defaults it resolves to, the config file's content,
    the mesh file's nor the plugin files': a run kept from before one of them changed is flown
    again."""
    from .runfolder import is_complete_run

    try:
        if not is_complete_run(run_dir):
            return False
        spec = json.loads((run_dir / "spec.json").read_text())
        return (
            (run_dir / "config.yaml").read_text() == cfg.to_yaml()
            and mesh_sha1 is not None
            and spec.get("mesh_sha1") == mesh_sha1
            and spec.get("plugins", []) == flown_files(cfg)
        )
    except (OSError, ValueError):
        return False


def _mesh_digest(cfg) -> str | None:
    """SHA-1 of the mesh file a configuration flies (the shipped airliner when mesh.path is
    None); None when it cannot be read (the mission then fails on it, naming the problem)."""
    from .mesh import default_mesh_path, mesh_file_sha1

    return mesh_file_sha1(cfg.mesh.path if cfg.mesh.path is not None else default_mesh_path())


class Interrupted(Exception):
    """Ctrl-C (or SIGTERM) during run_specs: the workers are stopped; ``rows`` holds the finished
    runs' rows (in spec order), ``total`` the number of specs."""

    def __init__(self, rows: list[dict], total: int):
        super().__init__(f"interrupted after {len(rows)} of {total} runs")
        self.rows = rows
        self.total = total


class RunsFailed(Exception):
    """Some runs of run_specs raised; every other run was flown to its end. ``rows`` holds the
    finished runs' rows (in spec order), ``failures`` a (run id, error) pair per failed run,
    ``total`` the number of specs. A failed run leaves no folder in runs/ (the next start flies
    it); what it flew, once its views started, is kept in failed/<run id> (termination "failed"),
    which its error's note names."""

    def __init__(self, rows: list[dict], failures: list[tuple[str, str]], total: int):
        first = f"{failures[0][0]}: {failures[0][1]}" if failures else ""
        super().__init__(f"{len(failures)} of {total} runs failed ({first})")
        self.rows = rows
        self.failures = failures
        self.total = total


def clean_stale_tmp(root: str | os.PathLike) -> int:
    """Removes the ``runs/.<id>.tmp<pid>`` folders (and failed/'s) left by runs that were killed
    (their process is gone); returns how many."""
    from .locks import lock_holder, pid_alive
    from .runfolder import run_name

    n = 0
    for d in [*(Path(root) / "runs").glob(".*.tmp*"), *(Path(root) / "failed").glob(".*.tmp*")]:
        pid = d.name.rsplit(".tmp", 1)[-1]
        if lock_holder(d.parent / run_name(d)) is not None:
            continue  # its run is being written (by a process this one cannot see, too)
        # (this process starts no run before cleaning: its own are stale too)
        if d.is_dir() and pid.isdigit() and not pid_alive(int(pid), os.getpid()):
            shutil.rmtree(d, ignore_errors=True)
            n += 1
    return n


def _worker_init(prog=None) -> None:
    """Pool workers print nbvkit's warnings as their command does (`prog`: console.install),
    leave Ctrl-C and a hang-up (sent to the terminal's whole process group) to
    the parent, which stops them, and die with the parent, should it be killed outright (Linux:
    the parent-death signal), instead of flying on unseen. (Each run loads the parent's plugin
    files first: run_one.)"""
    import signal

    console.install(prog)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        import ctypes
        import multiprocessing

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # not Linux: Ctrl-C and SIGTERM still stop the workers
        return
    parent = multiprocessing.parent_process()
    if parent is not None and os.getppid() != parent.pid:
        os._exit(1)  # the parent died while this worker was starting


def _unguarded_script_hint() -> str:
    """For a pool whose workers died: where the program is a script run by its path (`python
    my.py`), the likely cause, which Python's spawned workers print only on their own stderr."""
    import sys

    main = sys.modules.get("__main__")
    script = getattr(main, "__file__", None) if getattr(main, "__spec__", None) is None else None
    command = getattr(getattr(main, "main", None), "__module__", None) == f"{__package__}.cli"
    if not script or command:  # (the nbvkit command's script imports it, and is guarded)
        return ""
    return (
        f" (if {Path(script).name} calls nbvkit at its top level: each worker process imports the"
        ' script again, so put the calls under `if __name__ == "__main__":`)'
    )


def _worker_count(workers) -> int:
    """run_specs' `workers` as an int; ValueError unless it is a count >= 0."""
    try:
        n = None if isinstance(workers, bool) else operator.index(workers)
    except TypeError:
        n = None
    if n is None or n < 0:
        raise ValueError(
            f"workers must be a count >= 0 (0: one per core, 1: in this process), got {workers!r}"
        )
    return n


def run_specs(
    specs: list[RunSpec],
    root: str | os.PathLike,
    workers: int = 0,
    scheduler: str | None = None,
    progress: bool = True,
) -> list[dict]:
    """Runs every spec (skipping finished ones) and returns their rows, in spec order.

    workers: local processes (0: one per core, 1: in this process); scheduler: the address of a
    Dask distributed scheduler ("tcp://host:8786") to run on that cluster instead.
    """
    workers = _worker_count(workers)
    root = Path(root)
    if scheduler or not (workers == 1 or len(specs) <= 1):
        refuse_script_parts(specs)
    check_unchanged()  # a plugin file edited since it was loaded: load it again first
    if not scheduler:  # (a cluster's workers may hold files this machine does not)
        for path in {sp.flown_mesh[0] for sp in specs} - {None}:
            check_input_file(path, "mesh file")  # before any run: each would fail on it
    (root / "runs").mkdir(parents=True, exist_ok=True)
    clean_stale_tmp(root)
    rows: list = [None] * len(specs)
    failures: list = [None] * len(specs)  # per spec: the error of a run that raised
    try:
        with terminate_as_interrupt():
            _run_all(specs, root, workers, scheduler, progress, rows, failures)
    except KeyboardInterrupt:
        _finished_rows(specs, root, rows)
        raise Interrupted([r for r in rows if r is not None], len(specs)) from None
    failed = [(s.run_id, f) for s, f in zip(specs, failures) if f is not None]
    if failed:
        raise RunsFailed([r for r in rows if r is not None], failed, len(specs))
    return rows


def refuse_script_parts(specs: list[RunSpec]) -> None:
    """ValueError when a spec names a scenario or part (its scenario, planner.generators,
    planner.terminations, utility.name, a section it sets) registered in this process by no
    plugin file: worker processes know only nbvkit's and the plugin files' (each run would fail
    there, naming the scenario or key but not why)."""
    names = script_only()
    if not names:
        return
    for key in {(s.scenario, tuple(s.overrides), s.config_file) for s in specs}:
        used = [key[0]] if key[0] in names else []
        if not used:
            try:
                cfg = RunSpec(key[0], 0, overrides=key[1], config_file=key[2]).config()
            except (ValueError, KeyError, OSError):
                continue  # refused where it runs, naming the problem
            p = cfg.planner
            used = [n for n in (*p.generators, *p.terminations, cfg.utility.name, *cfg._user)
                    if n in names]  # fmt: skip
        if used:
            n = used[0]
            raise ValueError(
                f"the {names[n]} {n!r} was registered in this process, not by a plugin file: the "
                "worker processes cannot know it, and every run naming it would fail there. Put "
                "it in a file and load it with nbvkit.load_plugin(path) (nbvkit compare / sweep: "
                "--plugin FILE), or run with workers=1 (in this process)"
            )


def _progress(k: int, total: int, run_id: str, outcome: str) -> None:
    print(f"[{k}/{total}] {run_id}: {outcome}", flush=True)


def _run_all(specs, root, workers, scheduler, progress, rows, failures) -> None:
    """Fills rows (and failures: the error of each run that raised; the others go on) in place:
    on a Dask cluster, in this process, or in local processes."""
    if scheduler:
        from distributed import Client, wait

        with Client(scheduler) as client:
            files = loaded_files()
            futs = client.map(
                run_one, specs, root=str(root.resolve()), threads=1, plugins=files, pure=False
            )
            stop = None
            try:
                wait(futs)
            except KeyboardInterrupt as e:
                stop = e
            for i, f in enumerate(futs):
                if f.status == "finished":
                    rows[i] = f.result()
                elif stop is not None:
                    continue  # stopped: cancelled below
                elif f.status == "error":
                    failures[i] = error_line(f.exception())
                else:  # cancelled or lost by the cluster
                    failures[i] = f"the cluster did not finish it ({f.status})"
            if stop is not None:
                client.cancel(futs)
                raise stop
    elif workers == 1 or len(specs) <= 1:
        for i, s in enumerate(specs):
            t0 = time.perf_counter()
            try:
                rows[i] = run_one(s, root)
            except Exception as e:  # noqa: BLE001 (a run's own error: the others are flown)
                failures[i] = error_line(e)
            if progress:
                done = f"{time.perf_counter() - t0:.1f} s"
                _progress(i + 1, len(specs), s.run_id, done if rows[i] else failures[i])
    else:
        ncpu = os.cpu_count() or 1
        _run_pool(specs, root, min(workers or ncpu, len(specs)), ncpu, rows, failures, progress)


def _start_resource_tracker() -> None:
    """Starts multiprocessing's resource tracker (the pool's locks would) with a hang-up blocked:
    it ignores Ctrl-C and a kill itself, but SIGHUP (a closed terminal, sent to the whole process
    group) killed it, and the tracker started again in its place failed with a traceback."""
    import signal
    from multiprocessing import resource_tracker

    hup = {signal.SIGHUP} if hasattr(signal, "SIGHUP") else set()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, hup)  # the child inherits the mask
    try:
        resource_tracker.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)  # one that came meanwhile arrives now


def _run_pool(specs, root, n, ncpu, rows, failures, progress) -> None:
    """Runs specs in n spawned processes, filling rows (and failures: a run that raised leaves its
    error there, the others are flown); on Ctrl-C the queued runs are cancelled and the running
    ones killed (their temporary folders are removed on the next start)."""
    import concurrent.futures as cf
    import multiprocessing as mp

    threads = max(1, ncpu // n)
    files = loaded_files()
    _start_resource_tracker()
    ex = cf.ProcessPoolExecutor(
        n,
        mp_context=mp.get_context("spawn"),
        initializer=_worker_init,
        initargs=(console.current_prog(),),
    )
    try:
        futs = {ex.submit(run_one, s, root, threads, files): i for i, s in enumerate(specs)}
        for k, f in enumerate(cf.as_completed(futs)):
            i = futs[f]
            try:
                rows[i] = f.result()
            except cf.process.BrokenProcessPool as e:  # its worker died, or never started
                started = any(r is not None for r in rows)  # (then the pool's workers did)
                failures[i] = error_line(e) + ("" if started else _unguarded_script_hint())
            except Exception as e:  # noqa: BLE001 (a run's own error)
                failures[i] = error_line(e)
            if progress:
                done = f"{rows[i]['wall_time_s']:.1f} s" if rows[i] else failures[i]
                _progress(k + 1, len(specs), specs[i].run_id, done)
    except KeyboardInterrupt:
        # the workers and the pool's manager thread, taken before shutdown forgets them
        procs = list((getattr(ex, "_processes", None) or {}).values())
        manager = getattr(ex, "_executor_manager_thread", None)
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            p.terminate()
        for p in procs:
            p.join(5)
        # Let the manager thread see the dead workers and close its wake-up pipe now: at exit,
        # Python 3.11 wakes it without a lock and may write to the pipe as it closes ("Bad file
        # descriptor" printed after the sweep's last word).
        if manager is not None:
            manager.join(10)
        raise
    ex.shutdown(wait=True)
