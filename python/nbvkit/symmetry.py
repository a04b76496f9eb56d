"""Reflective-symmetry detection and symmetric prediction (the paper's sec. 3.2.2 and Fig. 3).

The work is done in C++ with PCL (``nbvkit._core``); this module holds thin wrappers with the
documentation and the mission-stage hook :func:`run_symmetry_prediction`; the figures
(:func:`plot_symmetry`, open3d's view) are in nbvkit.symmetry_figures, re-exported here.

Pipeline of :func:`detect_symmetry` (any pose: nothing assumes the plane's orientation or position)

1. voxel-grid downsampling (``voxel_size``, 0.2 m = twice the profile's laser voxel) and normals
   from ``normal_k`` = 50 neighbours (authors), oriented away from the centroid;
2. keypoints: 3D SIFT on the curvature (``keypoints="sift"``, authors: min scale 0.1 m, 3 octaves,
   4 scales per octave, min contrast 1e-4), or ``"iss"`` (intrinsic shape signatures), or
   ``"uniform"`` (one per cell of a ``uniform_leaf`` grid);
3. FPFH descriptors at the keypoints, the whole cloud as search surface (``fpfh_radius``);
4. each keypoint is matched to its most similar *other* keypoint. FPFH is not mirror-invariant:
   a reflection keeps the Darboux frame's u = n_s and w = u x v (up to the reflection) but flips
   v = d x u, so of PCL's three angular features only f2 = v . n_t changes sign. A keypoint's
   descriptor is therefore compared with the *mirrored* descriptors of the others (the 11 bins of
   the f2 sub-histogram reversed; f1 and f3 unchanged — checked on a mirrored cloud by
   ``tests/test_symmetry.py``). Candidates closer than ``min_pair_distance`` or whose normals are
   not mirror images about the pair's bisector (``max_normal_angle_deg``) are skipped;
5. every pair votes for its perpendicular-bisector plane; mean shift (flat kernel, ``bandwidth``
   over |n_a - n_b| and the offset difference divided by the cloud's RMS radius,
   ``mean_shift_seeds`` = 50 seeds as the authors) finds the modes; a plane and its negation are
   the same plane: each votes with both signs, so no cluster is split at a sign boundary;
6. the ``candidate_modes`` modes of most support are refined by reflective point-to-plane ICP and
   scored; the most mirror-consistent wins. Confidence = the fraction of points facing the plane
   (normal within ``facing_angle_deg``) whose reflection lies on an observed surface (within
   ``consistency_tolerance`` of the tangent plane of an observed point at most
   ``consistency_radius`` away). Surfaces perpendicular to a plane are left out because they map
   onto themselves under any reflection across them (the walls of every box), which is no
   evidence. ``accepted`` = support >= ``min_support`` and confidence >= ``min_confidence``.

:func:`predict_symmetric` reflects the cloud about a plane, aligns the reflection onto the cloud
with PCL's ICP (point-to-plane by default; authors: max correspondence 1 m, transformation
epsilon 1e-3, fitness epsilon 1e-2), takes the corrected plane from the improper isometry
ICP o reflection (the eigenvector of its linear part with eigenvalue -1, d from the
translation) and predicts the reflected points that no observed point explains.
"""
from __future__ import annotations

import math
import re
import time
from typing import Any

import numpy as np

from . import _core
from .limits import Bound
from .settings import cpp_section
from .symmetry_figures import plot_symmetry, show_symmetry_open3d, symmetry_geometries  # noqa: F401

SymmetryResult = _core.SymmetryResult
SymmetricPrediction = _core.SymmetricPrediction
PlaneClusters = _core.PlaneClusters
SymmetryOptions = _core.SymmetryOptions
SymmetricPredictionOptions = _core.SymmetricPredictionOptions

reflect_points = _core.reflect_points
reflection_matrix = _core.reflection_matrix
plane_from_pair = _core.plane_from_pair
canonical_plane = _core.canonical_plane
mirror_fpfh = _core.mirror_fpfh


