"""View evaluation: information gain, the occupied-cell constraint, validity, both map backends."""
from __future__ import annotations

import math

import numpy as np
import pytest

import nbvkit
from nbvkit import _core
from conftest import box_mesh, wall_mesh


def scanned_wall_map(res=0.2, repeats=1):
    """A wall at x = 15 scanned `repeats` times from (5, 0, 5) facing +x, in a -10..20 x -10..10 x
    0..10 workspace."""
    m = nbvkit.OccupancyMap(res, (-10, -10, 0), (20, 10, 10))
    cam = nbvkit.DepthCamera(wall_mesh(x=15.0), max_range=12.0)
    m.mark_free_segment((5, 0, 5), (5, 0, 5), 1.5)  # the take-off bubble
    for _ in range(repeats):
        m.integrate(cam.scan_pose([5.0, 0.0, 5.0, 0.0]))
    return m


CAMERA = set(_core.ViewCameraModel.fields())
UTILITY = set(_core.UtilityOptions.fields())
VALIDITY = set(_core.ValidityOptions.fields())


def score(m, cands, current=(5.0, 0.0, 5.0, 0.0), backend="grid", surface=None, memo=None, **kw):
    """evaluate_views with the options given as flat keywords (utility= names the utility)."""
    kw.setdefault("max_range", 12.0)
    if "utility" in kw:
        kw["name"] = kw.pop("utility")
    unknown = set(kw) - CAMERA - UTILITY - VALIDITY
    assert not unknown, unknown
    pick = lambda keys: {k: v for k, v in kw.items() if k in keys}  # noqa: E731
    return _core.evaluate_views(
        m,
        np.asarray(cands, float),
        np.asarray(current, float),
        camera=pick(CAMERA),
        utility=pick(UTILITY),
        validity=pick(VALIDITY),
        surface=surface,
        backend=backend,
        memo=memo,
    )


def test_view_facing_unknown_gains_more_than_view_facing_known_free():
    # seen free 6 times, the cells in front are clamped (zero entropy); behind is unknown (ln 2)
    m = scanned_wall_map(repeats=6)
    s = score(m, [[5, 0, 5, 0.0], [5, 0, 5, math.pi]], require_occupied=False)
    assert np.all(s["status"] == 0)
    assert s["gain"][1] > 10 * s["gain"][0]
    assert s["occupied_seen"][0] > 0 and s["occupied_seen"][1] == 0
    # the gain of the view facing unknown space is ln 2 per distinct cell it visits
    assert s["gain"][1] == pytest.approx(s["cells"][1] * math.log(2), rel=0.01)
    once = score(scanned_wall_map(repeats=1), [[5, 0, 5, 0.0]], require_occupied=False)
    assert once["gain"][0] > s["gain"][0]  # observed once, free cells still hold ~0.67 nats


def test_view_seeing_no_occupied_cell_is_rejected():
    m = scanned_wall_map()
    s = score(m, [[5, 0, 5, 0.0], [5, 0, 5, math.pi]])
    assert s["status"][0] == 0 and np.isfinite(s["utility"][0])
    assert s["status"][1] == 4 and s["utility"][1] == -np.inf
    # the authors' variant: the seen cell must have p > 0.8; one hit gives p = 0.7
    s = score(m, [[5, 0, 5, 0.0]], require_occupied_probability=0.8)
    assert s["status"][0] == 4


def test_candidate_inside_the_structure_or_outside_bounds_is_invalid():
    mesh = box_mesh((10, -2, 0), (14, 2, 8))
    m = nbvkit.OccupancyMap(0.2, (0, -10, 0), (20, 10, 10))
    m.mark_free_segment((4, 0, 4), (4, 0, 4), 1.5)
    cam = nbvkit.DepthCamera(mesh)
    m.integrate(cam.scan_pose([4.0, 0.0, 4.0, 0.0]))
    s = score(
        m,
        [[12, 0, 4, 0.0], [4.2, 0, 4, 0.0], [25, 0, 4, 0.0]],
        current=(4, 0, 4, 0),
        bounds_min=(0.9, -9.1, 0.9),
        bounds_max=(19.1, 9.1, 9.1),
    )
    assert s["status"].tolist() == [2, 0, 1]
    # a candidate in seen free space right in front of the box face, but nearer than the radius
    s = score(m, [[9.5, 0, 4, 0.0]], current=(4, 0, 4, 0))
    assert s["status"][0] == 2


