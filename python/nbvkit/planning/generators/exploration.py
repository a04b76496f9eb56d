"""The unknown space a view could open (the coverage tour's exploration targets, tour.explore):
unknown cells on the face of known free space, within the structure's extent or a given box,
and (tour.explore_hull) within the convex hull of what the map shows."""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ... import _core


def exploration_targets(occupancy_map, box=None, hull_margin=None) -> _core.SurfaceTargets:
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
    if hull_margin is None or len(targets) == 0:
        return targets
    keep = within_hull(m, targets.positions, hull_margin)
    return _core.SurfaceTargets(
        targets.positions[keep], targets.normals[keep], targets.weight[keep], targets.kind[keep]
    )


def within_hull(occupancy_map, points, margin: float) -> np.ndarray:
    """(N,) bool: whether each point (N, 3) lies within `margin` metres of the convex hull of
    the cells the map holds occupied or predicted (their centres). Fewer than 4 such cells, or
    cells all in one plane or line: every point (the box round them decides)."""
    points = np.asarray(points, float).reshape(-1, 3)
    occupied = occupancy_map.occupied_cells()
    inside = np.ones(len(points), bool)
    if len(points) == 0 or len(occupied) < 4:
        return inside
    try:
        planes = ConvexHull(occupied).equations  # unit outward normal n, offset b: n.x + b <= 0
    except QhullError:  # flat or degenerate: no volume to be inside of
        return inside
    for i in range(0, len(points), _HULL_SLICE):
        p = points[i : i + _HULL_SLICE]
        inside[i : i + _HULL_SLICE] = (p @ planes[:, :3].T + planes[:, 3] <= margin).all(axis=1)
    return inside


#: points tested against the hull's planes at a time (a (slice, planes) array)
_HULL_SLICE = 1 << 14
