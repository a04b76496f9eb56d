"""The next-best-view loop of the paper's Fig. 1, made of interchangeable parts: generators
propose views, the utility scores them (one call, scoring.Scorer), the selection picks one, the
vehicle flies there and senses, the after-view hooks run by name, the terminations decide."""
from __future__ import annotations

from dataclasses import dataclass

from ..settings import Names, nonneg, within
from ..termination import viewable_cells
from ..timing import StageTimers
from .legs import fly_leg, retreat
from .parts import PlanningContext, Step, propose, run_hooks
from .registry import get_generator, get_termination
from .scoring import Scorer
from .selection import Selector


@dataclass(frozen=True)
class PlannerConfig:
    """The planner's parts (nbvkit.planning): generators, terminations, how a view is chosen."""

    generators: Names = ("tour",)  # lattice | frontier | tour (first with views left leads)
    terminations: Names = ("budget",)  # entropy | stall | budget (any one ends the mission)
    min_gain: float = nonneg(0.8)  # m^2 of new surface (surface utility; else utility units); 0 any
    travel_lambda: float = nonneg(0.15)  # 1/m; a view ranks by utility * exp(-travel_lambda * path)
    # on a smaller structure (mapped surface A), m^2 thresholds x A/reference_area, tour.rate x
    # its square root (parts.threshold_scale); the profiles of the 35 m airliners map 417-502 m^2
    reference_area: float = nonneg(400.0)  # m^2 of mapped surface below which thresholds shrink
    frame_step: float = nonneg(1.0)  # m flown between frames on a leg; 0: at views only (paper)
    frame_novelty: float = within(0.0, 0.0, 1.0)  # new share a leg frame's preview needs; 0: all

    def check(self, key: str) -> None:
        from .registry import check_names

        check_names(self.generators, self.terminations)
        if 0 < self.frame_step < 0.1:  # a frame every few cm: thousands a leg
            raise ValueError(f"{key}.frame_step must be 0 (none) or >= 0.1 m: {self.frame_step}")


class Planner:
    """The loop of Fig. 1 over a World; its parts named by config.planner (registry.py), each
    built from its own section. ``hooks``: name -> hook(world, step), run after every view in
    order ("feedback": the generators that proposed the view learn of it, e.g. AGVS's scale); a
    mission adds its own (symmetry, recorder). ``timers``: each stage's time round the parts."""

    def __init__(self, config):
        ctx, p = PlanningContext.of(config), config.planner
        self.generators = [get_generator(n, config, ctx) for n in p.generators]
        self.terminations = {n: get_termination(n, config, ctx) for n in p.terminations}
        self.ended_by = None  # the termination whose reason ended the mission
        self.selector = Selector(ctx)
        self.score = Scorer(config.utility)
        c = config.camera
        fov = (c.hfov_deg, c.vfov_deg, c.min_range, c.max_range, ctx.resolution)
        self.c_view = viewable_cells(*fov, config.entropy.count_partial_cells)
        self.frames = (p.frame_step, p.frame_novelty)
        # legs through known free space: a vehicle a scan closed in on flies back out (retreat)
        self.radius = config.vehicle.collision_radius * (config.vehicle.blocked_path == "plan")
        self.timers = StageTimers()
        self.hooks = {"feedback": _feedback}

    def run(self, world, max_views: int) -> str:
        """Flies views until a termination fires, else max_views ("max_iterations"); says why."""
        t, entropy_before = self.timers, world.map.total_entropy()
        for iteration in range(1, max_views + 1):
            back = t.call("motion", retreat, world, self.radius) if self.radius else 0.0
            found = self.next_view(world)  # viewpoint sampling + evaluation + selection
            if isinstance(found, str):
                return found
            leg, frame_cells = fly_leg(world, found[3], *self.frames, t)
            scan = t.call("sensing", world.scan, "view")
            new_cells = frame_cells + t.call("mapping", world.integrate, scan, "view")
            delivered = t.call("evaluation", self.score.delivered, world, found[3])
            step = Step.of(iteration, found, world, entropy_before, self.c_view, new_cells)
            step.expected_m2, step.realized_m2 = delivered
            entropy_before = step.entropy_after  # the next row's change: all since this one's
            step.extra.update(leg_m=back + leg, scan=scan)
            run_hooks(self.hooks, world, step)  # all of them, then a part's error
            for name, term in self.terminations.items():
                if reason := term.check(world, step):
                    self.ended_by = name
                    return reason
        return "max_iterations"

    def next_view(self, world):
        """(proposal, its generators, scores, choice) of the next view to fly, or why there is
        none: "coverage_complete" (no generator proposes anything), a generator's own
        `stop_reason` where it gave up for another cause (a tour none of whose views could be
        reached: "no_reachable_view"), or "no_valid_viewpoint" (no candidate is valid and worth
        flying). The first generator with an exclusive proposal (a tour) leads; its views are
        tried in turn. Otherwise the non-exclusive proposals are scored together."""
        t = self.timers
        self.selector.begin()
        for _ in range(10_000):  # proposals rejected in a row before the search gives up
            proposal, makers = t.call("sampling", propose, self.generators, world)
            if proposal is None:
                why = [getattr(g, "stop_reason", None) for g in self.generators]
                return next(filter(None, why), "coverage_complete")
            scores = t.call("evaluation", self.score, world, proposal.poses)
            choice = t.call("selection", self.selector.choose, world, proposal.poses, scores)
            if choice is not None:
                return proposal, makers, scores, choice
            for g in makers:
                g.feedback(world, proposal, None)
            if not proposal.exclusive:
                break
        return "no_valid_viewpoint"


def _feedback(world, step: Step) -> None:
    """The generators that proposed the flown view learn of it (AGVS's scale follows dE_v)."""
    for g in step.makers:
        g.feedback(world, step.proposal, step)