def test_straight_path_through_unknown_is_blocked_and_a_path_is_planned_around():
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 12, 4))
    m.mark_free_segment((2, 6, 2), (10, 6, 2), 1.5)  # a free corridor along x ...
    m.mark_free_segment((2, 2, 2), (10, 2, 2), 1.5)  # ... a second one along x ...
    m.mark_free_segment((2, 2, 2), (2, 6, 2), 1.5)  # ... joined at x = 2
    s = score(m, [[10, 6, 2, 0.0]], current=(10, 2, 2, 0.0), require_occupied=False)
    assert s["status"][0] == 3  # the straight segment crosses unknown space between the corridors
    path = _core.plan_path(m, (10, 2, 2), (10, 6, 2), 0.8)
    assert len(path) >= 3
    np.testing.assert_allclose(path[0], [10, 2, 2]) and np.testing.assert_allclose(
        path[-1], [10, 6, 2]
    )
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert length > 8 + 4 - 1  # around through x = 2: about 8 + 4 + 8, shortened by line of sight
    for a, b in zip(path[:-1], path[1:]):
        assert _core.segment_is_free(m, a, b, 0.8)
    assert len(_core.plan_path(m, (10, 2, 2), (6, 9.5, 2), 0.8)) == 0  # target in unknown space


def test_the_free_component_answers_what_a_search_would_and_the_reference_agrees():
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 12, 4))
    m.mark_free_segment((2, 6, 2), (10, 6, 2), 1.5)  # two corridors joined at x = 2 ...
    m.mark_free_segment((2, 2, 2), (10, 2, 2), 1.5)
    m.mark_free_segment((2, 2, 2), (2, 6, 2), 1.5)
    m.mark_free_segment((9, 10, 2), (10.5, 10, 2), 1.5)  # ... and a pocket apart from them
    start = (10, 2, 2)
    goals = np.array([[10, 6, 2], [6, 2, 2], [9.8, 10, 2], [6, 9.5, 2], [2, 4, 2]])
    paths = [_core.plan_path(m, start, g, 0.8) for g in goals]
    for g, p in zip(goals, paths):  # the first implementation gives the same path
        np.testing.assert_array_equal(p, _core.plan_path(m, start, g, 0.8, reference=True))
    found = [len(p) > 0 for p in paths]
    assert found == [True, True, False, False, True]  # the pocket, and unknown space: no way
    component = _core.FreeComponent(m, start, 0.8)
    assert component.contains(m, goals).tolist() == found
    with pytest.raises(ValueError, match="targets"):
        component.contains(m, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="radius"):
        _core.FreeComponent(m, start, -1.0)


