"""Coverage tours (nbvkit's surface planner): plan views that together cover the surface still
to observe, fly them in a short order, and plan again when the tour is done.

A plan: surface targets -> patches -> candidate views (placement.py) -> what each would newly
cover (nbvkit._core.view_coverage: cells and the side they are seen from) -> a greedy set cover
(select_cover, views adding at least tour.min_gain) -> an open tour from the vehicle
(solve_tour: nearest neighbour, 2-opt, Or-opt) -> prize collecting: views that add less than
tour.rate m^2 per metre of the detour they cause are dropped, the worst first, until every view
pays. The tour is then proposed one view at a time (exclusive proposals): the planner re-scores
each against the current map and skips it when it no longer adds tour.min_gain. When the tour is
done the next plan is made from what the map shows then. With tour.explore, once a plan keeps no
view, every later plan also weighs views of the unknown space within the structure's extent
(exploration_targets: parts of the structure nothing has shown yet hold no surface target; with
tour.explore_first, by default on a large workspace, every plan does, the first one included); a
plan with no view left, or one none of whose views could be flown, ends the generator
(tour.max_plans caps the plans). With
tour.access_weight > 0 a view is also credited with the surface it would give access to: patches
whose every view fails the collision test for want of known free space, where its rays reach
the place of such a view and the vehicle could fly there through space not known to be occupied
(_access, _reachable; off by default, docs/RESULTS.md). On a structure
smaller than planner.reference_area both thresholds shrink with it (parts.threshold_scale).

On a large workspace (longer than 6 camera ranges: a 100 m plant, not a 35 m aircraft; by
default) plans keep at first only views adding 2^tour.gain_levels x min_gain, halving the
threshold each time a plan keeps none: the large gains of the whole structure are flown before
the small ones near the vehicle (a decreasing-threshold greedy; docs/RESULTS.md, "Large
structures"). With tour.region_size the tours are planned region by region (regions.py: the
region the vehicle is in, then the next of an open tour over the regions still holding value)
and explore the unknown space of the whole workspace from the first plan."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy import ndimage

from ... import _core
from ...settings import choice, nonneg, positive, within
from ..parts import Proposal, threshold_scale
from ..placement import Patches, place_views, refit_blocked, target_patches
from .exploration import exploration_targets
from .regions import Regions, is_large


@dataclass(frozen=True)
class TourConfig:
    """The coverage-tour generator: set cover of views over the surface targets, a shortest
    tour through them, flown; then again, until no planned view is worth its flight."""

    # how a plan chooses views: "cover" (greedy set cover, then a shortest tour) or "insertion"
    # (prize-collecting: new surface - rate x added tour length, by cheapest insertion)
    selection: str = choice("insertion", ("cover", "insertion"))
    min_gain: float = nonneg(1.2)  # m^2 of new surface a view must add to enter a plan (RESULTS.md)
    rate: float = nonneg(0.75)  # m^2 of new surface per metre of tour a planned view must pay for
    max_plans: int = within(0, 0, 10**6)  # tours planned at most (0: until a plan is empty)
    # a stranded patch: all its views fail the collision test for want of known free space;
    # a view whose rays reach where they would be gets this share of its weight
    access_weight: float = nonneg(0.0)  # a stranded patch's share credited to a view opening it
    # once no view of the surface the map shows is worth its flight, plans also weigh views of
    # the unknown space within the structure's extent (unknown cells bordering free space)
    explore: bool = True  # then also plan views that open unknown space; false: stop there
    # with explore: from the first plan on; null: on a workspace longer than 6 camera ranges
    # (regions.is_large: the plant, +2.1 points at 1,000 views in 13 % less flight; RESULTS.md)
    explore_first: Optional[bool] = None  # unknown space from the first plan; null: by size
    # plans first keep only views adding 2^gain_levels x min_gain, halving it each time a plan
    # keeps none; null: 3 on a workspace longer than 6 camera ranges (regions.is_large), else 0
    gain_levels: Optional[int] = within(None, 0, 20)  # the larger gains first; null: by size
    # with region_size, a workspace larger than it is toured region by region (regions.py),
    # exploring the unknown space of the whole workspace from the first plan
    region_size: Optional[float] = positive(None)  # m; null: one region


#: The memo of walks on a large workspace (regions.is_large), in place of 256 MiB: its exploring
#: plans hold tens of millions of coverage elements, and the memo only saves time (RESULTS.md).
LARGE_MEMO_BYTES = 64 << 20


class CoverageTour:
    Settings = TourConfig

    def __init__(self, settings: TourConfig, context):
        self.settings = settings
        self.ctx = context
        self.views = np.zeros((0, 4))
        self.aims = np.zeros((0, 3))
        self.next = 0
        self.plans: list[dict] = []  # per plan: views selected, kept, flown, planned length
        self.opened: set[int] = set()  # cells of stranded views a chosen view was credited with
        self.stop_reason = None  # why propose() gave up, when not because the surface is covered
        self.exploring = False  # plans include views of unknown space (tour.explore)
        # what earlier plans' walks found, for candidates asked for again (the same arrays)
        self.memo = _core.CoverageMemo()
        self.regions: Regions | None = None  # set at the first plan (tour.region_size)
        self.level = None  # the multiple of tour.min_gain plans keep now; None: no plan yet

    @property
    def regional(self) -> bool:
        """Whether the tours are planned region by region (tour.region_size)."""
        return self.regions is not None

    # ------------------------------------------------------------------ planning
    def candidates(self, world, explore: bool = False):
        """(targets, patches, candidate views (K, 4), the patch of each (K,), the patches no
        feasible view looks at (placement.fallback; none without it)) over the surface
        still to observe that the map shows now; with explore, also over the unknown space
        within the structure's extent that borders known free space (exploration_targets,
        grouped per cube of the camera's nearer stand-off, each looked at straight on; their
        patches follow the surface's)."""
        ctx = self.ctx
        bounds = (world.workspace.nav_min, world.workspace.nav_max)
        targets = _core.surface_targets(world.map, world.surface, ctx.targets)
        patches = target_patches(targets, ctx.placement.cluster(ctx.camera))
        candidates, owner = place_views(patches, ctx.camera, ctx.placement, bounds)
        unplaced = np.zeros(0, int)
        if ctx.placement.fallback:  # blocked patches from the nearest direction that can fly
            candidates, owner, unplaced = refit_blocked(
                candidates, owner, patches, ctx.camera, ctx.placement, bounds, world.can_hold
            )
        if explore:
            size = max(
                min(ctx.placement.standoffs) * ctx.camera.max_range,
                ctx.placement.cluster(ctx.camera),
            )
            box = None  # touring by regions: the whole workspace; else the structure's extent
            if self.regional:
                box = (world.workspace.bounds_min, world.workspace.bounds_max)
            more = target_patches(exploration_targets(world.map, box), size)
            straight = dataclasses.replace(ctx.placement, azimuth_spread_deg=0.0)
            views, of = place_views(more, ctx.camera, straight, bounds)
            candidates = np.vstack([candidates, views])
            owner = np.concatenate([owner, of + len(patches.weights)])
            patches = Patches(
                *(np.concatenate([getattr(patches, f), getattr(more, f)]) for f in _PATCH_FIELDS)
            )
        return targets, patches, candidates, owner, unplaced

    def coverage(self, world, candidates) -> dict:
        """What each candidate would newly cover, from the vehicle's pose (view_coverage)."""
        return _core.view_coverage(
            world.map,
            world.surface,
            candidates,
            world.state.pose,
            camera=world.view_camera,
            utility=self.ctx.utility.options(),
            validity=world.validity(blocked_path="plan"),
            memo=self.memo,
        )

    def plan(self, world, reachable_only: bool = False, explore: bool = False) -> np.ndarray:
        """The next tour (V, 4) from the vehicle's pose over what the map shows now; with
        reachable_only, over the candidates a path through known free space can reach now (the
        vehicle's free component); with explore, over views of the unknown space within the
        structure's extent too (candidates). On a workspace of several regions (regions.py)
        the tour is planned over one region's patches, exploring from the first plan."""
        ctx, own = self.ctx, self.settings
        if self.level is None:  # the first plan
            self.regions = Regions.of(world.workspace, own.region_size)
            large = is_large(world.workspace, ctx.camera)
            levels = own.gain_levels
            if levels is None:  # larger gains first on a large structure only
                levels = 3 if large else 0
            self.level = float(2**levels)
            first = large if own.explore_first is None else own.explore_first
            self.exploring = own.explore and first
            if large and self.memo is not None:  # room for the plans' own coverage sets
                self.memo = _core.CoverageMemo(max_bytes=LARGE_MEMO_BYTES)
        explore = explore or self.exploring or (self.regional and own.explore)
        scale = threshold_scale(world.map, ctx.planner.reference_area)
        min_gain, rate = own.min_gain * scale * self.level, own.rate * np.sqrt(scale)
        targets, patches, candidates, owner, unplaced = self.candidates(world, explore)
        if reachable_only and len(candidates):
            here = world.state.pose[:3]
            component = _core.FreeComponent(world.map, here, ctx.vehicle.collision_radius)
            reach = np.asarray(component.contains(world.map, candidates[:, :3]), bool)
            candidates, owner = candidates[reach], owner[reach]
        record = {
            "scale": float(scale),
            "targets": int(len(targets["weight"])),
            "candidates": int(len(candidates)),
            "selected": 0,
            "kept": 0,
            "flown": 0,
            "length_m": 0.0,
            "reachable_only": reachable_only,
            "explore": explore,
            "min_gain_m2": float(min_gain),
            "unplaced_patches": len(unplaced),
        }
        self.plans.append(record)
        views, self.aims = np.zeros((0, candidates.shape[1])), np.zeros((0, 3))
        if len(candidates):
            choose = self._regional if self.regional else self._choose
            views, self.aims = choose(world, candidates, owner, patches, record, min_gain, rate)
            _core.release_free_memory()  # the plan's coverage sets, freed across the arenas
        return views

    def _regional(self, world, candidates, owner, patches, record, min_gain, rate):
        """(views, aims) of the tour over the first region in the regions' order whose plan keeps
        a view; every region planned in is done for this pass over the regions. When no region
        left in the pass keeps a view, a new pass weighs the others again (what the flight
        found may have given them some); empty when that keeps nothing either."""
        regions, tried = self.regions, []
        where = regions.ids(patches.centers)[owner]
        min_value = min_gain / world.map.resolution**2
        here = world.state.pose
        for again in (False, True):
            if again:
                regions.done.clear()
            for r in regions.order(here, patches.centers, patches.weights, min_value, tried):
                sub = where == r
                views, aims = self._choose(
                    world, candidates[sub], owner[sub], patches, record, min_gain, rate
                )
                regions.done.add(r)  # visited in this pass over the regions
                if len(views):
                    regions.current, record["region"] = r, int(r)
                    return views, aims
                tried.append(r)
            if not regions.done - set(tried):
                break
        return np.zeros((0, candidates.shape[1])), np.zeros((0, 3))

    def _choose(self, world, candidates, owner, patches, record, min_gain, rate):
        """(views, aims) in flight order: the set of candidates the selection keeps (tour.selection
        over their coverage), then prize-collected; `record` gets the counts."""
        cell_m2 = world.map.resolution**2
        pose = world.state.pose
        coverage = self.coverage(world, candidates)  # (a large plan's walks' heap handed back)
        coverage, opens = self._access(world, coverage, candidates, owner, patches)
        if self.settings.selection == "insertion":
            # anchored at the vehicle, and with the first view's transit free (a far cluster
            # that pays only as a whole); the tour worth more after prize collection is flown
            found = _core.select_tours(  # one inverse of the coverage, the two tours at once
                coverage,
                candidates[:, :3],
                pose[:3],
                rate=rate / cell_m2,
                min_gain=min_gain / cell_m2,
                charges=[True, False],
            )
            tours = [_insertion_tour(c, g, candidates, pose, cell_m2, rate) for c, g in found]
            chosen, gains, order = max(tours, key=lambda t: t[3])[:3]
        else:
            chosen, gains = _core.select_cover(coverage, min_gain=min_gain / cell_m2)
            gains = np.asarray(gains) * cell_m2
            order = _core.solve_tour(candidates[chosen, :3], pose[:3])[0] if chosen else []
            order = prize_collect(pose[:3], candidates[chosen, :3], gains, order, rate)
        record["selected"] = len(chosen)
        for k in chosen:  # the places a chosen view opens are not credited again
            self.opened.update(opens.get(int(k), ()))
        views, aims = candidates[chosen], patches.centers[owner[chosen]]
        record["kept"] = len(order)
        record["length_m"] = 0.0
        if order:
            pts = np.vstack([pose[:3], views[order, :3]])
            record["length_m"] = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        return views[order], aims[order]

    def _access(self, world, coverage, candidates, owner, patches):
        """(coverage, opens): the coverage with, for each valid view, one element per stranded
        patch it would open, weighing tour.access_weight x the patch's weight; opens: per such
        view, the cells of the stranded views it reaches. A patch is stranded when none of its
        views is valid and some fail the collision test only for want of known free space (no
        occupied cell within the collision radius) and the vehicle could reach that view's place
        (_reachable: not behind walls the map shows, nor through a gap narrower than the
        vehicle); a valid view opens it when its rays reach the cell of one of those views (the
        cell is in its coverage set: unknown space the frame would make known)."""
        w = self.settings.access_weight
        status = coverage["status"]
        if w <= 0 or len(status) == 0:
            return coverage, {}
        valid = status == 0
        seen = np.zeros(len(patches.weights), bool)
        seen[owner[valid]] = True
        failed = np.flatnonzero((status == COLLISION) & ~seen[owner])
        if len(failed) == 0 or not valid.any():
            return coverage, {}
        m = world.map
        pos = candidates[failed, :3]
        r = self.ctx.vehicle.collision_radius
        free_of_structure = ~_occupied_within(m, pos, r)
        failed, pos = failed[free_of_structure], pos[free_of_structure]
        reach = _reachable(world, r) if len(failed) else None
        if reach is not None:  # not sealed off from the vehicle by cells known occupied
            ids = np.asarray(m.index_of(pos), np.int64)  # flat, Fortran order; -1 outside
            inside = (ids >= 0) & reach.ravel(order="F")[np.maximum(ids, 0)]
            failed, pos = failed[inside], pos[inside]
        cells = np.asarray(m.storage_index(pos), np.int64)
        keep = (cells >= 0) & ~np.isin(cells, list(self.opened))
        failed, cells = failed[keep], cells[keep]
        if len(failed) == 0:
            return coverage, {}
        order = np.argsort(cells, kind="stable")
        cells, patch = cells[order], owner[failed][order]
        off, el = (np.asarray(coverage[k]) for k in ("offsets", "elements"))
        hit = _elements_in_cells(el, cells)
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
        extra = (vp[:, 0], base + vp[:, 1], w * patches.weights[vp[:, 1]])
        return _append_elements(coverage, *extra), opens

    # ------------------------------------------------------------------ generator
    def propose(self, world):
        if self.next >= len(self.views):
            last = self.plans[-1] if self.plans else None
            unflyable = last is not None and last["kept"] and not last["flown"]
            if unflyable and last["reachable_only"]:
                self.stop_reason = "no_reachable_view"
                return None
            if self.settings.max_plans and len(self.plans) >= self.settings.max_plans:
                return None
            # after a tour none of whose views could be reached, the next plans only those
            # that can be (the same plan again would fail the same way)
            reach = bool(unflyable)
            self.views, self.next = self.plan(world, reach, self.exploring), 0
            while len(self.views) == 0 and self.level > 1:  # then the smaller gains
                self.level = max(1.0, self.level / 2)
                self.views = self.plan(world, reach, self.exploring)
            if (
                len(self.views) == 0
                and self.settings.explore
                and not self.exploring
                and not self.regional
            ):
                # no view of the surface the map shows is worth its flight: from now on views
                # that open the unknown space within the structure's extent compete too
                self.exploring = True
                self.views = self.plan(world, reach, explore=True)
            if len(self.views) == 0:
                return None
        k = slice(self.next, self.next + 1)
        return Proposal(self.views[k], "tour", exclusive=True, aims=self.aims[k])

    def feedback(self, world, proposal, step):
        self.next += 1  # flown or skipped, the tour moves on
        if step is not None:
            self.plans[-1]["flown"] += 1


