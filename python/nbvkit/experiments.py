"""Experiments: many missions (scenarios x starts x structures x parameter grids), run in
parallel, resumable, collected into one tidy table; and the paper's Table 2 from it.

Each run writes its own folder ``<out>/runs/<run id>/`` (the Mission results) atomically
(nbvkit.runfolder: into a temporary folder renamed into place once complete, ``manifest.json``
last, under a lock that two workers given the same run share by turns), so an interrupted sweep
restarted with the same arguments skips every run whose folder is complete and of the same
configuration, flies the others again, and loses no finished result. Runs execute in a
local process pool by default, or on a Dask distributed cluster given its scheduler address.
"""
from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import math
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .limits import shorten

#: the paper's Table 2 rows: label, profiling, symmetry, sampling
TABLE2_ROWS = [
    ("Profile", "yes", "no", "-"),
    ("1", "no", "no", "CGVS"),
    ("2", "yes", "no", "CGVS"),
    ("3", "yes", "no", "AGVS"),
    ("4", "yes", "yes", "CGVS"),
    ("5", "yes", "yes", "AGVS"),
]


#: Poisson depth of each run's mesh.ply in experiments (table, sweep, compare) unless the
#: configuration sets report.poisson_depth: 7 costs about a third of the default 8
SWEEP_POISSON_DEPTH = 7


@dataclass(frozen=True)
class RunSpec:
    """One mission: a scenario from a start on a structure, with config overrides."""

    scenario: str
    start: int
    mesh: str | None = None  # None: the shipped airliner
    mesh_scale: float = 1.0
    mesh_up: str = "z"
    overrides: tuple = ()  # ("key=value", ...)
    config_file: str | None = None
    labels: tuple = field(default=())  # (("name", value), ...) extra columns for the tidy table

    @property
    def run_id(self) -> str:
        name = Path(self.mesh).stem if self.mesh else "airliner"
        h = hashlib.sha1(
            json.dumps(
                [self.mesh, self.mesh_scale, self.mesh_up, list(self.overrides), self.config_file]
            ).encode()
        ).hexdigest()[:8]
        return f"{name}_s{self.scenario}_start{self.start}_{h}"

    def config(self):
        from .config import load_config

        over = [
            *self.overrides,
            f"scenario={json.dumps(self.scenario)}",
            f"start={self.start}",
            f"mesh.scale={self.mesh_scale}",
            f"mesh.up={self.mesh_up}",
            "progress=false",
        ]
        if self.mesh:
            over.append(f"mesh.path={json.dumps(str(self.mesh))}")
        return load_config(self.config_file, over)


def run_one(spec: RunSpec, root: str | os.PathLike, threads: int = 0, plugins=()) -> dict:
    """Runs one spec into ``root/runs/<run_id>`` unless it is already there; returns its row.
    plugins: plugin files to load first (a Dask worker's process has not loaded them)."""
    from . import set_num_threads
    from .mission import Mission
    from .plugins import load_plugins

    load_plugins(plugins)

    from .runfolder import write_json_atomic as _write_json_atomic
    from .runfolder import RunFolder

    root = Path(root)
    final = root / "runs" / spec.run_id
    cfg, mesh_sha1 = _resolved(spec)
    if _finished_with(final, cfg, mesh_sha1):
        return row_of(final)
    # A kept folder that is incomplete or of another configuration is replaced whole; another
    # worker flying the same run holds its lock: wait for it, then reuse what it wrote.
    with RunFolder(final, overwrite=True, wait=True, carry=()) as folder:
        if _finished_with(final, cfg, mesh_sha1):
            folder.cancel()
        else:
            set_num_threads(threads)
            mission = Mission(cfg)
            # one observable-surface cache for the whole experiment: once per structure
            mission.save(folder.tmp, mission.run(), finish=True, cache_dir=root / "cache")
            _write_json_atomic(
                folder.tmp / "spec.json", {**_spec_dict(spec), "mesh_sha1": mesh_sha1}
            )
    return row_of(final)


def _resolved(spec: RunSpec):
    """The configuration a spec runs with, and the SHA-1 of its mesh file (see _finished_with)."""
    from .config import _has_dotted

    cfg = spec.config()
    if not _has_dotted(cfg._user, "report.poisson_depth"):
        # sweeps: a cheaper mesh per run (a look, not a result) unless the user set it
        cfg = cfg.with_overrides([f"report.poisson_depth={SWEEP_POISSON_DEPTH}"])
    return cfg, _mesh_digest(cfg)


