"""The tables of an experiment: one tidy row per finished run folder (row_of), the runs table
as CSV, the paper's Table 2 (means and spreads over the starts, as Markdown, beside the paper's)
and the planner comparison. Re-exported by nbvkit.experiments."""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from .output_paths import naming_the_file
from .runfolder import read_json_object, read_summary

# ------------------------------------------------------------------ the runs table


def row_of(run_dir: Path) -> dict:
    """One tidy row from a finished run folder."""
    s = read_summary(run_dir)
    spec = (
        read_json_object(run_dir / "spec.json", "run spec")
        if (run_dir / "spec.json").exists()
        else {}
    )
    row = {
        "run_id": run_dir.name,
        "scenario": s["scenario"],
        "start": s["start"],
        **_mesh_columns(run_dir, spec),
        "overrides": " ".join(spec.get("overrides", [])),
        "iterations": s["iterations"],
        "views": s.get("views", s["iterations"]),
        "distance_m": s["distance_m"],
        "entropy_reduction": s["entropy_reduction"],
        "termination": s["termination"],
        "utility": s.get("utility", ""),
        "utility_only_checks": " ".join(s.get("utility_only_checks") or []),
        "wall_time_s": s["wall_time_s"],
        "ms_per_iteration": s["ms_per_iteration"],
        "cloud_points": s["cloud_points"],
        "chamfer_m": s["chamfer_m"],
    }
    for k in ("coverage", "area_coverage", "precision"):
        for r, v in s[k].items():
            row[f"{k}_{r}"] = v
    for k in ("completeness", "accuracy", "fscore"):
        for r, v in s[k].items():
            row[f"{k}_{r}"] = v
    for k in ("coverage_observable", "area_coverage_observable", "observable_fraction"):
        for r, v in s.get(k, {}).items():
            row[f"{k}_{r}"] = v
    m = s.get("reconstructed_mesh") or {}
    if m.get("written"):
        row["mesh_hausdorff95_m"] = m["hausdorff95_m"]
        for t, v in m["mesh_completeness"].items():
            row[f"mesh_completeness_{t}"] = v
    p = s.get("profile")
    if p:
        row["profile_distance_m"] = p["distance_m"]
        row["profile_entropy_reduction"] = p["entropy_reduction"]
        for r, v in p["coverage"].items():
            row[f"profile_coverage_{r}"] = v
    sym = s.get("symmetry")
    if sym:
        row["symmetry_accepted"] = sym.get("accepted")
        row["symmetry_confidence"] = sym.get("confidence")
    for name, value in spec.get("labels", []):
        row[name] = value
    return row


def _mesh_columns(run_dir: Path, spec: dict) -> dict:
    """mesh (its path, or "airliner" for the shipped one), mesh_scale and mesh_up of the mesh the
    run flew: the spec's flown_mesh, else (a folder from before it was recorded) the run's
    resolved config.yaml."""
    m = spec.get("flown_mesh")
    if not isinstance(m, dict):
        import yaml

        try:
            m = (yaml.safe_load((run_dir / "config.yaml").read_text()) or {}).get("mesh") or {}
        except (OSError, ValueError, AttributeError, yaml.YAMLError):
            m = {}
        if not isinstance(m, dict):
            m = {}
    return {
        "mesh": m.get("path") or "airliner",
        "mesh_scale": m.get("scale", 1.0),
        "mesh_up": m.get("up", "z"),
    }


def write_table(rows: list[dict], path: str | os.PathLike) -> None:
    """Writes rows as a CSV (the tidy table every plotting helper reads)."""
    import pandas as pd

    with naming_the_file(path):
        pd.DataFrame(rows).to_csv(path, index=False)


def read_table(path: str | os.PathLike):
    import pandas as pd

    return pd.read_csv(path)


# ------------------------------------------------------------------ Table 2

#: the paper's Table 2 rows: label, profiling, symmetry, sampling
TABLE2_ROWS = [
    ("Profile", "yes", "no", "-"),
    ("1", "no", "no", "CGVS"),
    ("2", "yes", "no", "CGVS"),
    ("3", "yes", "no", "AGVS"),
    ("4", "yes", "yes", "CGVS"),
    ("5", "yes", "yes", "AGVS"),
]


