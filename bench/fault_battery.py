"""Fault battery (issue 36): kills, full disks, shared folders, damaged caches and threads,
tried on real processes. Every case passes when the run folder is whole (a complete, consistent
run) or absent / marked incomplete, nothing claims a finished run that is not, errors are clean
messages (exit 2, no traceback), and nothing crashes or hangs.

Cases (each a row of the summary table):

  kill          SIGKILL at a random moment of a short `nbvkit run`, then the same command
                (with --overwrite, so that a kill after the folder appeared reruns too): the
                folder holds one complete, consistent run; no temporary folder is left
  kill-noover   the same without --overwrite: the rerun succeeds, or (killed after the folder
                appeared) refuses with "already holds a complete run" over a complete folder
  kill-late     SIGKILL the moment the folder has appeared, then the same command
  disk-full     the run's folder on a small tmpfs (as root), else under RLIMIT_FSIZE: exit 2
                naming the write error; no summary.json anywhere under the mount, no partial
                folder, no temporary folder left
  map-save-full OccupancyMap.save onto a full tmpfs (or /dev/full): OSError, no file left
  shared        two runs given the same --out at once: one fails at once with a clear message,
                the other succeeds; the folder is complete
  rerun         a second run into a finished folder: refused without --overwrite; with
                --overwrite and report.enabled=false no old report.html / mesh.ply stays
  reader        nbvkit evaluate on an incomplete folder (killed run of the old layout, a
                truncated file): refused with a message
  bad-cache     a damaged observable-surface cache file: recomputed (the run succeeds)
  threads-scan  camera scans in one thread while another calls set_num_threads in a loop
  threads-2m    two missions in two threads of one process: the results of serial runs
  threads-dask  a sweep of 4 runs on a Dask worker with 2 threads (the runner sets the thread
                count before every run): every run complete, the worker never restarted
  threads-map   integrate on one map from 4 threads: the serial map (states, log-odds,
                entropy total), mirror and totals consistent
  mission-twice a Mission run twice gives the result of a fresh one

Run: .venv/bin/python bench/fault_battery.py [--kills N] [--seed S] [--quick]
Prints one row per case kind (cases, good, bad, what was seen) and exits 1 if any case was bad.
tests/test_faults.py runs the fast cases.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import json
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

#: config overrides that make a mission take seconds (tests/conftest.py's TINY_RUN)
TINY = (
    "map.resolution=0.4",
    "evaluation.gt_density=50",
    "max_iterations=2",
    "evaluation.coverage_every=1",
    "profiling.sweep_step=0.5",
    "profiling.waypoints=3",
)


def run_argv(out, *extra) -> list:
    """`nbvkit run` of a tiny scenario-1 mission into out."""
    return [
        sys.executable,
        "-m",
        "nbvkit.cli",
        "run",
        "--scenario",
        "1",
        "--no-progress",
        "--set",
        *TINY,
        "--out",
        str(out),
        *map(str, extra),
    ]


def _env() -> dict:
    return dict(os.environ, MPLBACKEND="Agg")


def run(argv, timeout=300, **kw):
    """(returncode, stdout, stderr) of a subprocess."""
    p = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, env=_env(), **kw)
    return p.returncode, p.stdout, p.stderr


def clean_error(rc, err, *needles) -> str | None:
    """None if (rc, err) is a clean failure (exit 2, no traceback, naming the needles)."""
    if rc != 2:
        return f"exit {rc}: {err.strip()[-300:]}"
    if "Traceback" in err:
        return "traceback: " + err.strip()[-300:]
    for n in needles:
        if n not in err:
            return f"message lacks {n!r}: {err.strip()[-300:]}"
    return None


# ---------------------------------------------------------------------------------- checks


def _ply_vertices(path: Path) -> int:
    with open(path, "rb") as f:
        head = f.read(4096).split(b"end_header")[0].decode("ascii", "replace")
    for line in head.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[:2] == ["element", "vertex"]:
            return int(parts[2])
    return -1


def _csv_rows(path: Path) -> int:
    with open(path, newline="") as f:
        return sum(1 for _ in csv.reader(f)) - 1


def run_problems(folder, finished: bool = True) -> list:
    """What is wrong with folder as a complete run (empty: a complete, consistent run). With
    finished=False, a flight kept without its end-of-run outputs (saving stopped by the fault:
    summary.json's stopped_during "saving", no mesh.ply or report.html)."""
    import yaml

    from nbvkit.runfolder import _problem

    folder = Path(folder)
    why = _problem(folder)
    if why is not None:
        return [f"incomplete: {why}"]
    bad = []
    s = json.loads((folder / "summary.json").read_text())
    cfg = yaml.safe_load((folder / "config.yaml").read_text())
    if _ply_vertices(folder / "cloud.ply") != s["cloud_points"]:
        bad.append("cloud.ply's points differ from summary.json's cloud_points")
    if _csv_rows(folder / "iterations.csv") != s["iterations"]:
        bad.append("iterations.csv's rows differ from summary.json's iterations")
    if _csv_rows(folder / "trajectory.csv") < 1:
        bad.append("trajectory.csv is empty")
    try:
        import nbvkit

        nbvkit.OccupancyMap.load(folder / "map.ot")
    except Exception as e:  # noqa: BLE001
        bad.append(f"map.ot does not load: {e}")
    if finished:
        bad += _end_output_problems(folder, s, cfg)
    else:
        if s.get("stopped_during") != "saving":
            bad.append(f"kept, but stopped_during is {s.get('stopped_during')!r}, not 'saving'")
        held = [n for n in ("mesh.ply", "report.html") if (folder / n).exists()]
        if held:
            bad.append(f"kept without its end-of-run outputs, but holds {held}")
    stray = [p.name for p in folder.rglob("*") if ".tmp" in p.name]
    if stray:
        bad.append(f"temporary files inside: {stray}")
    return bad


def _end_output_problems(folder: Path, s: dict, cfg: dict) -> list:
    """Whether a finished run's mesh.ply and report.html are there as its summary and its
    configuration say."""
    bad = []
    written = (s.get("reconstructed_mesh") or {}).get("written", False)
    if (folder / "mesh.ply").exists() != bool(written):
        bad.append("mesh.ply does not match summary.json's reconstructed_mesh")
    rep = cfg.get("report", {})
    want_html = rep.get("enabled", True) and rep.get("html", True)
    if (folder / "report.html").exists() != bool(want_html):
        bad.append("report.html does not match the configuration's report section")
    return bad


def leftovers(folder) -> list:
    """Temporary folders and lock files of runs on `folder` left beside it."""
    folder = Path(folder)
    return [p.name for p in folder.parent.glob(f".{folder.name}.*")]


def summaries_under(root) -> list:
    return [str(p) for p in Path(root).rglob("summary.json")]


# ---------------------------------------------------------------------------------- cases


def measure_run(tmp: Path) -> float:
    """Seconds an unkilled tiny run takes (the kill moments are drawn over it)."""
    out = tmp / "timing"
    t0 = time.perf_counter()
    rc, _, err = run(run_argv(out))
    if rc != 0:
        raise SystemExit(f"the reference run failed: {err[-2000:]}")
    return time.perf_counter() - t0


def kill_case(tmp: Path, delay: float, overwrite: bool = True) -> tuple:
    """SIGKILL `delay` s into a run, then the same command. Returns (bad or None, note)."""
    out = tmp / "run"
    extra = ("--overwrite",) if overwrite else ()
    p = subprocess.Popen(
        run_argv(out, *extra), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=_env()
    )
    time.sleep(delay)
    killed = p.poll() is None
    p.kill()
    p.wait()
    # after the kill: the folder is absent, or a complete run
    if out.exists():
        bad = run_problems(out)
        if bad:
            return f"after the kill at {delay:.2f} s: {bad}", ""
    was_there = out.exists()
    rc, _, err = run(run_argv(out, *extra))
    if rc != 0:
        if overwrite or not was_there:
            return f"rerun exit {rc}: {err.strip()[-300:]}", ""
        e = clean_error(rc, err, "already holds a complete run", "--overwrite")
        if e:
            return e, ""
    bad = run_problems(out)
    if bad:
        return f"after the rerun: {bad}", ""
    left = leftovers(out)
    if left:
        return f"left beside the folder: {left}", ""
    phase = ("before the folder appeared" if not was_there else "after") if killed else "done"
    return None, phase


def kill_late_case(tmp: Path) -> tuple:
    """SIGKILL the moment the folder has appeared (the run is printing its figures), then the
    same command with --overwrite."""
    out = tmp / "run"
    p = subprocess.Popen(
        run_argv(out, "--overwrite"),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=_env(),
    )
    while p.poll() is None and not (out / "manifest.json").exists():
        time.sleep(0.002)
    killed = p.poll() is None
    p.kill()
    p.wait()
    bad = run_problems(out)
    if bad:
        return f"after the kill: {bad}", ""
    rc, _, err = run(run_argv(out, "--overwrite"))
    if rc != 0:
        return f"rerun exit {rc}: {err.strip()[-300:]}", ""
    bad = run_problems(out) or leftovers(out)
    return (str(bad) if bad else None), ("killed after the folder appeared" if killed else "done")


def can_mount_tmpfs() -> bool:
    if os.geteuid() != 0:
        return False
    d = tempfile.mkdtemp(prefix="nbvkit-mnt")
    try:
        r = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", d], capture_output=True
        )
        if r.returncode != 0:
            return False
        subprocess.run(["umount", d], capture_output=True)
        return True
    finally:
        os.rmdir(d)


