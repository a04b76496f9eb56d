"""The hostile-input battery (issue 36, "Inputs"): every numeric configuration key set to 0, -1,
nan, inf and 1e12, and the hostile files and meshes (FIFOs, devices, folders, oversized files, a
YAML alias bomb, meshes with NaN vertices or no area, a sliver, a 2 km tower, non-UTF-8 paths,
the Python API misused), each run in its own subprocess under a timeout and a memory watch.

Each outcome is classified:

- ``ok``: exit 0 (a value the mission flies with);
- ``error``: a clear refusal: exit 2, no traceback, a message naming the key or the file;
- ``unclear``: exit 2 without a traceback but the message does not name the key or the path;
- ``traceback``: a Python traceback (exit 1);
- ``crash``: killed by a signal (segfault, abort);
- ``hang``: still running after the timeout;
- ``>2GB``: peak resident memory above 2 GiB (killed at 2.5 GiB);
- ``silent``: exit 0 with a result known to be wrong (checked where the case can tell).

Usage: python bench/hostile_battery.py [--jobs 2] [--timeout 120] [--only SUBSTRING ...]
    [--groups GROUP ...] [--mesh MESH] [--md FILE] [--json FILE]. Prints a summary table (and
    every case that is not ok / error) in markdown. --mesh flies the configuration keys' cases on
    another structure than the unit cube (an absolute path).
The numeric keys are enumerated from the configuration's dataclasses (nbvkit.config), not listed.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from fuzz_meshes import gltf_file, obj_file, stl_ascii_file

ROOT = Path(__file__).resolve().parent.parent
CUBE = ROOT / "meshes" / "fixtures" / "cube.obj"
VALUES = ("0", "-1", "nan", "inf", "1e12")
KILL_RSS = int(2.5 * 2**30)  # killed above this (so that one case cannot take the machine)
LIMIT_RSS = 2 * 2**30  # ">2GB" above this peak
OUTCOMES = ("ok", "error", "unclear", "traceback", "crash", "hang", ">2GB", "silent")

#: Short runs on the unit cube: seconds each.
TINY = {
    "map.resolution": "0.4",
    "evaluation.gt_density": "50",
    "max_iterations": "2",
    "evaluation.coverage_every": "1",
    "profiling.sweep_step": "0.5",
    "profiling.waypoints": "3",
    "report.poisson_depth": "6",
    "report.view_points": "2000",
    "observability.pose_spacing": "2",
}

#: The scenario under which a section's keys are used (the default flies the others).
SCENARIO_OF = {
    "sampling": "5",
    "termination": "5",
    "symmetry": "5",
    "frontier": "surface_nbv",
    "stall": "surface_nbv",
}


@dataclass
class Case:
    group: str
    name: str
    argv: list  # a command (list) run with cwd = a fresh temporary folder
    needles: tuple = ()  # the message of a clear refusal names one of these
    check: object = None  # (rc, out, err, folder) -> "silent" or None, for cases that can tell
    setup: object = None  # folder -> None, run before the command
    outcome: str = ""
    detail: str = ""
    peak_mb: float = 0.0
    seconds: float = 0.0
    extra: list = field(default_factory=list)


def numeric_keys() -> list[tuple[str, str]]:
    """(dotted key, 'int' | 'float') of every numeric key of nbvkit.Config, from its dataclasses."""
    import typing
    from dataclasses import fields, is_dataclass

    from nbvkit.config import Config

    out = []

    def walk(cls, prefix):
        hints = typing.get_type_hints(cls)
        for f in fields(cls):
            if f.name.startswith("_"):
                continue
            tp = hints[f.name]
            if is_dataclass(tp):
                continue  # a section: below, with the planner parts' sections
            if typing.get_origin(tp) is typing.Union:
                tp = next(a for a in typing.get_args(tp) if a is not type(None))  # noqa: E721
            if tp in (int, float):
                out.append((prefix + f.name, tp.__name__))

    walk(Config, "")
    for name, section in Config().sections():
        if is_dataclass(section):
            walk(type(section), name + ".")
    return out


def nbvkit(*args) -> list:
    return [sys.executable, "-m", "nbvkit.cli", *map(str, args)]


def run_cmd(key: str | None = None, value: str | None = None, extra=(), mesh: Path = CUBE) -> list:
    """`nbvkit run` of a tiny mission on `mesh` (the unit cube) with `key=value` set."""
    sets = {k: v for k, v in TINY.items() if k != key}
    # the report (7 s of a 9 s run) only where its keys are tried
    sets["report.enabled"] = "true" if key and key.startswith("report.") else "false"
    if key is not None:
        sets[key] = value
    scenario = SCENARIO_OF.get(key.split(".")[0], "surface") if key else "surface"
    return nbvkit(
        "run", "--mesh", mesh, "--scenario", scenario, "--no-progress", "--out", "out",
        "--set", *[f"{k}={v}" for k, v in sets.items()], *extra,
    )  # fmt: skip


def key_cases(mesh: Path = CUBE) -> list[Case]:
    """Each numeric configuration key at each hostile value, flown on `mesh`."""
    cases = []
    for key, _ in numeric_keys():
        for v in VALUES:
            leaf = key.rsplit(".", 1)[-1]  # a message naming the option: "prob_hit must be"
            cases.append(Case("config keys", f"{key}={v}", run_cmd(key, v, mesh=mesh), (key, leaf)))
    return cases


# ---------------------------------------------------------------------------- files


def _fifo(name):
    def setup(d):
        os.mkfifo(d / name)

    return setup


def _link(name, target):
    def setup(d):
        os.symlink(target, d / name)

    return setup


def _write(name, text: str | bytes):
    def setup(d):
        data = text.encode() if isinstance(text, str) else text
        (d / name).write_bytes(data)

    return setup


def _mkdir(name):
    def setup(d):
        (d / name).mkdir()

    return setup


LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 10)}]\n" for i in range(8)
)


def file_cases() -> list[Case]:
    cases = []
    sweep_ok = "scenarios: ['1']\nstarts: 1\n"
    kinds = {
        "fifo": lambda n: _fifo(n),
        "/dev/zero": lambda n: _link(n, "/dev/zero"),
        "/dev/urandom": lambda n: _link(n, "/dev/urandom"),
        "directory": lambda n: _mkdir(n),
        "10 MB": lambda n: _write(n, "# " + "x" * (10 << 20) + "\n"),
        "alias bomb": lambda n: _write(n, LAUGHS),
    }
    for kind, make in kinds.items():
        cases.append(
            Case("files", f"config file: {kind}", nbvkit("run", "--config", "c.yaml", "--out", "o"),
                 ("c.yaml",), setup=make("c.yaml"))
        )  # fmt: skip
        cases.append(
            Case("files", f"sweep file: {kind}", nbvkit("sweep", "s.yaml", "--out", "o"),
                 ("s.yaml",), setup=make("s.yaml"))
        )  # fmt: skip
    for kind in ("fifo", "/dev/zero", "/dev/urandom", "directory"):
        for ext in (".npy", ".ply"):
            cases.append(
                Case("files", f"cloud file ({ext}): {kind}",
                     nbvkit("evaluate", "cloud" + ext, "--mesh", CUBE), ("cloud" + ext,),
                     setup=kinds[kind]("cloud" + ext))
            )  # fmt: skip
        cases.append(
            Case("files", f"mesh file: {kind}", nbvkit("run", "--mesh", "m.obj", "--out", "o"),
                 ("m.obj",), setup=kinds[kind]("m.obj"))
        )  # fmt: skip
    cases.append(
        Case("files", "sweep file: alias bomb in 'set'", nbvkit("sweep", "s.yaml", "--out", "o"),
             ("s.yaml",), setup=_write("s.yaml", sweep_ok + LAUGHS.replace("a: &a", "set: &a")))
    )  # fmt: skip
    return cases


# ---------------------------------------------------------------------------- meshes

CUBE_V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_F = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4), (2, 6, 3), (3, 6, 7),
          (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]  # fmt: skip


# The meshes' files as text (tests/test_bounds.py writes them too).
def obj_text(verts, faces) -> str:
    return obj_file(verts, faces).decode()


def stl_text(verts, faces) -> str:
    return stl_ascii_file(verts, faces).decode()


def gltf_text(verts, faces) -> str:
    return gltf_file(verts, faces).decode()


def _loads_with_wrong_area(name):
    """A check: the mission ran (exit 0) although the file holds a NaN vertex: silent."""

    def check(rc, out, err, d):
        return "silent" if rc == 0 else None

    return check


def mesh_cases() -> list[Case]:
    cases = []
    nan_v = list(CUBE_V)
    nan_v[7] = (float("nan"), 1.0, 1.0)
    inf_v = list(CUBE_V)
    inf_v[7] = (1.0, float("inf"), 1.0)
    for label, verts in (("NaN", nan_v), ("inf", inf_v)):
        for ext, text in (
            (".obj", obj_text(verts, CUBE_F)),
            (".stl", stl_text(verts, CUBE_F)),
            (".gltf", gltf_text(verts, CUBE_F)),
        ):
            name = "m" + ext
            cases.append(
                Case("meshes", f"{label} vertex ({ext})", run_cmd(extra=("--mesh", name)),
                     (name,), check=_loads_with_wrong_area(name), setup=_write(name, text))
            )  # fmt: skip
    flat = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)]
    cases.append(
        Case("meshes", "no triangle with an area", run_cmd(extra=("--mesh", "m.obj")), ("m.obj",),
             setup=_write("m.obj", obj_text(flat, [(0, 1, 2), (1, 2, 3)])))
    )  # fmt: skip
    sliver_v = CUBE_V + [(0.5, 0.5, 0.5), (2000.0, 0.5, 0.5), (2000.0, 0.6, 0.5)]
    sliver_f = CUBE_F + [(8, 9, 10)]
    cases.append(
        Case("meshes", "cube + a 2 km sliver triangle",
             nbvkit("run", "--mesh", "m.obj", "--no-progress", "--set", "max_iterations=2",
                    "--out", "o"),
             ("m.obj", "map", "resolution", "gt_density", "profil"),
             setup=_write("m.obj", obj_text(sliver_v, sliver_f)))
    )  # fmt: skip
    tower_v = [(2 * x, 2 * y, 2000 * z) for x, y, z in CUBE_V]
    cases.append(
        Case("meshes", "2 m x 2 m x 2 km box (surface planner)",
             nbvkit("run", "--mesh", "m.obj", "--no-progress", "--set", "max_iterations=20",
                    "--out", "o"),
             ("m.obj", "map", "resolution", "gt_density", "profil"),
             setup=_write("m.obj", obj_text(tower_v, CUBE_F)))
    )  # fmt: skip
    odd = os.fsencode("m\udcff\udcfe.obj")  # not UTF-8

    def odd_setup(d):
        with open(os.path.join(os.fsencode(str(d)), odd), "wb") as f:
            f.write(obj_text(CUBE_V, CUBE_F).encode())

    cases.append(
        Case("meshes", "non-UTF-8 mesh path (CLI)",
             [sys.executable, "-c", textwrap.dedent(f"""
                import os, sys
                from nbvkit.cli import main
                name = os.fsdecode({odd!r})
                sys.exit(main(["scan", "--mesh", name, "--pose", "0.5", "-3", "0.5", "1.57",
                               "--out", "x.npy"]))
             """)], ("m",), setup=odd_setup)
    )  # fmt: skip
    cases.append(
        Case("meshes", "non-UTF-8 mesh path (load_mesh(bytes))",
             [sys.executable, "-c", f"import nbvkit; m = nbvkit.load_mesh({odd!r}); "
              "assert abs(m.area - 6) < 1e-9, m.area"], (), setup=odd_setup)
    )  # fmt: skip
    cases.append(
        Case("meshes", "mesh path with spaces",
             run_cmd(extra=("--mesh", "a mesh.obj")), ("a mesh.obj",),
             setup=_write("a mesh.obj", obj_text(CUBE_V, CUBE_F)))
    )  # fmt: skip
    return cases


# ---------------------------------------------------------------------------- Python API


def api(code: str) -> list:
    """Python code run in a subprocess; it prints REFUSED <message> for a clear exception, or
    ACCEPTED for a silent acceptance (the case's check turns that into "silent")."""
    body = textwrap.dedent(code)
    wrapper = (
        "import sys\n"
        "try:\n" + textwrap.indent(body, "    ") + "\n    print('ACCEPTED')\n"
        "except (ValueError, TypeError, FileNotFoundError) as e:\n"
        "    print('REFUSED', type(e).__name__, str(e)[:300])\n"
    )
    return [sys.executable, "-c", wrapper]


def _accepted_is_silent(rc, out, err, d):
    return "silent" if rc == 0 and "ACCEPTED" in out else None


def api_cases() -> list[Case]:
    load = f"import numpy as np, nbvkit\nm = nbvkit.load_mesh({str(CUBE)!r})\n"
    cases = [
        ("mesh.faces mutated to an out-of-range index", load + "m.faces[0, 0] = 10**6\n"
         "nbvkit.RaycastScene(m)"),
        ("mesh.vertices mutated to NaN", load + "m.vertices[0, 0] = np.nan\n"
         "nbvkit.RaycastScene(m)"),
        ("Mesh(v, faces out of range)", load + "f = np.array(m.faces); f[0, 0] = 10**6\n"
         "nbvkit.Mesh(m.vertices, f)"),
        ("Mesh(v with NaN, f)", load + "v = np.array(m.vertices); v[0, 0] = np.nan\n"
         "nbvkit.Mesh(v, m.faces)"),
        ("empty planner.generators, profiling off",
         "import nbvkit\nnbvkit.load_config(overrides=['planner.generators=[]', "
         "'profiling.enabled=false'])"),
    ]  # fmt: skip
    return [
        Case("python API", name, api(code), (), check=_accepted_is_silent) for name, code in cases
    ]


# ---------------------------------------------------------------------------- running


def _rss_kb(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def _tree_rss_kb(pid: int) -> int:
    """Resident memory of a process and its children (a CLI may start workers)."""
    total = _rss_kb(pid)
    try:
        for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split():
            total += _tree_rss_kb(int(c))
    except OSError:
        pass
    return total


def run_case(case: Case, timeout: float) -> Case:
    with tempfile.TemporaryDirectory(prefix="nbv-hostile-") as tmp:
        d = Path(tmp)
        if case.setup:
            case.setup(d)
        env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT / "python"))
        t0 = time.perf_counter()
        p = subprocess.Popen(
            case.argv,
            cwd=d,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            start_new_session=True,
        )
        out_chunks, err_chunks = [], []
        readers = [
            threading.Thread(target=lambda: out_chunks.append(p.stdout.read()), daemon=True),
            threading.Thread(target=lambda: err_chunks.append(p.stderr.read()), daemon=True),
        ]
        for r in readers:
            r.start()
        status, rusage, killed = None, None, ""
        peak_kb = 0
        while True:
            pid, st, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                status, rusage = st, ru
                break
            peak_kb = max(peak_kb, _tree_rss_kb(p.pid))
            elapsed = time.perf_counter() - t0
            if elapsed > timeout or peak_kb * 1024 > KILL_RSS:
                killed = "hang" if elapsed > timeout else ">2GB"
                os.killpg(p.pid, signal.SIGKILL)
                _, status, rusage = os.wait4(p.pid, 0)
                break
            time.sleep(0.1)
        p.returncode = os.waitstatus_to_exitcode(status)
        for r in readers:
            r.join(timeout=10)
        case.seconds = time.perf_counter() - t0
        case.peak_mb = max(peak_kb, rusage.ru_maxrss) / 1024
        out = b"".join(out_chunks).decode("utf-8", "replace")
        err = b"".join(err_chunks).decode("utf-8", "replace")
        rc = p.returncode
        last = (err.strip().splitlines() or out.strip().splitlines() or [""])[-1]
        case.detail = last[:300]
        if killed:
            case.outcome = killed
        elif case.peak_mb * 2**20 > LIMIT_RSS:
            case.outcome = ">2GB"
        elif case.check and case.check(rc, out, err, d):
            case.outcome = case.check(rc, out, err, d)
        elif rc < 0:
            case.outcome = "crash"
            case.detail = f"signal {-rc}: {case.detail}"
        elif "Traceback" in err or rc == 1:
            case.outcome = "traceback"
        elif "REFUSED" in out:
            case.outcome = "error"
            case.detail = out.strip().splitlines()[-1][:300]
        elif rc == 0:
            case.outcome = "ok"
        elif rc == 2 and (not case.needles or any(n in err for n in case.needles)):
            case.outcome = "error"
        else:
            case.outcome = "unclear"
        if len(err) > 100_000:
            case.outcome = "unclear"
            case.detail = f"a message of {len(err):,} characters"
    return case


