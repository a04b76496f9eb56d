"""nbvkit compare: several planners (scenarios) from the same starts, side by side."""
from __future__ import annotations

import argparse
import sys
import time

from ..paths import check_output_dir
from .common import add_mesh_options


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "compare",
        help="fly several planners from the same starts and compare them",
        description="Run each planner (a scenario: surface, surface_nbv, 1-5, ...) from K "
        "predefined starts on a structure, in parallel, and write into DIR: runs.csv (one row "
        "per run), compare.csv and compare.md (mean and spread over the starts: coverage at "
        "each resolution, area coverage, distance, views, wall time), figures/"
        "coverage_vs_distance.png (coverage at 0.05 m against distance per planner, the "
        "paper's Scenario 5 end point marked) and each run's folder under DIR/runs/. "
        "Interrupted comparisons resume: finished runs are kept.",
    )
    add_mesh_options(p)
    p.add_argument(
        "--planners",
        default="surface,5",
        metavar="A,B,...",
        help="comma-separated scenarios to compare (default: surface,5)",
    )
    p.add_argument(
        "--starts", type=int, default=5, metavar="K", help="starts per planner, 1..5 (default 5)"
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
        "--out", metavar="DIR", default="runs/compare", help="output folder (default runs/compare)"
    )
    return p


def run(args) -> int:
    import pandas as pd

    from ..experiments import (
        Interrupted,
        compare_markdown,
        compare_specs,
        compare_table,
        run_specs,
        validate_specs,
        write_table,
    )
    from ..plots import plot_compare

    if not 1 <= args.starts <= 5:
        raise ValueError(f"--starts must be 1..5, got {args.starts}")
    planners = [p.strip() for p in args.planners.split(",") if p.strip()]
    if not planners:
        raise ValueError("--planners names no planner")
    specs = compare_specs(planners, args.mesh, args.mesh_scale, args.mesh_up, args.starts, args.set)
    validate_specs(specs)
    out = check_output_dir(args.out, "--out")
    t0 = time.perf_counter()
    try:
        rows = run_specs(specs, out, workers=args.workers, scheduler=args.scheduler)
    except Interrupted as e:
        if e.rows:
            write_table(e.rows, out / "runs.csv")
        print(
            f"nbvkit compare: interrupted: {len(e.rows)} of {e.total} runs finished"
            + (f" (their rows: {out / 'runs.csv'})" if e.rows else "")
            + "; resume with the same command (finished runs are kept)",
            file=sys.stderr,
        )
        return 130
    df = pd.DataFrame(rows)
    write_table(rows, out / "runs.csv")
    t = compare_table(df)
    t.to_csv(out / "compare.csv", index=False)
    (out / "compare.md").write_text(compare_markdown(t))
    plot_compare(out, df, out / "figures")
    from ..report import write_experiment_report

    write_experiment_report(
        out, df, f"nbvkit compare: {', '.join(planners)}", (out / "compare.md").read_text()
    )
    print((out / "compare.md").read_text())
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s -> {out}/")
    return 0