def _finished_rows(specs: list[RunSpec], root: Path, rows: list) -> None:
    """Fills the rows still missing from the run folders already finished on disk: a worker can
    finish a run (its folder renamed into place) just before Ctrl-C reaches the parent, which
    has then not yet received its row."""
    for i, spec in enumerate(specs):
        final = root / "runs" / spec.run_id
        if rows[i] is None and final.is_dir():
            try:
                if _finished_with(final, *_resolved(spec)):
                    rows[i] = row_of(final)
            except (OSError, ValueError, KeyError):
                pass  # unreadable: left for the next start to run again


def _finished_with(run_dir: Path, cfg, mesh_sha1: str | None) -> bool:
    """Whether run_dir holds a finished run of exactly this resolved configuration on the mesh
    file whose content has this SHA-1 (_mesh_digest). The run id hashes the spec (mesh path,
    overrides, config file name), not the defaults it resolves to, the config file's content nor
    the mesh's: a run kept from before one of them changed is flown again."""
    from .runfolder import is_complete_run

    try:
        return (
            is_complete_run(run_dir)
            and (run_dir / "config.yaml").read_text() == cfg.to_yaml()
            and mesh_sha1 is not None
            and json.loads((run_dir / "spec.json").read_text()).get("mesh_sha1") == mesh_sha1
        )
    except (OSError, ValueError):
        return False


def _mesh_digest(cfg) -> str | None:
    """SHA-1 of the mesh file a configuration flies (the shipped airliner when mesh.path is
    None); None when it cannot be read (the mission then fails on it, naming the problem)."""
    from .mesh import default_mesh_path

    from .limits import check_input_file

    path = cfg.mesh.path if cfg.mesh.path is not None else default_mesh_path()
    try:
        path = check_input_file(path, "mesh file")  # a FIFO would block open() forever
        with open(path, "rb") as f:
            return hashlib.file_digest(f, "sha1").hexdigest()
    except (OSError, ValueError):
        return None


class Interrupted(Exception):
    """Ctrl-C (or SIGTERM) during run_specs: the workers are stopped; ``rows`` holds the finished
    runs' rows (in spec order), ``total`` the number of specs."""

    def __init__(self, rows: list[dict], total: int):
        super().__init__(f"interrupted after {len(rows)} of {total} runs")
        self.rows = rows
        self.total = total


def clean_stale_tmp(root: str | os.PathLike) -> int:
    """Removes ``runs/.<id>.tmp<pid>`` folders left by runs that were killed (their process is
    gone); returns how many."""
    from .runfolder import _lock_holder, run_name

    n = 0
    for d in (Path(root) / "runs").glob(".*.tmp*"):
        pid = d.name.rsplit(".tmp", 1)[-1]
        if _lock_holder(d.parent / run_name(d)) is not None:
            continue  # its run is being written (by a process this one cannot see, too)
        if d.is_dir() and pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(d, ignore_errors=True)
            n += 1
    return n


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return False  # this process starts no run before cleaning
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _worker_init(plugins=()) -> None:
    """Pool workers load the parent's plugin files (their parts and sections); leave Ctrl-C to
    the parent, which stops them; and die with the parent, should it be killed outright (Linux:
    the parent-death signal), instead of flying on unseen."""
    import signal

    from .plugins import load_plugins

    load_plugins(plugins)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
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


@contextlib.contextmanager
def _terminate_as_interrupt():
    """While runs are flying, a `kill` (SIGTERM) stops them as Ctrl-C does: workers stopped,
    finished runs kept, the partial table written. (Main thread only: signals go there.)"""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _spec_dict(spec: RunSpec) -> dict:
    return {
        "scenario": spec.scenario,
        "start": spec.start,
        "mesh": spec.mesh,
        "mesh_scale": spec.mesh_scale,
        "mesh_up": spec.mesh_up,
        "overrides": list(spec.overrides),
        "config_file": spec.config_file,
        "labels": [list(x) for x in spec.labels],
    }