def table2(df):
    """The paper's Table 2 from a tidy table of runs: means over starts, with the spread (std)."""
    import pandas as pd

    _warn_pooled(df, "table2")
    out = []
    for label, prof, sym, samp in TABLE2_ROWS:
        sub = (
            df[df["scenario"].astype(str) == label.lower()]
            if label == "Profile"
            else df[df["scenario"].astype(str) == label]
        )
        if label == "Profile" and len(sub):
            cols = {
                "distance_m": "profile_distance_m",
                "entropy_reduction": "profile_entropy_reduction",
                "coverage_0.05": "profile_coverage_0.05",
                "coverage_0.1": "profile_coverage_0.1",
                "coverage_0.5": "profile_coverage_0.5",
            }
            # (no iterations, so no time per iteration: 0.0 ± 0.0 read as measured)
            sub = sub.assign(
                **{k: sub[v] for k, v in cols.items()}, iterations=np.nan, ms_per_iteration=np.nan
            )
        if not len(sub):
            continue
        r = {
            "Scenario": label,
            "Profiling": prof,
            "Symmetry": sym,
            "Sampling": samp,
            "runs": len(sub),
        }
        for col, name in (
            ("iterations", "Iterations"),
            ("distance_m", "Distance (m)"),
            ("entropy_reduction", "Entropy reduction"),
            ("coverage_0.05", "Coverage @0.05 m"),
            ("coverage_0.1", "Coverage @0.10 m"),
            ("coverage_0.5", "Coverage @0.50 m"),
            ("area_coverage_0.05", "Area cov. @0.05 m"),
            ("wall_time_s", "Wall time (s)"),
            ("ms_per_iteration", "ms/iteration"),
        ):
            v = pd.to_numeric(sub[col], errors="coerce") if col in sub else pd.Series(dtype=float)
            r[name] = v.mean() if v.notna().any() else np.nan
            r[name + " sd"] = v.std(ddof=0) if v.notna().sum() > 1 else 0.0
        out.append(r)
    return pd.DataFrame(out)


#: what a table's "±" is (the spread columns: pandas' std(ddof=0))
SPREAD = "mean ± standard deviation over the runs (population, ddof 0: one run gives ± 0)"

#: The columns of a runs table that tell one configuration from another (a sweep's grid values
#: are among its overrides): a table's ± is a spread over starts only within one.
CONFIG_COLUMNS = ("mesh", "mesh_scale", "mesh_up", "overrides")


def _warn_pooled(df, what: str) -> None:
    """A warning when a scenario's runs in `df` differ in a CONFIG_COLUMNS column (a sweep's
    results.csv given whole): `what` averages them as one."""
    cols = [
        c
        for c in CONFIG_COLUMNS
        if c in df and (df.groupby(df["scenario"].astype(str))[c].nunique(dropna=False) > 1).any()
    ]
    if cols:
        warnings.warn(
            f"{what} pools runs of different configurations under one scenario (they differ in "
            f"{', '.join(cols)}): its ± is not a spread over starts; select one configuration "
            "first (e.g. df[df['overrides'] == ...])",
            stacklevel=3,
        )


def _partial_note(df) -> str:
    """The line a table of an experiment stopped early ends with (df.attrs["runs_planned"]: the
    runs it was to fly; write_results sets it)."""
    planned = df.attrs.get("runs_planned")
    if not planned or planned <= len(df):
        return ""
    return (
        f"\nPartial: {len(df)} of {planned} runs finished (the experiment stopped early): a "
        "planner without a finished run is missing, and each ± is over the runs that finished.\n"
    )