def summary(cases: list[Case], wall: float) -> str:
    groups = list(dict.fromkeys(c.group for c in cases))
    head = "| cases | " + " | ".join(OUTCOMES) + " | peak RSS (max) | slowest |"
    lines = [head, "|---" * (len(OUTCOMES) + 3) + "|"]
    for g in groups + ["all"]:
        cs = [c for c in cases if g in ("all", c.group)]
        counts = [sum(c.outcome == o for c in cs) for o in OUTCOMES]
        slow = max(cs, key=lambda c: c.seconds)
        lines.append(
            f"| {g} ({len(cs)}) | "
            + " | ".join(str(n) for n in counts)
            + f" | {max(c.peak_mb for c in cs):.0f} MB | {slow.seconds:.0f} s ({slow.name}) |"
        )
    lines.append("")
    lines.append(f"{len(cases)} cases in {wall / 60:.1f} min")
    bad = [c for c in cases if c.outcome not in ("ok", "error")]
    if bad:
        lines += ["", "| case | outcome | peak MB | s | last line |", "|---|---|---|---|---|"]
        for c in bad:
            lines.append(
                f"| {c.group}: `{c.name}` | {c.outcome} | {c.peak_mb:.0f} | {c.seconds:.0f} | "
                f"{c.detail.replace('|', '/')} |"
            )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="cases run at once (default 2)")
    ap.add_argument("--timeout", type=float, default=120, help="seconds per case (default 120)")
    ap.add_argument(
        "--only", nargs="+", default=None, help="only cases whose name contains one of these"
    )
    ap.add_argument("--groups", nargs="+", default=None, help="only these groups")
    ap.add_argument("--md", default=None, help="also write the table to this file")
    ap.add_argument("--json", default=None, help="write every case's outcome to this file")
    ap.add_argument("--mesh", default=None, help="the configuration keys' structure (a path)")
    args = ap.parse_args(argv)
    mesh = Path(args.mesh).resolve() if args.mesh else CUBE
    cases = key_cases(mesh) + file_cases() + mesh_cases() + api_cases()
    if args.only:
        cases = [c for c in cases if any(s in c.name for s in args.only)]
    if args.groups:
        cases = [c for c in cases if c.group in args.groups]
    t0 = time.perf_counter()
    done = 0
    with ThreadPoolExecutor(args.jobs) as pool:
        for c in pool.map(lambda c: run_case(c, args.timeout), cases):
            done += 1
            print(
                f"[{done}/{len(cases)}] {c.outcome:9s} {c.seconds:5.1f} s {c.peak_mb:6.0f} MB  "
                f"{c.group}: {c.name}",
                file=sys.stderr,
                flush=True,
            )
    table = summary(cases, time.perf_counter() - t0)
    print(table)
    if args.md:
        Path(args.md).write_text(table + "\n")
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                [
                    dict(group=c.group, name=c.name, outcome=c.outcome, seconds=c.seconds,
                         peak_mb=c.peak_mb, detail=c.detail)
                    for c in cases
                ],
                indent=1,
            )
        )  # fmt: skip
    bad = [c for c in cases if c.outcome not in ("ok", "error")]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