@contextlib.contextmanager
def small_disk(size: str):
    """A folder on a tmpfs of `size` (e.g. '256k'), unmounted after."""
    d = tempfile.mkdtemp(prefix="nbvkit-full")
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", d], check=True)
    try:
        yield Path(d)
    finally:
        subprocess.run(["umount", "-l", d], capture_output=True)
        os.rmdir(d)


def _fsize_limit(limit: int):
    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return pre


def disk_full_case(tmp: Path, size: str, use_mount: bool) -> tuple:
    """A run whose folder fills up. (bad or None, the error seen)."""
    if use_mount:
        with small_disk(size) as d:
            out = d / "run"
            rc, _, err = run(run_argv(out))
            return _disk_full_outcome(rc, err, d, out)
    limit = {"k": 1 << 10, "m": 1 << 20}[size[-1]] * int(size[:-1])
    d = tmp / f"fsize{size}"
    d.mkdir()
    out = d / "run"
    p = subprocess.run(
        run_argv(out),
        capture_output=True,
        text=True,
        timeout=300,
        env=_env(),
        preexec_fn=_fsize_limit(limit),
    )
    return _disk_full_outcome(p.returncode, p.stderr, d, out)


def _disk_full_outcome(rc, err, d: Path, out: Path) -> tuple:
    if rc == 0:  # everything fitted: the folder must be whole
        bad = run_problems(out)
        return (f"fitted, but {bad}" if bad else None), "fitted"
    e = clean_error(rc, err)
    if e:
        return e, ""
    if out.exists():  # only a whole flight whose end-of-run outputs did not fit may stay
        bad = run_problems(out, finished=False) + leftovers(out)
        if bad:
            return f"a partial folder {out} stays: {sorted(os.listdir(out))}: {bad}", ""
        return None, "the flight kept without its end-of-run outputs"
    s = summaries_under(d)
    if s:
        return f"a summary.json stays: {s}", ""
    left = leftovers(out)
    if left:
        return f"left beside the folder: {left}", ""
    msg = err.strip().splitlines()[-1]
    for k in ("No space left on device", "File too large"):
        if k in msg:
            return None, k
    return None, msg[-80:]


