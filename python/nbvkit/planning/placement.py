"""Views aimed at surface targets: targets grouped into patches, and camera poses placed to see
each patch (used by the tour and frontier generators). Vectorised numpy over the targets that
nbvkit._core.surface_targets returns."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..limits import shorten
from ..settings import cpp_section, positive, within


TargetsConfig = cpp_section(
    "TargetsConfig",
    _core.SurfaceTargetOptions,
    "Surface still to observe, which the surface planners aim views at (the cone within which "
    "a side counts as seen is the utility's: utility.coverage_cone_deg).",
    only=[f for f in _core.SurfaceTargetOptions.fields() if f != "coverage_cone_deg"],
)


def target_options(targets, utility) -> _core.SurfaceTargetOptions:
    """The SurfaceTargetOptions of a targets section, with the utility section's coverage cone
    (one cone for what a view covers and what is left to cover)."""
    return targets.options().copy(coverage_cone_deg=utility.coverage_cone_deg)


@dataclass(frozen=True)
class PlacementConfig:
    """Views aimed at surface targets (tour and frontier generators)."""

    cluster_size: float = positive(1.5)  # m; targets grouped per cube of this size and side faced
    standoffs: tuple = (0.45, 0.7)  # view distances from a target patch, x camera.max_range
    azimuth_spread_deg: float = within(30.0, 0, 180)  # views this far either side of the normal
    elevation_margin_deg: float = within(4.0, 0, 90)  # patches kept this far inside vertical FOV

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


def target_patches(targets: dict, cluster_size: float) -> Patches:
    """Groups targets (positions (T, 3), normals (T, 3), weight (T,)) per cube of
    `cluster_size` metres and per face (6) of their normal, in a deterministic order."""
    p, n, w = (np.asarray(targets[k], float) for k in ("positions", "normals", "weight"))
    if len(p) == 0:
        return Patches(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    axis = np.argmax(np.abs(n), axis=1)
    face = 2 * axis + (n[np.arange(len(n)), axis] < 0)
    key = np.column_stack([np.floor(p / cluster_size).astype(np.int64), face])
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    weights = np.bincount(inv, w)
    centers = np.column_stack([np.bincount(inv, p[:, a] * w) for a in range(3)])
    centers /= np.maximum(weights, 1e-12)[:, None]
    normals = np.column_stack([np.bincount(inv, n[:, a] * w) for a in range(3)])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return Patches(centers, normals, weights)


def place_views(patches: Patches, camera, placement, bounds=None) -> tuple[np.ndarray, np.ndarray]:
    """Candidate poses (K, 4) looking at the patches, and the patch of each (K,).

    Per patch: from its centre out along its normal, tilted in elevation so that the patch stays
    placement.elevation_margin_deg inside the camera's vertical field of view (the camera only
    yaws: its pitch is its mount's), at each stand-off placement.standoffs x camera.max_range,
    straight on and placement.azimuth_spread_deg to each side; yaw faces the patch. A patch
    facing straight up or down (horizontal part of its normal < 0.3) is looked at from six
    azimuths. camera: the config's camera section (vfov_deg, max_range, mount_rpy_deg).
    bounds: (lo, hi) of the navigation space, or None; a view placed outside them is moved in
    (into_bounds) instead of being left to fail validation: surface near the floor or the ceiling
    of the navigation space, or near its sides, is then looked at from the nearest pose that can
    fly and still holds it in the field of view."""
    if len(patches.centers) == 0:
        return np.zeros((0, 4)), np.zeros(0, int)
    half = math.radians(camera.vfov_deg / 2 - placement.elevation_margin_deg)
    axis_el = -math.radians(camera.mount_rpy_deg[1])  # optical axis elevation (pitch > 0: down)
    spread = math.radians(placement.azimuth_spread_deg)
    rows, owner = [], []
    for i, (c, n) in enumerate(zip(patches.centers, patches.normals)):
        h = math.hypot(n[0], n[1])
        el = math.atan2(n[2], h)  # elevation of the direction patch -> camera
        # the camera looks back along -u: its elevation -el must be within the FOV band
        el = -min(max(-el, axis_el - half), axis_el + half)
        if h > 0.3:
            az0 = math.atan2(n[1], n[0])
            azimuths = [az0] if spread == 0 else [az0, az0 - spread, az0 + spread]
        else:
            azimuths = [k * math.pi / 3 for k in range(6)]
        for az in azimuths:
            u = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
            yaw = math.atan2(-u[1], -u[0]) - math.radians(camera.mount_rpy_deg[2])
            for s in placement.standoffs:
                p = c + s * camera.max_range * u
                rows.append((p[0], p[1], p[2], math.remainder(yaw, 2 * math.pi)))
                owner.append(i)
    poses, owner = np.asarray(rows, float), np.asarray(owner, int)
    if bounds is not None:
        poses[:, :3] = into_bounds(
            poses[:, :3],
            patches.centers[owner],
            bounds,
            (axis_el - half, axis_el + half),
            (min(placement.standoffs) * camera.max_range / 2, camera.max_range),
        )
    return poses, owner


def into_bounds(positions, aims, bounds, band, distances) -> np.ndarray:
    """Views (K, 3) looking at `aims` (K, 3), moved into the box bounds = (lo, hi) where they lie
    outside it: to the box's floor or ceiling, then horizontally away from or towards the aim,
    along the same azimuth, just far enough that the aim stays within the camera's vertical band
    (lowest, highest elevation in view, radians), and no farther than the box's sides. A view
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
    need = np.zeros(len(fix))
    down, up = -band[0], band[1]  # the largest depression and elevation in view
    below = rise > 0
    need[below] = rise[below] / np.tan(down) if down > 1e-6 else np.inf
    need[~below] = -rise[~below] / np.tan(up) if up > 1e-6 else np.inf
    # the farthest the view may go along its azimuth and stay between the box's sides
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(
            u > 0, (hi[:2] - a[:, :2]) / u, np.where(u < 0, (lo[:2] - a[:, :2]) / u, np.inf)
        )
    reach = reach.min(axis=1)
    h_new = np.minimum(np.maximum(h, need), reach)
    dist = np.hypot(h_new, rise)
    ok = (h_new >= need) & (dist >= distances[0]) & (dist <= distances[1])
    q = np.column_stack([a[:, :2] + h_new[:, None] * u, z])
    p[fix[ok]] = q[ok]
    return p
