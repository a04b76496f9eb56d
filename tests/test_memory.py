"""Memory that grows with the surface, not with the workspace box (issue 37, part 4)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import nbvkit
from conftest import QUICK_MISSION, box_mesh
from nbvkit.config import load_config
from nbvkit.mission import Mission


def _two_boxes(gap: float) -> nbvkit.Mesh:
    """Two 4 m boxes `gap` metres apart along x."""
    a, b = box_mesh((0, 0, 0), (4, 4, 4)), box_mesh((gap, 0, 0), (gap + 4, 4, 4))
    return nbvkit.Mesh(np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + 8]))


@pytest.fixture(scope="module")
def two_boxes_flown():
    """(mission, config, mesh): two small structures 150 m apart (a 154 m workspace, 192 m^2
    of surface), flown for 6 views without a profile."""
    mesh = _two_boxes(150.0)
    cfg = load_config(overrides=[*QUICK_MISSION, "max_iterations=6", "profiling.enabled=false"])
    mission = Mission(cfg, mesh=mesh)
    mission.run()
    return mission, cfg, mesh


def test_the_camera_record_holds_the_bricks_of_the_surface_seen_not_the_workspace(two_boxes_flown):
    mission, cfg, mesh = two_boxes_flown
    record = mission.world.surface
    seen = record.seen_grid()  # the dense copy, read through the sparse storage
    assert np.count_nonzero(seen) == record.seen_cells() > 0
    assert np.count_nonzero(record.hits_grid()) == record.seen_cells()
    res = cfg.map.resolution
    bricks = math.prod(math.ceil(d / 4) for d in seen.shape)  # the workspace's 4^3-cell bricks
    # a brick is a 4-cell cube: a plane crosses at most 3 bricks per brick face of its area
    surface_bricks = 3 * float(mesh.area) / (4 * res) ** 2
    assert 0 < record.allocated_bricks <= surface_bricks < bricks / 20
    # the bytes follow the bricks held: the brick table, and 14 bytes per cell of a held brick
    # (directions 4, hits 2, patches 8)
    dense = seen.size * 14
    assert record.bytes < 4 * bricks + 64 * 14 * 2 * (record.allocated_bricks + 1) < dense / 5
    # what the camera saw of one box lies in its bricks: seen cells only near the surface
    i, j, k = np.nonzero(seen)
    assert len(i) == record.seen_cells()
    # the planner's memos of walks, used in flight, are dropped before the end-of-run results
    memos = [p.memo for p in (mission.planner.score, *mission.planner.generators)]
    memos = [m for m in memos if hasattr(m, "entries")]
    assert memos and sum(m.stats()["walked"] for m in memos) > 0
    assert all(m.entries == 0 and m.bytes == 0 for m in memos)


def test_a_large_workspace_sums_its_camera_cloud_in_single_precision(two_boxes_flown):
    # cloud.single_precision null: by size; the 154 m workspace is large, so the camera cloud
    # holds 16 bytes a voxel and its index; the laser's keeps the exact sums (the symmetry's)
    mission, cfg, mesh = two_boxes_flown
    world = mission.world
    assert cfg.cloud.single_precision is None
    cam, laser = world.camera_cloud, world.laser_cloud
    assert cam.options.single_precision and not laser.options.single_precision
    exact = nbvkit.PointCloud(options=cam.options, single_precision=False)
    assert len(cam) > 1000
    small = Mission(load_config(overrides=[*QUICK_MISSION]), mesh=_two_boxes(10.0)).world
    assert not small.camera_cloud.options.single_precision  # a 14 m workspace: exact sums
    forced = load_config(overrides=[*QUICK_MISSION, "cloud.single_precision=false"])
    assert not Mission(forced, mesh=mesh).world.camera_cloud.options.single_precision
    # every centroid within its voxel (faces on voxel boundaries here: the boxes' at whole
    # metres), in fewer bytes (the sums: 12 bytes a voxel against 24)
    exact.add(cam.points)  # one point a voxel: the same voxels
    assert len(exact) == len(cam)
    single = nbvkit.PointCloud(options=cam.options)  # grown as `exact` is: capacities alike
    single.add(cam.points)
    assert len(single) == len(cam) and exact.bytes - single.bytes >= 12 * len(cam)


def test_a_large_workspace_weighs_the_unknown_space_from_the_first_plan(two_boxes_flown):
    # tour.explore_first null: by size; the 154 m workspace is longer than 6 camera ranges, so
    # every plan weighs views of the unknown space, the first one included
    mission = two_boxes_flown[0]
    assert mission.config.tour.explore_first is None
    tour = next(g for g in mission.planner.generators if hasattr(g, "plans"))
    assert tour.plans and all(p["explore"] for p in tour.plans)


def test_a_large_workspace_pools_its_plans_unknown_space_per_brick(two_boxes_flown):
    # tour.pool_unknown null: by size; on the 154 m workspace the plans' coverage sets hold the
    # unknown space away from surface as one element per brick (past every cell's element); on
    # a 14 m one, one element per cell. True with access credit (which needs the cells) is
    # refused before any work
    mission = two_boxes_flown[0]
    assert mission.config.tour.pool_unknown is None
    tour = next(g for g in mission.planner.generators if hasattr(g, "plans"))
    assert tour.pool
    world = mission.world
    cov = tour.coverage(world, tour.candidates(world, explore=True)[2])
    assert (cov.elements >= 128 * world.map.grid_bricks[1]).sum() > 100
    small = Mission(load_config(overrides=[*QUICK_MISSION, "max_iterations=2"]), mesh=_two_boxes(4))
    small.run()
    small_tour = next(g for g in small.planner.generators if hasattr(g, "plans"))
    assert small_tour.plans and not small_tour.pool
    with pytest.raises(ValueError, match="pool_unknown.*access_weight"):
        load_config(overrides=["tour.pool_unknown=true", "tour.access_weight=0.5"])


def test_starts_of_a_scene_with_an_empty_centre_face_a_structure_within_reach():
    # the inward walk towards the workspace centre finds nothing there: each start then turns
    # towards the nearest structure, and faces it from within the camera's reach
    mission = Mission(load_config(overrides=[*QUICK_MISSION]), mesh=_two_boxes(150.0))
    world = mission.world
    reach = world.config.camera.max_range
    samples = np.array([[x, y, z] for x in (0, 2, 4) for y in (0, 2, 4) for z in (0, 2, 4)], float)
    boxes = np.vstack([samples, samples + [150.0, 0, 0]])
    for pose in world.starts:
        d = np.linalg.norm(boxes - pose[:3], axis=1)
        assert d.min() <= reach + 1e-6
        scan = world.scan("view", pose)
        assert len(scan.hits) > 0  # the camera sees a box from every start


def test_a_mission_that_saw_nothing_says_so_rather_than_coverage_complete():
    # the profile circles the workspace centre, between the boxes and beyond the laser's reach
    # of both: no point is seen, and the planner has nothing to cover
    cfg = load_config(overrides=[*QUICK_MISSION, "max_iterations=6"])
    mission = Mission(cfg, mesh=_two_boxes(150.0))
    with pytest.warns(RuntimeWarning, match="saw no surface"):
        summary = mission.run()
    assert summary["termination"] == "nothing_seen"
    assert summary["cloud_points"] == 0


def test_the_map_holds_cells_for_the_bricks_its_rays_reached_not_the_workspace(two_boxes_flown):
    # the map's grid gives cells only to the bricks its sensors reached
    m = two_boxes_flown[0].world.map
    allocated, total = m.grid_bricks
    flags = np.asarray(m.flag_grid())
    pad = [(0, -s % 4) for s in flags.shape]
    known = np.pad(flags != 0, pad).reshape(
        *(x for s in flags.shape for x in (math.ceil(s / 4), 4))
    )
    known_bricks = int(known.any(axis=(1, 3, 5)).sum())
    assert total == known.size // 64
    # every brick holding a known cell has cells of its own, and (no cell was made unknown
    # again) no other brick has
    assert 0 < allocated == known_bricks < total / 20
    # 9 bytes a cell of an allocated brick and of the shared unknown one (log-odds, entropy,
    # flag), and 11 a brick of tables
    assert m.grid_memory_bytes == (allocated + 1) * 64 * 9 + total * 11
    assert m.grid_memory_bytes < flags.size * 9 / 10  # a tenth of the dense grid's
    # the map answers as before: the entropy summed cell by cell equals the kept total
    assert m.total_entropy() == m.recompute_total_entropy()