MAP_SAVE = """
import sys, os, nbvkit
m = nbvkit.OccupancyMap(0.1)
import numpy as np
rng = np.random.default_rng(0)
m.integrate([0, 0, 5], rng.uniform(-19, 19, (200000, 3)) * [1, 1, 0.2] + [0, 0, 5])
path = sys.argv[1]
try:
    m.save(path)
except OSError as e:
    print("OSError", e.errno, e)
    print("exists", os.path.exists(path))
    sys.exit(0)
print("saved", os.path.getsize(path))
"""


def map_save_full_case(use_mount: bool) -> tuple:
    if use_mount:
        with small_disk("64k") as d:
            rc, out, err = run([sys.executable, "-c", MAP_SAVE, str(d / "map.ot")])
            left = sorted(os.listdir(d))
    else:
        rc, out, err = run([sys.executable, "-c", MAP_SAVE, "/dev/full"])
        left = []
    if rc != 0:
        return f"exit {rc}: {err.strip()[-300:]}", ""
    if not out.startswith("OSError"):
        return f"no error: {out.strip()}", ""
    if "exists True" in out and use_mount:
        return "a partial map.ot stays", ""
    if left:
        return f"files left: {left}", ""
    return None, out.splitlines()[0][8:60]


def shared_case(tmp: Path) -> tuple:
    """Two runs on one --out at once."""
    out = tmp / "shared"
    a = subprocess.Popen(
        run_argv(out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env()
    )
    lock = out.parent / f".{out.name}.lock"
    t0 = time.time()
    while not (lock.exists() and lock.read_text().strip()) and time.time() - t0 < 60:
        time.sleep(0.05)
    t1 = time.perf_counter()
    rc_b, _, err_b = run(run_argv(out))
    fail_s = time.perf_counter() - t1
    rc_a = a.wait(300)
    err_a = a.stderr.read()
    if rc_a != 0:
        return f"the first run failed: {err_a.strip()[-300:]}", ""
    e = clean_error(rc_b, err_b, "being written by another nbvkit run")
    if e:
        return f"the second run: {e}", ""
    bad = run_problems(out)
    if bad:
        return str(bad), ""
    return None, f"second refused in {fail_s:.1f} s"


def rerun_case(tmp: Path) -> tuple:
    out = tmp / "rerun"
    rc, _, err = run(run_argv(out))
    if rc != 0:
        return f"first run: {err[-300:]}", ""
    had_mesh = (out / "mesh.ply").exists()
    rc, _, err = run(run_argv(out))
    e = clean_error(rc, err, "already holds a complete run", "--overwrite")
    if e:
        return f"second run without --overwrite: {e}", ""
    rc, _, err = run(run_argv(out, "--overwrite", "--set", "report.enabled=false"))
    if rc != 0:
        return f"--overwrite: {err[-300:]}", ""
    stale = [n for n in ("report.html", "mesh.ply") if (out / n).exists()]
    if stale:
        return f"old {stale} stayed beside the new run", ""
    bad = run_problems(out)
    if bad:
        return str(bad), ""
    # a folder holding a user's other files is never overwritten
    (out / "notes.txt").write_text("mine")
    rc, _, err = run(run_argv(out, "--overwrite"))
    e = clean_error(rc, err, "holds files nbvkit did not write", "notes.txt")
    if e:
        return f"--overwrite over a user's file: {e}", ""
    return None, f"mesh.ply before: {had_mesh}"


def reader_case(tmp: Path, base: Path) -> tuple:
    """evaluate refuses incomplete folders: no manifest, a truncated file, being written."""
    import shutil

    out = tmp / "reader"
    shutil.copytree(base, out)
    ev = [sys.executable, "-m", "nbvkit.cli", "evaluate", "--gt-density", "50"]
    rc, _, err = run([*ev, str(out)])
    if rc != 0:
        return f"evaluate of a complete folder: {err[-300:]}", ""
    with open(out / "cloud.ply", "r+b") as f:
        f.truncate(os.path.getsize(out / "cloud.ply") // 2)
    for target in (out, out / "cloud.ply"):
        rc, _, err = run([*ev, str(target)])
        e = clean_error(rc, err, "not a complete nbvkit run", "cloud.ply")
        if e:
            return f"evaluate of a truncated run ({target.name}): {e}", ""
    (out / "manifest.json").unlink()
    rc, _, err = run([*ev, str(out)])
    e = clean_error(rc, err, "not a complete nbvkit run", "manifest.json")
    if e:
        return f"evaluate of a folder without manifest: {e}", ""
    return None, "3 refused"


def bad_cache_case(tmp: Path, base: Path) -> tuple:
    """A damaged cache file in a run folder's cache: the next run recomputes it."""
    import shutil

    out = tmp / "cache_run"
    shutil.copytree(base, out)
    caches = list((out / "cache").glob("observable-*.npz"))
    if not caches:
        return "the run wrote no cache", ""
    for c in caches:
        c.write_bytes(b"PK\x03\x04 this is not a zip file")
    rc, _, err = run(run_argv(out, "--overwrite"))
    if rc != 0:
        return f"exit {rc}: {err.strip()[-300:]}", ""
    s = json.loads((out / "summary.json").read_text())
    if s.get("observability", {}).get("cached", True):
        return "the damaged cache was used", ""
    bad = run_problems(out)
    return (str(bad) if bad else None), "recomputed"


THREADS_SCAN = """
import threading, time, numpy as np, nbvkit
mesh = nbvkit.Mesh(np.array([[5, -50, -50], [5, 50, -50], [5, 50, 50], [5, -50, 50]], float),
                   np.array([[0, 1, 2], [0, 2, 3]], np.int32))
scene = nbvkit.RaycastScene(mesh)
cam = nbvkit.DepthCamera(scene, width=320, height=240, noise_k=0.0)
ref = len(cam.scan_pose([0, 0, 0, 0]).hits)
stop = False
def flip():
    k = 0
    while not stop:
        nbvkit.set_num_threads(1 + k % 4)
        k += 1
t = threading.Thread(target=flip)
t.start()
t0 = time.time(); n = 0
try:
    while time.time() - t0 < {seconds}:
        assert len(cam.scan_pose([0, 0, 0, 0]).hits) == ref
        n += 1
finally:
    stop = True
    t.join()
print("scans", n)
"""

THREADS_2M = """
import threading, numpy as np, nbvkit
from nbvkit.config import load_config
over = {over!r}
def fly(k, out):
    nbvkit.set_num_threads(1 + k)  # as the experiment runner does before every run
    m = nbvkit.Mission(load_config(overrides=list(over) + ["scenario=1", f"start={{k}}",
                                                            "progress=false"]))
    s = m.run()
    out[k] = (s["distance_m"], s["entropy_final"], s["cloud_points"],
              [tuple(r) for r in m.world.state.trajectory])
serial, par = {{}}, {{}}
for k in range(2):
    fly(k, serial)
ts = [threading.Thread(target=fly, args=(k, par)) for k in range(2)]
for t in ts: t.start()
for t in ts: t.join()
assert par == serial, "two missions in two threads differ from serial runs"
print("same", [round(serial[k][0], 3) for k in range(2)])
"""

THREADS_MAP = """
import threading, numpy as np, nbvkit
mesh = nbvkit.Mesh(np.array([[5, -50, -50], [5, 50, -50], [5, 50, 50], [5, -50, 50]], float),
                   np.array([[0, 1, 2], [0, 2, 3]], np.int32))
cam = nbvkit.DepthCamera(nbvkit.RaycastScene(mesh), width=160, height=120)
# four scans per thread, each cell updated at most 4 times: no clamping, so the result does
# not depend on the order the threads took turns in
poses = [[0, y, 3 + z, 0] for y in (-6, -2, 2, 6) for z in (-1.0, 1.0)]
scans = [cam.scan_pose(p) for p in poses]
def fresh():
    return nbvkit.OccupancyMap(0.2, (-10, -10, 0), (10, 10, 8))
serial = fresh()
for s in scans:
    serial.integrate(s)
for trial in range({trials}):
    m = fresh()
    def work(k):
        for s in scans[k::4]:
            m.integrate(s)
            m.total_entropy(); m.state([[1, 0, 3]])
    ts = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in ts: t.start()
    for t in ts: t.join()
    assert (m.state_grid() == serial.state_grid()).all(), "states differ"
    np.testing.assert_allclose(m.log_odds_grid(), serial.log_odds_grid(), atol=1e-5)
    assert abs(m.total_entropy() - m.recompute_total_entropy()) < 1e-6, "running entropy off"
    assert abs(m.total_entropy() - serial.total_entropy()) < 1e-3, "entropy differs"
    assert m.verify_mirror() == 0, "mirror out of sync"
print("same", {trials})
"""

DASK_2T = """
import tempfile
from pathlib import Path
import distributed
from nbvkit.experiments import RunSpec, run_specs
from nbvkit.runfolder import is_complete_run
over = {over!r}
with tempfile.TemporaryDirectory() as d, distributed.LocalCluster(
    n_workers=1, threads_per_worker=2, processes=True, host="127.0.0.1",
    dashboard_address=None) as cluster, distributed.Client(cluster) as client:
    before = set(client.scheduler_info()["workers"])
    specs = [RunSpec("1", k, overrides=tuple(over)) for k in range({runs})]
    rows = run_specs(specs, d, scheduler=cluster.scheduler_address, progress=False)
    after = set(client.scheduler_info()["workers"])
    assert before == after, f"the worker was restarted: {{before}} -> {{after}}"
    assert all(is_complete_run(Path(d) / "runs" / s.run_id) for s in specs)
    assert [r["start"] for r in rows] == list(range({runs}))
print("{runs} runs on 1 worker x 2 threads, no restart")
"""

MISSION_TWICE = """
import nbvkit
from nbvkit.config import load_config
cfg = load_config(overrides=list({over!r}) + ["scenario=1", "progress=false"])
m = nbvkit.Mission(cfg)
a = m.run(); ta = list(m.world.state.trajectory)
b = m.run(); tb = list(m.world.state.trajectory)
c = nbvkit.Mission(cfg).run()
keys = ("distance_m", "entropy_final", "iterations", "cloud_points", "coverage", "termination")
for k in keys:
    assert a[k] == b[k] == c[k], (k, a[k], b[k], c[k])
assert ta == tb
print("same")
"""


def _has_distributed() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def python_case(code: str, timeout=300) -> tuple:
    rc, out, err = run([sys.executable, "-c", textwrap.dedent(code)], timeout=timeout)
    if rc != 0:
        sig = f" (signal {-rc})" if rc < 0 else ""
        return f"exit {rc}{sig}: {err.strip()[-300:]}", ""
    return None, out.strip().splitlines()[-1]


# ---------------------------------------------------------------------------------- main


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=12, help="kill moments (default 12)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="a few cases of each kind")
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    rows = {}

    def record(kind, result, what=""):
        bad, note = result
        r = rows.setdefault(kind, {"cases": 0, "good": 0, "bad": [], "seen": [], "what": what})
        r["cases"] += 1
        if bad is None:
            r["good"] += 1
            if note and note not in r["seen"]:
                r["seen"].append(note)
        else:
            r["bad"].append(bad)
        print(f"  {kind}: {'ok' if bad is None else 'BAD ' + bad} {note}", flush=True)

    kills = 3 if args.quick else args.kills
    with tempfile.TemporaryDirectory(prefix="nbvkit-faults") as t:
        tmp = Path(t)
        t_run = measure_run(tmp)
        base = tmp / "timing"
        print(f"a tiny run takes {t_run:.1f} s", flush=True)
        for i in range(kills):
            d = tmp / f"kill{i}"
            d.mkdir()
            record("kill", kill_case(d, rng.uniform(0.05, 1.05) * t_run))
        for i in range(max(2, kills // 3)):
            d = tmp / f"killno{i}"
            d.mkdir()
            record("kill-noover", kill_case(d, rng.uniform(0.05, 1.05) * t_run, overwrite=False))
        for i in range(1 if args.quick else 3):
            d = tmp / f"killlate{i}"
            d.mkdir()
            record("kill-late", kill_late_case(d))
        mount = can_mount_tmpfs()
        sizes = (
            ["64k", "256k", "1m", "4m"]
            if args.quick
            else ["16k", "64k", "128k", "256k", "512k", "1m", "2m", "4m", "8m", "16m"]
        )
        for size in sizes:
            record("disk-full", disk_full_case(tmp, size, mount))
        record("map-save-full", map_save_full_case(mount))
        for i in range(1 if args.quick else 3):
            d = tmp / f"shared{i}"
            d.mkdir()
            record("shared", shared_case(d))
        record("rerun", rerun_case(tmp))
        record("reader", reader_case(tmp, base))
        record("bad-cache", bad_cache_case(tmp, base))
        record("threads-scan", python_case(THREADS_SCAN.format(seconds=2 if args.quick else 10)))
        record("threads-2m", python_case(THREADS_2M.format(over=TINY)))
        if _has_distributed():
            record("threads-dask", python_case(DASK_2T.format(over=TINY, runs=4)))
        record("threads-map", python_case(THREADS_MAP.format(trials=3 if args.quick else 20)))
        record("mission-twice", python_case(MISSION_TWICE.format(over=TINY)))

    print()
    print(f"disk full by: {'tmpfs mounts' if mount else 'RLIMIT_FSIZE (no mount permission)'}")
    print()
    print("| fault | cases | good | bad | seen |")
    print("|---|---|---|---|---|")
    n_bad = 0
    for kind, r in rows.items():
        n_bad += len(r["bad"])
        seen = "; ".join(r["seen"])[:120]
        print(f"| {kind} | {r['cases']} | {r['good']} | {len(r['bad'])} | {seen} |")
    for kind, r in rows.items():
        for b in r["bad"]:
            print(f"BAD {kind}: {b}")
    return 1 if n_bad else 0


if __name__ == "__main__":
    sys.exit(main())