SymmetryConfig = cpp_section(
    "SymmetryConfig",
    _core.SymmetryOptions,
    """Symmetry detection and prediction (sec. 3.2.2), owned by nbvkit.symmetry.

    The mission's keys, then every option of detect_symmetry (SymmetryOptions) and of
    predict_symmetric (SymmetricPredictionOptions), named, defaulted and documented by the C++
    structs.""",
    before=[
        ("mode", str, "predict", "none | report (detect, write nothing) | predict (into the map)"),
        ("refresh_every", int, 10, "views between re-predictions from the camera cloud (0: never)"),
        ("prediction_probability", float, 0.6, "of a predicted cell (paper; authors' code: 0.7)"),
    ],
    extra=(_core.SymmetricPredictionOptions,),
    choices={"mode": ("none", "report", "predict"), "keypoints": ("sift", "iss", "uniform")},
    bounds={
        "refresh_every": Bound(lo=0, hi=10**6),
        "prediction_probability": Bound(lo=0.5, hi=1, lo_open=True, hi_open=True),
        "max_descriptor_distance": Bound(inf=True),
        "normal_k": Bound(hi=1000),
        "sift_octaves": Bound(hi=16),
        "sift_scales_per_octave": Bound(hi=32),
        "matches_per_keypoint": Bound(hi=100),
        "mean_shift_seeds": Bound(hi=10_000),
        "mean_shift_max_iterations": Bound(hi=100_000),
        "candidate_modes": Bound(hi=1000),
        "refine_iterations": Bound(hi=1000),
        "refine_max_points": Bound(hi=10**7),
        "icp_normal_k": Bound(hi=1000),
        "icp_max_iterations": Bound(hi=100_000),
        # voxel grids' cells (voxelgrid_sampling takes up to 1000 m): named here, before any work
        "voxel_size": Bound(hi=1000),
        "icp_voxel_size": Bound(hi=1000),
        "uniform_leaf": Bound(hi=1000),
    },
)


def _options_doc(options_type) -> str:
    """The options' documentation, generated from the bound C++ struct (its one source)."""
    defaults = options_type()
    return "\n".join(
        f"    - ``{name}`` = {getattr(defaults, name)!r}: {doc}"
        for name, doc in options_type.fields().items()
    )


def detect_symmetry(points, options=None, **overrides) -> SymmetryResult:
    """Detects the dominant mirror plane of a point cloud.

    points: (N, 3) float64, any frame, any pose (N >= 10). options: a :class:`SymmetryOptions`, a
    dict of its fields or None (the defaults); keyword overrides are applied on top (None keeps
    the value). See the module docstring for the pipeline; the options are listed below.

    Returns a :class:`SymmetryResult`: ``plane`` (4,) [nx, ny, nz, d] with unit normal n and
    n . p = d on the plane (sign: the largest |n_i| positive), ``support`` (pairs voting for it),
    ``confidence`` in [0, 1], ``accepted``, ``reason`` (why not accepted), and diagnostics:
    ``keypoints`` (K, 3), ``pairs`` (P, 2) indices into keypoints, ``pair_planes`` (P, 4),
    ``pair_distances`` (P,), ``inliers`` (P,) bool, ``modes`` (M, 4), ``mode_support`` (M,),
    ``mode_confidence`` (M,) (NaN: not checked), ``vote_share``, ``consistency_all``,
    ``facing_fraction``, ``num_points`` (after downsampling), ``scale`` (m) and ``timings``
    (dict stage -> seconds, with "total"). When no pair survives matching, ``plane`` is NaN and
    ``support`` 0. The plane is reported even when not accepted (for diagnostics): use it only if
    ``accepted``.

    Raises ValueError for a wrong shape, NaN/inf, fewer than 10 points or a bad option (an
    unknown name, a wrong type or a bad value). Runs without the GIL; deterministic (the same
    input gives the same plane).

    Options (``SymmetryOptions.fields()``; default, then meaning):
    """
    return _core.detect_symmetry(points, options, **overrides)


def predict_symmetric(points, plane, options=None, **overrides) -> SymmetricPrediction:
    """Predicts the unobserved mirror half of a cloud.

    points: (N, 3) float64 observed points (N >= 10); plane: [nx, ny, nz, d] (any scale and sign;
    normalised). options: a :class:`SymmetricPredictionOptions`, a dict of its fields or None;
    keyword overrides on top (e.g. ``icp=False`` skips the paper's step 7, the ICP refinement).

    Returns a :class:`SymmetricPrediction` that unpacks as ``(predicted, plane)``:
    ``predicted`` (M, 3) world-frame points = every input point reflected about the (corrected)
    plane, minus those within explained_tolerance of an observed point; ``plane`` (4,) the
    corrected plane; plus ``input_plane``, ``transform`` (4x4 improper isometry ICP o reflection),
    ``icp_converged``, ``icp_applied``, ``icp_fitness`` (m^2), ``residual_rotation_deg`` and
    ``timings``. Raises ValueError for bad points, a bad plane or a bad option.

    Options (``SymmetricPredictionOptions.fields()``; default, then meaning):
    """
    return _core.predict_symmetric(points, plane, options, **overrides)


