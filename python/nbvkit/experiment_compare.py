"""nbvkit.compare: planners side by side from Python, as ``nbvkit compare`` flies them."""
from __future__ import annotations

import os

from .experiment_specs import compare_specs, override_strings, validate_specs
from .experiment_tables import compare_table, write_compare, write_results
from .experiments import Interrupted, RunsFailed, run_specs
from .limits import shorten
from .output_paths import check_experiment_dir


def compare(
    planners,
    out: str | os.PathLike,
    *,
    mesh: str | os.PathLike | None = None,
    starts: int = 5,
    overrides: list[str] | dict | None = None,
    workers: int = 0,
    scheduler: str | None = None,
    progress: bool = True,
):
    """``nbvkit compare`` from Python: every planner (a scenario name: nbvkit's, the paper's, or
    one you registered) flown from the same `starts` (1..5) predefined starts on `mesh` (a path;
    None: the configuration's), each run with `overrides` (as ``nbvkit.load_config``'s: "key=value"
    strings or a {key: value} dict). Writes into `out` what the command writes (runs.csv,
    compare.csv, compare.md, figures/coverage_vs_distance.png, report.html and each run's folder
    under out/runs/; finished runs are kept and reused) and returns the comparison table (a
    pandas DataFrame: one row per planner, the mean and sd over its starts of each column).

    workers, scheduler: as run_specs'. A part registered in this process by no plugin file flies
    only with workers=1. Interrupted or RunsFailed (their ``rows``: the finished runs) after the
    partial tables are written."""
    import pandas as pd

    from .plots import plot_compare

    if not isinstance(planners, (list, tuple)) or not all(
        isinstance(p, (str, int)) and not isinstance(p, bool) for p in planners
    ):
        raise TypeError(
            "planners must be a list of scenario names, e.g. ['surface', '5'], "
            f"got {shorten(planners)}"
        )
    if not planners:
        raise ValueError("planners names no planner: give one or more, e.g. ['surface', '5']")
    if isinstance(starts, bool) or not isinstance(starts, int) or not 1 <= starts <= 5:
        raise ValueError(f"starts must be 1..5, got {starts!r}")
    mesh = None if mesh is None else os.fspath(mesh)
    names = [str(p) for p in planners]
    specs = compare_specs(names, mesh, None, None, starts, override_strings(overrides))
    validate_specs(specs)
    out = check_experiment_dir(out, "out")
    try:
        rows = run_specs(specs, out, workers=workers, scheduler=scheduler, progress=progress)
    except (Interrupted, RunsFailed) as e:
        if e.rows:
            write_results(out, e.rows, "", tables=write_compare, report=False, planned=len(specs))
        raise
    write_results(out, rows, f"nbvkit compare: {', '.join(names)}", tables=write_compare,
                  plot=plot_compare)  # fmt: skip
    return compare_table(pd.DataFrame(rows))