def test_a_path_floor_keeps_every_search_above_the_height_the_views_keep():
    """Two ways join a and b (both 2.5 m up): a short one down through a tunnel 1 m above the
    ground and a long one over the top at 6 m. Without a floor every search takes the tunnel;
    with the views' floor at 2 m (vehicle.min_altitude) plan_path, its reference, search_path,
    plan_paths_to and FreeComponent all keep above it (cell tops; the waypoints within half a
    cell), and a target in the tunnel is out of reach."""
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 12, 8))
    for seg in [((2, 6, 2.5), (2, 6, 1)), ((2, 6, 1), (10, 6, 1)), ((10, 6, 1), (10, 6, 2.5))]:
        m.mark_free_segment(*seg, 0.8)  # the tunnel
    for seg in [((2, 6, 2.5), (1, 6, 6)), ((1, 6, 6), (11, 6, 6)), ((11, 6, 6), (10, 6, 2.5))]:
        m.mark_free_segment(*seg, 0.8)  # the way over the top
    a, b, r, low = (2, 6, 2.5), (10, 6, 2.5), 0.5, (6, 6, 1)

    def lowest(path):
        assert len(path) >= 3
        np.testing.assert_allclose([path[0], path[-1]], [a, b])
        for p, q in zip(path[:-1], path[1:]):
            assert _core.segment_is_free(m, p, q, r)
        return float(np.min(path[:, 2]))

    assert lowest(_core.plan_path(m, a, b, r)) < 1.2  # through the tunnel
    paths = [
        _core.plan_path(m, a, b, r, floor=2.0),
        _core.plan_path(m, a, b, r, reference=True, floor=2.0),
        _core.search_path(m, a, b, r, floor=2.0).path,
        _core.plan_paths_to(m, [a], b, r, floor=2.0).paths[0],
    ]
    np.testing.assert_array_equal(paths[0], paths[1])  # the first implementation agrees
    for path in paths:
        assert lowest(path) >= 2.0 - 0.1 - 1e-9  # over the top
        assert path_length(path) > 12
    assert _core.FreeComponent(m, a, r).contains(m, [low, b]).tolist() == [True, True]
    assert _core.FreeComponent(m, a, r, floor=2.0).contains(m, [low, b]).tolist() == [False, True]
    assert len(_core.plan_path(m, a, low, r, floor=2.0)) == 0
    assert len(_core.plan_path(m, a, b, r, floor=7.9)) == 0  # a floor above the ways: none
    assert len(_core.plan_path(m, a, b, r, floor=-100.0)) > 0  # one below the grid: none
    with pytest.raises(ValueError, match="path floor must be finite"):
        _core.plan_path(m, a, b, r, floor=float("nan"))
    with pytest.raises(TypeError, match="path floor must be a number"):
        _core.FreeComponent(m, a, r, floor=True)


def test_a_view_placed_at_the_path_floor_is_reached_whatever_the_rounding():
    """Views are clipped to the navigation floor (placement.into_bounds), so a view at the floor
    must be in a traversable cell: 0.6 / 0.2 rounds to 2.9999999999999996, and a floor layer
    taken with a tolerance left the view's cell (layer 2) below it. A wall up to 2.8 m stands
    between the vehicle and the view: the way is over it and down to the floor."""
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (6, 3, 4))
    ii = np.stack(np.meshgrid(*[np.arange(k) for k in m.shape], indexing="ij"), -1).reshape(-1, 3)
    wall = (ii[:, 0] == 15) & (ii[:, 2] < 14)
    m.update_cells((ii[~wall] + 0.5) * 0.2, occupied=False)
    m.update_cells((ii[wall] + 0.5) * 0.2, occupied=True)
    a, b, r, floor = (1.5, 1.5, 1.7), (4.5, 1.5, 0.6), 0.5, 0.6
    assert not _core.segment_is_free(m, a, b, r)
    path = _core.plan_path(m, a, b, r, floor=floor)
    assert len(path) >= 3 and np.min(path[:, 2]) >= floor - 0.1 - 1e-9
    assert len(_core.plan_path(m, a, b, r, reference=True, floor=floor)) == len(path)
    assert len(_core.plan_paths_to(m, [a], b, r, floor=floor).paths[0]) >= 3
    assert _core.FreeComponent(m, a, r, floor=floor).contains(m, [b]).tolist() == [True]


