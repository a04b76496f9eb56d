"""Planning from a known model (issue 33, ``--planner model``): an inspection team that holds a
CAD, BIM or an earlier scan plans before take-off, and flies the plan with the real sensors.

Before the first view the structure's mesh is written into the map as it would be seen: from a
lattice of collision-free positions reachable from outside the structure (the observable
surface's, nbvkit._core.observable_samples), coarse noise-free depth frames in every direction
are ray-cast against the mesh and integrated, so the map knows the free space round the
structure and its surface cells, as a model does. Then the coverage tours of the surface planner
(tour.py: surface targets -> placement -> the surface utility -> set cover -> tour) plan over
every surface cell of the model, legs are planned through the model's free space (A*), and the
views are flown with the real camera: coverage, distance and views are scored as any run's. The
map's entropy starts from the model's knowledge, so its entropy figures are not comparable with
an online planner's; its coverage, distance and views are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import _core
from ...sensors import build_camera
from ...settings import nonneg, positive, within
from .tour import CoverageTour, TourConfig


@dataclass(frozen=True)
class ModelConfig:
    """The model planner: how the known model is written into the map before take-off."""

    pose_spacing: float = positive(4.0, 100)  # m between the positions the model is seen from
    frame_rays: int = within(48, 4, 1024)  # rays across each coarse 90 x 90 deg frame (square)
    # the tours' thresholds, as tour.min_gain and tour.rate
    min_gain: float = nonneg(TourConfig.min_gain)  # m^2 of new surface a planned view must add
    rate: float = nonneg(TourConfig.rate)  # m^2 per metre of tour a planned view must pay for


class ModelPlan:
    """Coverage tours over every surface cell of a known model (see the module docstring)."""

    Settings = ModelConfig

    def __init__(self, settings: ModelConfig, context):
        self.settings = settings
        self.ctx = context
        # the surface planner's tours, on the model: no exploration (nothing is unknown)
        tour = TourConfig(min_gain=settings.min_gain, rate=settings.rate, explore=False)
        self.tour = CoverageTour(tour, context)
        self.known = False
        self.stop_reason = None

    @property
    def plans(self):
        return self.tour.plans

    def propose(self, world):
        if not self.known:
            write_model(world, self.settings, self.ctx)
            self.known = True
        proposal = self.tour.propose(world)
        self.stop_reason = self.tour.stop_reason
        if proposal is not None:
            proposal.source = "model"
        return proposal

    def feedback(self, world, proposal, step):
        self.tour.feedback(world, proposal, step)


def write_model(world, settings: ModelConfig, ctx) -> int:
    """Integrates coarse noise-free frames of the mesh into world.map, from every reachable
    collision-free lattice position of the navigation space, in 6 directions level and straight
    up and down; returns the frames integrated. The vehicle's own state is untouched."""
    ws = world.workspace
    reach = _core.observable_samples(
        world.scene,
        np.zeros((0, 3)),
        np.zeros((0, 3)),
        world.camera,
        ws.nav_min,
        ws.nav_max,
        options=_core.ObservabilityOptions(pose_spacing=settings.pose_spacing),
        collision_radius=ctx.vehicle.collision_radius,
    )
    diagonal = float(np.linalg.norm(ws.bounds_max - ws.bounds_min))
    n = settings.frame_rays
    probe = build_camera(
        ctx.camera,
        world.scene,
        0,
        width=n,
        height=n,
        hfov_deg=90.0,
        vfov_deg=90.0,
        min_range=0.05,
        max_range=diagonal,
        noise_k=0.0,
    )
    # a cube of frames: four level, one straight down, one straight up
    directions = [(k * math.pi / 2, 0.0) for k in range(4)]
    directions += [(0.0, math.pi / 2), (0.0, -math.pi / 2)]
    frames = 0
    for p in np.asarray(reach.poses, float):
        for yaw, pitch in directions:
            world.map.integrate(probe.scan_pose(np.array([*p, yaw, pitch])))
            frames += 1
    return frames