def table2_markdown(t) -> str:
    """Table 2 as Markdown, mean ± spread over the starts."""

    def fmt(name, v, sd):
        if v != v:  # NaN
            return "—"
        if name.startswith("Coverage") or name.startswith("Area"):
            return f"{v:.1%} ± {sd:.1%}".replace("%", " %")
        if name in ("Iterations",):
            return f"{v:.0f} ± {sd:.0f}"
        if name == "Entropy reduction":
            return f"{v:,.0f} ± {sd:,.0f}"
        return f"{v:,.1f} ± {sd:,.1f}"

    cols = [
        "Iterations",
        "Distance (m)",
        "Entropy reduction",
        "Coverage @0.05 m",
        "Coverage @0.10 m",
        "Coverage @0.50 m",
        "Area cov. @0.05 m",
        "Wall time (s)",
        "ms/iteration",
    ]
    head = ["Scenario", "Profiling", "Symmetry", "Sampling", *cols, "runs"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in t.iterrows():
        cells = [str(r["Scenario"]), r["Profiling"], r["Symmetry"], r["Sampling"]]
        cells += [fmt(c, r[c], r[c + " sd"]) for c in cols] + [str(int(r["runs"]))]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join([*lines, "", SPREAD]) + "\n"


def write_table2(df, out: Path) -> None:
    t = table2(df)
    with naming_the_file(out / "table2.csv"):
        t.to_csv(out / "table2.csv", index=False)
    with naming_the_file(out / "table2.md"):
        (out / "table2.md").write_text(table2_markdown(t) + _partial_note(df))


def compare_with_paper(t, paper_csv) -> str:
    """Markdown: our Table 2 (means over starts) beside the paper's (its table2.csv layout)."""
    import pandas as pd

    paper = pd.read_csv(paper_csv, dtype={"scenario": str})
    lines = [
        "| Scenario | Iterations (ours / paper) | Distance m | Entropy reduction "
        "| Coverage @0.05 m | "
        "Coverage @0.10 m | Coverage @0.50 m |",
        "|---|---|---|---|---|---|---|",
    ]
    for _, r in t.iterrows():
        p = paper[paper["scenario"].astype(str) == str(r["Scenario"])]
        if not len(p):
            continue
        p = p.iloc[0]

        def pair(ours, theirs, kind):
            if kind == "pct":
                return f"{ours:.1%} / {theirs:.1%}".replace("%", " %")
            if kind == "int":
                return (
                    ("—" if ours != ours else f"{ours:,.0f}")
                    + " / "
                    + ("—" if theirs != theirs else f"{theirs:,.0f}")
                )
            return f"{ours:,.1f} / {theirs:,.1f}"

        lines.append(
            "| "
            + " | ".join(
                [
                    str(r["Scenario"]),
                    pair(r["Iterations"], p["iterations"], "int"),
                    pair(r["Distance (m)"], p["distance_m"], "num"),
                    pair(r["Entropy reduction"], p["entropy_reduction"], "int"),
                    pair(r["Coverage @0.05 m"], p["coverage_0.05"], "pct"),
                    pair(r["Coverage @0.10 m"], p["coverage_0.10"], "pct"),
                    pair(r["Coverage @0.50 m"], p["coverage_0.50"], "pct"),
                ]
            )
            + " |"
        )
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ planner comparisons

#: The paper's full method (Scenario 5) as its Table 2 reports it: mean over five starts on its
#: aircraft (coverage against its sparse reference cloud; see docs/RESULTS.md).
PAPER_SCENARIO5 = {"distance_m": 665.2, "coverage_0.05": 0.865, "iterations": 257}

#: (column of the run table, heading) of the comparison table, in order.
COMPARE_COLUMNS = (
    ("coverage_0.05", "Coverage @0.05 m"),
    ("coverage_0.1", "Coverage @0.10 m"),
    ("coverage_0.5", "Coverage @0.50 m"),
    ("area_coverage_0.05", "Area cov. @0.05 m"),
    ("area_coverage_0.1", "Area cov. @0.10 m"),
    # the same, of the surface a camera flown through the navigation space could see
    ("area_coverage_observable_0.05", "Observable area cov. @0.05 m"),
    ("distance_m", "Distance (m)"),
    ("views", "Views"),
    ("wall_time_s", "Wall time (s)"),
)


def compare_table(df):
    """Per planner (in first-seen order): the mean and spread (std) over starts of each of
    COMPARE_COLUMNS, and the number of runs."""
    import pandas as pd

    _warn_pooled(df, "compare_table")
    out = []
    for planner in dict.fromkeys(df["scenario"].astype(str)):
        sub = df[df["scenario"].astype(str) == planner]
        r = {"Planner": planner, "runs": len(sub)}
        for col, name in COMPARE_COLUMNS:
            v = pd.to_numeric(sub[col], errors="coerce") if col in sub else pd.Series(dtype=float)
            r[name] = v.mean() if v.notna().any() else np.nan
            r[name + " sd"] = v.std(ddof=0) if v.notna().sum() > 1 else 0.0
        out.append(r)
    return pd.DataFrame(out)


def compare_markdown(t) -> str:
    def fmt(name, v, sd):
        if v != v:
            return "—"
        if "cov" in name.lower():
            return f"{v:.1%} ± {sd:.1%}".replace("%", " %")
        if name == "Views":
            return f"{v:.0f} ± {sd:.0f}"
        return f"{v:,.1f} ± {sd:,.1f}"

    names = [n for _, n in COMPARE_COLUMNS]
    lines = ["| Planner | " + " | ".join(names) + " | runs |", "|" + "---|" * (len(names) + 2)]
    for _, r in t.iterrows():
        cells = [fmt(n, r[n], r[n + " sd"]) for n in names]
        lines.append(f"| {r['Planner']} | " + " | ".join(cells) + f" | {int(r['runs'])} |")
    return "\n".join([*lines, "", SPREAD]) + "\n"


def write_compare(out: Path, df) -> str:
    """compare.csv and compare.md (compare_table of the runs table `df`) into the folder `out`;
    returns the markdown."""
    t = compare_table(df)
    md = compare_markdown(t) + _partial_note(df)
    with naming_the_file(Path(out) / "compare.csv"):
        t.to_csv(Path(out) / "compare.csv", index=False)
    with naming_the_file(Path(out) / "compare.md"):
        (Path(out) / "compare.md").write_text(md)
    return md


def write_results(
    root, rows, title: str, rows_file="runs.csv", tables=None, plot=None, report=True, planned=None
):
    """An experiment's results into the folder `root`: its rows (one per run) in root/rows_file,
    then `tables(root, df)` (its summary tables; returns their markdown), `plot(root, df,
    root/figures)` and, with `report`, root/report.html titled `title`. Returns the tables'
    markdown (or None). Of an unfinished experiment: its rows and tables (report=False), which
    say how many of the `planned` runs finished."""
    import pandas as pd

    from .experiment_report import write_experiment_report

    root = Path(root)
    df = pd.DataFrame(rows)
    df.attrs["runs_planned"] = planned
    write_table(rows, root / rows_file)
    markdown = tables(root, df) if tables is not None else None
    if plot is not None:
        plot(root, df, root / "figures")
    if report:
        write_experiment_report(root, df, title, markdown)
    return markdown