def row_of(run_dir: Path) -> dict:
    """One tidy row from a finished run folder."""
    s = json.loads((run_dir / "summary.json").read_text())
    spec = (
        json.loads((run_dir / "spec.json").read_text()) if (run_dir / "spec.json").exists() else {}
    )
    row = {
        "run_id": run_dir.name,
        "scenario": s["scenario"],
        "start": s["start"],
        "mesh": spec.get("mesh") or "airliner",
        "overrides": " ".join(spec.get("overrides", [])),
        "iterations": s["iterations"],
        "views": s.get("views", s["iterations"]),
        "distance_m": s["distance_m"],
        "entropy_reduction": s["entropy_reduction"],
        "termination": s["termination"],
        "wall_time_s": s["wall_time_s"],
        "ms_per_iteration": s["ms_per_iteration"],
        "cloud_points": s["cloud_points"],
        "chamfer_m": s["chamfer_m"],
    }
    for k in ("coverage", "area_coverage", "precision"):
        for r, v in s[k].items():
            row[f"{k}_{r}"] = v
    for k in ("completeness", "accuracy", "fscore"):
        for r, v in s[k].items():
            row[f"{k}_{r}"] = v
    for k in ("coverage_observable", "area_coverage_observable", "observable_fraction"):
        for r, v in s.get(k, {}).items():
            row[f"{k}_{r}"] = v
    m = s.get("reconstructed_mesh") or {}
    if m.get("written"):
        row["mesh_hausdorff95_m"] = m["hausdorff95_m"]
        for t, v in m["mesh_completeness"].items():
            row[f"mesh_completeness_{t}"] = v
    p = s.get("profile")
    if p:
        row["profile_distance_m"] = p["distance_m"]
        row["profile_entropy_reduction"] = p["entropy_reduction"]
        for r, v in p["coverage"].items():
            row[f"profile_coverage_{r}"] = v
    sym = s.get("symmetry")
    if sym:
        row["symmetry_accepted"] = sym.get("accepted")
        row["symmetry_confidence"] = sym.get("confidence")
    for name, value in spec.get("labels", []):
        row[name] = value
    return row


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
    root = Path(root)
    (root / "runs").mkdir(parents=True, exist_ok=True)
    clean_stale_tmp(root)
    rows: list = [None] * len(specs)
    try:
        with _terminate_as_interrupt():
            _run_all(specs, root, workers, scheduler, progress, rows)
    except KeyboardInterrupt:
        _finished_rows(specs, root, rows)
        raise Interrupted([r for r in rows if r is not None], len(specs)) from None
    return rows


def _run_all(specs, root, workers, scheduler, progress, rows) -> None:
    """Fills rows in place: on a Dask cluster, in this process, or in local processes."""
    if scheduler:
        from distributed import Client

        with Client(scheduler) as client:
            from .plugins import loaded

            futs = client.map(
                run_one, specs, root=str(root.resolve()), threads=1, plugins=loaded(), pure=False
            )
            try:
                rows[:] = client.gather(futs)
            except KeyboardInterrupt:
                for i, f in enumerate(futs):
                    if f.status == "finished":
                        rows[i] = f.result()
                client.cancel(futs)
                raise
    elif workers == 1 or len(specs) <= 1:
        for i, s in enumerate(specs):
            t0 = time.perf_counter()
            rows[i] = run_one(s, root)
            if progress:
                print(
                    f"[{i + 1}/{len(specs)}] {s.run_id}: {time.perf_counter() - t0:.1f} s",
                    flush=True,
                )
    else:
        ncpu = os.cpu_count() or 1
        _run_pool(specs, root, min(workers or ncpu, len(specs)), ncpu, rows, progress)


