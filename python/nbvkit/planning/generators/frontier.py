"""Views aimed at the surface still to observe near the vehicle: surface targets (observed
surface not yet seen from an open side, predicted cells, and frontier cells - unknown cells
between known free space and surface) grouped into patches; the `frontier.patches` heaviest
after discounting by distance are each looked at from a few stand-offs (placement.py)."""
from __future__ import annotations

import numpy as np

from ... import _core
from ..parts import Proposal
from ..placement import place_views, target_patches


class FrontierGenerator:
    def __init__(self, config):
        self.cfg = config

    def propose(self, world):
        cfg = self.cfg
        targets = _core.surface_targets(world.map, world.surface, cfg.targets.options())
        patches = target_patches(targets, cfg.placement.cluster_size)
        if len(patches.weights) == 0:
            return None
        d = np.linalg.norm(patches.centers - world.state.pose[:3], axis=1)
        rank = np.argsort(-patches.weights * np.exp(-cfg.planner.travel_lambda * d), kind="stable")
        keep = np.sort(rank[: cfg.frontier.patches])
        patches.centers, patches.normals = patches.centers[keep], patches.normals[keep]
        patches.weights = patches.weights[keep]
        poses, owner = place_views(
            patches, cfg.camera, cfg.placement, (world.workspace.nav_min, world.workspace.nav_max)
        )
        if not len(poses):
            return None
        return Proposal(poses, "frontier", aims=patches.centers[owner])

    def feedback(self, world, proposal, step):
        pass
