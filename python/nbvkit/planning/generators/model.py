"""Planning from a known model (issue 33, ``--planner model``): an inspection team that holds a
CAD, BIM or an earlier scan plans before take-off, and flies the plan with the real sensors.

Before the first view the structure's mesh is written into the map as it would be seen: from a
lattice of collision-free positions reachable from outside the structure (the observable
surface's, nbvkit._core.observable_samples), coarse noise-free depth frames in every direction
are ray-cast against the mesh and integrated, so the map knows the free space round the
structure; then every cell holding an observable sample of the mesh (samples an eighth of a
cell apart, seen by the camera on its gimbal from one of those positions) is marked occupied,
so the map knows all the surface a camera could see, as a model does (the coarse frames alone
mark about two thirds of it: they pass the rest at grazing angles or carve it free). Then the
coverage tours of the surface planner (tour.py: surface targets -> placement -> the surface
utility -> set cover -> tour) plan over every surface cell of the model, legs are planned
through the model's free space (A*), and the views are flown with the real camera: coverage,
distance and views are scored as any run's. The map's entropy starts from the model's
knowledge, so its entropy figures are not comparable with an online planner's; its coverage,
distance and views are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import _core
from ...observability import observability_options, sample_normals
from ...sensors import build_camera
from ...settings import nonneg, positive, within
from .tour import CoverageTour, TourConfig


@dataclass(frozen=True)
class ModelConfig:
    """The model planner: how the known model is written into the map before take-off."""

    pose_spacing: float = positive(4.0, 100)  # m between the positions the model is seen from
    frame_rays: int = within(48, 4, 1024)  # rays across each coarse 90 x 90 deg frame (square)
    # the tours' thresholds, as tour.min_gain and tour.rate: a plan over the whole surface, with
    # frames every 0.5 m (the model preset) and cells done once their scans stop finding new
    # squares (utility.saturation_hits), flies 0.63-0.71 x the online planner's distance on the
    # aircraft, covering more (RESULTS.md)
    min_gain: float = nonneg(TourConfig.min_gain)  # m^2 of new surface a planned view must add
    rate: float = nonneg(0.45)  # m^2 per metre of tour a planned view must pay for


class ModelPlan:
    """Coverage tours over every surface cell of a known model (see the module docstring)."""

    Settings = ModelConfig

    def __init__(self, settings: ModelConfig, context):
        self.settings = settings
        self.ctx = context
        # the surface planner's tours, on the model: no exploration (nothing is unknown), and
        # every view that may add min_gain walked (the reference leaves none out on an estimate)
        tour = TourConfig(
            min_gain=settings.min_gain, rate=settings.rate, explore=False, coarse_margin=1.0
        )
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
    """Writes the known model into world.map (see the module docstring): integrates coarse
    noise-free frames of the mesh from every reachable collision-free lattice position of the
    navigation space, in 6 directions level and straight up and down, then marks occupied the
    cells of the mesh's observable samples; returns the frames integrated. The vehicle's own
    state is untouched."""
    ws, res = world.workspace, world.map.resolution
    # samples an eighth of a cell apart: every cell the surface crosses holds some, also where it
    # only cuts a cell's corner (a quarter cell apart leaves 4 % of the twinjet's cells empty)
    count = int(min(MAX_SURFACE_SAMPLES, world.mesh.area / (res / 8) ** 2))
    points, faces = world.mesh.sample_surface(count, 0, return_faces=True)
    seen = _core.observable_samples(
        world.scene,
        points,
        sample_normals(world.mesh, faces),
        world.camera,
        ws.nav_min,
        ws.nav_max,
        options=observability_options(world.config, pose_spacing=settings.pose_spacing),
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
    for p in np.asarray(seen.poses, float):
        for yaw, pitch in directions:
            world.map.integrate(probe.scan_pose(np.array([*p, yaw, pitch])))
            frames += 1
    mark_occupied(world.map, points[np.asarray(seen.observable, bool)])
    return frames


#: Mesh samples written as the model's surface at most (an eighth of a cell apart, 4 million
#: cover 2,500 m^2 at the 0.2 m map, 10,000 m^2 at 0.4 m; a larger surface gets sparser samples,
#: still well under a cell apart: 0.07 m on a 19,700 m^2 plant at 0.2 m).
MAX_SURFACE_SAMPLES = 4_000_000


def mark_occupied(occ_map, points, max_rounds: int = 16) -> None:
    """Hit updates of the cells holding points (N, 3) until each is occupied (a cell the frames
    carved free takes a few: OctoMap's clamped log-odds -2 needs 3 hits of 0.7 to pass 0.6)."""
    for _ in range(max_rounds):
        points = points[occ_map.state(points) != 1]
        if len(points) == 0:
            return
        occ_map.update_cells(points, occupied=True)