def prize_collect(start, points, gains, order, rate) -> list:
    """Drops stretches of an open tour `order` (indices into points (N, 3), gains (N,) in m^2)
    while some run of consecutive views adds less than `rate` m^2 per metre of the flight its
    removal saves - a single view's detour, or a far cluster's transit there and back - the
    worst deficit (rate x saving - gain) first. Returns the kept order."""
    order = list(order)
    if rate <= 0:
        return order
    while order:
        seq = np.vstack([start, points[order]])
        leg = np.linalg.norm(np.diff(seq, axis=0), axis=1)  # leg k ends at order[k]
        n = len(order)
        cum_leg = np.concatenate([[0.0], np.cumsum(leg)])
        cum_gain = np.concatenate([[0.0], np.cumsum(gains[order])])
        best, best_ij = 0.0, None
        for i in range(n):  # remove order[i..j]
            j = np.arange(i, n)
            inner = cum_leg[j + 1] - cum_leg[i]  # from the view before i through j
            after = np.where(j + 1 < n, leg[np.minimum(j + 1, n - 1)], 0.0)
            bridge = np.where(
                j + 1 < n, np.linalg.norm(seq[np.minimum(j + 2, n)] - seq[i], axis=1), 0.0
            )
            saving = inner + after - bridge
            deficit = rate * saving - (cum_gain[j + 1] - cum_gain[i])
            k = int(np.argmax(deficit))
            if deficit[k] > best + 1e-12:
                best, best_ij = float(deficit[k]), (i, int(j[k]))
        if best_ij is None:
            break
        del order[best_ij[0] : best_ij[1] + 1]
    return order


