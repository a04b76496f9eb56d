"""Views aimed at the surface still to observe near the vehicle: surface targets (observed
surface not yet seen from an open side, predicted cells, and frontier cells - unknown cells
between known free space and surface) grouped into patches; the `frontier.patches` heaviest
after discounting by distance are each looked at from a few stand-offs (placement.py)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import _core
from ...settings import within
from ..parts import Proposal
from ..placement import place_views, target_patches


@dataclass(frozen=True)
class FrontierConfig:
    """The frontier generator: views aimed at the nearest surface targets, each iteration."""

    patches: int = within(40, 1, 100_000)  # target patches per iteration: nearest, heaviest first


class FrontierGenerator:
    Settings = FrontierConfig

    def __init__(self, settings: FrontierConfig, context):
        self.settings = settings
        self.ctx = context

    def propose(self, world):
        ctx = self.ctx
        targets = _core.surface_targets(world.map, world.surface, ctx.targets)
        patches = target_patches(targets, ctx.placement.cluster(ctx.camera))
        if len(patches.weights) == 0:
            return None
        d = np.linalg.norm(patches.centers - world.state.pose[:3], axis=1)
        rank = np.argsort(-patches.weights * np.exp(-ctx.planner.travel_lambda * d), kind="stable")
        keep = np.sort(rank[: self.settings.patches])
        patches.centers, patches.normals = patches.centers[keep], patches.normals[keep]
        patches.weights = patches.weights[keep]
        poses, owner = place_views(
            patches, ctx.camera, ctx.placement, (world.workspace.nav_min, world.workspace.nav_max)
        )
        if not len(poses):
            return None
        return Proposal(poses, "frontier", aims=patches.centers[owner])

    def feedback(self, world, proposal, step):
        pass