def _run_pool(specs, root, n, ncpu, rows, progress) -> None:
    """Runs specs in n spawned processes, filling rows; on Ctrl-C the queued runs are cancelled
    and the running ones killed (their temporary folders are removed on the next start)."""
    import concurrent.futures as cf
    import multiprocessing as mp

    threads = max(1, ncpu // n)
    from .plugins import loaded

    ex = cf.ProcessPoolExecutor(
        n, mp_context=mp.get_context("spawn"), initializer=_worker_init, initargs=(loaded(),)
    )
    try:
        futs = {ex.submit(run_one, s, root, threads): i for i, s in enumerate(specs)}
        for k, f in enumerate(cf.as_completed(futs)):
            rows[futs[f]] = f.result()
            if progress:
                print(
                    f"[{k + 1}/{len(specs)}] {rows[futs[f]]['run_id']}: "
                    f"{rows[futs[f]]['wall_time_s']:.1f} s",
                    flush=True,
                )
    except KeyboardInterrupt:
        procs = list((getattr(ex, "_processes", None) or {}).values())
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            p.terminate()
        for p in procs:
            p.join(5)
        raise
    ex.shutdown(wait=True)


def write_table(rows: list[dict], path: str | os.PathLike) -> None:
    """Writes rows as a CSV (the tidy table every plotting helper reads)."""
    import pandas as pd

    pd.DataFrame(rows).to_csv(path, index=False)


def read_table(path: str | os.PathLike):
    import pandas as pd

    return pd.read_csv(path)


# ------------------------------------------------------------------ Table 2


def table2_specs(mesh=None, mesh_scale=1.0, mesh_up="z", starts=5, overrides=()) -> list[RunSpec]:
    """The Profile row and Scenarios 1-5, each from `starts` predefined starts."""
    return [
        RunSpec(sc, k, mesh, mesh_scale, mesh_up, tuple(overrides))
        for sc in ("profile", "1", "2", "3", "4", "5")
        for k in range(starts)
    ]


def table2(df):
    """The paper's Table 2 from a tidy table of runs: means over starts, with the spread (std)."""
    import pandas as pd

    out = []
    for label, prof, sym, samp in TABLE2_ROWS:
        sub = (
            df[df["scenario"].astype(str) == label.lower()]
            if label == "Profile"
            else df[df["scenario"].astype(str) == label]
        )
        if label == "Profile" and len(sub):
            cols = {
                "distance_m": "profile_distance_m",
                "entropy_reduction": "profile_entropy_reduction",
                "coverage_0.05": "profile_coverage_0.05",
                "coverage_0.1": "profile_coverage_0.1",
                "coverage_0.5": "profile_coverage_0.5",
            }
            sub = sub.assign(**{k: sub[v] for k, v in cols.items()}, iterations=np.nan)
        if not len(sub):
            continue
        r = {
            "Scenario": label,
            "Profiling": prof,
            "Symmetry": sym,
            "Sampling": samp,
            "runs": len(sub),
        }
        for col, name in (
            ("iterations", "Iterations"),
            ("distance_m", "Distance (m)"),
            ("entropy_reduction", "Entropy reduction"),
            ("coverage_0.05", "Coverage @0.05 m"),
            ("coverage_0.1", "Coverage @0.10 m"),
            ("coverage_0.5", "Coverage @0.50 m"),
            ("area_coverage_0.05", "Area cov. @0.05 m"),
            ("wall_time_s", "Wall time (s)"),
            ("ms_per_iteration", "ms/iteration"),
        ):
            v = pd.to_numeric(sub[col], errors="coerce") if col in sub else pd.Series(dtype=float)
            r[name] = v.mean() if v.notna().any() else np.nan
            r[name + " sd"] = v.std(ddof=0) if v.notna().sum() > 1 else 0.0
        out.append(r)
    return pd.DataFrame(out)


def table2_markdown(t) -> str:
    """Table 2 as Markdown, mean ± spread over the starts."""

    def fmt(name, v, sd):
        if v != v:  # NaN
            return "—"
        if name.startswith("Coverage") or name.startswith("Area"):
            return f"{v:.1%} ± {sd:.1%}".replace("%", " %")
        if name in ("Iterations",):
            return f"{v:.0f} ± {sd:.0f}"
        if name == "Entropy reduction":
            return f"{v:,.0f} ± {sd:,.0f}"
        return f"{v:,.1f} ± {sd:,.1f}"

    cols = [
        "Iterations",
        "Distance (m)",
        "Entropy reduction",
        "Coverage @0.05 m",
        "Coverage @0.10 m",
        "Coverage @0.50 m",
        "Area cov. @0.05 m",
        "Wall time (s)",
        "ms/iteration",
    ]
    head = ["Scenario", "Profiling", "Symmetry", "Sampling", *cols, "runs"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in t.iterrows():
        cells = [str(r["Scenario"]), r["Profiling"], r["Symmetry"], r["Sampling"]]
        cells += [fmt(c, r[c], r[c + " sd"]) for c in cols] + [str(int(r["runs"]))]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_table2(df, out: Path) -> None:
    t = table2(df)
    t.to_csv(out / "table2.csv", index=False)
    (out / "table2.md").write_text(table2_markdown(t))


# ------------------------------------------------------------------ sweeps


#: Runs one sweep file may describe (meshes x scenarios x starts x grid values).
MAX_SWEEP_RUNS = 100_000


def sweep_specs(sweep: dict) -> list[RunSpec]:
    """Specs of a sweep description (see `nbvkit sweep --help`): meshes x scenarios x starts x
    every combination of the grid's values, with the fixed overrides in `set`."""
    known = {
        "meshes",
        "scenarios",
        "starts",
        "grid",
        "set",
        "config",
        "out",
        "workers",
        "scheduler",
    }
    unknown = set(sweep) - known
    if unknown:
        raise KeyError(f"unknown sweep key(s) {sorted(unknown)}; known: {sorted(known)}")
    meshes = sweep.get("meshes") or [None]
    if not isinstance(meshes, list):
        raise ValueError(
            f"sweep 'meshes' must be a list of paths or mappings, got {shorten(meshes)}"
        )
    for m in meshes:
        if isinstance(m, dict):
            bad = set(m) - {"path", "scale", "up"}
            if bad:
                raise KeyError(
                    f"unknown key(s) {sorted(bad)} in sweep mesh entry {shorten(m)}; "
                    "known: ['path', 'scale', 'up']"
                )
            scale = m.get("scale", 1.0)
            if isinstance(scale, bool) or not isinstance(scale, (int, float)):
                raise ValueError(f"sweep mesh entry {shorten(m)}: 'scale' must be a number")
        elif m is not None and not isinstance(m, str):
            raise ValueError(f"sweep mesh entry {shorten(m)} must be a path, a mapping or null")
    scenarios = sweep.get("scenarios", ["5"])
    if not isinstance(scenarios, list):
        raise ValueError(
            f'sweep \'scenarios\' must be a list (e.g. ["1", "5"]), got {shorten(scenarios)}'
        )
    scenarios = [str(s) for s in scenarios]
    starts = sweep.get("starts", [0])
    if isinstance(starts, int) and not isinstance(starts, bool):
        if not 0 <= starts <= 5:
            raise ValueError(f"sweep 'starts' count must be 0..5 (five predefined starts), "
                             f"got {shorten(starts)}")  # fmt: skip
        starts = list(range(starts))
    if not isinstance(starts, list) or not all(
        isinstance(s, int) and not isinstance(s, bool) for s in starts
    ):
        raise ValueError(
            f"sweep 'starts' must be a count or a list of start indices, got {shorten(starts)}"
        )
    grid = sweep.get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(v, list) for v in grid.values()):
        raise ValueError("sweep 'grid' must map config keys to lists of values")
    fixed_set = sweep.get("set") or {}
    if not isinstance(fixed_set, dict):
        raise ValueError(
            f"sweep 'set' must map config keys to values (e.g. {{max_iterations: 200}}), "
            f"got {shorten(fixed_set)}"
        )
    fixed = [f"{k}={json.dumps(v)}" for k, v in fixed_set.items()]
    keys = list(grid)
    runs = len(meshes) * len(scenarios) * len(starts) * math.prod(len(grid[k]) for k in keys)
    if runs > MAX_SWEEP_RUNS:
        raise ValueError(
            f"the sweep makes {runs:,} runs (meshes x scenarios x starts x grid values), more "
            f"than the limit {MAX_SWEEP_RUNS:,}; split it into smaller sweeps"
        )
    specs = []
    for mesh in meshes:
        m = mesh if isinstance(mesh, dict) else {"path": mesh}
        for combo in itertools.product(*[grid[k] for k in keys]):
            over = fixed + [f"{k}={json.dumps(v)}" for k, v in zip(keys, combo)]
            labels = tuple((k, v) for k, v in zip(keys, combo))
            for sc in scenarios:
                for st in starts:
                    specs.append(
                        RunSpec(
                            sc,
                            int(st),
                            m.get("path"),
                            float(m.get("scale", 1.0)),
                            m.get("up", "z"),
                            tuple(over),
                            sweep.get("config"),
                            labels,
                        )
                    )
    validate_specs(specs)
    return specs


def validate_specs(specs: list[RunSpec]) -> None:
    """Builds each distinct configuration once, so that a bad key or value fails before any run."""
    for s in {(sp.mesh, sp.overrides, sp.config_file) for sp in specs}:
        RunSpec("1", 0, s[0], overrides=s[1], config_file=s[2]).config()


def compare_with_paper(t, paper_csv) -> str:
    """Markdown: our Table 2 (means over starts) beside the paper's (its table2.csv layout)."""
    import pandas as pd

    paper = pd.read_csv(paper_csv, dtype={"scenario": str})
    lines = [
        "| Scenario | Iterations (ours / paper) | Distance m | Entropy reduction "
        "| Coverage @0.05 m | "
        "Coverage @0.10 m | Coverage @0.50 m |",
        "|---|---|---|---|---|---|---|",
    ]
    for _, r in t.iterrows():
        p = paper[paper["scenario"].astype(str) == str(r["Scenario"])]
        if not len(p):
            continue
        p = p.iloc[0]

        def pair(ours, theirs, kind):
            if kind == "pct":
                return f"{ours:.1%} / {theirs:.1%}".replace("%", " %")
            if kind == "int":
                return (
                    ("—" if ours != ours else f"{ours:,.0f}")
                    + " / "
                    + ("—" if theirs != theirs else f"{theirs:,.0f}")
                )
            return f"{ours:,.1f} / {theirs:,.1f}"

        lines.append(
            "| "
            + " | ".join(
                [
                    str(r["Scenario"]),
                    pair(r["Iterations"], p["iterations"], "int"),
                    pair(r["Distance (m)"], p["distance_m"], "num"),
                    pair(r["Entropy reduction"], p["entropy_reduction"], "int"),
                    pair(r["Coverage @0.05 m"], p["coverage_0.05"], "pct"),
                    pair(r["Coverage @0.10 m"], p["coverage_0.10"], "pct"),
                    pair(r["Coverage @0.50 m"], p["coverage_0.50"], "pct"),
                ]
            )
            + " |"
        )
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ planner comparisons

#: The paper's full method (Scenario 5) as its Table 2 reports it: mean over five starts on its
#: aircraft (coverage against its sparse reference cloud; see docs/RESULTS.md).
PAPER_SCENARIO5 = {"distance_m": 665.2, "coverage_0.05": 0.865, "iterations": 257}


def compare_specs(planners, mesh=None, mesh_scale=1.0, mesh_up="z", starts=5, overrides=()):
    """Every planner (scenario name) from `starts` predefined starts, with the same overrides.
    Progress coverage is sampled every 5 views (the coverage-vs-distance figure)."""
    from .scenarios import SCENARIOS

    for p in planners:
        if p not in SCENARIOS:
            raise ValueError(f"unknown planner {p!r}; known: {', '.join(SCENARIOS)}")
    over = ("evaluation.coverage_every=5", *overrides)
    return [
        RunSpec(p, k, mesh, mesh_scale, mesh_up, tuple(over))
        for p in planners
        for k in range(starts)
    ]


#: (column of the run table, heading) of the comparison table, in order.
COMPARE_COLUMNS = (
    ("coverage_0.05", "Coverage @0.05 m"),
    ("coverage_0.1", "Coverage @0.10 m"),
    ("coverage_0.5", "Coverage @0.50 m"),
    ("area_coverage_0.05", "Area cov. @0.05 m"),
    ("area_coverage_0.1", "Area cov. @0.10 m"),
    # the same, of the surface a camera flown through the navigation space could see
    ("area_coverage_observable_0.05", "Observable area cov. @0.05 m"),
    ("distance_m", "Distance (m)"),
    ("views", "Views"),
    ("wall_time_s", "Wall time (s)"),
)


def compare_table(df):
    """Per planner (in first-seen order): the mean and spread (std) over starts of each of
    COMPARE_COLUMNS, and the number of runs."""
    import pandas as pd

    out = []
    for planner in dict.fromkeys(df["scenario"].astype(str)):
        sub = df[df["scenario"].astype(str) == planner]
        r = {"Planner": planner, "runs": len(sub)}
        for col, name in COMPARE_COLUMNS:
            v = pd.to_numeric(sub[col], errors="coerce") if col in sub else pd.Series(dtype=float)
            r[name] = v.mean() if v.notna().any() else np.nan
            r[name + " sd"] = v.std(ddof=0) if v.notna().sum() > 1 else 0.0
        out.append(r)
    return pd.DataFrame(out)


def compare_markdown(t) -> str:
    def fmt(name, v, sd):
        if v != v:
            return "—"
        if "cov" in name.lower():
            return f"{v:.1%} ± {sd:.1%}".replace("%", " %")
        if name == "Views":
            return f"{v:.0f} ± {sd:.0f}"
        return f"{v:,.1f} ± {sd:,.1f}"

    names = [n for _, n in COMPARE_COLUMNS]
    lines = ["| Planner | " + " | ".join(names) + " | runs |", "|" + "---|" * (len(names) + 2)]
    for _, r in t.iterrows():
        cells = [fmt(n, r[n], r[n + " sd"]) for n in names]
        lines.append(f"| {r['Planner']} | " + " | ".join(cells) + f" | {int(r['runs'])} |")
    return "\n".join(lines) + "\n"
