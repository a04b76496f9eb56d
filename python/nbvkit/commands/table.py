"""nbvkit table: the paper's Table 2 (Profile + Scenarios 1-5 x starts) on a structure."""
from __future__ import annotations

import argparse
import sys
import time

from ..paths import check_output_dir
from .common import add_mesh_options


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "table",
        help="rerun the paper's Table 2 (Profile + Scenarios 1-5, averaged over starts)",
        description="Run the Profile row and Scenarios 1-5 from K predefined starts each, in "
        "parallel, "
        "and write into DIR: runs.csv (one row per run), table2.md and table2.csv (the "
        "paper's layout, mean and spread over the starts), figures/*.png and each run's "
        "folder under DIR/runs/. Interrupted tables resume: finished runs are kept.",
    )
    add_mesh_options(p)
    p.add_argument(
        "--starts", type=int, default=5, metavar="K", help="starts per scenario, 1..5 (default 5)"
    )
    p.add_argument(
        "--set",
        nargs="+",
        action="extend",
        default=[],
        metavar="KEY=VALUE",
        help="config overrides applied to every run (e.g. max_iterations=100)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=0,
        metavar="N",
        help="local worker processes (default: one per core; 1 = serial)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on a Dask distributed cluster at this scheduler address instead",
    )
    p.add_argument(
        "--out", metavar="DIR", default="runs/table2", help="output folder (default runs/table2)"
    )
    return p


def run(args) -> int:
    from ..experiments import (
        Interrupted,
        run_specs,
        table2_specs,
        validate_specs,
        write_table,
        write_table2,
    )
    from ..plots import plot_experiment

    if not 1 <= args.starts <= 5:
        raise ValueError(f"--starts must be 1..5, got {args.starts}")
    specs = table2_specs(args.mesh, args.mesh_scale, args.mesh_up, args.starts, args.set)
    validate_specs(specs)
    out = check_output_dir(args.out, "--out")
    t0 = time.perf_counter()
    import pandas as pd

    try:
        rows = run_specs(specs, out, workers=args.workers, scheduler=args.scheduler)
    except Interrupted as e:
        if e.rows:
            write_table(e.rows, out / "runs.csv")
            write_table2(pd.DataFrame(e.rows), out)
        print(
            f"nbvkit table: interrupted: {len(e.rows)} of {e.total} runs finished"
            + (f" (partial tables: {out / 'runs.csv'}, {out / 'table2.md'})" if e.rows else "")
            + "; resume with the same command (finished runs are kept)",
            file=sys.stderr,
        )
        return 130

    df = pd.DataFrame(rows)
    write_table(rows, out / "runs.csv")
    write_table2(df, out)
    plot_experiment(out, df, out / "figures")
    from ..report import write_experiment_report

    write_experiment_report(out, df, "nbvkit table: Table 2", (out / "table2.md").read_text())
    print((out / "table2.md").read_text())
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s -> {out}/")
    return 0
