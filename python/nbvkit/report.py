"""What a mission leaves for a person: the observable-surface figures, the reconstruction as a
mesh (``mesh.ply``, scored against the ground truth), ``figures/coverage.png`` and a
self-contained ``report.html``; and one ``report.html`` per experiment (table, sweep, compare).

``finish_run(mission, out, summary, cache_dir)`` runs as a mission's folder is written
(``Mission.run(out, finish=True)``, ``Mission.save``); it adds to the summary and
writes the files. Each part is switched by the ``observability`` and ``report`` config sections
(``ReportConfig``, here).

The parts live in their own modules, and their names are importable from here:
nbvkit.finish (finish_run), nbvkit.reconstruction (the Poisson mesh and its scores),
nbvkit.coverage_view (the coverage classes and coverage.png), nbvkit.run_report (a run's
report.html and its flight section), nbvkit.experiment_report (an experiment's report.html) and
nbvkit.htmlpage (plotly.js and the page). A run folder's coverage colouring for a notebook,
which loads the run's configuration, is nbvkit.runview.run_view.
"""
from __future__ import annotations

from dataclasses import dataclass

from .coverage_view import CLASS_COLOURS, CLASS_NAMES, coverage_classes, plot_coverage
from .experiment_report import write_experiment_report
from .finish import finish_run
from .htmlpage import plotly_js
from .reconstruction import MIN_MESH_POINTS, reconstruct_mesh, score_mesh, write_mesh_ply
from .run_report import (
    FLIGHT_BEGIN,
    FLIGHT_END,
    flight_section,
    update_flight_section,
    write_run_report,
)
from .settings import nonneg, within

__all__ = [
    "ReportConfig",
    "finish_run",
    "reconstruct_mesh",
    "score_mesh",
    "write_mesh_ply",
    "coverage_classes",
    "plot_coverage",
    "write_run_report",
    "flight_section",
    "update_flight_section",
    "write_experiment_report",
    "plotly_js",
    "MIN_MESH_POINTS",
    "CLASS_COLOURS",
    "CLASS_NAMES",
    "FLIGHT_BEGIN",
    "FLIGHT_END",
]


@dataclass(frozen=True)
class ReportConfig:
    """End-of-run outputs: mesh.ply (Poisson), figures/coverage.png, report.html."""

    enabled: bool = True  # write them at the end of every mission
    mesh: bool = True  # reconstruct and score mesh.ply from the final cloud
    poisson_depth: int = within(8, 1, 12)  # octree depth of open3d's Poisson (experiments: 7)
    mesh_max_points: int = within(60000, 1, 10**7)  # the cloud is voxel-thinned to ~this many
    density_quantile: float = within(0.05, 0, 1)  # vertices of the lowest Poisson densities trimmed
    trim_distance: float = nonneg(0.3)  # m; vertices farther than this from the cloud are trimmed
    html: bool = True  # write report.html (plotly, self-contained)
    view_points: int = within(50000, 1, 2 * 10**6)  # ground-truth samples in the report's 3D view
