"""An experiment's ``report.html`` (table, sweep, compare): its summary table, one row per run
linking to the run's own report, and its figures. Importable from nbvkit.report."""
from __future__ import annotations

import html
from pathlib import Path

from .htmlpage import fmt, img, page, plain, write_text

__all__ = ["write_experiment_report"]


def write_experiment_report(root, df, title: str, markdown: str | None = None) -> Path:
    """``root/report.html`` of an experiment (table, sweep, compare): the summary table
    (``markdown``, e.g. Table 2, shown as preformatted text), one row per run of ``df`` (the
    tidy runs table) with a link to its ``runs/<run_id>/report.html``, and every PNG of
    ``root/figures``. Self-contained except for the links."""
    root = Path(root)
    body = [f"<h1>{html.escape(title)}</h1>"]
    if markdown:
        body.append("<h2>Summary</h2><pre>" + html.escape(markdown) + "</pre>")
    cols = [
        c
        for c in (
            "scenario",
            "start",
            "mesh",
            "iterations",
            "distance_m",
            "coverage_0.05",
            "coverage_observable_0.05",
            "coverage_0.1",
            "coverage_0.5",
            "observable_fraction_0.05",
            "chamfer_m",
            "mesh_hausdorff95_m",
            "wall_time_s",
            "termination",
        )
        if c in df.columns
    ]
    head = "<tr><th>run</th>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols) + "</tr>"
    rows = []
    for _, r in df.iterrows():
        rid = str(r["run_id"])
        link = f"runs/{rid}/report.html"
        cell = (
            f"<a href='{html.escape(link)}'>{html.escape(rid)}</a>"
            if (root / link).exists()
            else html.escape(rid)
        )
        vals = "".join(f"<td>{fmt(plain(r[c]))}</td>" for c in cols)
        rows.append(f"<tr><td>{cell}</td>{vals}</tr>")
    body.append("<h2>Runs</h2><table>" + head + "".join(rows) + "</table>")
    figs = sorted((root / "figures").glob("*.png")) if (root / "figures").exists() else []
    if figs:
        body.append("<h2>Figures</h2>")
        body.extend(img(f) for f in figs)
    path = root / "report.html"
    write_text(path, page(title, "\n".join(body), plotly=False))
    return path
