"""Views aimed at surface targets: targets grouped into patches, and camera poses placed to see
each patch (used by the tour and frontier generators). Vectorised numpy over the targets that
nbvkit._core.surface_targets returns."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .. import _core
from ..limits import Bound, shorten
from ..settings import cpp_section, positive, within


TargetsConfig = cpp_section(
    "TargetsConfig",
    _core.SurfaceTargetOptions,
    "Surface still to observe, which the surface planners aim views at (the cone within which "
    "a side counts as seen is the utility's: utility.coverage_cone_deg).",
    only=[f for f in _core.SurfaceTargetOptions.fields() if f != "coverage_cone_deg"],
    bounds={"frontier_weight": Bound(lo=0, hi=1)},
)


def target_options(targets, utility) -> _core.SurfaceTargetOptions:
    """The SurfaceTargetOptions of a targets section, with the utility section's coverage cone
    (one cone for what a view covers and what is left to cover)."""
    return targets.options().copy(coverage_cone_deg=utility.coverage_cone_deg)


@dataclass(frozen=True)
class PlacementConfig:
    """Views aimed at surface targets (tour and frontier generators)."""

    # a patch keeps its share of the camera's footprint: 1.5 m for the paper's 8 m camera
    cluster_size: Optional[float] = positive(None)  # m, cubes of targets; null: 0.1875 x range
    standoffs: tuple = (0.45, 0.7)  # view distances from a patch, x camera.max_range (0, 1]
    azimuth_spread_deg: float = within(30.0, 0, 180)  # views this far either side of the normal
    elevation_margin_deg: float = within(4.0, 0, 90)  # patches kept this far inside vertical FOV
    # also face the patches the level camera cannot face head-on (roofs, undersides) by the
    # gimbal's pitch (camera.gimbal_pitch_deg); false: level views (docs/RESULTS.md, "gimbal")
    gimbal: bool = False
    # views of the unknown space (tour.explore) also look down into it by the gimbal's pitch
    # (never up) while the surface's views stay level: a level camera cannot open a shaft or an
    # open top from above (a 100 m open chimney: 55 -> 98 % of its area; RESULTS.md, "Looking
    # down into an open top"); false: level
    explore_gimbal: bool = True
    # a patch none of whose views can be flown (outside the navigation space, or the vehicle's
    # sphere there not known free) is looked at from the nearest direction that can: its
    # normal tilted by 15, 30, ... 75 deg (refit_blocked); false: such a patch waits; null: on a
    # workspace longer than 6 camera ranges (workspace.is_large), once no other view is left (plants
    # flown to the end: +1.45 and +0 points; from the first plan: -1.5 at 1,000 views; RESULTS.md)
    fallback: Optional[bool] = None

    def cluster(self, camera) -> float:
        """The patch size (m): cluster_size, or a share of the camera's range."""
        return self.cluster_size if self.cluster_size is not None else 0.1875 * camera.max_range

    def check(self, key: str) -> None:
        if not (self.standoffs and all(0 < x <= 1 for x in self.standoffs)):
            raise ValueError(
                f"config key '{key}.standoffs' must be fractions of the camera range in (0, 1], "
                f"got {shorten(list(self.standoffs))}"
            )


@dataclass
class Patches:
    centers: np.ndarray  # (P, 3) weighted centroids of the targets
    normals: np.ndarray  # (P, 3) unit weighted mean normals
    weights: np.ndarray  # (P,) summed target weights


