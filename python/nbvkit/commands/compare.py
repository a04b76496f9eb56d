"""nbvkit compare: several planners (scenarios) from the same starts, side by side."""
from __future__ import annotations

import argparse
import time

from ..paths import check_output_dir
from .common import add_experiment_options, add_mesh_options, check_starts, report_interrupted


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
    add_experiment_options(p, "planner", "runs/compare")
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

    check_starts(args.starts)
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
        return report_interrupted("compare", e, f"their rows: {out / 'runs.csv'}")
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
