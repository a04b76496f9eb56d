"""nbvkit compare: several planners (scenarios) from the same starts, side by side."""
from __future__ import annotations

import argparse

from ..paths import check_experiment_dir
from .common import (
    add_experiment_options,
    add_mesh_options,
    check_starts,
    fly_experiment,
    shift_override,
)


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "compare",
        help="fly several planners from the same starts and compare them",
        description="Run each planner (a scenario: surface, surface_nbv, 1-5, ...) from K "
        "predefined starts on a structure, in parallel, and write into DIR: runs.csv (one row "
        "per run), compare.csv and compare.md (mean and spread over the starts: coverage at "
        "each resolution, area coverage, area coverage of the observable surface, distance, "
        "views, wall time), figures/"
        "coverage_vs_distance.png (coverage at 0.05 m against distance per planner, the "
        "paper's Scenario 5 end point marked) and each run's folder under DIR/runs/. "
        "Interrupted comparisons resume: finished runs are kept. The mesh may be given by "
        "--mesh/--mesh-scale/--mesh-up/--mesh-shift or by --set mesh.path=... (each key "
        "once: both is refused); runs are labelled with the mesh flown.",
    )
    add_mesh_options(p)
    # None: not given, the configuration decides (mesh.* in --set; given twice is refused)
    p.set_defaults(mesh_scale=None, mesh_up=None)
    p.add_argument(
        "--planners",
        default="surface,5",
        metavar="A,B,...",
        help="comma-separated scenarios to compare, each named once (default: surface,5)",
    )
    add_experiment_options(p, "planner", "runs/compare")
    return p


def run(args) -> int:
    from ..experiment_specs import with_mesh_shift
    from ..experiments import compare_specs, validate_specs, write_compare
    from ..plots import plot_compare

    check_starts(args.starts)
    planners = [p.strip() for p in args.planners.split(",") if p.strip()]
    if not planners:
        raise ValueError("--planners names no planner")
    overrides = with_mesh_shift(args.set, shift_override(args))
    specs = compare_specs(
        planners, args.mesh, args.mesh_scale, args.mesh_up, args.starts, overrides
    )
    validate_specs(specs)
    out = check_experiment_dir(args.out, "--out")

    return fly_experiment(
        "compare",
        specs,
        out,
        f"nbvkit compare: {', '.join(planners)}",
        args.workers,
        args.scheduler,
        tables=write_compare,
        plot=plot_compare,
        partial=f"partial tables: {out / 'runs.csv'}, {out / 'compare.md'}",
    )
