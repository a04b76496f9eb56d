"""A finished run folder reopened for a look (notebooks/run.ipynb): its surface's coverage
colouring rebuilt from config.yaml and cloud.ply. Above nbvkit.config (it loads the run's
configuration), so not part of nbvkit.report."""
from __future__ import annotations

from .cloud import read_points
from .config import load_config
from .coverage_view import view_classes
from .evaluation import Evaluator
from .mesh import flown_mesh
from .observability import observable_surface
from .runfolder import read_summary, require_complete_run

__all__ = ["run_view"]


def run_view(run_dir, view_points: int = 60000):
    """The coverage colouring of a finished run folder: ``(points, classes, summary)`` with a
    subsample of the ground-truth samples (N, 3) and their class (0 covered, 1 observable but
    missed, 2 unobservable), rebuilt from its ``config.yaml`` and ``cloud.ply`` (the observable
    surface comes from the run's cache when it is there). ValueError where the mesh it flew
    cannot be had from here: not found, changed since the run, or given in memory."""
    run_dir = require_complete_run(run_dir)
    cfg = load_config(run_dir / "config.yaml", [])
    summary = read_summary(run_dir)
    mesh, why = flown_mesh(cfg, summary)
    if mesh is None:  # (another mesh would colour the cloud against another structure)
        raise ValueError(f"run_view: the run {run_dir} cannot be coloured: {why}")
    ev = Evaluator(mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
    # the run's cache, or an experiment's (DIR/runs/RUN: DIR/cache) where there is one; else the
    # run's own folder, not whatever lies two folders above a run of its own
    shared = run_dir.parent.parent / "cache"
    own = run_dir / "cache"
    cache = (
        shared if not own.exists() and run_dir.parent.name == "runs" and shared.exists() else own
    )
    mask = observable_surface(mesh, cfg, evaluator=ev, cache_dir=cache).observable
    classes, pts = view_classes(ev, read_points(run_dir / "cloud.ply"), mask, view_points, cfg.seed)
    return pts, classes, summary
