"""nbvkit table: the paper's Table 2 (Profile + Scenarios 1-5 x starts) on a structure."""
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
        "table",
        help="rerun the paper's Table 2 (Profile + Scenarios 1-5, averaged over starts)",
        description="Run the Profile row and Scenarios 1-5 from K predefined starts each, in "
        "parallel, "
        "and write into DIR: runs.csv (one row per run), table2.md and table2.csv (the "
        "paper's layout, mean and spread over the starts), figures/*.png and each run's "
        "folder under DIR/runs/. Interrupted tables resume: finished runs are kept.",
    )
    add_mesh_options(p)
    # None: not given, the configuration decides (mesh.* in --set; given twice is refused)
    p.set_defaults(mesh_scale=None, mesh_up=None)
    add_experiment_options(p, "scenario", "runs/table2")
    return p


def run(args) -> int:
    from ..experiment_specs import with_mesh_shift
    from ..experiments import table2_specs, validate_specs, write_table2
    from ..plots import plot_experiment

    check_starts(args.starts)
    overrides = with_mesh_shift(args.set, shift_override(args))
    specs = table2_specs(args.mesh, args.mesh_scale, args.mesh_up, args.starts, overrides)
    validate_specs(specs)
    out = check_experiment_dir(args.out, "--out")

    def tables(out, df) -> str:
        write_table2(df, out)
        return (out / "table2.md").read_text()

    return fly_experiment(
        "table",
        specs,
        out,
        "nbvkit table: Table 2",
        args.workers,
        args.scheduler,
        tables=tables,
        plot=plot_experiment,
        partial=f"partial tables: {out / 'runs.csv'}, {out / 'table2.md'}",
    )
