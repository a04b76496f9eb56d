"""The next-best-view loop of the paper's Fig. 1, made of interchangeable parts."""
from __future__ import annotations

import numpy as np

from .. import _core
from ..termination import viewable_cells
from ..timing import StageTimers
from .parts import Proposal, Step
from .registry import GENERATORS, TERMINATIONS
from .selection import Selector


class Planner:
    """Generators propose views, the utility scores them (one C++ call), the selection picks
    one, the vehicle flies there and senses, the terminations decide whether to go on.

    config: a resolved nbvkit.Config (planner.generators / planner.terminations name the parts,
    registry.py). `on_step(step)` is called after every view (records, progress)."""

    def __init__(self, config, resolution: float, on_step=None):
        self.config = config
        self.generators = [GENERATORS[n](config) for n in config.planner.generators]
        self.terminations = [TERMINATIONS[n](config) for n in config.planner.terminations]
        self.selector = Selector(config, resolution)
        self.utility = config.utility.options()
        self.surface = config.utility.name == "surface"  # its gain: cells of new surface
        c = config.camera
        self.c_view = viewable_cells(
            c.hfov_deg,
            c.vfov_deg,
            c.min_range,
            c.max_range,
            resolution,
            config.termination.count_partial_cells,
        )
        self.on_step = on_step
        self.timers = StageTimers()
        # the paper's IG walks kept between iterations: the same scores, fewer walks
        self.memo = _core.ViewMemo()

    def run(self, world, max_views: int) -> str:
        """Flies views until a termination fires or max_views are flown ("max_iterations");
        returns why it stopped."""
        t = self.timers
        for iteration in range(1, max_views + 1):
            found = self.next_view(world)  # viewpoint sampling + evaluation + selection
            if isinstance(found, str):
                return found
            proposal, contributors, scores, choice = found
            entropy_before = world.map.total_entropy()
            with t("motion"):
                leg = world.fly_to(choice.pose, "nbv", choice.path)
            with t("sensing"):
                scan = world.camera.scan_pose(world.state.pose)
            with t("mapping"):
                world.map.integrate(scan)
                world.camera_cloud.add(scan.hits)
                new_cells = world.surface.add_scan(scan)
                world.state.capture("view")
            entropy_after = world.map.total_entropy()
            with t("evaluation"):
                expected, realized = self.delivered(world, choice)
            step = Step(
                iteration,
                choice,
                proposal.source,
                len(proposal.poses),
                int((scores["status"] == 0).sum()),
                entropy_before,
                entropy_after,
                (entropy_before - entropy_after) / self.c_view,
                new_cells * world.map.resolution**2,
                world.state.distance_m,
                extra={"leg_m": leg, "scan": scan},
                expected_m2=expected,
                realized_m2=realized,
            )
            for g in contributors:
                g.feedback(world, proposal, step)
            if self.on_step:
                self.on_step(step)
            for term in self.terminations:
                reason = term.check(world, step)
                if reason:
                    return reason
        return "max_iterations"

    def score(self, world, poses) -> dict:
        """The utility's scores of candidate views `poses` (K, 4 or 5) from where the vehicle is:
        one C++ call (evaluate_views) with the planner's memo."""
        return _core.evaluate_views(
            world.map,
            poses,
            world.state.pose,
            camera=world.view_camera,
            utility=self.utility,
            validity=world.validity(),
            surface=world.surface,
            memo=self.memo,
        )

    def delivered(self, world, choice):
        """(expected, realized) m^2 of the view just flown, in the surface utility's own terms
        (None, None for other utilities): the new surface its score counted when it was chosen,
        and how much of that the frame brought - the score's drop when the same pose is scored
        again on the map after it. What is still counted after the view was flown from there
        (unknown space the structure hides, surface beyond the camera's reach) was expected of
        it and not delivered."""
        if not self.surface:
            return None, None
        after = self.score(world, choice.pose[None])
        cell_m2 = world.map.resolution**2
        left = float(after["gain"][0]) if after["status"][0] == 0 else 0.0
        return choice.gain * cell_m2, max(0.0, choice.gain - left) * cell_m2

    def next_view(self, world):
        """(proposal, its generators, scores, choice) of the next view to fly, or why there is
        none: "coverage_complete" (no generator proposes anything), a generator's own
        `stop_reason` where it gave up for another cause (a tour none of whose views could be
        reached: "no_reachable_view"), or "no_valid_viewpoint" (no candidate is valid and worth
        flying). The first generator with an exclusive proposal (a
        tour) leads; its views are tried in turn. Otherwise the non-exclusive proposals are
        scored together."""
        t = self.timers
        self.selector.begin()
        while True:
            with t("sampling"):
                proposal, contributors = self.propose(world)
            if proposal is None:
                reasons = (getattr(g, "stop_reason", None) for g in self.generators)
                return next((r for r in reasons if r), "coverage_complete")
            with t("evaluation"):
                scores = self.score(world, proposal.poses)
            with t("selection"):
                choice = self.selector.choose(world, proposal.poses, scores)
            if choice is not None:
                return proposal, contributors, scores, choice
            for g in contributors:
                g.feedback(world, proposal, None)
            if not proposal.exclusive:
                return "no_valid_viewpoint"

    def propose(self, world):
        """(proposal, generators): an exclusive proposal of the first generator that has one,
        else the union of the others' proposals and the generators that made it."""
        merged, makers = [], []
        for g in self.generators:
            p = g.propose(world)
            if p is None:
                continue
            if p.exclusive:
                return p, [g]
            merged.append(p)
            makers.append(g)
        if not merged:
            return None, []
        if len(merged) == 1:
            return merged[0], makers
        if len({p.poses.shape[1] for p in merged}) > 1:  # level (K, 4) beside (K, 5): pitch 0
            poses = np.vstack(
                [np.pad(p.poses, ((0, 0), (0, 5 - p.poses.shape[1]))) for p in merged]
            )
        else:
            poses = np.vstack([p.poses for p in merged])
        return Proposal(poses, "+".join(p.source for p in merged)), makers
