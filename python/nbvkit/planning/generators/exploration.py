"""The unknown space a view could open (the coverage tour's exploration targets, tour.explore):
unknown cells on the face of known free space, within the structure's extent or a given box."""
from __future__ import annotations

import numpy as np

from ... import _core


def exploration_targets(occupancy_map, box=None) -> dict:
    """Unknown cells that a view could open: those with a free face neighbour, inside the box of
    the cells known occupied or predicted grown by one cell (the structure's extent as the map
    shows it, not the open sky round it) or inside box = (lo, hi) in metres when given, and
    with no occupied or predicted face neighbour
    (those are surface_targets' frontier). Same keys as surface_targets: positions (T, 3) cell
    centres, normals (T, 3) the unit sum of the directions to their free neighbours, weight (T,)
    ones."""
    m, res = occupancy_map, occupancy_map.resolution
    if box is None:
        found = _core.exploration_targets(m)
    else:  # metres to the cells [lo, hi)
        lo_m = np.asarray(m.bounds[0], float)
        a, b = (np.floor((np.asarray(x, float) - lo_m) / res).astype(int) for x in box)
        found = _core.exploration_targets(m, np.maximum(a, 0), np.maximum(b + 1, 0))
    sides = found["free_sides"].astype(float)
    norm = np.linalg.norm(sides, axis=1)
    keep = norm > 0  # free on opposite faces only: no side to look from
    start = np.asarray(found["lo"], int)
    lo = np.asarray(m.bounds[0], float) + start * res
    return {
        "positions": lo + (found["cells"][keep] - start + 0.5) * res,
        "normals": sides[keep] / norm[keep, None],
        "weight": np.ones(int(keep.sum())),
    }
