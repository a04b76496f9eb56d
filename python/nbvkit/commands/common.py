"""Options shared by several subcommands."""
from __future__ import annotations

import argparse
import sys
import time

from ..mesh import default_mesh_path, load_mesh


def add_mesh_options(p: argparse.ArgumentParser, required: bool = False) -> None:
    p.add_argument(
        "--mesh",
        metavar="PATH",
        type=mesh_path,
        required=required,
        help="structure mesh (PLY, OBJ and STL read by nbvkit's own readers in double "
        "precision; DAE, glTF, ... with assimp); default: the shipped generated airliner",
    )
    p.add_argument(
        "--mesh-scale",
        metavar="S",
        type=float,
        default=1.0,
        help="multiply the mesh coordinates by S (default 1; e.g. 0.001 for millimetres)",
    )
    p.add_argument(
        "--mesh-up",
        choices=("auto", "y", "z"),
        default="auto",
        help="the mesh file's up axis; y-up files are rotated to z-up (default auto: as its "
        "format defines it, glTF/GLB y, DAE its <up_axis>, others as they are: z)",
    )
    add_mesh_shift_option(p)


def mesh_path(text: str) -> str:
    """argparse type of --mesh: a path, never empty (an empty one is no file: refused, rather
    than flying the default mesh)."""
    return path_arg(text, "give a mesh file's path, or leave --mesh out for the shipped airliner")


def path_arg(text: str, hint: str = "give a path, or leave it out") -> str:
    """argparse type of a file or folder option: never empty (an empty path is no file, and
    `or` would replace it with the option's default: refused instead, with `hint`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"is empty ({text!r}): {hint}")
    return text


def mesh_from_args(args):
    path = args.mesh if args.mesh is not None else default_mesh_path()
    return load_mesh(path, scale=args.mesh_scale, up=args.mesh_up, shift=args.mesh_shift)


def add_mesh_shift_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--mesh-shift",
        nargs=3,
        type=float,
        default=None,
        metavar=("X", "Y", "Z"),
        help="add (X, Y, Z) metres to the mesh coordinates after scale and up axis, e.g. to "
        "bring a georeferenced mesh near the origin (results are in the shifted frame)",
    )


def shift_override(args) -> list:
    """The config override of --mesh-shift, if given."""
    if args.mesh_shift is None:
        return []
    return ["mesh.shift=[" + ",".join(repr(float(x)) for x in args.mesh_shift) + "]"]


def worker_count(text: str) -> int:
    """argparse type of --workers: a count >= 1 (argparse names the option in its error)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(
            f"must be >= 1 (1 = serial; leave it out for one per core), got {n}"
        )
    return n


def add_workers_option(p: argparse.ArgumentParser, default, help: str) -> None:
    """--workers N: local worker processes, a count >= 1 (refused otherwise, naming --workers)."""
    p.add_argument("--workers", type=worker_count, default=default, metavar="N", help=help)


def add_set_option(p: argparse.ArgumentParser, help: str) -> None:
    """--set KEY=VALUE ...: config overrides (repeatable; every one given counts)."""
    p.add_argument("--set", nargs="+", action="extend", default=[], metavar="KEY=VALUE", help=help)


def add_experiment_options(p: argparse.ArgumentParser, what: str, out: str) -> None:
    """--starts, --set, --workers, --scheduler and --out of the experiments over the five starts
    (`what`: what each start is flown for, e.g. "planner")."""
    p.add_argument(
        "--starts", type=int, default=5, metavar="K", help=f"starts per {what}, 1..5 (default 5)"
    )
    add_set_option(p, "config overrides applied to every run (e.g. max_iterations=100)")
    add_workers_option(p, 0, "local worker processes (default: one per core; 1 = serial)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on a Dask distributed cluster at this scheduler address instead",
    )
    p.add_argument(
        "--out", metavar="DIR", type=path_arg, default=out, help=f"output folder (default {out})"
    )


def check_starts(starts: int) -> None:
    if not 1 <= starts <= 5:
        raise ValueError(f"--starts must be 1..5, got {starts}")