def path_length(path) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def test_grid_and_octree_backends_agree():
    mesh = box_mesh((10, -2, 0), (14, 2, 8))
    m = nbvkit.OccupancyMap(0.2, (0, -10, 0), (20, 10, 10))
    m.mark_free_segment((3, 0, 4), (8, 0, 4), 4.5)  # a known-free region for the candidates
    cam = nbvkit.DepthCamera(mesh)
    for pose in ([4.0, 0.0, 4.0, 0.0], [5.0, -3.0, 5.0, 0.4], [5.0, 3.0, 3.0, -0.4]):
        m.integrate(cam.scan_pose(pose))
    m.set_unknown_cells(np.array([[14.1, 0.0, 4.0], [14.1, 0.2, 4.0]]), 0.6)  # predicted cells too
    rng = np.random.default_rng(1)
    cands = np.column_stack(
        [
            rng.uniform(3, 8, 40),
            rng.uniform(-3, 3, 40),
            rng.uniform(2, 6, 40),
            rng.uniform(-1, 1, 40),
        ]
    )
    a = score(m, cands, current=(4, 0, 4, 0), backend="grid")
    b = score(m, cands, current=(4, 0, 4, 0), backend="octree")
    assert (a["status"] == 0).sum() >= 20
    np.testing.assert_array_equal(a["status"], b["status"])
    np.testing.assert_array_equal(a["cells"], b["cells"])
    np.testing.assert_array_equal(a["occupied_seen"], b["occupied_seen"])
    np.testing.assert_allclose(a["gain"], b["gain"], rtol=1e-6)


def test_distance_utility_discounts_gain():
    m = scanned_wall_map()
    c = [[5, 0, 5, 0.0], [6, 0, 5, 0.0]]
    ig = score(m, c, current=(5, 0, 5, 0))
    igd = score(m, c, current=(5, 0, 5, 0), utility="ig_distance", distance_lambda=0.5)
    np.testing.assert_allclose(igd["utility"], ig["gain"] * np.exp(-0.5 * np.array([0.0, 1.0])))
    with pytest.raises(ValueError, match="unknown utility"):
        score(m, c, utility="nope")


def test_default_ray_grid_is_one_ray_per_cell_on_the_far_plane():
    c = _core.ViewCameraModel.for_resolution(60, 45, 8.0, 0.2)
    assert (c.rays_x, c.rays_y) == (47, 34)
    c = _core.ViewCameraModel.for_resolution(60, 45, 8.0, 0.4)
    assert (c.rays_x, c.rays_y) == (24, 17)


def test_bad_input():
    m = scanned_wall_map()
    with pytest.raises(ValueError, match=r"\(K, 4\)"):
        score(m, [[5, 0, 5]])
    with pytest.raises(ValueError, match="NaN"):
        score(m, [[5, 0, np.nan, 0]])
    with pytest.raises(TypeError, match="unknown UtilityOptions option 'nope'"):
        _core.evaluate_views(m, [[5, 0, 5, 0]], (5, 0, 5, 0), utility={"nope": 1})
    with pytest.raises(ValueError, match="current pose"):
        score(m, [[5, 0, 5, 0]], current=(0, 0, 0))
    with pytest.raises(ValueError, match="backend"):
        score(m, [[5, 0, 5, 0]], backend="gpu")
    with pytest.raises(ValueError):
        _core.sphere_is_free(m, (np.nan, 0, 0), 1.0)
    with pytest.raises(ValueError, match="centres"):
        _core.spheres_are_free(m, [[np.nan, 0, 0]], 1.0)
    with pytest.raises(ValueError, match="radius"):
        _core.spheres_are_free(m, [[5, 0, 5]], -1.0)


def test_spheres_are_free_answers_as_sphere_is_free_for_each_centre():
    m = scanned_wall_map()
    rng = np.random.default_rng(3)
    lo, hi = (np.asarray(b, float) for b in m.bounds)
    centres = rng.uniform(lo - 1.0, hi + 1.0, size=(400, 3))
    for r in (0.0, 0.5, 0.8):
        many = _core.spheres_are_free(m, centres, r)
        one = [_core.sphere_is_free(m, c, r) for c in centres]
        assert many.dtype == bool and many.tolist() == one
        assert 0 < many.sum() < len(centres)  # both answers occur
    assert _core.spheres_are_free(m, np.zeros((0, 3)), 0.8).shape == (0,)