detect_symmetry.__doc__ += "\n" + _options_doc(SymmetryOptions) + "\n"
predict_symmetric.__doc__ += "\n" + _options_doc(SymmetricPredictionOptions) + "\n"


def mean_shift_planes(
    planes,
    center,
    scale: float,
    bandwidth: float = SymmetryOptions().bandwidth,
    seeds: int = SymmetryOptions().mean_shift_seeds,
    max_iterations: int = SymmetryOptions().mean_shift_max_iterations,
) -> PlaneClusters:
    """Mean shift over planes (P, 4) [nx, ny, nz, d] (step 5 of detect_symmetry, exposed).

    Distance between planes: sqrt(|n_a - n_b|^2 + ((d_a - n_a.c) - (d_b - n_b.c))^2 / scale^2)
    with c = ``center`` (metres) and ``scale`` (metres); each plane votes with both signs. Seeds:
    the ``seeds`` planes of highest vote density, one bandwidth apart. Returns a
    :class:`PlaneClusters`: ``plane`` (4,) the mode of most support, ``support``, ``inliers``
    (P,) bool, ``modes`` (M, 4) most support first, ``mode_support`` (M,).
    """
    return _core.mean_shift_planes(planes, center, scale, bandwidth, seeds, max_iterations)


def plane_from_improper_isometry(transform) -> tuple[np.ndarray, float]:
    """(plane, residual_rotation_deg) of a 4x4 improper isometry x -> A x + t (det A < 0): the
    eigenvector of A's symmetric part with the smallest eigenvalue (-1 for a mirror), d = n.t / 2.
    Raises ValueError for a proper (det > 0) transform."""
    return _core.plane_from_improper_isometry(np.asarray(transform, float))


def compute_fpfh(
    points,
    indices,
    normal_k: int = SymmetryOptions().normal_k,
    radius: float = SymmetryOptions().fpfh_radius,
) -> np.ndarray:
    """(K, 33) float32 PCL FPFH at points[indices] (every point as search surface; normals from
    normal_k neighbours, oriented away from the centroid). For tests and diagnostics."""
    return _core.compute_fpfh(points, [int(i) for i in indices], normal_k, radius)


# ------------------------------------------------------------------------------ mission hook


def _finite_or_none(x) -> Any:
    x = float(x)
    return x if math.isfinite(x) else None


def detection_options(cfg) -> dict:
    """detect_symmetry keyword options (every SymmetryOptions field) from a SymmetryConfig."""
    return cfg.options_for(SymmetryOptions).to_dict()


def prediction_options(cfg) -> dict:
    """predict_symmetric keyword options (every SymmetricPredictionOptions field) from a
    SymmetryConfig."""
    return cfg.options_for(SymmetricPredictionOptions).to_dict()


