"""Choosing the view to fly among scored candidates.

A candidate qualifies when it is valid (status 0) and its gain is at least planner.min_gain (surface
utility: m^2 of new surface, scaled down on a structure smaller than planner.reference_area,
parts.threshold_scale; other utilities: their own unit, as set). Among those the best utility *
exp(-travel_lambda * d) wins, d the length of the flight to it: straight (vehicle blocked_path
'reject': the straight leg was checked by the scoring) or an A* path through known free space
('plan'), computed lazily - the best by straight distance first, re-ranked by its path, until the
top one's path is known. Ties go to the lower index, so the paper's scenarios (travel_lambda 0,
straight legs) choose exactly the best valid utility as before.

A failed search is final unless it stopped at its cap on expanded cells (vehicle.path_expansions;
on a large map the way round a structure can take more). Within one planning step (begin() to the
next begin(): the map does not change) the first search cut short by its cap floods the vehicle's
free component once (_core.FreeComponent): a view inside it is searched again without the cap,
and a later candidate outside it is passed over without a search. It changes no choice: a search
to such a view always fails.
"""
from __future__ import annotations

import heapq
import math
from collections import Counter

import numpy as np

from .. import _core
from .parts import Choice, threshold_scale

#: Why a candidate was not chosen (`Selector.refused`, a summary's `refused_views`): the core's
#: view status (VIEW_STATUS_NAMES) and the selection's own two causes, in the console's words.
#: Counted per refusal: a view proposed again in the same planning step counts again.
REFUSALS = {
    "out_of_bounds": "outside the workspace",
    "collision": "within vehicle.collision_radius of occupied or unknown space",
    "path_blocked": "a straight leg through occupied or unknown space",
    "sees_no_occupied": "seeing no occupied cell",
    "below_min_gain": "worth less than planner.min_gain",
    "no_path": "no way there through known free space",
}


def refusal_words(refused: dict) -> str:
    """The console's words for a plan's refused candidates (`refused_views`), most first."""
    most = sorted(((n, k) for k, n in refused.items() if n > 0), key=lambda nk: -nk[0])
    return ", ".join(f"{n:,} {REFUSALS.get(k, k)}" for n, k in most)


#: why a mission may plan no view at all (its generators' candidates all refused)
NOTHING_FLOWN = (
    "no planned view was flown: every candidate was invalid (in occupied or unknown space, "
    "within vehicle.collision_radius of it, outside the workspace, or not reachable: with "
    "vehicle.blocked_path=reject a straight leg must cross known free space, or seeing no "
    "occupied cell: utility.require_occupied) or worth less than planner.min_gain (in the "
    "utility's own units)"
)


def nothing_flown(refused: dict) -> str:
    """Why a mission flew no planned view, with its refusals by cause (`refused_views`)."""
    words = refusal_words(refused)
    return (
        f"{NOTHING_FLOWN}; refused in the last planning step: {words}" if words else NOTHING_FLOWN
    )


class Selector:
    def __init__(self, context):
        p, resolution = context.planner, context.resolution
        self.travel_lambda = p.travel_lambda
        self.surface = context.utility.name == "surface"
        self.min_gain = p.min_gain / resolution**2 if self.surface else p.min_gain
        self.reference_area = p.reference_area
        self.plan_paths = context.vehicle.blocked_path == "plan"
        self.radius = context.vehicle.collision_radius
        self.component = None  # the vehicle's free component, once a search has failed
        self.refused = Counter()  # the candidates not chosen this planning step, by REFUSALS

    def begin(self) -> None:
        """A new planning step: the map may have changed since the last."""
        self.component = None
        self.refused = Counter()

    def _reachable(self, world, pose) -> bool:
        return self.component is None or bool(self.component.contains(world.map, pose[None, :3])[0])

    def choose(self, world, poses: np.ndarray, scores: dict):
        here = world.state.pose[:3]
        min_gain = self.min_gain
        if self.surface and min_gain > 0:
            min_gain *= threshold_scale(world.map, self.reference_area)
        ok = np.flatnonzero((scores["status"] == 0) & (scores["gain"] >= min_gain))
        if len(ok) == 0:
            self._tally(scores, min_gain)
            return None
        straight = np.linalg.norm(poses[ok, :3] - here, axis=1)
        value = scores["utility"][ok] * np.exp(-self.travel_lambda * straight)
        heap = [(-float(v), int(k), float(d), False) for v, k, d in zip(value, ok, straight)]
        heapq.heapify(heap)
        paths = {}
        while heap:
            neg, k, d, exact = heapq.heappop(heap)
            if exact or not self.plan_paths:
                path = paths.get(k) if self.plan_paths else None
                return Choice(
                    k,
                    poses[k].copy(),
                    float(scores["utility"][k]),
                    float(scores["gain"][k]),
                    path,
                    d,
                )
            path = None
            if self._reachable(world, poses[k]):
                search = world.search_path(poses[k])
                path = search.path if len(search.path) else None
                if search.capped:  # cut short by its cap: search it all if it can end there
                    if self.component is None:
                        self.component = world.free_component()
                    if self._reachable(world, poses[k]):
                        path = world.plan_path(poses[k], max_expansions=world.map.num_cells)
            if path is None:  # no way there through known free space
                continue
            length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
            paths[k] = path
            v = float(scores["utility"][k]) * math.exp(-self.travel_lambda * length)
            heapq.heappush(heap, (-v, k, length, True))
        self._tally(scores, min_gain, no_path=len(ok))
        return None

    def _tally(self, scores: dict, min_gain: float, no_path: int = 0) -> None:
        """Counts a proposal none of whose views was chosen into `refused`: its invalid views by
        status, those valid but worth less than min_gain, and `no_path` with no way there."""
        status = scores["status"]
        below = int(((status == 0) & (scores["gain"] < min_gain)).sum())
        codes, n = np.unique(status[status != 0], return_counts=True)
        counts = {_core.VIEW_STATUS_NAMES[c]: int(k) for c, k in zip(codes, n)}
        self.refused.update({**counts, "below_min_gain": below, "no_path": no_path})
