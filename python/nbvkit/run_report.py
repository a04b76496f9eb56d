"""A run's ``report.html``: the summary figures, an interactive 3D view of the surface's coverage
with the trajectory and the chosen views, the progress plots, the flight section (the estimated
flight time; an export's sorties replace it: update_flight_section) and the run's figures.
Self-contained (plotly.js inlined). Importable from nbvkit.report."""
from __future__ import annotations

import csv
import html
import json
from pathlib import Path

import numpy as np

from .coverage_view import CLASS_COLOURS, CLASS_NAMES
from .htmlpage import img, page, plot_div, rounded, table, write_text
from .locks import folder_lock
from .planning.registry import parts_words
from .planning.terminations.budget import budget_note
from .runfolder import mark_incomplete, run_name, write_manifest

__all__ = [
    "write_run_report",
    "flight_section",
    "update_flight_section",
    "FLIGHT_BEGIN",
    "FLIGHT_END",
]


def write_run_report(out, summary: dict, points, classes, records=None, flight=None) -> Path:
    """``out/report.html``: the summary figures, an interactive 3D view of the surface
    (``points`` (N, 3) coloured by ``classes`` (N,): covered / observable but missed /
    unobservable) with the trajectory (``out/trajectory.csv``) and the chosen views
    (``records`` or ``out/iterations.csv``), the progress plots, the estimated flight time
    (``flight``: the mission's estimate or why there is none, see flight_section) and the run's
    PNG figures. Self-contained: plotly.js is inlined; it opens offline."""
    out = Path(out)
    its = _records(out, records)
    traces = _surface_traces(points, classes) + _flight_traces(out, its)
    layout3d = {
        "title": "surface coverage, trajectory and chosen views",
        "scene": {"aspectmode": "data"},
        "legend": {"itemsizing": "constant"},
        "margin": {"l": 0, "r": 0, "t": 40, "b": 0},
    }
    name = run_name(out)  # the folder's name once in place (not its temporary name)
    body = [f"<h1>nbvkit run: {html.escape(name)}</h1>"]
    body.append(table(_summary_rows(summary)))
    note = budget_note(summary)  # the console's note: a budget, not coverage, ended the run
    if note:
        body.append(f"<p><b>note:</b> {html.escape(note)}</p>")
    body.append(_per_res_table(summary))
    body.append(flight_section(flight))
    body.extend(_mesh_section(summary.get("reconstructed_mesh")))
    body.append("<h2>3D view</h2>")
    body.append(
        "<p>Ground-truth surface samples (decimated): green covered (their 0.1 m cell holds a "
        "reconstructed point), red observable but missed, grey unobservable from any "
        "collision-free pose. Click the legend to hide a class.</p>"
    )
    body.append(plot_div("view3d", traces, layout3d))
    if its:
        body.extend(_progress_section(its))
    figs = sorted((out / "figures").glob("*.png")) if (out / "figures").exists() else []
    if figs:
        body.append("<h2>Figures</h2>")
        body.extend(img(f) for f in figs)
    body.append(
        "<h2>summary.json</h2><pre>"
        + html.escape(json.dumps(summary, indent=1, default=str)[:20000])
        + "</pre>"
    )
    path = out / "report.html"
    write_text(path, page(f"nbvkit run {name}", "\n".join(body)))
    return path


def _surface_traces(points, classes) -> list:
    """The 3D view's surface samples, one trace per class."""
    pts = np.asarray(points, float).reshape(-1, 3)
    cls = np.asarray(classes)
    traces = []
    for k, (name, col) in enumerate(zip(CLASS_NAMES, CLASS_COLOURS)):
        p = pts[cls == k]
        traces.append(
            {
                "type": "scatter3d",
                "mode": "markers",
                "name": f"{name} ({len(p) / max(len(pts), 1):.1%})",
                "x": rounded(p[:, 0], 2),
                "y": rounded(p[:, 1], 2),
                "z": rounded(p[:, 2], 2),
                "marker": {"size": 1.6, "color": col},
                "hoverinfo": "skip",
            }
        )
    return traces


