"""Coverage tours (nbvkit's surface planner): plan views that together cover the surface still
to observe, fly them in a short order, and plan again when the tour is done.

A plan: surface targets -> patches -> candidate views (placement.py) -> one C++ call over the
map and the memo (nbvkit._core.plan_tour, a typed TourPlan): what each would newly cover (cells
and the side they are seen from) -> the views that add at least tour.min_gain (tour.selection:
prize-collecting insertion tours, or a greedy set cover) -> an open tour from the vehicle
(nearest neighbour, 2-opt, Or-opt) -> prize collecting: views that add less than tour.rate m^2
per metre of the detour they cause are dropped, the worst first, until every view pays. The
tour is then proposed one view at a time (exclusive proposals): the planner re-scores
each against the current map and skips it when it no longer adds tour.min_gain. When the tour is
done (or once tour.replan_views of its views were flown) the next plan is made from what the map
shows then. With tour.explore, once a plan keeps no
view, every later plan also weighs views of the unknown space within the structure's extent
and within tour.explore_range camera ranges of the surface the map shows (exploration_targets:
parts of the structure nothing has shown yet hold no surface target; with
tour.explore_first, by default on a large workspace, every plan does, the first one included); a
plan with no view left, or one none of whose views could be flown, ends the generator
(tour.max_plans caps the plans); with tour.final_rate, a plan that keeps no view at tour.rate is
followed by plans at that lower rate first. With
tour.access_weight > 0 a view is also credited with the surface it would give access to: patches
whose every view fails the collision test for want of known free space, where its rays reach
the place of such a view and the vehicle could fly there through space not known to be occupied
(access.py; off by default, docs/RESULTS.md). On a structure
smaller than planner.reference_area both thresholds shrink with it (parts.threshold_scale).

On a large workspace (longer than 6 camera ranges: a 100 m plant, not a 35 m aircraft; by
default) plans keep at first only views adding 2^tour.gain_levels x min_gain, halving the
threshold each time a plan keeps fewer than tour.level_views views (it selects again at the
lower level): the large gains of the whole structure are flown before
the small ones near the vehicle (a decreasing-threshold greedy; docs/RESULTS.md, "Large
structures"); once no plan keeps a view, patches whose own views are all blocked get views
from tilted directions (placement.fallback null) before the generator ends; and the coverage
sets hold the unknown space away from surface as one element per brick of the map
(tour.pool_unknown null), not per cell: plans of 12-30x fewer elements. With
tour.region_size the tours are planned region by region (regions.py: the
region the vehicle is in, then the next of an open tour over the regions still holding value)
and explore the unknown space of the whole workspace from the first plan."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ... import _core
from ...limits import require_type
from ...settings import choice, nonneg, positive, within
from ..parts import MIN_RATE_SCALE, Proposal, threshold_scale
from ..placement import Patches, explore_placement, place_views, refit_blocked, target_patches
from .access import access_elements
from .exploration import exploration_targets
from ...workspace import is_large
from ...world import World
from .regions import Regions


@dataclass(frozen=True)
class TourConfig:
    """The coverage-tour generator: set cover of views over the surface targets, a shortest
    tour through them, flown; then again, until no planned view is worth its flight."""

    # how a plan chooses views: "cover" (greedy set cover, then a shortest tour) or "insertion"
    # (prize-collecting: new surface - rate x added tour length, by cheapest insertion)
    selection: str = choice("insertion", ("cover", "insertion"))
    min_gain: float = nonneg(1.2)  # m^2 of new surface a view must add to enter a plan (RESULTS.md)
    rate: float = nonneg(0.5)  # m^2 of new surface per metre of tour a planned view must pay for
    max_plans: int = within(0, 0, 10**6)  # tours planned at most (0: until a plan is empty)
    # a stranded patch: all its views fail the collision test for want of known free space;
    # a view whose rays reach where they would be gets this share of its weight
    access_weight: float = nonneg(0.0)  # a stranded patch's share credited to a view opening it
    # once no view of the surface the map shows is worth its flight, plans also weigh views of
    # the unknown space within the structure's extent (unknown cells bordering free space)
    explore: bool = True  # then also plan views that open unknown space; false: stop there
    # with explore: from the first plan on; null: on a workspace longer than 6 camera ranges
    # (workspace.is_large: the plant, +2.1 points at 1,000 views in 13 % less flight; RESULTS.md)
    explore_first: Optional[bool] = None  # unknown space from the first plan; null: by size
    # the unknown space explored lies within this many camera ranges of a cell the map holds
    # occupied or predicted, not anywhere in the box round them: to completion, a diagonal
    # bridge and the airliner at 3x fly a third less, a plant covers 7 points less of its
    # observable area (90.4 %) in a third less flight (RESULTS.md); 0: the whole box
    explore_range: float = nonneg(1.0)  # camera ranges from the mapped surface; 0: its box
    # plans first keep only views adding 2^gain_levels x min_gain, halving it each time a plan
    # keeps too few (level_views); null: 3 on a workspace longer than 6 camera ranges
    # (workspace.is_large), else 0
    gain_levels: Optional[int] = within(None, 0, 20)  # the larger gains first; null: by size
    # a plan above the lowest level that keeps fewer views than this selects again at half
    # the level, before any view is flown (1: only when it keeps none; 8 on the plants: 1.3-1.9
    # points less coverage at 1,000 views; RESULTS.md)
    level_views: int = within(1, 1, 10**6)  # views a plan keeps before its level halves
    # with region_size, a workspace larger than it is toured region by region (regions.py),
    # exploring the unknown space of the whole workspace from the first plan
    region_size: Optional[float] = positive(None)  # m; null: one region
    # a candidate is first walked along every coarse_stride-th ray across and down; one whose
    # gain so estimated is below coarse_margin x the plan's min_gain is not walked whole
    # (view_coverage; with tour.access_weight every candidate is: credit may lift it). 0: every
    # candidate walked whole
    coarse_stride: int = within(3, 0, 64)  # rays of the estimate before a walk; 0: off
    # the estimate runs 2.5-3.1 x the walked gain (the median over views reaching min_gain on
    # the airliner); at 2, 15 % less planning a view, 8 of 10 aircraft flights the same
    # (RESULTS.md); 1: every view that might reach min_gain is walked
    coarse_margin: float = positive(2.0)  # multiple of min_gain an estimate must reach
    # a view's credits of unknown space away from surface (utility.unknown_prior: most of its
    # coverage elements, 3-16 % of its gain on a plant) pooled per brick of 4 x 4 x 4 cells, one
    # element each (view_coverage's pool_unknown): 12-30x fewer on a plant; null: on a workspace
    # longer than 6 camera ranges (workspace.is_large); not with access_weight (which looks
    # for single unknown cells in the sets)
    pool_unknown: Optional[bool] = None  # unknown space pooled per brick; null: by size
    # a tour is planned again from the map of the moment once this many of its views were
    # flown (what the views and the frames of their legs saw makes the rest of it stale); 0:
    # only when it is done
    replan_views: int = within(0, 0, 10**6)  # views flown before the tour is planned again
    # once no plan keeps a view at tour.rate (the unknown space explored, the blocked patches
    # refitted), plans go on at this rate: the views left that each add min_gain but did not pay
    # for their flight are flown (more coverage for more flight; RESULTS.md); null: the
    # generator ends there
    final_rate: Optional[float] = nonneg(None)  # m^2 per metre of the last plans; null: none

    def __post_init__(self):
        if self.pool_unknown and self.access_weight > 0:
            raise ValueError(
                "tour.pool_unknown cannot be true with tour.access_weight > 0: access credit "
                "looks for single unknown cells in the coverage sets"
            )


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
        self.refit = bool(context.placement.fallback)  # blocked patches' tilted views planned
        self.refit_last = False  # and from the first plan that keeps no view (set at the first)
        # what earlier plans' walks found, for candidates asked for again (the same arrays)
        self.memo = _core.CoverageMemo()
        self.regions: Regions | None = None  # set at the first plan (tour.region_size)
        self.level = None  # the multiple of tour.min_gain plans keep now; None: no plan yet
        self.pool = bool(settings.pool_unknown)  # unknown space pooled per brick (first plan)
        self.final = False  # plans at tour.final_rate (once none keeps a view at tour.rate)

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
        grouped per cube of the camera's nearer stand-off, each looked at straight on, and
        down by the gimbal with placement.explore_gimbal (explore_placement); their patches
        follow the surface's; with pitched views of the unknown space and level views of the
        surface, the surface's get a pitch of 0)."""
        ctx = self.ctx
        bounds = (world.workspace.nav_min, world.workspace.nav_max)
        targets = _core.surface_targets(world.map, world.surface, ctx.targets)
        patches = target_patches(targets, ctx.placement.cluster(ctx.camera))
        candidates, owner = place_views(patches, ctx.camera, ctx.placement, bounds)
        unplaced = np.zeros(0, int)
        if self.refit:  # blocked patches from the nearest direction that can fly
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
            near = self.settings.explore_range * ctx.camera.max_range or None
            more = target_patches(exploration_targets(world.map, box, near), size)
            explore_at, camera = explore_placement(ctx.placement, ctx.camera)
            views, of = place_views(more, camera, explore_at, bounds)
            if views.shape[1] > candidates.shape[1]:  # the surface's views level
                if np.any(views[:, 4]):  # some of the unknown's pitched: the surface's at 0
                    candidates = np.column_stack([candidates, np.zeros(len(candidates))])
                else:  # all level: 4 numbers, as the surface's
                    views = views[:, :4]
            candidates = np.vstack([candidates, views])
            owner = np.concatenate([owner, of + len(patches.weights)])
            patches = Patches(
                *(np.concatenate([getattr(patches, f), getattr(more, f)]) for f in _PATCH_FIELDS)
            )
        return targets, patches, candidates, owner, unplaced

    def coverage(self, world, candidates) -> _core.CoverageSets:
        """What each candidate would newly cover, from the vehicle's pose (view_coverage): the
        sets of every candidate, as the access credit reads them."""
        return _core.view_coverage(
            world.map,
            world.surface,
            candidates,
            world.state.pose,
            **_walk_options(world, self.ctx.utility),
            memo=self.memo,
            pool_unknown=self.pool,
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
            self.refit_last = large and ctx.placement.fallback is None  # null: by size
            if own.pool_unknown is None:
                self.pool = large and own.access_weight <= 0
        explore = explore or self.exploring or (self.regional and own.explore)
        scale = threshold_scale(world.map, ctx.planner.reference_area)
        rate_scale = threshold_scale(world.map, ctx.planner.reference_area, MIN_RATE_SCALE)
        rate = (own.final_rate if self.final else own.rate) * np.sqrt(rate_scale)
        min_gain = own.min_gain * scale * self.level
        targets, patches, candidates, owner, unplaced = self.candidates(world, explore)
        if reachable_only and len(candidates):
            component = world.free_component()
            reach = np.asarray(component.contains(world.map, candidates[:, :3]), bool)
            candidates, owner = candidates[reach], owner[reach]
        record = {
            "scale": float(scale),
            "targets": len(targets),
            "candidates": int(len(candidates)),
            "selected": 0,
            "kept": 0,
            "flown": 0,
            "length_m": 0.0,
            "reachable_only": reachable_only,
            "explore": explore,
            "min_gain_m2": float(min_gain),
            "unplaced_patches": len(unplaced),
            "refit": self.refit,
            "final": self.final,
            "unpaid": 0,  # views adding min_gain that no tour paid for (a plan keeping none)
            "unpaid_m2": 0.0,
        }
        self.plans.append(record)
        views, self.aims = np.zeros((0, candidates.shape[1])), np.zeros((0, 3))
        if len(candidates):
            if self.regional:
                views, self.aims = self._regional(
                    world, candidates, owner, patches, record, min_gain, rate
                )
            else:
                views, self.aims = self._choose(
                    world, candidates, owner, patches, record, min_gain, rate, drop=True
                )
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

    def _choose(self, world, candidates, owner, patches, record, min_gain, rate, drop=False):
        """(views, aims) in flight order: the plan over the candidates (_plan), prize-collected;
        `record` gets the counts. With drop, while the plan keeps fewer than tour.level_views
        views above the lowest level, the level halves and the plan is made again."""
        coverage, opens = None, {}
        if self.settings.access_weight > 0:  # every set: access credit may lift a view
            coverage, opens = self._access(
                world, self.coverage(world, candidates), candidates, owner, patches
            )
        plan = self._plan(world, candidates, coverage, min_gain, rate)
        while drop and len(plan.order) < self.settings.level_views and self.level > 1:
            min_gain /= self.level
            self.level = max(1.0, self.level / 2)
            min_gain *= self.level
            plan = self._plan(world, candidates, coverage, min_gain, rate)
        record["min_gain_m2"] = float(min_gain)
        record["selected"] = len(plan.chosen)
        for k in plan.chosen:  # the places a chosen view opens are not credited again
            self.opened.update(opens.get(int(k), ()))
        record["kept"] = len(plan.order)
        record["unpaid"], record["unpaid_m2"] = plan.unpaid, plan.unpaid_area
        record["length_m"] = plan.length
        return candidates[plan.flight], patches.centers[owner[plan.flight]]

    def _plan(self, world, candidates, coverage, min_gain, rate):
        """The TourPlan of tour.selection over the candidates at min_gain (m^2) and rate (m^2 a
        metre) from the vehicle's pose (plan_tour: its coverage sets only those of views that
        can be chosen), or over the given coverage sets."""
        own, pose = self.settings, world.state.pose
        kw = dict(selection=own.selection, min_gain=min_gain, rate=rate)
        if coverage is not None:
            cell_m2 = world.map.resolution**2
            return _core.plan_tour_over(coverage, candidates[:, :3], pose[:3], cell_m2, **kw)
        coarse = dict(coarse_stride=own.coarse_stride, coarse_margin=own.coarse_margin)
        utility = self.ctx.utility
        return plan_tour(world, candidates, utility, self.memo, **coarse, **kw, pool=self.pool)

    def _access(self, world, coverage, candidates, owner, patches):
        """access.access_elements with tour.access_weight, the vehicle's collision radius and
        the places already credited to a chosen view."""
        w, r = self.settings.access_weight, self.ctx.vehicle.collision_radius
        return access_elements(world, coverage, candidates, owner, patches, w, r, self.opened)

    # ------------------------------------------------------------------ generator
    def propose(self, world):
        if self.next >= len(self.views) or self._replan_due():
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
            if len(self.views) == 0 and self.refit_last and not self.refit:
                self.refit = True  # the last resort: blocked patches from tilted directions
                self.views = self.plan(world, reach, self.exploring)
            if len(self.views) == 0 and self.settings.final_rate is not None and not self.final:
                self.final = True  # what is left, at the lower rate
                self.views = self.plan(world, reach, self.exploring)
            if len(self.views) == 0:
                if reach:  # the last tour's views could not be flown, and no view can be now
                    self.stop_reason = "no_reachable_view"
                return None
        k = slice(self.next, self.next + 1)
        self.stop_reason = None  # (a reason given before is not this step's)
        return Proposal(self.views[k], "tour", exclusive=True, aims=self.aims[k])

    def _replan_due(self) -> bool:
        """Whether the rest of the tour is planned again (tour.replan_views of it flown, and
        tour.max_plans leaves another plan: else the tour is flown to its end)."""
        every, cap = self.settings.replan_views, self.settings.max_plans
        if not every or not self.plans or (cap and len(self.plans) >= cap):
            return False
        return self.plans[-1]["flown"] >= every

    def feedback(self, world, proposal, step):
        self.next += 1  # flown or skipped, the tour moves on
        if step is not None:
            self.plans[-1]["flown"] += 1


_PATCH_FIELDS = ("centers", "normals", "weights")


def plan_tour(
    world,
    candidates,
    utility=None,
    memo=None,
    selection: str | None = None,
    min_gain: float | None = None,
    rate: float | None = None,
    coarse_stride: int = 0,
    coarse_margin: float = 1.0,
    pool: bool = False,
) -> _core.TourPlan:
    """The coverage tour over candidate views (K, 4 or 5) from where the vehicle is, in one C++ call
    over the world's map and camera observations (nbvkit._core.plan_tour): what each would newly
    cover, as the surface utility credits it (utility: a UtilityConfig, the `utility` section,
    whose priors and cone it takes; None: the world's configuration's), the views adding at
    least min_gain m^2 (selection "insertion": prize-collecting insertion tours; "cover": a
    greedy set cover), their open tour from the vehicle, and prize collection at rate m^2 per
    metre (selection, min_gain and rate: None takes the world's configuration's tour.*,
    unscaled). memo: a CoverageMemo kept between calls (fewer walks). Views are valid as the
    planner's are (the navigation space, the collision sphere in known free space). Returns a
    TourPlan: plan.flight indexes candidates in flight order."""
    require_type(world, World, "plan_tour: world", "an nbvkit.World (a mission's: Mission.world)")
    if memo is not None and not isinstance(memo, _core.CoverageMemo):
        raise TypeError(
            f"plan_tour: memo is a nbvkit.CoverageMemo or None, not {type(memo).__name__}"
        )
    tour = world.config.tour
    return _core.plan_tour(
        world.map,
        world.surface,
        candidates,  # (converted and checked there: complex or bool views are refused)
        world.state.pose,
        **_walk_options(world, world.config.utility if utility is None else utility),
        memo=memo,
        selection=tour.selection if selection is None else selection,
        min_gain=tour.min_gain if min_gain is None else min_gain,
        rate=tour.rate if rate is None else rate,
        coarse_stride=coarse_stride,
        coarse_margin=coarse_margin,
        pool_unknown=pool,
    )


def _walk_options(world, utility) -> dict:
    """The camera, utility and validity of view_coverage and plan_tour: the world's view camera,
    the utility section's priors and cone (None: the defaults) and the planner's validity."""
    if utility is not None and not callable(getattr(utility, "options", None)):
        raise TypeError(
            "plan_tour: utility is the configuration's utility section (context.utility) or None, "
            f"not {type(utility).__name__}"
        )
    options = utility.options() if utility is not None else _core.UtilityOptions()
    return dict(
        camera=world.view_camera, utility=options, validity=world.validity(blocked_path="plan")
    )