def assert_same_scores(a, b):
    for k in ("utility", "gain", "cells", "occupied_seen", "status"):
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_the_memo_of_walks_scores_as_walking_again():
    """A view scored again at the same pose is served from its ViewMemo record while every cell its
    rays reached keeps its occupancy and every neutral brick they stepped over stays neutral, with
    the gain, cells and occupied_seen of a new walk to the last bit; otherwise it is walked."""
    m = scanned_wall_map(repeats=6)  # clamped (neutral) free cells between x = 5 and the wall
    cands = [[5, 0, 5, 0.0], [5, 0, 5, math.pi], [5, 0.4, 5, 0.3], [4.6, 0, 5.2, -0.2]]
    memo = _core.ViewMemo()
    kw = dict(require_occupied=False, require_occupied_probability=0.6)

    def check(reused, walked, stale):
        a, b = score(m, cands, memo=memo, **kw), score(m, cands, **kw)
        assert_same_scores(a, b)
        assert memo.stats() == dict(reused=reused, walked=walked, stale=stale)
        return a

    first = check(0, 4, 0)
    assert (first["status"] == 0).all() and first["occupied_seen"][0] > 0
    check(4, 4, 0)  # the same map: every view from its record
    # behind the camera an unknown cell becomes free: its entropy changes, no occupancy does
    m.update_cells([[2.1, 0.1, 5.1]], occupied=False)
    after = check(8, 4, 0)
    assert after["gain"][1] < first["gain"][1] and after["gain"][0] == first["gain"][0]
    # a hit in the clamped free space before the wall: still free, but its brick is no longer
    # neutral, so the rays that stepped over it would now visit it (view 0 looks through it)
    m.update_cells([[10.1, 0.1, 5.1]], occupied=True)
    check(9, 7, 3)  # the three views towards +x looked through it; the one towards -x did not
    for _ in range(3):  # hit again until occupied: the rays through it stop there
        m.update_cells([[10.1, 0.1, 5.1]], occupied=True)
    blocked = check(10, 10, 6)
    assert blocked["gain"][0] != first["gain"][0]
    assert memo.entries == 4 and memo.bytes > 0
    score(m, cands, memo=memo, max_range=10.0)  # another camera: the records are dropped
    assert memo.stats()["walked"] == 14 and memo.entries == 4


def test_the_memo_agrees_with_walking_over_random_edits():
    rng = np.random.default_rng(3)
    m = scanned_wall_map(repeats=3)
    poses = np.column_stack(
        [[5, 0, 5] + rng.uniform(-0.6, 0.6, (12, 3)), rng.uniform(-np.pi, np.pi, 12)]
    )
    memo = _core.ViewMemo(keep_calls=3)
    for r in range(24):
        pts = rng.uniform([-9, -9, 0.5], [19, 9, 9.5], (60, 3))
        for _ in range(r % 3 + 1):  # 1-3 hits (occupied from the second), or a miss
            m.update_cells(pts, occupied=r % 4 != 0)
        cands = poses[rng.choice(12, 8, replace=False)]
        a = score(m, cands, memo=memo, collision_radius=0.0)
        assert_same_scores(a, score(m, cands, collision_radius=0.0))
    stats = memo.stats()
    assert stats["reused"] > 10 and stats["stale"] > 10
    assert memo.entries <= 12


