"""Credit for access (tour.access_weight): a view is also credited with the surface it would
give access to - patches whose every view fails the collision test for want of known free space,
where the view's rays reach the place of such a view and the vehicle could fly there through
space not known to be occupied. Off by default (docs/RESULTS.md)."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ... import _core

COLLISION = 2  # ViewStatus::Collision (_core.view_status_names)


def access_elements(world, coverage, candidates, owner, patches, weight, radius, opened):
    """(coverage, opens): the coverage with, for each valid view, one element per stranded
    patch it would open, weighing `weight` x the patch's weight; opens: per such
    view, the cells of the stranded views it reaches. A patch is stranded when none of its
    views is valid and some fail the collision test only for want of known free space (no
    occupied cell within the collision radius) and the vehicle could reach that view's place
    (reachable: not behind walls the map shows, nor through a gap narrower than the
    vehicle); a valid view opens it when its rays reach the cell of one of those views (the
    cell is in its coverage set: unknown space the frame would make known)."""
    status = coverage.status
    if weight <= 0 or len(status) == 0:
        return coverage, {}
    valid = status == 0
    seen = np.zeros(len(patches.weights), bool)
    seen[owner[valid]] = True
    failed = np.flatnonzero((status == COLLISION) & ~seen[owner])
    if len(failed) == 0 or not valid.any():
        return coverage, {}
    m = world.map
    pos = candidates[failed, :3]
    free_of_structure = ~occupied_within(m, pos, radius)
    failed, pos = failed[free_of_structure], pos[free_of_structure]
    reach = reachable(world, radius) if len(failed) else None
    if reach is not None:  # not sealed off from the vehicle by cells known occupied
        ids = np.asarray(m.index_of(pos), np.int64)  # flat, Fortran order; -1 outside
        inside = (ids >= 0) & reach.ravel(order="F")[np.maximum(ids, 0)]
        failed, pos = failed[inside], pos[inside]
    cells = np.asarray(m.storage_index(pos), np.int64)
    keep = (cells >= 0) & ~np.isin(cells, list(opened))
    failed, cells = failed[keep], cells[keep]
    if len(failed) == 0:
        return coverage, {}
    order = np.argsort(cells, kind="stable")
    cells, patch = cells[order], owner[failed][order]
    off, el = coverage.offsets, coverage.elements
    hit = elements_in_cells(el, cells)
    at = el[hit] // 2
    lo, hi = np.searchsorted(cells, at, "left"), np.searchsorted(cells, at, "right")
    n = hi - lo
    rows = np.repeat(np.arange(len(hit)), n)
    idx = np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())
    view = np.searchsorted(off, hit, "right") - 1  # the view holding each hit element
    pairs = np.unique(np.column_stack([view[rows], patch[idx], cells[idx]]), axis=0)
    if len(pairs) == 0:
        return coverage, {}
    opens: dict = {}
    for v, c in zip(pairs[:, 0], pairs[:, 2]):
        opens.setdefault(int(v), []).append(int(c))
    vp = np.unique(pairs[:, :2], axis=0)  # (view, patch), sorted by view
    base = int(el.max()) + 1 if len(el) else 0  # past every cell's element
    extra = (vp[:, 0], base + vp[:, 1], weight * patches.weights[vp[:, 1]])
    return append_elements(coverage, *extra), opens


def append_elements(coverage, views, elements, weights) -> _core.CoverageSets:
    """The coverage sets (a CoverageSets: per view, its elements in increasing order) with
    elements[i] (larger than any of the view's own) and its weight appended to the set of
    views[i]; views in increasing order. The sets move as blocks between the views that grow: no
    array per element beyond the new ones (a plan holds 20-46 M elements on a 100 m plant)."""
    off, el, wt = coverage.offsets, coverage.elements, coverage.weights
    elements, weights = np.asarray(elements), np.asarray(weights, wt.dtype)
    if len(elements) and int(elements.max()) > np.iinfo(el.dtype).max:
        raise OverflowError(f"coverage elements beyond {el.dtype}: {int(elements.max())}")
    extra = np.bincount(views, minlength=len(off) - 1)
    before = np.concatenate([[0], np.cumsum(extra)])  # extra elements before each view's set
    new_el = np.empty(len(el) + len(views), el.dtype)
    new_wt = np.empty(len(wt) + len(views), wt.dtype)
    src = j = 0  # the next old element and the next extra to place
    for v in np.flatnonzero(extra):
        end, shift, k = int(off[v + 1]), int(before[v]), int(extra[v])
        new_el[src + shift : end + shift], new_wt[src + shift : end + shift] = (
            el[src:end],
            wt[src:end],
        )
        new_el[end + shift : end + shift + k] = elements[j : j + k]
        new_wt[end + shift : end + shift + k] = weights[j : j + k]
        src, j = end, j + k
    new_el[src + len(views) :], new_wt[src + len(views) :] = el[src:], wt[src:]
    return _core.CoverageSets(
        off + before, new_el, new_wt, coverage.status, coverage.pooled_from, coverage.pool_cap
    )


#: Elements tested at a time by elements_in_cells (4 M: 16 MB of their cells).
_CHUNK = 1 << 22


def elements_in_cells(elements, cells) -> np.ndarray:
    """Indices of the coverage elements (cell x 2 + side) whose cell is in `cells`: by a table
    over the cells, a chunk of elements at a time (numpy's isin would hold 20 bytes an element)."""
    if len(elements) == 0:
        return np.zeros(0, np.int64)
    table = np.zeros(int(elements.max()) // 2 + 1, bool)
    table[cells[cells < len(table)]] = True
    parts = [
        b + np.flatnonzero(table[elements[b : b + _CHUNK] >> 1])
        for b in range(0, len(elements), _CHUNK)
    ]
    return np.concatenate(parts)


def occupied_within(occupancy_map, points, radius) -> np.ndarray:
    """(N,) whether an occupied cell lies within `radius` of each point (cells sampled at the
    map's resolution over the ball)."""
    res = occupancy_map.resolution
    k = int(np.ceil(radius / res))
    g = np.arange(-k, k + 1) * res
    off = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    off = off[np.linalg.norm(off, axis=1) <= radius + 0.5 * res]
    q = (points[:, None, :] + off[None]).reshape(-1, 3)
    return (occupancy_map.state(q).reshape(len(points), -1) == 1).any(axis=1)


def reachable(world, radius):
    """(nx, ny, nz) bool over the map's workspace cells: those the vehicle could fly to from
    where it is through space not known to be occupied - cells inside the navigation bounds
    with no occupied cell centre within `radius`, joined to the vehicle's cell through faces. A
    place behind walls the map shows, or in a gap narrower than the vehicle, is not. None when
    the vehicle's own cell and its neighbours are not clear (no test can be made)."""
    m = world.map
    res, lo = m.resolution, np.asarray(m.bounds[0], float)
    occupied = m.state_grid() == m.OCCUPIED
    clear = ndimage.distance_transform_edt(~occupied, sampling=res) > radius
    for axis in range(3):
        centre = lo[axis] + (np.arange(clear.shape[axis]) + 0.5) * res
        inside = (centre >= world.workspace.nav_min[axis]) & (
            centre <= world.workspace.nav_max[axis]
        )
        shape = [1, 1, 1]
        shape[axis] = -1
        clear &= inside.reshape(shape)
    labels, _ = ndimage.label(clear)
    at = np.floor((np.asarray(world.state.pose[:3], float) - lo) / res).astype(int)
    near = labels[tuple(slice(max(a - 2, 0), a + 3) for a in at)]
    near = near[near > 0]
    if len(near) == 0:
        return None
    own = labels[tuple(np.clip(at, 0, np.array(labels.shape) - 1))]
    return labels == (own if own > 0 else np.bincount(near).argmax())