def target_patches(targets, cluster_size: float) -> Patches:
    """Groups targets (a SurfaceTargets, or a dict of its arrays positions (T, 3), normals
    (T, 3), weight (T,)) per cube of `cluster_size` metres and per face (6) of their normal, in
    a deterministic order. ValueError unless cluster_size is a finite number > 0."""
    if isinstance(cluster_size, bool) or not (
        isinstance(cluster_size, (int, float, np.integer, np.floating))
        and np.isfinite(cluster_size)
        and cluster_size > 0
    ):
        raise ValueError(
            f"target_patches: cluster_size must be a finite number > 0 m, got {cluster_size!r}"
        )
    if isinstance(targets, dict):  # checked as SurfaceTargets checks a script's arrays
        targets = _core.SurfaceTargets(**targets)
    p, n, w = targets.positions, targets.normals, targets.weight
    if len(p) == 0:
        return Patches(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    axis = np.argmax(np.abs(n), axis=1)
    face = 2 * axis + (n[np.arange(len(n)), axis] < 0)
    cube = np.floor(p / cluster_size).astype(np.int64)
    cube -= cube.min(axis=0)
    # one integer per (cube, face), in the order of the rows (cube x, y, z, face) sorted
    span = cube.max(axis=0) + 1
    key = ((cube[:, 0] * span[1] + cube[:, 1]) * span[2] + cube[:, 2]) * 6 + face
    _, inv = np.unique(key, return_inverse=True)
    weights = np.bincount(inv, w)
    centers = np.column_stack([np.bincount(inv, p[:, a] * w) for a in range(3)])
    centers /= np.maximum(weights, 1e-12)[:, None]
    normals = np.column_stack([np.bincount(inv, n[:, a] * w) for a in range(3)])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return Patches(centers, normals, weights)


def place_views(patches: Patches, camera, placement, bounds=None) -> tuple[np.ndarray, np.ndarray]:
    """Candidate views looking at the patches, and the patch of each (K,): (K, 5) [x, y, z, yaw,
    pitch] with placement.gimbal and a camera gimbal (camera.gimbal_pitch_deg other than [0, 0]),
    else (K, 4) level views.

    Per patch: from its centre out along its normal, at each stand-off placement.standoffs x
    camera.max_range, straight on and placement.azimuth_spread_deg to each side; yaw faces the
    patch. The level camera's views are tilted in elevation so that the patch stays
    placement.elevation_margin_deg inside its vertical field of view; a patch it cannot face
    head-on (a roof, an underside) is also faced by the gimbal's pitch (a roof from straight
    above looking down, an underside from below looking up), clamped at its limits. A patch
    facing up or down (horizontal part of its normal < 0.3) that a view does not face head-on is
    looked at from six azimuths. camera: the config's camera section (vfov_deg, max_range,
    mount_rpy_deg, gimbal_pitch_deg). bounds: (lo, hi) of the navigation space, or None; a view
    placed outside them is moved in (into_bounds) instead of being left to fail validation:
    surface near the floor or the ceiling of the navigation space, or near its sides, is then
    looked at from the nearest pose that can fly and still holds it in the field of view."""
    lo_p, hi_p = (math.radians(x) for x in camera.gimbal_pitch_deg)
    gimbal = placement.gimbal and (lo_p, hi_p) != (0.0, 0.0)
    if len(patches.centers) == 0:
        return np.zeros((0, 5 if gimbal else 4)), np.zeros(0, int)
    h = [math.hypot(x, y) for x, y in patches.normals[:, :2].tolist()]  # Python's rounding
    poses, owner, bands = _core.place_patch_views(
        patches.centers,
        patches.normals,
        h,
        [s * camera.max_range for s in placement.standoffs],
        half=math.radians(camera.vfov_deg / 2 - placement.elevation_margin_deg),
        mount=math.radians(camera.mount_rpy_deg[1]),  # the mount's pitch (> 0: down)
        mount_yaw=math.radians(camera.mount_rpy_deg[2]),
        spread=math.radians(placement.azimuth_spread_deg),
        gimbal=gimbal,
        lo_pitch=lo_p,
        hi_pitch=hi_p,
    )
    if bounds is not None:
        poses[:, :3] = into_bounds(
            poses[:, :3],
            patches.centers[owner],
            bounds,
            bands,
            (min(placement.standoffs) * camera.max_range / 2, camera.max_range),
        )
    return (poses if gimbal else poses[:, :4]), owner


def explore_placement(placement, camera):
    """(placement, camera) for views of the unknown space (tour.explore): straight on
    (azimuth_spread_deg 0); with placement.gimbal pitched either way as the surface's views are,
    else with placement.explore_gimbal pitched down only (the camera's gimbal range above
    level: an open top is opened from above; unknown space under a structure is seen from its
    sides). Level when the gimbal cannot look down."""
    straight = dataclasses.replace(placement, azimuth_spread_deg=0.0)
    lo, hi = camera.gimbal_pitch_deg
    if placement.gimbal or not placement.explore_gimbal or hi <= 0:
        return straight, camera
    down = dataclasses.replace(camera, gimbal_pitch_deg=(max(lo, 0.0), hi))
    return dataclasses.replace(straight, gimbal=True), down


def into_bounds(positions, aims, bounds, band, distances) -> np.ndarray:
    """Views (K, 3) looking at `aims` (K, 3), moved into the box bounds = (lo, hi) where they lie
    outside it: to the box's floor or ceiling, then horizontally away from or towards the aim,
    along the same azimuth, just far enough that the aim stays within the camera's vertical band
    (lowest, highest elevation in view, radians: a pair, or (K, 2) one per view), and no
    farther than the box's sides. A view
    that cannot be moved in (out of the band, or its distance to the aim outside distances =
    (nearest, farthest)) is left as it was.
    Views inside the box, and views straight above or below their aim, are not changed."""
    lo, hi = (np.asarray(b, float) for b in bounds)
    p = np.asarray(positions, float)
    out = ~np.all((p >= lo) & (p <= hi), axis=1)
    d = p[:, :2] - aims[:, :2]
    h = np.linalg.norm(d, axis=1)
    fix = np.flatnonzero(out & (h > 1e-6))
    if len(fix) == 0:
        return p
    a, u, h = aims[fix], d[fix] / h[fix, None], h[fix]
    z = np.clip(p[fix, 2], lo[2], hi[2])
    rise = z - a[:, 2]  # > 0: the camera looks down at its aim
    band = np.broadcast_to(np.asarray(band, float), (len(p), 2))[fix]
    # the line of sight to the aim, at elevation atan2(-rise, h), must lie within the band:
    # a horizontal distance between need (nearest) and most (farthest)
    need, most = _distances_in_band(rise, band)
    # the farthest the view may go along its azimuth and stay between the box's sides
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(
            u > 0, (hi[:2] - a[:, :2]) / u, np.where(u < 0, (lo[:2] - a[:, :2]) / u, np.inf)
        )
    reach = reach.min(axis=1)
    h_new = np.minimum(np.maximum(h, need), np.minimum(reach, most))
    dist = np.hypot(h_new, rise)
    ok = (h_new >= need) & (h_new <= most)
    ok &= (dist >= distances[0]) & (dist <= distances[1])
    q = np.column_stack([a[:, :2] + h_new[:, None] * u, z])
    p[fix[ok]] = q[ok]
    return p


def _distances_in_band(rise, band):
    """(nearest, farthest) horizontal distances (K,) from which an aim `rise` (K,) below the
    camera (< 0: above it) is seen at an elevation within band (K, 2) = (lowest, highest),
    radians within [-pi/2, pi/2]."""
    depth = np.abs(rise)
    # seen from above: the line of sight's depression, atan(rise / h), in [-hi, -lo]; from
    # below its elevation, atan(-rise / h), in [lo, hi]
    steep = np.where(rise > 0, -band[:, 0], band[:, 1])  # the steepest sight line in view
    flat = np.where(rise > 0, -band[:, 1], band[:, 0])  # the flattest
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(steep >= np.pi / 2 - 1e-9, 0.0, depth / np.tan(steep))
        most = np.where(flat > 1e-9, depth / np.tan(flat), np.inf)
    need = np.where(steep <= 1e-9, np.inf, need)  # nothing in view on that side
    return need, most


#: The tilts (deg) away from a blocked patch's normal that refit_blocked tries, nearest first,
#: each at FALLBACK_AZIMUTHS directions around the normal.
FALLBACK_TILTS_DEG = (15.0, 30.0, 45.0, 60.0, 75.0)
FALLBACK_AZIMUTHS = 8


def refit_blocked(poses, owner, patches, camera, placement, bounds, feasible):
    """(poses, owner, unplaced): the views of place_views with, for each patch none of whose
    views is feasible, the feasible views from the nearest direction that has some: its normal
    tilted by FALLBACK_TILTS_DEG towards FALLBACK_AZIMUTHS directions round it, placed and aimed
    as place_views does (straight on, at each stand-off); unplaced: the patches (indices) for
    which no tilt gives one. feasible: (K, 3) positions -> (K,) bool (the navigation space and
    the vehicle's collision sphere in known free space). The views of the other patches are
    kept as they were, feasible or not."""
    ok = np.asarray(feasible(poses[:, :3]), bool) if len(poses) else np.zeros(0, bool)
    placed = np.zeros(len(patches.weights), bool)
    placed[owner] = True
    served = np.zeros(len(patches.weights), bool)
    served[owner[ok]] = True
    left = np.flatnonzero(placed & ~served)
    if len(left) == 0:
        return poses, owner, left
    straight = dataclasses.replace(placement, azimuth_spread_deg=0.0)
    n = patches.normals
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    phi = 2 * np.pi * np.arange(FALLBACK_AZIMUTHS) / FALLBACK_AZIMUTHS
    more, of = [poses], [owner]
    for tilt in np.radians(FALLBACK_TILTS_DEG):
        patch = np.repeat(left, FALLBACK_AZIMUTHS)
        a = np.tile(phi, len(left))[:, None]
        dirs = np.cos(tilt) * n[patch] + np.sin(tilt) * (
            np.cos(a) * e1[patch] + np.sin(a) * e2[patch]
        )
        tilted = Patches(patches.centers[patch], dirs, patches.weights[patch])
        views, which = place_views(tilted, camera, straight, bounds)
        good = np.asarray(feasible(views[:, :3]), bool)
        views, which = views[good], patch[which[good]]
        more.append(views)
        of.append(which)
        left = np.setdiff1d(left, which)
        if len(left) == 0:
            break
    return np.vstack(more), np.concatenate(of), left
