"""The unknown space a view could open (the coverage tour's exploration targets, tour.explore):
unknown cells on the face of known free space, within the structure's extent or a given box."""
from __future__ import annotations

import numpy as np

from ...mapping import CellFlag


def exploration_targets(occupancy_map, box=None) -> dict:
    """Unknown cells that a view could open: those with a free face neighbour, inside the box of
    the cells known occupied or predicted grown by one cell (the structure's extent as the map
    shows it, not the open sky round it) or inside box = (lo, hi) in metres when given, and
    with no occupied or predicted face neighbour
    (those are surface_targets' frontier). Same keys as surface_targets: positions (T, 3) cell
    centres, normals (T, 3) the unit sum of the directions to their free neighbours, weight (T,)
    ones."""
    m = occupancy_map
    state, flag = m.state_grid(), m.flag_grid()
    solid = (state == m.OCCUPIED) | (flag == CellFlag.PREDICTED)
    empty = {"positions": np.zeros((0, 3)), "normals": np.zeros((0, 3)), "weight": np.zeros(0)}
    if box is None and not solid.any():
        return empty
    if box is not None:
        lo_m, res = np.asarray(m.bounds[0], float), m.resolution
        ij = [np.floor((np.asarray(b, float) - lo_m) / res).astype(int) for b in box]
        box = tuple(slice(max(a, 0), max(b + 1, 0)) for a, b in zip(*ij))
    else:
        box = []
        for axis in range(3):
            on = np.flatnonzero(solid.any(axis=tuple(a for a in range(3) if a != axis)))
            box.append(slice(max(on[0] - 1, 0), on[-1] + 2))
        box = tuple(box)
    state, solid = state[box], solid[box]
    unknown = (state == m.UNKNOWN) & ~solid
    free = np.pad(state == m.FREE, 1)
    solid = np.pad(solid, 1)
    inner = tuple(slice(1, -1) for _ in range(3))
    near_free = np.zeros_like(unknown)
    near_solid = np.zeros_like(unknown)
    shifted = {}
    for axis in range(3):
        for step in (-1, 1):
            at = list(inner)
            at[axis] = slice(1 + step, free.shape[axis] - 1 + step)
            shifted[axis, step] = free[tuple(at)]
            near_free |= shifted[axis, step]
            near_solid |= solid[tuple(at)]
    frontier = unknown & near_free & ~near_solid
    ijk = np.nonzero(frontier)
    if len(ijk[0]) == 0:
        return empty
    normals = np.zeros((len(ijk[0]), 3))
    for (axis, step), f in shifted.items():
        normals[:, axis] += step * f[ijk]
    norm = np.linalg.norm(normals, axis=1)
    keep = norm > 0  # free on opposite faces only: no side to look from
    lo = np.asarray(m.bounds[0], float) + [b.start * m.resolution for b in box]
    positions = lo + (np.column_stack(ijk)[keep] + 0.5) * m.resolution
    return {
        "positions": positions,
        "normals": normals[keep] / norm[keep, None],
        "weight": np.ones(int(keep.sum())),
    }
