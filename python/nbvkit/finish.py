"""The end-of-run outputs of a finished mission (``finish_run``, importable from nbvkit.report):
the observable-surface figures, the reconstruction as a mesh (``mesh.ply``, scored against the
ground truth: nbvkit.reconstruction), ``figures/coverage.png`` (nbvkit.coverage_view) and a
self-contained ``report.html`` (nbvkit.run_report) with the estimated flight time
(nbvkit.flight). Each part is switched by the ``observability`` and ``report`` config sections.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import _core
from .coverage_view import plot_coverage, view_classes
from .flight import estimate
from .flight_rows import run_flight
from .flight_time import FlightModel
from .observability import observable_surface
from .reconstruction import reconstruct_mesh, score_mesh, write_mesh_ply
from .run_report import write_run_report
from .vehicle import FLIGHT_COLUMNS

__all__ = ["finish_run", "flight_estimate"]


def finish_run(mission, out, summary: dict, cache_dir=None) -> dict:
    """The end-of-run outputs of a finished mission: writes ``mesh.ply``,
    ``figures/coverage.png`` and ``report.html`` into its results folder `out` and returns
    `summary` with the observable-surface figures and the mesh scores added (the caller writes
    summary.json once, last: Mission.save / Recorder.write).

    mission: the ``nbvkit.Mission`` that has run (its evaluator, world and records are used);
    cache_dir: the observable-surface cache (default ``out/cache``; a sweep passes its own
    folder's so that every run of a structure shares one entry). Stage timings go into
    ``summary["finish_s"]``.
    """
    out = Path(out)
    cfg = mission.config
    summary = dict(summary)
    timings: dict = {}
    t_all = time.perf_counter()

    mask = None
    if cfg.observability.enabled:
        t0 = time.perf_counter()
        mask = _observable_figures(
            mission, summary, out / "cache" if cache_dir is None else cache_dir
        )
        timings["observable"] = time.perf_counter() - t0

    rep = cfg.report
    # the final clouds, read in place: never stacked whole (26 M points, 0.6 GB, on a 100 m
    # structure)
    clouds = mission.world.clouds
    if rep.enabled and rep.mesh:
        _mesh_outputs(mission, out, summary, clouds, timings)

    if rep.enabled:
        t0 = time.perf_counter()
        classes, pts = view_classes(mission.evaluator, clouds, mask, rep.view_points, cfg.seed)
        plot_coverage(pts, classes, out / "figures" / "coverage.png")
        timings["coverage_png"] = time.perf_counter() - t0
        if rep.html:
            t0 = time.perf_counter()
            summary["finish_s"] = {**timings, "total": time.perf_counter() - t_all}
            flight = flight_estimate(mission, out, summary)
            write_run_report(out, summary, pts, classes, records=mission.records, flight=flight)
            timings["report_html"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    summary["finish_s"] = timings
    return summary


def _observable_figures(mission, summary: dict, cache_dir) -> np.ndarray:
    """Computes the observable surface (cached in cache_dir), hands it to the mission's
    evaluator, adds the coverage of it and its share of the surface to `summary`; returns the
    ground-truth samples' observable mask."""
    ev = mission.evaluator
    obs = observable_surface(
        mission.mesh, mission.config, evaluator=ev, cache_dir=cache_dir, scene=mission.world.scene
    )
    mask = obs.observable
    ev.set_observable(mask)
    # of the final cloud, in one pass that keeps no per-point state: a coverage tracker would
    # hold 1.4 GiB at its peak for the 26 M points of a 100 m plant, against 0.4 GiB
    ev.forget_clouds()
    cov = ev.coverage(mission.world.clouds, track=False)
    _core.release_free_memory()  # the heap the count held, before the mesh
    for k in (
        "coverage_observable",
        "area_coverage_observable",
        "observable_fraction",
        "observable_area_fraction",
        "covered_unobservable_fraction",
        "covered_unobservable_shared_fraction",
    ):
        summary[k] = cov[k]
    summary["observability"] = {
        k: obs.stats[k]
        for k in ("samples", "observable_samples", "poses", "lattice_points", "settings")
        if k in obs.stats
    }
    summary["observability"]["cached"] = obs.cached
    summary["observability"]["compute_s"] = obs.stats.get("wall_time_s")
    return mask


def _mesh_outputs(mission, out: Path, summary: dict, clouds, timings: dict) -> None:
    """Reconstructs mesh.ply from the final clouds (read in place), writes and scores it (or
    says why not) into summary["reconstructed_mesh"]; the stages' seconds go into timings."""
    rep = mission.config.report
    t0 = time.perf_counter()
    mesh, info = reconstruct_mesh(
        clouds,
        depth=rep.poisson_depth,
        max_points=rep.mesh_max_points,
        density_quantile=rep.density_quantile,
        trim_distance=rep.trim_distance,
        viewpoints=_viewpoints(mission),
    )
    timings["mesh"] = time.perf_counter() - t0
    if mesh is None:
        print(f"mesh.ply not written: {info['message']}")
        summary["reconstructed_mesh"] = {"written": False, "message": info["message"]}
        return
    write_mesh_ply(out / "mesh.ply", mesh)
    t0 = time.perf_counter()
    taus = tuple(float(t) for t in summary["completeness"])
    scores = score_mesh(mesh, mission.evaluator, taus=taus)
    timings["mesh_score"] = time.perf_counter() - t0
    summary["reconstructed_mesh"] = {"written": True, **info, **scores}


def _viewpoints(mission) -> np.ndarray:
    """Where the sensors were: the trajectory's rows and the chosen views, (K, 3)."""
    rows = [r[1:4] for r in mission.world.state.trajectory]
    rows += [(r.x, r.y, r.z) for r in mission.records]
    return np.asarray(rows, float).reshape(-1, 3)


def flight_estimate(mission, out, summary: dict):
    """The mission's estimated flight (nbvkit.flight.estimate at FlightModel's default speeds:
    what nbvkit.export.estimate_flight gives for the finished run folder), from the mission in
    memory (its folder `out` holds no summary.json yet), or the error that kept it from being
    estimated (OSError, ValueError, RuntimeError: no launch point, ...)."""
    try:
        rows = [dict(zip(FLIGHT_COLUMNS, r)) for r in mission.world.state.flight]
        map_path = Path(out) / "map.ot"
        fl = run_flight(
            out,
            rows,
            summary.get("workspace") or {},
            mission.config,
            map_path if map_path.is_file() else None,
        )
        return estimate(fl, FlightModel(), occ_map=mission.map)
    except (OSError, ValueError, RuntimeError) as err:
        return err
