"""Scoring a reconstruction against ground truth: coverage (the paper's metric), area coverage,
precision, completeness / accuracy / F-score and the Chamfer distance. The work is one C++ call
(``nbv::evaluate``); this module adapts arguments and shapes the result as a JSON-ready dict.

Ground-truth density. The cell count ``coverage`` depends on how densely the mesh is sampled:
a cell the surface only grazes is a GT cell only if a sample happens to land in it. The
default, DEFAULT_GT_DENSITY = 1000 points per m², was chosen by measurement
(``bench/bench_evaluation.py --stability``) on ../shared/meshes/twinjet.obj (727 m²) against
a camera reconstruction from 60 random views (1.17 M points after the 0.02 m voxel filter),
evaluated with GT seeds 0-7 (pp = percentage points)::

    density  samples   coverage 0.05 m           0.1 m    0.5 m    area_coverage 0.05 m
    (/m²)              mean    spread  std       spread   spread   mean     spread
      250      182 k   68.41 %  0.27   0.10 pp   0.24     0.24     68.58 %  0.25
      500      364 k   68.19 %  0.22   0.07      0.12     0.19     68.55 %  0.21
     1000      727 k   67.81 %  0.11   0.03      0.05     0.18     68.51 %  0.18
     2000     1.45 M   67.16 %  0.06   0.02      0.06     0.11     68.51 %  0.09
     4000     2.91 M   66.30 %  0.05   0.02      0.03     0.11     68.50 %  0.07
     8000     5.82 M   65.42 %  0.04   0.01      0.06     0.10     68.50 %  0.04
    16000    11.6 M    64.66 %  0.04   0.01      0.03     0.05     68.50 %  0.04

Every density keeps the spread of 8 seeds under 0.5 pp, but below 1000 /m² the standard
deviation (0.07-0.10 pp) lets the range over more seeds approach it (±3σ = 0.4-0.6 pp);
1000 /m² is the smallest with a wide margin (σ 0.03 pp; a sparse 0.1 m-voxel cloud: spread
0.08 pp) and it evaluates a 1 M-point cloud in under a second. Note the *mean* of
``coverage`` drifts down by ~0.7 pp per doubling of the density (more grazed cells become GT
cells), so coverage figures are comparable only at the same density: always quote it (the
result carries it). ``area_coverage`` does not drift (68.5 % at every density). Distances
are to the GT *samples*: a point exactly on the surface is on average ~0.5/√density from
the nearest sample (≈ 1.6 cm at 1000 /m²), a floor under ``chamfer_m``, and it is farther
than tau from every sample with probability exp(−π tau² density) (0.04 % at tau = 0.05 m,
1000 /m²: a perfect cloud scores 99.96 % accuracy there). Raise ``gt_density`` for
sub-centimetre Chamfer comparisons (2000 /m² takes that probability to 1.5e-7).
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _core
from ._core import Mesh
from .cloud import _as_points, _is_cloud_list
from .settings import nonneg, positive

__all__ = [
    "evaluate",
    "Evaluator",
    "format_report",
    "DEFAULT_GT_DENSITY",
    "DEFAULT_RESOLUTIONS",
    "DEFAULT_TAUS",
    "MAX_GT_POINTS",
    "SUMMARY_KEYS",
]

_DEF = _core.EvaluationOptions()
#: Ground-truth samples per m² of mesh surface (see ``evaluate`` for how it was chosen).
DEFAULT_GT_DENSITY: float = _DEF.gt_density
#: The paper's three coverage resolutions, metres.
DEFAULT_RESOLUTIONS: tuple = tuple(_DEF.resolutions)
#: Distance thresholds of completeness / accuracy / F-score, metres.
DEFAULT_TAUS: tuple = tuple(_DEF.taus)
#: Cap on the number of ground-truth samples (area × density is capped to it, with a warning).
MAX_GT_POINTS: int = _DEF.max_gt_points
#: The headline figures of an ``evaluate`` result that a run's summary carries.
SUMMARY_KEYS: tuple = (
    "coverage",
    "area_coverage",
    "precision",
    "completeness",
    "accuracy",
    "fscore",
    "chamfer_m",
    "n_points",
    "gt_density",
    "gt_area_m2",
)


@dataclass(frozen=True)
class EvaluationConfig:
    """Scoring against the ground truth."""

    gt_density: Optional[float] = positive(None)  # points per m^2; None: nbvkit.evaluate's default
    # iterations between coverage refreshes in the progress and iterations.csv, whose last row
    # then holds the run's coverage (a checkpoint's: as refreshed); 0: none
    coverage_every: int = nonneg(25)


def _key(v: float) -> str:
    return f"{v:g}"


def _evaluator_keywords(kw: dict) -> dict:
    """The keyword overrides with a single resolution or tau accepted as a number."""
    return {
        k: (v,) if k in ("resolutions", "taus") and isinstance(v, numbers.Real) else v
        for k, v in kw.items()
    }


def evaluate(gt, cloud, options=None, **kw) -> dict:
    """Score a reconstructed cloud against ground truth.

    Args:
        gt: the structure's ``Mesh`` (its surface is sampled uniformly, area-weighted, at
            ``gt_density`` points per m² with ``seed``: ``mesh.sample_surface(round(area *
            gt_density), seed)``), or a reference point cloud ``(M, 3)`` used as is (as the
            authors did, with a densified cloud of their mesh).
        cloud: the reconstruction, ``(N, 3)`` float64 world-frame points, or a ``PointCloud``.
        options: an ``EvaluationOptions`` (or a dict of its fields, or None for the defaults),
            with keyword overrides of its fields (a keyword set to None keeps the value):

            - ``resolutions``: cell sizes (m) of the coverage grids; the paper's 0.05 / 0.1 / 0.5
              (one number is accepted for one grid);
            - ``taus``: distance thresholds (m) of completeness / accuracy / F-score;
            - ``gt_density``: ground-truth samples per m² (mesh only);
            - ``seed``: seed of the ground-truth sampling; the same seed gives identical results;
            - ``max_gt_points``: cap on the number of samples; a larger ``area * gt_density`` is
              capped with a ``RuntimeWarning``;
            - ``part_points``: the distances are scored one part of the cloud at a time, holding
              a kd-tree of at most this many points (about 54 bytes each; default 4,194,304):
              the same figures, but for the last bits of the mean distances.

    Returns a dict (JSON-ready: plain floats/ints, ``None`` instead of NaN). Per resolution r,
    keyed ``f"{r:g}"`` ("0.05", "0.1", "0.5"), with every point in cell ``floor(p / r)`` of one
    grid anchored at the origin; a coordinate within 1e-9 (relative) of a cell boundary lies on
    it, in the cell above, so that a face on a boundary plane (an axis-aligned face at a
    multiple of r) keeps its samples and the points reconstructed on it in one cell whatever
    the last bits of their coordinates (floor alone split them between two layers of cells):

    - ``coverage``: the paper's metric — GT cells also holding a cloud point ÷ GT cells.
    - ``area_coverage``: the fraction of GT surface area whose cell holds a cloud point, i.e.
      the fraction of (area-uniform) GT samples in such cells. Unlike ``coverage`` it does not
      depend on the sampling density in expectation: a cell the surface only grazes counts by
      its area, not as a whole cell.
    - ``precision``: cloud cells also holding a GT sample ÷ cloud cells. It rises with the GT
      density (at 0.05 m a cell holds ~2.5 samples at 1,000 per m^2: many surface cells none);
      ``accuracy`` does not.

    Per threshold tau (keys "0.05", "0.1"), with exact nearest-neighbour distances:

    - ``completeness``: GT samples within tau (``<=``) of a cloud point ÷ GT samples.
    - ``accuracy``: cloud points within tau of a GT sample ÷ cloud points.
    - ``fscore``: 2PR / (P + R) with P = accuracy, R = completeness (0 when both are 0).

    And ``chamfer_m``: 0.5 · (mean cloud→GT + mean GT→cloud nearest distance), metres (``None``
    for an empty cloud), ``mean_dist_cloud_to_gt_m`` / ``mean_dist_gt_to_cloud_m`` (its two
    halves), ``n_points``, ``n_gt_points``, ``gt_density`` (samples per m² used; ``None`` for a
    reference cloud), ``gt_area_m2`` (``None`` for a reference cloud), ``gt_source`` ("mesh" or
    "points"), ``seed``, ``resolutions``, ``taus``, and the cell counts ``gt_cells``,
    ``cloud_cells``, ``covered_cells`` per resolution.

    With an observable mask (``Evaluator.set_observable``, ``nbvkit.observable_surface``) the
    result also holds, per resolution: ``coverage_observable`` (covered cells among the cells
    holding an observable sample ÷ those cells), ``area_coverage_observable`` (observable
    samples in covered cells ÷ observable samples) and ``observable_fraction`` (cells holding an
    observable sample ÷ GT cells: the observable share of the surface measured in cells of that
    size), plus ``observable_area_fraction`` (observable samples ÷ samples: the observable share
    of the area), ``covered_unobservable_fraction`` (per resolution: samples in covered cells
    that the mask holds unobservable ÷ samples), ``covered_unobservable_shared_fraction`` (the
    part of it in cells that also hold an observable sample: a part thinner than the cell, an
    edge, where the cell's points may all lie on the observable side; the rest lies in cells of
    its own: seen at a grazing angle the mask does not count, or from where the mask's lattice
    has no position) and the cell counts ``observable_cells``, ``covered_observable_cells``.

    An empty cloud scores 0 everywhere with ``chamfer_m`` None. Raises ValueError for NaN/inf in
    either input (naming which), non-positive or duplicate resolutions or taus, an unknown
    option, or an empty ground truth.

    Ground-truth density: DEFAULT_GT_DENSITY = 1000 points per m², chosen by measurement (the
    module's docstring: coverage figures are comparable only at the same density).
    Threads do not change any number (per-point results, sums in a fixed order).
    """
    return Evaluator(gt, options, _stacklevel=3, **kw)(cloud)


class Evaluator:
    """Ground truth prepared once, to score many clouds against it (e.g. during a mission).

    ``Evaluator(gt, options, **kw)`` takes the arguments of ``evaluate`` except the cloud
    (``options`` is an ``EvaluationOptions``, a dict or None, with keyword overrides); sampling the
    mesh, the samples' kd-tree and their cells at every resolution are built here, once.
    ``evaluator(cloud)`` (or ``.evaluate(cloud)``) then returns exactly what
    ``evaluate(gt, cloud, ...)`` would. ``gt_points`` is the ``(M, 3)`` ground truth used.
    """

    def __init__(self, gt, options=None, *, _stacklevel: int = 2, **kw):
        if not isinstance(gt, Mesh):
            gt = _as_points(gt)
        self._core = _core._Evaluator(gt, options, **_evaluator_keywords(kw))
        self._tracker = None  # coverage() of growing SurfaceClouds, made on first use
        o = self._core.options
        for what, values in (("resolutions", o.resolutions), ("taus", o.taus)):
            keys = [_key(v) for v in values]  # the result's dict keys must not collide
            if len(set(keys)) != len(keys):
                raise ValueError(f"{what} has duplicate values: {list(values)}")
        for w in self._core.gt_info.warnings:
            warnings.warn(w, RuntimeWarning, stacklevel=_stacklevel)

    def evaluate(self, cloud) -> dict:
        """Score ``cloud`` ((N, 3), a PointCloud, or a list of them scored as their points
        stacked, without holding a stacked copy); see ``nbvkit.evaluate`` for the dict."""
        if _is_cloud_list(cloud):
            return _to_dict(self._core.evaluate_of(list(cloud)))
        return _to_dict(self._core.evaluate(_as_points(cloud)))

    __call__ = evaluate

    def forget_clouds(self) -> None:
        """Frees the ``CoverageTracker`` that ``coverage`` keeps of a list of clouds (its state
        per cloud point: 0.7 GB for the 100 m plant's 19 M points); a later such call builds it
        again. A mission calls it before its final ``evaluate``, which does not use it."""
        self._tracker = None

    def set_observable(self, mask) -> None:
        """Marks which ground-truth samples (``gt_points`` order) are observable (a ``(M,)``
        bool array, e.g. from ``nbvkit.observable_surface``). Every later result also carries
        ``coverage_observable``, ``area_coverage_observable``, ``observable_fraction`` (per
        resolution) and ``observable_area_fraction``. ``None`` clears it."""
        if mask is None:
            self._core.set_observable(np.zeros(0, bool))
            return
        mask = np.asarray(mask)
        if mask.shape != (self.num_gt_points,):
            raise ValueError(
                f"observable mask must have shape ({self.num_gt_points},), got {mask.shape}"
            )
        if mask.dtype != bool and not (
            mask.dtype.kind in "iuf" and np.isin(mask, (0, 1)).all()
        ):  # 0.5 or NaN is no answer to "observable?": refused, not rounded
            raise ValueError(f"observable mask must be bool (or 0/1), got dtype {mask.dtype}")
        self._core.set_observable(mask.astype(bool))

    @property
    def options(self) -> _core.EvaluationOptions:
        """The ``EvaluationOptions`` used (a copy)."""
        return self._core.options

    @property
    def has_observable(self) -> bool:
        return self._core.has_observable

    def coverage(self, cloud, track: bool = True) -> dict:
        """The cell figures of ``evaluate`` alone (``coverage``, ``area_coverage``, ``precision``,
        their cell counts, and the observable figures when set) at a fraction of its cost: no
        kd-tree, no distances. ``cloud``: points, or a list of ``SurfaceCloud`` objects read in
        place, one after the other (the same figures as of their points stacked, without copying
        them: a mission's progress refreshes).

        For a list of clouds the evaluator keeps a ``CoverageTracker``: a later call with the same
        clouds, grown since, looks again only at the voxels added or moved (the same figures; it
        holds 4 bytes per cloud point and 4 more per resolution). ``track=False``: one pass
        instead, per cloud cell only, that keeps nothing (a last call: a quarter of the tracker's
        memory, in half its time)."""
        if not _is_cloud_list(cloud):
            d = _to_dict(self._core.evaluate_cells(_as_points(cloud)))
        elif not track:
            d = _to_dict(self._core.evaluate_cells_of(list(cloud)))
        else:
            if self._tracker is None:
                self._tracker = _core.CoverageTracker(self._core)
            d = _to_dict(self._tracker.update(list(cloud)))
        keep = (
            "coverage",
            "area_coverage",
            "precision",
            "gt_cells",
            "cloud_cells",
            "covered_cells",
        ) + _OBSERVABLE_KEYS
        return {k: v for k, v in d.items() if k in keep or k.startswith("n_")}

    @property
    def gt_points(self) -> np.ndarray:
        """(M, 3) float64 ground-truth points (mesh samples in sampling order, or the reference)."""
        return self._core.gt_points

    @property
    def num_gt_points(self) -> int:
        return self._core.num_gt_points

    def __repr__(self) -> str:
        info = self._core.gt_info
        src = (
            f"mesh sampled at {info.gt_density:.0f} points/m^2"
            if info.from_mesh
            else "reference cloud"
        )
        return f"<nbvkit.Evaluator {self.num_gt_points} ground-truth points, {src}>"


_OBSERVABLE_KEYS = (
    "coverage_observable",
    "area_coverage_observable",
    "observable_fraction",
    "observable_area_fraction",
    "observable_cells",
    "covered_observable_cells",
    "covered_unobservable_fraction",
    "covered_unobservable_shared_fraction",
)


def unobservable_note(result: dict, resolution: str = "0.05", above: float = 0.02) -> str | None:
    """The words for a result (an evaluation's or a run's summary) whose covered cells hold more
    than `above` of the area that the observable surface counts unseeable; None otherwise."""
    total = result.get("covered_unobservable_fraction", {}).get(resolution, 0.0)
    if total <= above:
        return None
    shared = result.get("covered_unobservable_shared_fraction", {}).get(resolution, 0.0)
    return (
        f"{total:.1%} of the area lies in covered {resolution} m cells though the observable "
        f"surface counts it unseeable: {shared:.1%} in cells that also hold observable surface (a "
        f"part thinner than the cell, an edge: their camera points may all lie on the seen side), "
        f"{total - shared:.1%} in cells of its own (seen at a grazing angle beyond "
        "observability.max_incidence_deg, or from where the observable surface's lattice has no "
        "position: a finer --set observability.pose_spacing=S counts more of those)"
    )


def _to_dict(r) -> dict:
    rk = [_key(v) for v in r.resolutions]
    tk = [_key(v) for v in r.taus]

    def per(keys, values):
        return {k: float(v) for k, v in zip(keys, values)}

    def per_int(keys, values):
        return {k: int(v) for k, v in zip(keys, values)}

    out = _to_dict_base(r, rk, tk, per, per_int)
    if r.has_observable:
        out["coverage_observable"] = per(rk, r.coverage_observable)
        out["area_coverage_observable"] = per(rk, r.area_coverage_observable)
        out["observable_fraction"] = per(rk, r.observable_fraction)
        out["observable_area_fraction"] = float(r.observable_area_fraction)
        out["observable_cells"] = per_int(rk, r.observable_cells)
        out["covered_observable_cells"] = per_int(rk, r.covered_observable_cells)
        # the share of the area in covered cells though the observable surface counts it
        # unseeable, and the part of it whose cells also hold observable samples
        seen = {
            k: c * out["observable_area_fraction"]
            for k, c in out["area_coverage_observable"].items()
        }
        out["covered_unobservable_fraction"] = {
            k: max(0.0, out["area_coverage"][k] - v) for k, v in seen.items()
        }
        out["covered_unobservable_shared_fraction"] = {
            k: max(0.0, c - seen[k]) for k, c in zip(rk, r.area_coverage_observable_cells)
        }
    return out


def _to_dict_base(r, rk, tk, per, per_int) -> dict:
    return {
        "coverage": per(rk, r.coverage),
        "area_coverage": per(rk, r.area_coverage),
        "precision": per(rk, r.precision),
        "completeness": per(tk, r.completeness),
        "accuracy": per(tk, r.accuracy),
        "fscore": per(tk, r.fscore),
        "chamfer_m": r.chamfer,
        "mean_dist_cloud_to_gt_m": r.mean_cloud_to_gt,
        "mean_dist_gt_to_cloud_m": r.mean_gt_to_cloud,
        "n_points": int(r.n_points),
        "n_gt_points": int(r.n_gt_points),
        "gt_density": float(r.gt_density) if r.from_mesh else None,
        "gt_area_m2": float(r.gt_area) if r.from_mesh else None,
        "gt_source": "mesh" if r.from_mesh else "points",
        "seed": int(r.seed) if r.from_mesh else None,
        "resolutions": [float(v) for v in r.resolutions],
        "taus": [float(v) for v in r.taus],
        "gt_cells": per_int(rk, r.gt_cells),
        "cloud_cells": per_int(rk, r.cloud_cells),
        "covered_cells": per_int(rk, r.covered_cells),
    }


def _pct(v):
    return f"{100 * v:6.2f} %"


def format_report(result: dict) -> str:
    """A readable table of an ``evaluate`` result."""
    out = []
    if result.get("gt_source") == "mesh":
        out.append(
            f"ground truth: mesh, {result['gt_area_m2']:.1f} m^2 sampled at "
            f"{result['gt_density']:.0f} points/m^2 ({result['n_gt_points']:,} samples, "
            f"seed {result['seed']})"
        )
    else:
        out.append(f"ground truth: reference cloud, {result['n_gt_points']:,} points")
    out.append(f"cloud: {result['n_points']:,} points")
    out.append("")
    out.append(
        f"{'resolution':>10}  {'coverage':>9}  {'area cov.':>9}  {'precision':>9}  "
        f"{'GT cells':>10}  {'cloud cells':>11}"
    )
    for k in result["coverage"]:
        out.append(
            f"{k + ' m':>10}  {_pct(result['coverage'][k]):>9}  "
            f"{_pct(result['area_coverage'][k]):>9}  {_pct(result['precision'][k]):>9}  "
            f"{result['gt_cells'][k]:>10,}  {result['cloud_cells'][k]:>11,}"
        )
    out.append("")
    if "coverage_observable" in result:
        out.append(
            f"observable surface: {_pct(result['observable_area_fraction']).strip()} of the area"
        )
        out.append(f"{'resolution':>10}  {'obs. cov.':>9}  {'obs. area':>9}  {'obs. cells':>10}")
        for k in result["coverage_observable"]:
            out.append(
                f"{k + ' m':>10}  {_pct(result['coverage_observable'][k]):>9}  "
                f"{_pct(result['area_coverage_observable'][k]):>9}  "
                f"{_pct(result['observable_fraction'][k]):>10}"
            )
        note = unobservable_note(result)
        if note:
            out.append("note: " + note)
        out.append("")
    out.append(f"{'tau':>10}  {'complete.':>9}  {'accuracy':>9}  {'F-score':>9}")
    for k in result["completeness"]:
        out.append(
            f"{k + ' m':>10}  {_pct(result['completeness'][k]):>9}  "
            f"{_pct(result['accuracy'][k]):>9}  {_pct(result['fscore'][k]):>9}"
        )
    out.append("")
    if result["chamfer_m"] is None:
        out.append("Chamfer distance: n/a (empty cloud)")
    else:
        out.append(
            f"Chamfer distance: {result['chamfer_m']:.4f} m (cloud->GT "
            f"{result['mean_dist_cloud_to_gt_m']:.4f} m, GT->cloud "
            f"{result['mean_dist_gt_to_cloud_m']:.4f} m)"
        )
    return "\n".join(out)