def run_symmetry_prediction(mission, write_map: bool = True) -> dict:
    """The mission's symmetry stage (after profiling): detect the mirror plane of the laser profile
    ``mission.laser_cloud.points``, and if it is accepted predict the unobserved half and write it
    into ``mission.map`` with ``set_unknown_cells(predicted, cfg.prediction_probability)`` (only
    unknown cells change; a later observation overrides a prediction). Config:
    ``mission.config.symmetry`` (a SymmetryConfig).

    Returns a JSON-safe summary: {"plane": [nx, ny, nz, d] or None, "confidence", "support",
    "accepted", "predicted_points", "cells_set", "time_s", "detected_plane", "icp_applied",
    "reason", "timings"} — "plane" is the ICP-corrected plane of an accepted detection and None
    otherwise (never a plane without enough evidence); "detected_plane" is the detector's best
    plane before ICP, kept for diagnostics even when rejected (None without any pair).
    Keeps the results on the mission as
    ``mission.symmetry_result`` and ``mission.symmetry_prediction`` (None when not accepted), and
    the profile it read as ``mission.symmetry_profile``, for the figure (``plot_symmetry``), which
    a mission draws with its results. A profile of fewer than 10 points is reported (not
    accepted); a bad option raises ValueError.
    With ``write_map=False`` (the "profile" scenario: detection reported, the map left as the
    profile made it) the prediction is computed but not written; "cells_set" is then 0 and
    "written" False.
    """
    t0 = time.perf_counter()
    cfg = mission.config.symmetry
    profile = np.asarray(mission.laser_cloud.points, float)
    summary: dict = {
        "plane": None,
        "confidence": 0.0,
        "support": 0,
        "accepted": False,
        "predicted_points": 0,
        "cells_set": 0,
        "time_s": 0.0,
        "detected_plane": None,
        "icp_applied": False,
        "reason": "",
        "timings": {},
        "written": False,
    }
    mission.symmetry_result = None
    mission.symmetry_prediction = None
    mission.symmetry_profile = profile
    if len(profile) < 10:  # nothing to detect; a bad option, in contrast, raises ValueError
        summary[
            "reason"
        ] = f"the profile has {len(profile)} points; symmetry detection needs at least 10"
        summary["time_s"] = time.perf_counter() - t0
        return summary
    res = detect_symmetry(profile, **detection_options(cfg))
    mission.symmetry_result = res
    plane = np.asarray(res.plane, float)
    detected = [float(v) for v in plane] if np.all(np.isfinite(plane)) else None
    summary.update(
        detected_plane=detected,
        confidence=float(res.confidence),
        support=int(res.support),
        accepted=bool(res.accepted),
        reason=res.reason,
        timings={f"detect_{k}": float(v) for k, v in res.timings.items()},
    )
    pred = None
    if res.accepted:
        popts = prediction_options(cfg)
        pred = predict_symmetric(profile, plane, **popts)
        mission.symmetry_prediction = pred
        cells = (
            mission.map.set_unknown_cells(pred.predicted, cfg.prediction_probability)
            if write_map
            else 0
        )
        summary.update(
            plane=[float(v) for v in pred.plane],
            predicted_points=int(len(pred.predicted)),
            cells_set=int(cells),
            icp_applied=bool(pred.icp_applied),
            written=write_map,
        )
        summary["timings"].update({f"predict_{k}": float(v) for k, v in pred.timings.items()})
    summary["confidence"] = _finite_or_none(summary["confidence"]) or 0.0
    summary["time_s"] = time.perf_counter() - t0
    return summary


def summary_line(sym: dict) -> str:
    """The console's line for a run's symmetry step (its summary's `symmetry`): the mirror plane
    and the cells it predicted, or why no plane was accepted (then nothing was predicted)."""
    if not sym.get("accepted"):
        why = re.sub(r"\d+\.\d{3,}", lambda m: f"{float(m.group()):.2f}", sym.get("reason") or "")
        return f"symmetry: no mirror plane accepted ({why or 'none found'}): nothing predicted"
    a, b, c, d = (round(v, n) + 0.0 for v, n in zip(sym["plane"], (3, 3, 3, 2)))  # no "-0.00"
    said = f"{sym['cells_set']:,} cells predicted" if sym.get("written") else "nothing written"
    if sym.get("refreshed_cells"):
        said += f", {sym['refreshed_cells']:,} more from the camera's views"
    return (
        f"symmetry: mirror plane {a:.3f} x {b:+.3f} y {c:+.3f} z = {d:.2f} "
        f"(confidence {sym['confidence']:.2f}, {sym['support']} pairs), {said}"
    )


__all__ = [
    "detect_symmetry",
    "predict_symmetric",
    "mean_shift_planes",
    "SymmetryResult",
    "SymmetricPrediction",
    "PlaneClusters",
    "SymmetryOptions",
    "SymmetricPredictionOptions",
    "run_symmetry_prediction",
    "plot_symmetry",
    "show_symmetry_open3d",
    "symmetry_geometries",
    "reflect_points",
    "reflection_matrix",
    "plane_from_pair",
    "canonical_plane",
    "plane_from_improper_isometry",
    "mirror_fpfh",
    "compute_fpfh",
    "detection_options",
    "prediction_options",
    "summary_line",
]
