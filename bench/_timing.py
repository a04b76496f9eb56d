"""Helpers shared by the benchmark scripts (imported from the scripts' own folder): timing, the
common command line and the structure to time."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import nbvkit


def mesh_parser(doc: str, repeat: int | None = None) -> argparse.ArgumentParser:
    """A parser described by the first line of `doc`, with --mesh (default: the shipped
    airliner) and, given a default count, --repeat."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--mesh", default=None, help="structure mesh (default: the shipped airliner)")
    if repeat is not None:
        ap.add_argument("--repeat", type=int, default=repeat)
    return ap


def flown_map_parser(doc: str, iterations: int) -> argparse.ArgumentParser:
    """mesh_parser (--repeat 5) with --iterations (views flown before measuring, default
    `iterations`) and --scenario (default 1): the map a benchmark times its calls on."""
    ap = mesh_parser(doc, repeat=5)
    ap.add_argument(
        "--iterations", type=int, default=iterations, help="mission iterations before measuring"
    )
    ap.add_argument("--scenario", default="1")
    return ap


def flown_mission(args):
    """The Mission of args (flown_map_parser's), flown: its world holds the map to time on."""
    over = [f"max_iterations={args.iterations}", "progress=false", f"scenario={args.scenario}"]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    m = nbvkit.Mission(nbvkit.load_config(overrides=over))
    m.run()
    return m


def flown_map(args, folder) -> dict:
    """The map a benchmark times on: with args.run, that finished mission's (its map.ot,
    workspace, flown poses and collision radius); else flown_mission(args)'s, its map saved into
    `folder`. A dict: path, lo, hi (the map's bounds, lists), nav (the navigation space's
    corners), poses (N, 3) and radius."""
    if getattr(args, "run", None):
        run = Path(args.run).resolve()
        ws = json.loads((run / "summary.json").read_text())["workspace"]
        config = nbvkit.Config.from_yaml(run / "config.yaml")
        poses = np.loadtxt(run / "trajectory.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3))
        return dict(path=run / "map.ot", lo=ws["bounds_min"], hi=ws["bounds_max"],
                    nav=(ws["nav_min"], ws["nav_max"]), poses=np.atleast_2d(poses),
                    radius=config.vehicle.collision_radius)  # fmt: skip
    m = flown_mission(args)
    path = Path(folder) / "map.ot"
    m.world.map.save(path)
    w = m.world.workspace
    return dict(path=path, lo=list(map(float, w.bounds_min)), hi=list(map(float, w.bounds_max)),
                nav=(w.nav_min, w.nav_max), radius=m.config.vehicle.collision_radius,
                poses=np.array([row[1:4] for row in m.world.state.trajectory], float))  # fmt: skip


def print_best(best, same: bool, what: str, same_what: str) -> None:
    """Prints alternate()'s least times, one line a checkout ("ms `what`"), and with two
    checkouts their ratio and whether every run gave the same result (`same_what`)."""
    for label, t in best:
        print(f"{label:>30}: {t * 1e3:9.2f} ms {what}")
    if len(best) == 2:
        print(f"ratio {best[1][1] / best[0][1]:.2f}x; {same_what}: {same}")
    elif not same:
        raise SystemExit("the runs differ")


def bench_mesh(path=None):
    """(mesh, lo, hi, centre): the structure at `path` (default: the shipped airliner), its
    bounding box corners and centre."""
    mesh = nbvkit.load_mesh(path or nbvkit.default_mesh_path())
    lo, hi = mesh.bounds
    return mesh, lo, hi, (lo + hi) / 2


def median_time(fn, repeat: int) -> float:
    """Median wall time (s) of `repeat` calls of fn, after one warm-up call."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def checkouts(against: str | None) -> list:
    """[(label, package dir)]: this checkout's (None: the nbvkit already importable) and, with
    --against DIR, another checkout's package, DIR/python or DIR (a saved copy of a package)."""
    runs = [("this checkout", None)]
    if against:
        d = Path(against).resolve()
        runs.append((against, d / "python" if (d / "python").is_dir() else d))
    return runs


def table_header(*columns: str) -> None:
    """Prints a Markdown table's header: a "code" column (which checkout), then `columns`."""
    print("| code | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 1) + "|")


def run_each(snippet: str, args, against: str | None, row) -> list:
    """Runs `snippet` (run_snippet) once in this checkout and, with `against`, once in that one,
    each in a process of its own; prints row(label, result) after each. Returns the results."""
    results = []
    for label, package in checkouts(against):
        results.append(run_snippet(snippet, args, package))
        print(row(label, results[-1]), flush=True)
    return results


def alternate(snippet: str, args, against: str, rounds: int, key="time"):
    """Runs `snippet` (run_snippet) in this checkout and in `against`'s, alternating, `rounds`
    times each: ([(label, the least `key` over its runs)] for both - with a tuple of keys,
    (label, the least of each) -, whether every run printed the same "digest")."""
    runs = {label: [] for label, _ in checkouts(against)}
    for _ in range(rounds):
        for label, py in checkouts(against):
            runs[label].append(run_snippet(snippet, args, py))
    keys = (key,) if isinstance(key, str) else tuple(key)
    best = [(label, *(min(r[k] for r in rr) for k in keys)) for label, rr in runs.items()]
    return best, len({r["digest"] for rr in runs.values() for r in rr}) == 1


def run_snippet(snippet: str, args, package_dir=None) -> dict:
    """Runs `python -c snippet *args` with nbvkit imported from package_dir (None: as this process
    imports it), from a temporary folder; returns the JSON object its last output line prints.
    File arguments must be absolute paths."""
    env = dict(os.environ)
    if package_dir is not None:
        env["PYTHONPATH"] = str(package_dir) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run(
        [sys.executable, "-c", snippet, *map(str, args)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    return json.loads(out.stdout.strip().splitlines()[-1])
