"""Budgets: the limits that end a mission before its planner finds the structure covered.

`view_cap` resolves max_iterations (the cap on camera views after profiling); `Budget` is the
termination of the budget section: distance flown (m, profiling included), camera views and
wall time (s); 0 disables a limit. A mission that one of them ended says so in its summary
(`stopped_by_budget`) and on the console: its coverage is what the budget allowed, not what the
planner could reach."""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

from ...settings import nonneg

#: max_iterations left unset (null) follows the structure: this many views per m^2 of its
#: surface, and at least MIN_VIEW_CAP. The recommended planner flies about 0.23 views per m^2 of
#: observable surface on the airliner; twice the whole surface's worth is a cap that a planner
#: making progress does not meet, and still ends one that flies on without any.
VIEWS_PER_M2 = 0.5
MIN_VIEW_CAP = 1000

#: The termination reasons that are budgets (nothing about the structure's coverage), each with
#: the config key that sets it.
BUDGET_KEYS = {
    "max_iterations": "max_iterations",
    "budget_distance": "budget.max_distance_m",
    "budget_views": "budget.max_views",
    "budget_time": "budget.max_time_s",
}
BUDGET_REASONS = tuple(BUDGET_KEYS)


@dataclass(frozen=True)
class BudgetConfig:
    """Hard limits (0: none), checked after every view."""

    max_distance_m: float = nonneg(0.0)
    max_views: int = nonneg(0)
    max_time_s: float = nonneg(0.0)


def view_cap(max_iterations, surface_area_m2: float) -> int:
    """The cap on camera views after profiling: max_iterations as set, or (None) the one that
    follows the structure: max(MIN_VIEW_CAP, VIEWS_PER_M2 x its surface area)."""
    if max_iterations is not None:
        return int(max_iterations)
    return max(MIN_VIEW_CAP, int(math.ceil(VIEWS_PER_M2 * surface_area_m2)))


#: Why a mission whose sensors saw no surface ends (termination "nothing_seen").
NOTHING_SEEN = (
    "the sensors saw no surface of the structure (no point from the profile nor from a view): "
    "the planner had nothing to cover. The start may be out of the sensors' reach of every "
    "part (structures far apart: try profiling.enabled=false, or another start)"
)


def ended_by(termination: str, world) -> str:
    """The planner's termination, or "nothing_seen" (with a RuntimeWarning) where it found
    nothing to cover because the sensors never saw a surface, not because it is covered."""
    if termination == "coverage_complete" and not any(map(len, world.clouds)):
        warnings.warn(NOTHING_SEEN, RuntimeWarning, stacklevel=4)
        return "nothing_seen"
    return termination


def budget_note(summary: dict) -> str | None:
    """A line for the console when a budget ended the mission, naming the budget and how to
    raise it; when the sensors saw nothing (NOTHING_SEEN); or when the coverage tours ended with
    views left that each add tour.min_gain but did not pay for their flight (the last plan's
    unpaid views), naming the rate and tour.final_rate. None otherwise."""
    if summary.get("termination") == "nothing_seen":
        return NOTHING_SEEN
    last = (summary.get("tours") or [{}])[-1]
    if summary.get("termination") == "coverage_complete" and last.get("unpaid"):
        rate = "tour.final_rate" if last.get("final") else "tour.rate"
        n, m2 = last["unpaid"], last["unpaid_m2"]
        how = " (--set tour.final_rate=R flies them at R m2 a metre; docs/USAGE.md)"
        how = "" if last.get("final") else how
        return (
            f"{n} view{'' if n == 1 else 's'} adding {m2:.1f} m2 of surface in all "
            f"({last['min_gain_m2']:.2f} m2 each at least) did not pay {rate} for their flight "
            f"and were not flown{how}"
        )
    key = BUDGET_KEYS.get(summary.get("termination"))
    if key is None:
        return None
    if key == "max_iterations":
        n = summary.get("max_views")
        what = f"the view cap ({n} planned view{'' if n == 1 else 's'} after the first)"
    else:
        what = f"the budget {key}"
    return stopped_by_budget(what, key)


def stopped_by_budget(what: str, key: str, runs: str = "") -> str:
    """The console's words for runs a budget stopped: `what` stopped them (`runs`: which), and
    the key that raises it."""
    return (
        f"stopped by {what}, not because the structure is covered{runs}: the coverage is what the "
        f"budget allowed (raise it with --set {key}=...)"
    )


class Budget:
    Settings = BudgetConfig

    def __init__(self, settings: BudgetConfig, context=None):
        self.b = settings
        self.t0 = time.perf_counter()

    def check(self, world, step):
        b = self.b
        if b.max_distance_m and world.state.distance_m >= b.max_distance_m:
            return "budget_distance"
        if b.max_views and world.state.views >= b.max_views:
            return "budget_views"
        if b.max_time_s and time.perf_counter() - self.t0 >= b.max_time_s:
            return "budget_time"
        return None