def report_interrupted(command: str, e, partial: str, resume: str = "the same command") -> int:
    """Tell the user what an interrupted experiment kept (`partial`: where its finished runs'
    rows are, shown when there are any) and how to resume; returns the exit code 130."""
    print(
        f"nbvkit {command}: interrupted: {len(e.rows)} of {e.total} runs finished"
        + (f" ({partial})" if e.rows else "")
        + f"; resume with {resume} (finished runs are kept)",
        file=sys.stderr,
    )
    return 130


def report_failed(command: str, e, partial: str, resume: str = "the same command") -> int:
    """Tell the user which runs of an experiment failed and why (every other run was flown), what
    it kept (`partial`: where the finished runs' rows are) and how to fly the failed ones again;
    returns the exit code 1."""
    lines = [f"  {run_id}: {error}" for run_id, error in e.failures]
    print(
        f"nbvkit {command}: {len(e.failures)} of {e.total} runs failed:\n"
        + "\n".join(lines)
        + f"\n{len(e.rows)} finished"
        + (f" ({partial})" if e.rows else "")
        + f"; fly the failed ones again with {resume} (finished runs are kept)",
        file=sys.stderr,
    )
    return 1


def _run_ids(rows) -> str:
    ids = [str(r["run_id"]) for r in rows]
    return ", ".join(ids[:5]) + (f" and {len(ids) - 5} more" if len(ids) > 5 else "")


def experiment_notes(rows) -> list:
    """The console's notes on an experiment's finished runs (`rows`, as row_of makes them), as
    `nbvkit run` prints for one: the runs a budget stopped before the structure was covered, per
    budget, and the runs whose generators plan by the surface they cover, their utility only
    checking each view."""
    from ..planning.registry import checks_only_words
    from ..planning.terminations.budget import BUDGET_KEYS, stopped_by_budget

    notes = []
    for reason, key in BUDGET_KEYS.items():
        hit = [r for r in rows if r.get("termination") == reason]
        if hit:
            runs = f" ({_run_ids(hit)})"
            notes.append(f"{len(hit)} of {len(rows)} runs " + stopped_by_budget(key, key, runs))
    checked = [r for r in rows if r.get("utility_only_checks")]
    if checked:
        gens = sorted({g for r in checked for g in str(r["utility_only_checks"]).split()})
        utilities = ", ".join(sorted({str(r.get("utility") or "?") for r in checked}))
        more = "; column utility_only_checks"
        notes.append(
            f"in {len(checked)} of {len(rows)} runs ({_run_ids(checked)}) "
            + checks_only_words(gens, utilities, more)
        )
    return notes


def fly_experiment(
    command: str,
    specs,
    out,
    title: str,
    workers=None,
    scheduler=None,
    rows_file: str = "runs.csv",
    tables=None,
    plot=None,
    partial: str = "their rows",
    resume: str = "the same command",
) -> int:
    """Fly an experiment's `specs` into the folder `out` (finished runs are kept and reused) and
    write its results: one row per run in out/rows_file, then `tables(out, df)` (the command's
    summary tables; returns their markdown, printed and shown in the report), `plot(out, df,
    figures_dir)` and out/report.html titled `title`. When interrupted, writes the rows and
    tables of the finished runs, says where (`partial`) and how to `resume`, and returns 130;
    when some runs failed (every other one flown), the same with each failed run's error, and
    returns 1; else 0."""
    from ..experiments import Interrupted, RunsFailed, run_specs, write_results

    t0 = time.perf_counter()
    try:
        rows = run_specs(specs, out, workers=workers, scheduler=scheduler)
    except (Interrupted, RunsFailed) as e:
        if e.rows:
            write_results(out, e.rows, title, rows_file, tables, report=False, planned=len(specs))
        if isinstance(e, RunsFailed):
            return report_failed(command, e, partial, resume)
        return report_interrupted(command, e, partial, resume)
    markdown = write_results(out, rows, title, rows_file, tables, plot)
    if markdown is not None:
        print(markdown)
    for note in experiment_notes(rows):
        print("note: " + note)
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s -> {out}/")
    return 0