def _flight_traces(out: Path, its: list[dict]) -> list:
    """The 3D view's trajectory (out/trajectory.csv), chosen views and view directions."""
    traces = []
    traj = _read_csv(out / "trajectory.csv")
    if traj:
        traces.append(
            {
                "type": "scatter3d",
                "mode": "lines",
                "name": "trajectory",
                "x": rounded([float(r["x"]) for r in traj]),
                "y": rounded([float(r["y"]) for r in traj]),
                "z": rounded([float(r["z"]) for r in traj]),
                "line": {"color": "#1f77b4", "width": 3},
            }
        )
    if not its:
        return traces
    x = np.array([r["x"] for r in its])
    y = np.array([r["y"] for r in its])
    z = np.array([r["z"] for r in its])
    yaw = np.array([r["yaw"] for r in its])
    # the camera's axis: body yaw, then the gimbal's pitch (> 0 looks down)
    pitch = np.array([r.get("pitch", 0.0) for r in its])
    traces.append(
        {
            "type": "scatter3d",
            "mode": "markers",
            "name": "chosen views",
            "x": rounded(x),
            "y": rounded(y),
            "z": rounded(z),
            "text": [f"view {r['iteration']} ({r['source']})" for r in its],
            "marker": {"size": 2.5, "color": "#ff7f0e"},
        }
    )
    traces.append(
        {
            "type": "cone",
            "name": "view directions",
            "x": rounded(x),
            "y": rounded(y),
            "z": rounded(z),
            "u": rounded(np.cos(yaw) * np.cos(pitch)),
            "v": rounded(np.sin(yaw) * np.cos(pitch)),
            "w": rounded(-np.sin(pitch)),
            "sizemode": "absolute",
            "sizeref": 0.5,
            "anchor": "tail",
            "visible": "legendonly",
            "showscale": False,
            "colorscale": [[0, "#ff7f0e"], [1, "#ff7f0e"]],
            "showlegend": True,
        }
    )
    return traces


def _summary_rows(summary: dict) -> list[tuple]:
    return [
        ("scenario", summary.get("scenario")),
        ("start", summary.get("start")),
        ("mesh", summary.get("mesh")),
        ("iterations", summary.get("iterations")),
        ("distance flown (m)", summary.get("distance_m")),
        ("termination", summary.get("termination")),
        ("planner", parts_words(summary)),
        ("wall time (s)", summary.get("wall_time_s")),
        ("cloud points", summary.get("cloud_points")),
        ("Chamfer distance (m)", summary.get("chamfer_m")),
        (
            "observable share of the area",
            f"{100 * summary['observable_area_fraction']:.2f} %"
            if "observable_area_fraction" in summary
            else "not computed",
        ),
    ]


def _mesh_section(m) -> list[str]:
    """The reconstructed mesh's scores (or why there is no mesh.ply)."""
    if not m:
        return []
    if not m.get("written"):
        return [f"<p>No mesh.ply: {html.escape(m.get('message', ''))}</p>"]
    rows = [("triangles", m["triangles"]), ("area (m²)", m["area_m2"])]
    for key, label in (("mesh_accuracy", "accuracy"), ("mesh_completeness", "completeness")):
        rows += [(f"mesh {label} @ {t} m", f"{100 * v:.2f} %") for t, v in m[key].items()]
    rows += [("Hausdorff 95th percentile (m)", m["hausdorff95_m"])]
    return ["<h2>Reconstructed mesh (mesh.ply)</h2>", table(rows)]


