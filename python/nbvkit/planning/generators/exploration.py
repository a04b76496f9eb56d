"""The unknown space a view could open (the coverage tour's exploration targets, tour.explore):
unknown cells on the face of known free space, within the structure's extent or a given box,
and (tour.explore_range) near the surface the map shows."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ... import _core


def exploration_targets(occupancy_map, box=None, within=None) -> _core.SurfaceTargets:
    """Unknown cells that a view could open: those with a free face neighbour, inside the box of
    the cells known occupied or predicted grown by one cell (the structure's extent as the map
    shows it, not the open sky round it) or inside box = (lo, hi) in metres when given, and
    with no occupied or predicted face neighbour (those are surface_targets' frontier). A
    SurfaceTargets (nbvkit._core.exploration_targets) of kind 3: positions (T, 3) cell centres,
    normals (T, 3) the unit sum of the directions to their free neighbours, weight (T,) ones."""
    m = occupancy_map
    if box is None:
        targets = _core.exploration_targets(m)
    else:
        lo_m = np.asarray(m.bounds[0], float)  # metres to the cells [lo, hi)
        a, b = (np.floor((np.asarray(x, float) - lo_m) / m.resolution).astype(int) for x in box)
        targets = _core.exploration_targets(m, np.maximum(a, 0), np.maximum(b + 1, 0))
    if within is None or len(targets) == 0:
        return targets
    keep = near_surface(m, targets.positions, within)
    return _core.SurfaceTargets(
        targets.positions[keep], targets.normals[keep], targets.weight[keep], targets.kind[keep]
    )


def near_surface(occupancy_map, points, within: float) -> np.ndarray:
    """(N,) bool: whether each point (N, 3) lies within about `within` metres of a cell the map
    holds occupied or predicted (none: all False). Distances are measured on a grid of
    within / 4 cells (exact to a quarter of `within` times the square root of 3)."""
    points = np.asarray(points, float).reshape(-1, 3)
    occupied = occupancy_map.occupied_cells()
    if len(points) == 0 or len(occupied) == 0:
        return np.zeros(len(points), bool)
    step = max(within / 4.0, occupancy_map.resolution)
    lo = np.minimum(occupied.min(axis=0), points.min(axis=0))
    hi = np.maximum(occupied.max(axis=0), points.max(axis=0))
    shape = np.floor((hi - lo) / step).astype(int) + 1
    solid = np.zeros(shape, bool)
    solid[tuple(np.floor((occupied - lo) / step).astype(int).T)] = True
    distance = ndimage.distance_transform_edt(~solid, sampling=step)
    return distance[tuple(np.floor((points - lo) / step).astype(int).T)] <= within