def test_the_memo_keeps_only_recent_records_and_refuses_bad_use():
    m = scanned_wall_map()
    memo = _core.ViewMemo(keep_calls=1)
    score(m, [[5, 0, 5, 0.0]], memo=memo)
    score(m, [[5, 0, 5, 0.5]], memo=memo)  # the first record was not used by this call
    assert memo.entries == 1
    score(m, [[5, 0, 5, 0.0]], memo=memo)
    assert memo.stats() == dict(reused=0, walked=3, stale=0)
    memo.clear()
    assert memo.entries == 0 and memo.keep_calls == 1
    with pytest.raises(ValueError, match="keep_calls"):
        _core.ViewMemo(0)
    with pytest.raises(ValueError, match="memo"):
        score(m, [[5, 0, 5, 0.0]], memo=memo, backend="octree")
    # utilities that cannot replay a walk score every view
    score(m, [[5, 0, 5, 0.0]], memo=memo, utility="average_entropy")
    score(m, [[5, 0, 5, 0.0]], memo=memo, utility="average_entropy")
    assert memo.entries == 0


def test_collision_checks_keep_off_cells_the_camera_hit_that_the_map_holds_free():
    """Rays passing beside a surface that cuts a cell can carve the cell free in the map; given
    the camera observations, every collision check treats a cell holding a camera hit as
    blocked, so the sphere keeps off the surface points seen (a flight planned on the map alone
    passed 0.57 m from the airliner with a 0.8 m radius)."""
    slab = box_mesh((4, 4, 1.9), (8, 8, 2.03))  # its top face cuts the cells of z in [2.0, 2.2)
    scan = nbvkit.DepthCamera(slab, width=160, height=120).scan_pose([6, 6, 5, 0, math.pi / 2])
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 12, 6))
    surface = _core.SurfaceObservations(m)
    assert surface.add_scan(scan) > 0
    assert np.all(np.abs(scan.hits[:, 2] - 2.03) < 1e-6)
    m.mark_free_segment((6, 6, 3.2), (6, 6, 3.2), 1.6)  # the slab's top cells held free
    low, high, r = (6, 6, 2.9), (6, 6, 3.3), 0.8  # the sphere reaches 2.1 and 2.5 m
    assert _core.sphere_is_free(m, low, r)  # the map alone: all known free
    assert not _core.sphere_is_free(m, low, r, surface=surface)
    assert _core.sphere_is_free(m, high, r, surface=surface)  # above the hit cells: free
    many = _core.spheres_are_free(m, [low, high], r, surface=surface)
    assert many.tolist() == [False, True]
    assert _core.segment_is_free(m, (5.6, 6, 2.9), (6.4, 6, 2.9), r)
    assert not _core.segment_is_free(m, (5.6, 6, 2.9), (6.4, 6, 2.9), r, surface=surface)
    path = _core.plan_path(m, (5.6, 6, 3.3), (6.4, 6, 3.3), r, surface=surface)
    assert len(path) == 2  # straight, above them
    for reference in (False, True):  # down to the hit cells: only on the map alone
        args = (m, (5.6, 6, 3.3), (6.4, 6, 2.9), r)
        assert len(_core.plan_path(*args, reference=reference)) > 0
        assert len(_core.plan_path(*args, reference=reference, surface=surface)) == 0
    search = _core.search_path(m, (5.6, 6, 3.3), (6.4, 6, 2.9), r, surface=surface)
    assert len(search.path) == 0 and not search.capped
    component = _core.FreeComponent(m, high, r, surface=surface)
    assert component.contains(m, [high, low, (6.2, 6, 3.4)]).tolist() == [True, False, True]
    assert _core.FreeComponent(m, high, r).contains(m, [low]).tolist() == [True]
    # a view there: a collision unless keep_off_hits is off (the paper's scenarios)
    for keep, status in ((True, 2), (False, 4)):  # 4: walked, sees no occupied cell
        s = score(m, [[*low, 0.0]], current=(*high, 0.0), surface=surface, keep_off_hits=keep)
        assert s["status"][0] == status
    other = nbvkit.OccupancyMap(0.2, (0, 0, 0), (10, 12, 6))  # observations of another grid
    with pytest.raises(ValueError):
        _core.sphere_is_free(other, low, r, surface=surface)