def _progress_section(its: list[dict]) -> list[str]:
    """Coverage, map entropy and distance flown against the iteration."""
    body = ["<h2>Progress</h2>"]
    it = [r["iteration"] for r in its]
    cov_tr = []
    for key, lab in (
        ("coverage_005", "0.05 m"),
        ("coverage_01", "0.1 m"),
        ("coverage_05", "0.5 m"),
    ):
        xs = [r["iteration"] for r in its if r.get(key) not in (None, "")]
        ys = [float(r[key]) for r in its if r.get(key) not in (None, "")]
        if xs:
            cov_tr.append(
                {"type": "scatter", "x": xs, "y": rounded(ys, 4), "name": f"coverage @ {lab}"}
            )
    if cov_tr:
        body.append(
            plot_div(
                "progress_cov",
                cov_tr,
                {"title": "coverage", "xaxis": {"title": "iteration"}},
                "plot small",
            )
        )
    body.append(
        plot_div(
            "progress_ent",
            [
                {
                    "type": "scatter",
                    "x": it,
                    "y": rounded([r["entropy"] for r in its], 1),
                    "name": "entropy",
                },
                {
                    "type": "scatter",
                    "x": it,
                    "y": rounded([r["distance_m"] for r in its], 2),
                    "name": "distance (m)",
                    "yaxis": "y2",
                },
            ],
            {
                "title": "map entropy and distance flown",
                "xaxis": {"title": "iteration"},
                "yaxis": {"title": "entropy"},
                "yaxis2": {"title": "distance (m)", "overlaying": "y", "side": "right"},
            },
            "plot small",
        )
    )
    return body


def _per_res_table(summary: dict) -> str:
    keys = [
        ("coverage", "coverage"),
        ("coverage_observable", "coverage of the observable surface"),
        ("area_coverage", "area coverage"),
        ("area_coverage_observable", "area coverage of the observable surface"),
        ("observable_fraction", "observable share of the surface (cells)"),
        ("precision", "precision"),
    ]
    res = list(summary.get("coverage", {}))
    head = "<tr><th>per resolution</th>" + "".join(f"<th>{r} m</th>" for r in res) + "</tr>"
    rows = []
    for k, label in keys:
        if k in summary:
            rows.append(
                f"<tr><td>{label}</td>"
                + "".join(f"<td>{100 * summary[k][r]:.2f} %</td>" for r in res)
                + "</tr>"
            )
    return "<table>" + head + "".join(rows) + "</table>"


FLIGHT_BEGIN, FLIGHT_END = "<!-- nbvkit:flight -->", "<!-- /nbvkit:flight -->"
#: colours of the sorties in the report's flight view (cycled)
SORTIE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")


