"""The unknown space a view could open (the coverage tour's exploration targets, tour.explore):
unknown cells on the face of known free space, within the structure's extent or a given box,
and (tour.explore_range) near the surface the map shows."""
from __future__ import annotations

import numpy as np

from ... import _core


def exploration_targets(occupancy_map, box=None, within=None) -> _core.SurfaceTargets:
    """Unknown cells that a view could open: those with a free face neighbour, inside the box of
    the cells known occupied or predicted grown by one cell (the structure's extent as the map
    shows it, not the open sky round it) or inside box = (lo, hi) in metres when given, and
    with no occupied or predicted face neighbour (those are surface_targets' frontier), and
    within `within` metres of the occupied cells when given (_core.near_surface). A
    SurfaceTargets (nbvkit._core.exploration_targets) of kind 3: positions (T, 3) cell centres,
    normals (T, 3) the unit sum of the directions to their free neighbours, weight (T,) ones."""
    m = occupancy_map
    if box is None:
        return _core.exploration_targets(m, within=within)
    lo_m = np.asarray(m.bounds[0], float)  # metres to the cells [lo, hi)
    a, b = (np.floor((np.asarray(x, float) - lo_m) / m.resolution).astype(int) for x in box)
    return _core.exploration_targets(m, np.maximum(a, 0), np.maximum(b + 1, 0), within)