COLLISION = 2  # ViewStatus::Collision (_core.view_status_names)
_PATCH_FIELDS = ("centers", "normals", "weights")


def _append_elements(coverage, views, elements, weights) -> dict:
    """The coverage sets (offsets, elements, weights: per view, its elements in increasing order)
    with elements[i] (larger than any of the view's own) and its weight appended to the set of
    views[i]; views in increasing order. The sets move as blocks between the views that grow: no
    array per element beyond the new ones (a plan holds 20-46 M elements on a 100 m plant)."""
    off, el, wt = (np.asarray(coverage[k]) for k in ("offsets", "elements", "weights"))
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
    out = dict(coverage)
    out.update(offsets=off + before, elements=new_el, weights=new_wt)
    return out


#: Elements tested at a time by _elements_in_cells (4 M: 16 MB of their cells).
_CHUNK = 1 << 22


def _elements_in_cells(elements, cells) -> np.ndarray:
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


def _occupied_within(occupancy_map, points, radius) -> np.ndarray:
    """(N,) whether an occupied cell lies within `radius` of each point (cells sampled at the
    map's resolution over the ball)."""
    res = occupancy_map.resolution
    k = int(np.ceil(radius / res))
    g = np.arange(-k, k + 1) * res
    off = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    off = off[np.linalg.norm(off, axis=1) <= radius + 0.5 * res]
    q = (points[:, None, :] + off[None]).reshape(-1, 3)
    return (occupancy_map.state(q).reshape(len(points), -1) == 1).any(axis=1)


def _reachable(world, radius):
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


def _insertion_tour(chosen, gains, candidates, pose, cell_m2, rate):
    """(chosen, gains m^2, kept order into chosen, net value m^2) of a prize-collecting
    insertion tour from the vehicle (select_tour's views and gains in cell units, paying rate
    m^2 per metre): the shorter of its insertion order and the tour solved over its views, then
    prize-collected; net value: the kept views' gains - rate x the length of the kept tour."""
    if not chosen:
        return chosen, np.zeros(0), [], 0.0
    gains = np.asarray(gains) * cell_m2
    points = candidates[chosen, :3]
    order, length = _core.solve_tour(points, pose[:3])
    kept = list(range(len(chosen)))
    if _length(pose[:3], points, kept) <= length:
        order = kept
    order = prize_collect(pose[:3], points, gains, order, rate)
    value = float(gains[order].sum()) - rate * _length(pose[:3], points, order) if order else 0.0
    return chosen, gains, order, value


def _length(start, points, order) -> float:
    seq = np.vstack([start, points[order]])
    return float(np.linalg.norm(np.diff(seq, axis=0), axis=1).sum())