def flight_section(flight=None, export: dict | None = None, paths=None) -> str:
    """The report's "Flight" section (between FLIGHT_BEGIN and FLIGHT_END): the whole mission's
    estimated flight time and, with an export's budget, the sorties: a table, and ``paths``
    ((N, 3) mesh-frame waypoints per sortie) drawn in colour.

    flight: the mission's estimated flight (nbvkit.flight.estimate's dict; for a run folder,
    nbvkit.export.estimate_flight's), or the error that kept it from being estimated (an
    exception or its text); export: the summary of an export_mission, whose flight is shown
    instead."""
    if export is not None:
        mission, model = export["mission"], export["model"]
    elif isinstance(flight, dict):
        model = flight["model"]
        mission = {k: flight[k] for k in ("time_s", "distance_m", "views")}
    else:
        why = "no estimate" if flight is None else str(flight)
        body = f"<p>Flight time not estimated: {html.escape(why)}</p>"
        return f"{FLIGHT_BEGIN}<h2>Flight</h2>{body}{FLIGHT_END}"
    speed = model.get("speed", model.get("speed_m_s"))
    climb = model.get("climb_rate", model.get("climb_rate_m_s"))
    rows = [
        ("estimated flight time (min)", f"{mission['time_s'] / 60:.1f}"),
        ("flight distance with take-off and return (m)", f"{mission['distance_m']:.1f}"),
        ("views", mission["views"]),
        ("model", f"{speed:g} m/s, climb {climb:g} m/s, hover {model['hover_s']:g} s per view"),
    ]
    body = [f"<h2>Flight</h2>{table(rows)}"]
    if export is not None and export.get("budget"):
        b = export["budget"]
        limits = []
        if b.get("flight_time_min") is not None:
            limits.append(f"a {b['flight_time_min']:g} min battery ({b['reserve_pct']:g}% reserve)")
        if b.get("max_items") is not None:
            limits.append(f"at most {b['max_items']:,} mission items a file")
        body.append(
            f"<p>Sorties for {' and '.join(limits)}: {len(export['sorties'])}"
            + (f"; not flown: {len(export['unreachable'])} points" if export["unreachable"] else "")
            + "</p>"
        )
        body.append(
            table(
                [("sortie", "views / distance (m) / time (min)")]
                + [
                    (s["sortie"], f"{s['views']} / {s['distance_m']:.1f} / {s['time_min']:.2f}")
                    for s in export["sorties"]
                ]
            )
        )
        if paths:
            traces = [
                {
                    "type": "scatter3d",
                    "mode": "lines",
                    "name": f"sortie {k + 1}",
                    "x": rounded(p[:, 0]),
                    "y": rounded(p[:, 1]),
                    "z": rounded(p[:, 2]),
                    "line": {"color": SORTIE_COLOURS[k % len(SORTIE_COLOURS)], "width": 4},
                }
                for k, p in enumerate(paths)
            ]
            layout = {"title": "sorties", "scene": {"aspectmode": "data"}}
            body.append(plot_div("sorties3d", traces, layout))
    return FLIGHT_BEGIN + "\n".join(body) + FLIGHT_END


def update_flight_section(out, export: dict, paths=None) -> bool:
    """Replaces the flight section of ``out/report.html`` (if there) with one for ``export``;
    True if the report was updated. Raises OSError if the new report cannot be written, with
    the folder (report and manifest) left as it was, ValueError naming it where it is not text."""
    path = Path(out) / "report.html"
    if not path.is_file():
        return False
    with folder_lock(out):  # another export of the run waits (its report.html.tmp is ours)
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as e:
            raise ValueError(f"{path} is damaged, not a report nbvkit wrote ({e})") from None
        a, b = text.find(FLIGHT_BEGIN), text.find(FLIGHT_END)
        if a < 0 or b < a:
            return False
        new = text[:a] + flight_section(export=export, paths=paths) + text[b + len(FLIGHT_END) :]
        tmp = path.with_suffix(".html.tmp")
        try:  # written whole before the folder is touched: a full disk or a read-only folder
            tmp.write_text(new)  # leaves the run as it was, its manifest kept
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        listed = mark_incomplete(out)  # the manifest lists report.html's size
        try:
            tmp.replace(path)
        finally:  # the manifest written again, the report replaced or not (an interrupt), of
            tmp.unlink(missing_ok=True)  # the files it listed (not a user's added since)
            if listed is not None:
                write_manifest(out, only=listed)
    return True


def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _records(out: Path, records) -> list[dict]:
    if records is not None:
        return [
            {
                "iteration": r.iteration,
                "x": r.x,
                "y": r.y,
                "z": r.z,
                "yaw": r.yaw,
                "pitch": r.pitch,
                "source": r.source,
                "entropy": r.entropy,
                "distance_m": r.distance_m,
                "coverage_005": r.coverage_005,
                "coverage_01": r.coverage_01,
                "coverage_05": r.coverage_05,
            }
            for r in records
        ]
    rows = _read_csv(out / "iterations.csv")
    num = ("x", "y", "z", "yaw", "entropy", "distance_m")
    return [
        {
            **r,
            "iteration": int(r["iteration"]),
            **{k: float(r[k]) for k in num},
            "pitch": float(r.get("pitch") or 0.0),  # runs written before views had a pitch: level
        }
        for r in rows
    ]
