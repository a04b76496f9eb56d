"""nbvkit sweep: any grid of config overrides x scenarios x starts x structures."""
from __future__ import annotations

import argparse
import os
import shlex
from pathlib import Path

from ..yamlio import read_yaml_mapping
from ..limits import shorten
from ..paths import check_experiment_dir
from ..plugins import load_plugins
from .common import add_workers_option, fly_experiment, path_arg

EXAMPLE = """example sweep file:
  meshes:                       # default: [null], the configuration's mesh
    - null                      # (the shipped airliner unless config/set/grid set mesh.*)
    - {path: ../shared/meshes/boat_yup.obj, scale: 4.5, up: y}
  scenarios: ["1", "5"]
  starts: [0, 1, 2]             # or a count: 3
  grid:                         # every combination of these config keys' values
    map.resolution: [0.2, 0.4]
    lattice.delta_d: [1.0, 2.0]
  set: {max_iterations: 200}    # fixed overrides for every run
  config: null                  # optional config file under every run (meshes/set/grid win)
  out: runs/my_sweep            # optional; --out wins
  workers: 2                    # optional; --workers wins
  scheduler: null               # optional Dask scheduler address; --scheduler wins
  plugins: [my_parts.py]        # optional plugin files loaded first, as with --plugin

Every list names each value once and none is empty (refused: a run counted twice, or no run).
A mesh key (mesh.path, mesh.scale, mesh.up) given by a 'meshes' entry and by set/grid too is
refused; set/grid alone may give it (e.g. grid: {mesh.path: [a.obj, b.obj]}). The tables label
each run with the mesh it flew (mesh, mesh_scale, mesh_up).
"""


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "sweep",
        help="run a grid of parameter overrides x scenarios x starts x structures",
        description="Run every combination a sweep file describes, in parallel (local processes or "
        "a Dask cluster), resumable (finished runs are skipped), into one tidy table "
        "DIR/results.csv that the plotting helpers read.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("config", metavar="CONFIG", help="sweep file (YAML)")
    p.add_argument(
        "--out",
        metavar="DIR",
        type=path_arg,
        default=None,
        help="output folder (default: the file's out, " "else runs/<file name>)",
    )
    add_workers_option(
        p,
        None,
        "local worker processes (default: the file's workers, else one per core; 1 = serial)",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", default=None, help="Dask scheduler address")
    return p


def run(args) -> int:
    from ..experiments import sweep_specs

    path = Path(args.config)
    sweep = read_yaml_mapping(path, "sweep file", "configs/sweep_example.yaml shows one")
    for key in ("out", "scheduler"):
        if sweep.get(key) is not None and not (isinstance(sweep[key], str) and sweep[key].strip()):
            raise ValueError(
                f"sweep file {path}: '{key}' must be a "
                + ("folder path" if key == "out" else "Dask scheduler address")
                + f", got {shorten(sweep[key])}"
            )
    files = sweep.get("plugins")
    files = [] if files is None else files
    if not isinstance(files, list) or not all(isinstance(f, str) and f for f in files):
        raise ValueError(
            f"sweep 'plugins' must be a list of plugin file paths, got {shorten(files)}"
        )
    try:  # before the specs: their parts' scenarios, sections and names
        load_plugins(files, wrap=True)  # a file's own error: PluginLoadError, naming it
    except FileNotFoundError as e:
        raise FileNotFoundError(
            f"sweep file {path}: plugin file {e.filename} not found (its 'plugins' are paths "
            f"from the folder nbvkit runs in, {os.getcwd()})"
        ) from None
    specs = sweep_specs(sweep)
    out = check_experiment_dir(args.out or sweep.get("out") or f"runs/{path.stem}", "--out")
    workers = args.workers if args.workers is not None else sweep.get("workers")
    if workers is None:
        workers = 0  # one per core
    elif isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(
            f"sweep 'workers' must be a count >= 1 (1 = serial; leave it out for one per core), "
            f"got {shorten(workers)}"
        )
    given = [  # (the options given: its workers, which a copy of the line without them lost)
        *(["--out", str(args.out)] if args.out else []),
        *(["--workers", str(args.workers)] if args.workers is not None else []),
        *(["--scheduler", args.scheduler] if args.scheduler else []),
        *(a for f in getattr(args, "plugin", []) for a in ("--plugin", str(f))),
    ]
    resume = "the same command: " + shlex.join(["nbvkit", "sweep", str(args.config), *given])
    return fly_experiment(
        "sweep",
        specs,
        out,
        f"nbvkit sweep: {path.name}",
        workers,
        args.scheduler or sweep.get("scheduler"),
        rows_file="results.csv",
        partial=f"table of them: {out / 'results.csv'}",
        resume=resume,
    )
