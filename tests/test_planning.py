"""The planner's parts: tours, set cover, prize collecting, view placement, surface targets,
generators' contracts, every scenario end to end, and bad planner configurations."""
from __future__ import annotations

import itertools
import json
import math
import warnings

import numpy as np
import pytest

import nbvkit
from nbvkit import _core
from nbvkit.config import Config, load_config
from nbvkit.mission import Mission
from nbvkit.recorder import STAGES
from nbvkit.planning.parts import PlanningContext
from nbvkit.planning.registry import get_generator
from nbvkit.planning.generators.exploration import exploration_targets
from nbvkit.planning.terminations.budget import budget_note
from nbvkit.planning.placement import (
    Patches,
    PlacementConfig,
    into_bounds,
    place_views,
    refit_blocked,
    target_patches,
)
from nbvkit.scenarios import SCENARIOS
from conftest import box_mesh, wall_mesh


def tour_length(start, pts, order):
    seq = np.vstack([start, pts[order]])
    return float(np.linalg.norm(np.diff(seq, axis=0), axis=1).sum())


# ------------------------------------------------------------------ tours


@pytest.mark.parametrize("seed", range(5))
def test_tour_visits_every_view_once_and_is_no_longer_than_nearest_neighbour(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-20, 20, (60, 3))
    start = np.array([25.0, 0.0, 5.0])
    nn, nn_len = _core.solve_tour(pts, start, improve=False)
    order, length = _core.solve_tour(pts, start)
    assert sorted(order) == list(range(60)) and sorted(nn) == list(range(60))
    assert length == pytest.approx(tour_length(start, pts, order))
    assert nn_len == pytest.approx(tour_length(start, pts, nn))
    assert length <= nn_len + 1e-9
    # a 2-opt local optimum: no reversal of a stretch of the open tour shortens it
    seq = np.vstack([start, pts[order]])
    d = lambda a, b: np.linalg.norm(seq[a] - seq[b])  # noqa: E731
    for i in range(1, 61):
        for j in range(i + 1, 61):
            delta = d(i - 1, j) - d(i - 1, i) + (d(i, j + 1) - d(j, j + 1) if j < 60 else 0.0)
            assert delta > -1e-9


def test_tour_is_optimal_on_small_instances():
    rng = np.random.default_rng(7)
    pts = rng.uniform(0, 10, (7, 3))
    start = np.zeros(3)
    best = min(tour_length(start, pts, list(p)) for p in itertools.permutations(range(7)))
    _, length = _core.solve_tour(pts, start)
    assert length <= best * 1.05  # local search lands within 5 % of the optimum here


def test_tour_on_a_matrix_avoids_impassable_legs_and_rejects_bad_matrices():
    d = np.array([[0, 1, 2, 3], [1, 0, 1, 2], [2, 1, 0, 1], [3, 2, 1, 0]], float)
    d[1, 2] = d[2, 1] = np.inf  # views 0 and 1 (rows 1, 2) cannot follow each other
    order, length = _core.solve_tour_matrix(d)
    assert sorted(order) == [0, 1, 2] and np.isfinite(length)
    seq = [0] + [o + 1 for o in order]
    assert all(np.isfinite(d[a, b]) for a, b in zip(seq[:-1], seq[1:]))
    with pytest.raises(ValueError, match="symmetric"):
        _core.solve_tour_matrix(np.array([[0, 1.0], [2.0, 0]]))
    with pytest.raises(ValueError, match=">= 0"):
        _core.solve_tour_matrix(np.array([[0, -1.0], [-1.0, 0]]))
    with pytest.raises(ValueError, match="NaN"):
        _core.solve_tour(np.array([[np.nan, 0, 0]]), np.zeros(3))


def test_prize_collecting_drops_views_that_do_not_pay_for_their_detour():
    prize_collect = _core.prize_collect
    start = np.zeros(3)
    pts = np.array([[1.0, 0, 0], [2.0, 0, 0], [2.0, 10.0, 0], [3.0, 0, 0]])
    gains = np.array([5.0, 5.0, 3.0, 5.0])  # view 2 is a 20 m detour for 3 m^2
    order = [0, 1, 2, 3]
    assert prize_collect(start, pts, gains, order, rate=1.0) == [0, 1, 3]
    assert prize_collect(start, pts, gains, order, rate=0.1) == order  # cheap flight: keep all
    assert prize_collect(start, pts, gains, order, rate=0.0) == order
    # a far cluster: each view's own detour is small, the transit to the cluster is not
    far = np.array([[1.0, 0, 0], [2.0, 0, 0], [30.0, 0, 0], [31.0, 0, 0], [32.0, 0, 0]])
    g = np.array([5.0, 5.0, 4.0, 4.0, 4.0])
    assert prize_collect(start, far, g, [0, 1, 2, 3, 4], rate=1.0) == [0, 1]
    assert prize_collect(start, far, g, [0, 1, 2, 3, 4], rate=0.3) == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError, match="one gain per point"):
        prize_collect(start, far, g[:3], [0, 1, 2], rate=1.0)
    with pytest.raises(ValueError, match="order indexes past"):
        prize_collect(start, far, g, [0, 5], rate=1.0)
    with pytest.raises(ValueError, match="order lists point 0 twice"):  # it kept [0, 0]
        prize_collect(start, far, g, [0, 0], rate=1.0)
    with pytest.raises(ValueError, match="zero vector"):  # a direction bin of no direction
        _core.direction_bin([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="gains must be finite"):
        prize_collect(start, far, [5.0, np.nan, 4, 4, 4], [0, 1], rate=1.0)
    with pytest.raises(ValueError, match="rate must be finite"):
        prize_collect(start, far, g, [0, 1], rate=np.inf)


def _prize_collect_in_numpy(start, points, gains, order, rate) -> list:
    """Prize collection as the tour generator did it in Python, numpy step for step: the
    reference the C++ one must give back exactly (the flights of before, to the last digit)."""
    order = list(order)
    if rate <= 0:
        return order
    while order:
        seq = np.vstack([start, points[order]])
        leg = np.linalg.norm(np.diff(seq, axis=0), axis=1)
        n = len(order)
        cum_leg = np.concatenate([[0.0], np.cumsum(leg)])
        cum_gain = np.concatenate([[0.0], np.cumsum(gains[order])])
        best, best_ij = 0.0, None
        for i in range(n):
            j = np.arange(i, n)
            inner = cum_leg[j + 1] - cum_leg[i]
            after = np.where(j + 1 < n, leg[np.minimum(j + 1, n - 1)], 0.0)
            bridge = np.where(
                j + 1 < n, np.linalg.norm(seq[np.minimum(j + 2, n)] - seq[i], axis=1), 0.0
            )
            deficit = rate * (inner + after - bridge) - (cum_gain[j + 1] - cum_gain[i])
            k = int(np.argmax(deficit))
            if deficit[k] > best + 1e-12:
                best, best_ij = float(deficit[k]), (i, int(j[k]))
        if best_ij is None:
            break
        del order[best_ij[0] : best_ij[1] + 1]
    return order


def test_prize_collection_is_numpys_to_the_last_digit():
    rng = np.random.default_rng(11)
    dropped = 0
    for trial in range(400):
        n = int(rng.integers(0, 30))
        pts = rng.uniform(-20, 20, (n, 3))
        pts[rng.random(n) < 0.2] = pts[0] if n else 0.0  # repeated points: ties
        gains = np.round(rng.uniform(0, 20, n), 1) * (rng.random(n) < 0.85)
        order = [int(k) for k in rng.permutation(n)]
        rate = float(rng.choice([0.0, 0.25, 0.75, 1.5, 4.0]))
        start = rng.uniform(-25, 25, 3)
        want = _prize_collect_in_numpy(start, pts, gains, order, rate)
        assert _core.prize_collect(start, pts, gains, order, rate) == want
        dropped += len(order) - len(want)
    assert dropped > 100  # the cases drop views, not only keep them


# ------------------------------------------------------------------ set cover


def test_greedy_cover_picks_the_largest_new_coverage_first():
    # view 0 covers {1, 2, 3}, view 1 {3, 4}, view 2 {4, 5, 6, 7}, view 3 {1, 2} (redundant)
    sets = [[1, 2, 3], [3, 4], [4, 5, 6, 7], [1, 2]]
    cov = {
        "offsets": np.cumsum([0] + [len(s) for s in sets]).astype(np.int64),
        "elements": np.concatenate(sets).astype(np.int64),
        "weights": np.ones(sum(map(len, sets)), np.float32),
        "status": np.zeros(4, np.int8),
    }
    views, gains = _core.select_cover(cov, min_gain=0.5, max_views=10)
    assert views == [2, 0] and gains == [4.0, 3.0]  # then nothing new is left
    views, _ = _core.select_cover(cov, min_gain=0.5, max_views=1)
    assert views == [2]
    cov["status"][2] = 2  # an invalid view is never chosen
    views, gains = _core.select_cover(cov, min_gain=0.5, max_views=10)
    assert views == [0, 1] and gains == [3.0, 1.0]
    # other integer and float types are read as well (converted); lists too
    as_lists = {
        k: v.astype(np.int32 if k != "weights" else np.float64).tolist() for k, v in cov.items()
    }
    assert _core.select_cover(as_lists, min_gain=0.5, max_views=10) == (views, gains)


def test_cover_and_tour_reject_malformed_coverage_with_a_message():
    good = {
        "offsets": np.array([0, 2, 3], np.int64),
        "elements": np.array([1, 2, 2], np.int64),
        "weights": np.ones(3, np.float32),
        "status": np.zeros(2, np.int8),
    }
    pos, start = np.zeros((2, 3)), np.zeros(3)
    bad = [
        ({**good, "elements": good["elements"].reshape(3, 1)}, "1-D"),
        ({**good, "weights": np.ones(2, np.float32)}, "inconsistent"),
        ({**good, "offsets": np.array([0, 3, 2], np.int64)}, "inconsistent"),
        ({**good, "status": np.zeros(3, np.int8)}, "inconsistent"),
        ({**good, "weights": ["a", "b", "c"]}, "weights"),
        (
            {**good, "elements": np.array([1, 2, 2**31], np.int64)},
            "2147483648 does not fit int32",
        ),
        ({**good, "elements": np.array([-(2**31) - 1, 2, 2], np.int64)}, "does not fit int32"),
        ({**good, "elements": np.array([1, 2, 2**32], np.uint64)}, "does not fit int32"),
        ({**good, "elements": np.array([1, 1.5, 2])}, r"elements'\]: 1.5 is not an integer"),
        ({**good, "status": np.array([0, 256])}, r"status'\]: 256 does not fit int8"),
        ({**good, "status": np.array([0, 0.5])}, "0.5 is not an integer"),
        ({**good, "offsets": np.array([0, 2, np.nan])}, "nan is not an integer"),
        ({**good, "status": np.array([0, 1j])}, "dtype complex128"),
        ({**good, "elements": np.array([1, -2, 2], np.int64)}, "elements must be >= 0"),
        ({**good, "weights": np.array([1, np.nan, 1], np.float32)}, "finite and >= 0"),
        ({**good, "weights": np.array([1, 1, np.inf], np.float32)}, "finite and >= 0"),
        ({**good, "weights": np.array([-1, 1, 1], np.float32)}, "finite and >= 0"),
    ]
    for cov, message in bad:
        with pytest.raises(ValueError, match=message):
            _core.select_cover(cov)
        with pytest.raises(ValueError, match=message):
            _core.select_tour(cov, pos, start, rate=0.1)
        with pytest.raises(ValueError, match=message):
            _core.plan_tour_over(cov, pos, start, 0.04)
        with pytest.raises(ValueError, match=message):  # nor built as a CoverageSets
            _core.CoverageSets(*(cov[k] for k in ("offsets", "elements", "weights", "status")))
    with pytest.raises(KeyError):
        _core.select_tour({k: v for k, v in good.items() if k != "status"}, pos, start, rate=0.1)
    with pytest.raises(TypeError, match="CoverageSets"):
        _core.select_cover([good])


# ------------------------------------------------------------------ placement and targets


class _Cam:
    vfov_deg, max_range, mount_rpy_deg = 45.0, 8.0, (0.0, 0.0, 0.0)
    gimbal_pitch_deg = (0.0, 0.0)  # level: the paper's camera


class _Gimbal(_Cam):
    gimbal_pitch_deg = (-30.0, 90.0)  # 30 deg up to straight down


class _Place:
    standoffs, azimuth_spread_deg, elevation_margin_deg = (0.5, 0.75), 30.0, 4.0
    gimbal = False


class _PlaceGimbal(_Place):
    gimbal = True  # placement.gimbal: also face roofs and undersides by the gimbal's pitch


def test_views_are_placed_at_their_standoff_facing_the_patch_inside_the_fov():
    patches = Patches(
        centers=np.array([[0.0, 0, 3], [5, 5, 2], [-3, 0, 4]]),
        normals=np.array([[1.0, 0, 0], [0, 0, 1.0], [-0.6, 0.0, -0.8]]),
        weights=np.ones(3),
    )
    poses, owner = place_views(patches, _Cam, _Place)
    assert len(poses) == 3 * 2 + 6 * 2 + 3 * 2  # facing up: 6 azimuths
    half = math.radians(45 / 2)
    for pose, i in zip(poses, owner):
        to_patch = patches.centers[i] - pose[:3]
        dist = np.linalg.norm(to_patch)
        assert min(abs(dist - 4.0), abs(dist - 6.0)) < 1e-9
        heading = np.array([math.cos(pose[3]), math.sin(pose[3])])
        horiz = to_patch[:2] / max(np.linalg.norm(to_patch[:2]), 1e-12)
        assert heading @ horiz > math.cos(1e-6) or np.linalg.norm(to_patch[:2]) < 1e-9
        elevation = math.atan2(to_patch[2], np.linalg.norm(to_patch[:2]))
        assert abs(elevation) <= half  # the patch is in the vertical field of view
    assert np.all(np.isfinite(poses))


def test_views_below_the_floor_move_up_and_out_until_the_patch_is_in_view():
    # a patch on the side of a beam 2 m below the navigation floor (z 0), facing +x, and one 1 m
    # above the ceiling (z 10) facing -y: the views placed along their normals leave the box
    patches = Patches(
        centers=np.array([[0.0, 0, -2.0], [0.0, 0, 11.0]]),
        normals=np.array([[1.0, 0, 0], [0.0, -1.0, 0]]),
        weights=np.ones(2),
    )
    box = (np.array([-20.0, -20, 0]), np.array([20.0, 20, 10]))
    free, owner = place_views(patches, _Cam, _Place)
    assert np.all((free[:, 2] < 0) | (free[:, 2] > 10))  # all outside without the bounds
    poses, owner2 = place_views(patches, _Cam, _Place, box)
    assert np.array_equal(owner, owner2) and np.array_equal(poses[:, 3], free[:, 3])
    lowest = -math.radians(45 / 2 - 4.0)  # the band the patch must stay in
    moved_out = False
    for pose, i, before in zip(poses, owner, free):
        assert np.all(pose[:3] >= box[0]) and np.all(pose[:3] <= box[1])
        assert pose[2] in (0.0, 10.0)  # on the floor or the ceiling, not farther in
        to_patch = patches.centers[i] - pose[:3]
        h = np.linalg.norm(to_patch[:2])
        elevation = math.atan2(to_patch[2], h)
        assert lowest - 1e-9 <= elevation <= -lowest + 1e-9
        # the same azimuth from the patch as before, and no farther than the band requires
        out = before[:2] - patches.centers[i, :2]
        assert (pose[:2] - patches.centers[i, :2]) @ out / np.linalg.norm(out) == pytest.approx(h)
        need = abs(to_patch[2]) / math.tan(-lowest)  # out far enough for the band
        assert h == pytest.approx(max(need, np.linalg.norm(out)))
        moved_out |= need > np.linalg.norm(out)
    assert moved_out  # the floor's 4 m views had to back off to 6 m
    # a view that would have to go beyond the range, or a patch straight below, is left alone
    far = into_bounds(
        np.array([[0.0, 0, -9.0], [3.0, 0, -9.0]]),
        np.array([[0.0, 0, -12.0], [0.0, 0, -12.0]]),
        box,
        (lowest, -lowest),
        (1.0, 8.0),
    )
    assert np.array_equal(far, [[0.0, 0, -9.0], [3.0, 0, -9.0]])
    # inside the box: unchanged
    inside = np.array([[1.0, 2.0, 3.0]])
    assert np.array_equal(into_bounds(inside, inside + 1, box, (lowest, -lowest), (1, 8)), inside)


def test_select_tours_gives_select_tours_of_each_charge_from_one_inverse():
    rng = np.random.default_rng(5)
    for trial in range(20):
        k = int(rng.integers(1, 80))
        sizes = rng.integers(0, 40, k)
        cov = {
            "offsets": np.r_[0, np.cumsum(sizes)].astype(np.int64),
            "elements": rng.integers(0, 300, sizes.sum()).astype(np.int64),
            "weights": rng.choice([0.25, 0.5, 1.0], sizes.sum()).astype(np.float32),
            "status": (rng.random(k) < 0.2).astype(np.int8),
        }
        pos = rng.uniform(-30, 30, (k, 3))
        kw = dict(rate=float(rng.uniform(0, 2)), min_gain=float(rng.uniform(0.5, 4)))
        charges = [True, False, True] if trial % 2 else [False]
        tours = _core.select_tours(cov, pos, (0, 0, 1), charges=charges, **kw)
        one = [_core.select_tour(cov, pos, (0, 0, 1), charge_transit=c, **kw) for c in charges]
        assert [(list(v), list(g)) for v, g in tours] == [(list(v), list(g)) for v, g in one]
    assert _core.select_tours(cov, pos, (0, 0, 1), charges=[], **kw) == []


def test_a_tour_flies_to_a_far_cluster_that_pays_for_its_transit_only_as_a_whole():
    def plan_for(gain_per_view, selection="insertion"):
        # five views 1 m apart, 50 m from the vehicle, each adding gain_per_view new elements
        n = gain_per_view
        cov = {
            "offsets": np.arange(0, 5 * n + 1, n, dtype=np.int64),
            "elements": np.arange(5 * n, dtype=np.int64),
            "weights": np.ones(5 * n, np.float32),
            "status": np.zeros(5, np.int8),
        }
        cand = np.array([[50.0 + i, 0, 0] for i in range(5)])
        kw = dict(rate=0.45, min_gain=1.2)  # m^2 per metre; a weight of 1 is 1 m^2
        anchored = _core.select_tour(cov, cand, np.zeros(3), charge_transit=True, **kw)
        plan = _core.plan_tour_over(cov, cand, np.zeros(3), 1.0, selection=selection, **kw)
        return anchored, plan

    anchored, plan = plan_for(6)  # 30 m^2 for 54 m: worth 30 - 0.45 x 54 = 5.7
    assert anchored == ([], [])  # no single view pays 0.45 x 50 m
    assert sorted(plan.flight) == [0, 1, 2, 3, 4]
    np.testing.assert_array_equal(plan.flight, plan.chosen[plan.order])
    assert plan.value == pytest.approx(30 - 0.45 * 54) and plan.length == pytest.approx(54)
    assert plan.gains.tolist() == [6.0] * 5 and (plan.unpaid, plan.unpaid_area) == (0, 0.0)
    _, plan = plan_for(4)  # 20 m^2 for 54 m: the transit is not worth it
    assert len(plan.order) == 0 and plan.value == 0.0 and plan.length == 0.0
    assert len(plan.flight) == 0 and plan.flight.dtype.kind == "i"  # indexes an empty plan
    assert (plan.unpaid, plan.unpaid_area) == (5, 20.0)  # what no tour paid for
    _, cover = plan_for(6, "cover")  # a set cover, its tour prize-collected: the same views
    assert sorted(cover.flight) == [0, 1, 2, 3, 4] and cover.length == pytest.approx(54)
    _, cover = plan_for(4, "cover")
    assert len(cover.order) == 0 and cover.unpaid == 5


def test_a_tour_plan_from_the_map_is_the_plan_over_its_coverage_sets():
    # plan_tour: view_coverage at min_gain and the plan over its sets, in one call
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    whole = _core.view_coverage(m, surface, poses, current, **kw)
    sums, cell = _set_sums(whole), m.resolution**2  # m^2 of a weight of 1
    mg = float(np.median(sums[whole.status == 0])) * cell  # m^2
    for selection in ("insertion", "cover"):
        for rate in (0.0, 0.05, 0.5):
            opts = dict(selection=selection, min_gain=mg, rate=rate)
            plan = _core.plan_tour(m, surface, poses, current, **kw, **opts)
            cut = _core.view_coverage(m, surface, poses, current, min_gain=mg / cell, **kw)
            over = _core.plan_tour_over(cut, poses[:, :3], current[:3], cell, **opts)
            assert plan.flight.tolist() == over.flight.tolist()
            assert plan.gains.tolist() == over.gains.tolist() and plan.value == over.value
            assert len(plan.chosen) > 0 and (rate > 0.1 or len(plan.order) > 0)
            # each chosen view's gain is its marginal area: at most its set's, all of it for the
            # one a set cover takes first
            assert (plan.gains <= sums[plan.chosen] * cell * (1 + 1e-6)).all()
            if selection == "cover":
                assert plan.gains[0] == pytest.approx(sums[plan.chosen[0]] * cell, rel=1e-5)
            kept = plan.gains[plan.order].sum()
            assert plan.value == pytest.approx(kept - rate * plan.length)
    with pytest.raises(ValueError, match="selection must be 'insertion' or 'cover'"):
        _core.plan_tour(m, surface, poses, current, selection="greedy", **kw)
    for bad, match in (
        (dict(rate=-1.0), "rate must be a finite number >= 0"),
        (dict(min_gain=float("nan")), "min_gain must be a finite number >= 0"),
        (dict(max_views=-1), "max_views must be >= 0"),
    ):
        with pytest.raises(ValueError, match=match):
            _core.plan_tour(m, surface, poses, current, **kw, **bad)
    with pytest.raises(ValueError, match="cell_area must be a finite number > 0"):
        _core.plan_tour_over(whole, poses[:, :3], current[:3], 0.0)
    with pytest.raises(ValueError, match="one position per candidate"):
        _core.plan_tour_over(whole, poses[:5, :3], current[:3], cell)


def test_area_thresholds_shrink_with_a_structure_smaller_than_the_reference_area():
    from types import SimpleNamespace

    from nbvkit.planning.parts import threshold_scale
    from nbvkit.planning.selection import Selector

    def world_showing(side):  # a map whose occupied cells make a side x side plane of 0.2 m cells
        m = nbvkit.OccupancyMap(0.2, (-10, -10, -1), (10, 10, 1))
        g = (np.arange(side) + 0.5) * 0.2 - 9.0
        x, y = np.meshgrid(g, g)
        m.update_cells(np.c_[x.ravel(), y.ravel(), np.full(side * side, 0.1)], occupied=True)
        assert m.counts()["occupied"] == side * side
        return SimpleNamespace(map=m, state=SimpleNamespace(pose=np.zeros(4)))

    small, large = world_showing(50), world_showing(90)  # 100 m^2 and 324 m^2 of surface
    assert threshold_scale(small.map, 400.0) == pytest.approx(100 / 400)
    assert threshold_scale(large.map, 300.0) == 1.0  # at least the reference: as set
    assert threshold_scale(small.map, 0.0) == 1.0  # reference 0: as set at any size
    assert threshold_scale(small.map, 4000.0) == 0.1  # never below a tenth
    assert threshold_scale(small.map, 4000.0, 1e-4) == pytest.approx(100 / 4000)  # the rate's

    # planner.min_gain 0.8 m^2 = 20 cells; on the 100 m^2 structure a quarter of it, 5 cells
    cfg = load_config(overrides=["vehicle.blocked_path=reject"])
    scores = {
        "status": np.zeros(2, np.int8),
        "gain": np.array([4.0, 8.0]),  # cells of new surface
        "utility": np.array([4.0, 8.0]),
    }
    poses = np.array([[1.0, 0, 0, 0], [2.0, 0, 0, 0]])
    choice = Selector(PlanningContext.of(cfg)).choose(small, poses, scores)
    assert choice is not None and choice.index == 1  # 8 cells pass, 4 would not
    assert Selector(PlanningContext.of(cfg)).choose(large, poses, scores) is None
    absolute = load_config(overrides=["vehicle.blocked_path=reject", "planner.reference_area=0"])
    assert Selector(PlanningContext.of(absolute)).choose(small, poses, scores) is None
    refusing = Selector(PlanningContext.of(cfg))  # why none was chosen, counted by cause
    assert refusing.choose(large, poses, {**scores, "status": np.int8([0, 2])}) is None
    assert +refusing.refused == {"below_min_gain": 1, "collision": 1}
    refusing.begin()  # a new planning step counts anew
    assert +refusing.refused == {}


def test_a_structure_a_metre_across_is_toured_and_a_map_too_coarse_for_it_is_named(tmp_path):
    """The airliner at 1 m (mesh.scale 0.03): tour.rate stopped shrinking at a tenth of the
    structure's scale, so no view paid for its detour and the mission ended after the profile
    at 74.9 % of the observable surface; the rate now follows the structure down. The 0.2 m map
    spans it in 5 cells: a warning names a resolution that fits it."""
    cfg = load_config(overrides=["mesh.scale=0.03", "progress=false", "report.enabled=false"])
    with pytest.warns(
        RuntimeWarning, match=r"spans 1\.05 m, 5\.2 cells of the 0\.2 m map.*map\.resolution=0\.05"
    ):
        s = Mission(cfg.with_overrides(["max_iterations=20"])).run(tmp_path, finish=True)
    assert s["tours"][0]["scale"] == 0.1  # the area thresholds keep their floor
    assert s["iterations"] >= 2
    written = json.loads((tmp_path / "summary.json").read_text())  # with the end-of-run outputs
    assert written["area_coverage_observable"]["0.05"] >= 0.85
    from nbvkit.workspace import warn_coarse

    fine = cfg.with_overrides(["map.resolution=0.05"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_coarse(nbvkit.load_mesh(nbvkit.default_mesh_path(), scale=0.03).bounds, fine)
    # under a metre, the unit comes first: its finer map alone was refused for the camera's rays
    tiny = cfg.with_overrides(["mesh.scale=0.006"])
    with pytest.warns(
        RuntimeWarning, match=r"0\.21 m across at mesh\.scale = 0\.006 \(nbvkit"
    ) as w:
        warn_coarse(nbvkit.load_mesh(nbvkit.default_mesh_path(), scale=0.006).bounds, tiny)
    assert "map.resolution=" not in str(w[0].message)  # (refused for the camera's rays)


def test_selection_floods_the_free_component_only_after_a_search_cut_short_by_its_cap():
    from types import SimpleNamespace

    from nbvkit.planning.selection import Selector

    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 12, 4))
    m.mark_free_segment((2, 2, 2), (10, 2, 2), 1.5)  # the vehicle's corridor
    m.mark_free_segment((2, 9, 2), (10, 9, 2), 1.5)  # another, apart from it
    poses = np.array([[9, 9, 2, 0], [5, 9, 2, 0], [9, 2, 2, 0.0]])  # two apart, one reachable
    utility = np.array([9.0, 8.0, 1.0])  # the views apart are worth more
    scores = {"status": np.zeros(3, np.int8), "gain": np.full(3, 1e3), "utility": utility}
    cfg = load_config(overrides=["vehicle.blocked_path=plan"])
    for cap in (5, 200000):
        searched = []

        def search_path(target, max_expansions=None):
            searched.append(tuple(target[:3]))
            return _core.search_path(m, (3, 2, 2), target[:3], 0.8, max_expansions or cap)

        def plan_path(target, max_expansions=None):
            path = search_path(target, max_expansions).path
            return path if len(path) else None

        world = SimpleNamespace(map=m, state=SimpleNamespace(pose=np.array([3, 2, 2, 0.0])))
        world.search_path, world.plan_path = search_path, plan_path
        world.free_component = lambda: _core.FreeComponent(m, (3, 2, 2), 0.8)
        selector = Selector(PlanningContext.of(cfg))
        selector.begin()
        choice = selector.choose(world, poses, scores)
        assert choice.index == 2  # the only reachable view, whatever its utility
        if cap == 5:
            # the first view apart is searched, cut short by the cap; the flood that follows
            # holds neither view apart: the other is passed over without a search
            assert selector.component is not None
            assert len(searched) == 2 and searched[0][1] == 9 and searched[1] == (9, 2, 2)
            selector.begin()  # a new step: the map may have changed, every view is searched again
            searched.clear()
            assert selector.choose(world, poses, scores).index == 2 and len(searched) == 2
        else:
            # each search to a view apart fails for good: no flood, the next view is searched
            assert selector.component is None
            assert sorted(searched[:2]) == [(5, 9, 2), (9, 9, 2)] and searched[2] == (9, 2, 2)
        apart = {k: v[:2] for k, v in scores.items()}  # only the views apart: no way to either
        assert selector.choose(world, poses[:2], apart) is None
        assert +selector.refused == {"no_path": 2}


def test_patches_group_targets_by_cell_and_side():
    t = {
        "positions": np.array([[0.1, 0, 0], [0.2, 0, 0], [0.1, 0, 0], [5, 5, 5]]),
        "normals": np.array([[1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0]]),
        "weight": np.array([1.0, 1.0, 0.5, 1.0]),
    }
    p = target_patches(t, 1.0)
    assert len(p.weights) == 3  # the two sides of the first cell stay apart
    assert sorted(p.weights.tolist()) == [0.5, 1.0, 2.0]
    # the same arrays as a SurfaceTargets (what surface_targets returns): the same patches
    typed = _core.SurfaceTargets(t["positions"], t["normals"], t["weight"])
    assert len(typed) == 4 and (typed.kind == 0).all()
    q = target_patches(typed, 1.0)
    for f in ("centers", "normals", "weights"):
        np.testing.assert_array_equal(getattr(q, f), getattr(p, f))
    with pytest.raises(ValueError, match="read-only"):
        typed.weight[0] = 2.0  # a view into the object, not a copy to edit
    for size in (0, -1.0, float("nan"), float("inf"), "1", True):  # 0 and NaN gave 5 patches
        with pytest.raises(ValueError, match="cluster_size must be a finite number > 0"):
            target_patches(t, size)


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(normals=np.zeros((3, 3))), "2 positions but 3 normals"),
        (dict(weight=np.ones(3)), "weight must be"),
        (dict(weight=[1.0, -1.0]), "finite and >= 0"),
        (dict(weight=[1.0, np.nan]), "finite and >= 0"),
        (dict(positions=[[0, 0, np.inf], [0, 0, 0]]), "positions"),
        (dict(kind=[0, 4]), "kind 4 is not 0-3"),
        (dict(kind=[0]), "kind must be"),
        (dict(normals=[[1.0, 0, 0], [0, 0, 0]]), "normal 1 is zero"),  # (no direction)
    ],
)
def test_script_built_targets_are_checked(change, message):
    args = dict(positions=np.zeros((2, 3)), normals=[[1.0, 0, 0]] * 2, weight=[1.0, 0.5])
    with pytest.raises(ValueError, match=message):
        _core.SurfaceTargets(**{**args, **change})


def test_script_built_targets_normals_are_unit_as_the_planners_own():
    """A script's normal of length 3 was kept as given, where the placement reads a unit one."""
    t = _core.SurfaceTargets(np.zeros((2, 3)), [[3.0, 0, 0], [0, 1e-3, 1e-3]], [1.0, 1.0])
    np.testing.assert_allclose(t.normals, [[1, 0, 0], [0, 0.5**0.5, 0.5**0.5]])


def test_surface_targets_of_a_wall_seen_from_the_front_are_on_its_back():
    m = nbvkit.OccupancyMap(0.2, (-2, -4, -4), (12, 4, 4))
    cam = nbvkit.DepthCamera(wall_mesh(x=5.0, half=1.0), max_range=8.0)
    surface = _core.SurfaceObservations(m)
    for _ in range(3):
        scan = cam.scan_pose([0.0, 0.0, 0.0, 0.0])
        m.integrate(scan)
        surface.add_scan(scan)
    t = _core.surface_targets(m, surface, dict(frontier=False, predicted=False))
    kinds = t.kind
    assert len(kinds) > 0 and np.all(kinds == 0)
    # the front was seen from the camera's side: what is left faces away from it (+x)
    assert np.all(t.normals[:, 0] > 0.5)
    t2 = _core.surface_targets(m, surface)
    assert (t2.kind == 2).any()  # unknown space behind the wall borders its surface
    fr = t2.normals[t2.kind == 2]
    # frontier cells are seen from known free space: the camera's side or past the wall's edges,
    # never from the unknown space behind the wall
    assert np.all(fr[:, 0] <= 1e-9) and (fr[:, 0] < -0.5).any()


def test_frontier_targets_in_bricks_never_written_are_found_beside_written_ones():
    # an occupied and a free cell in two bricks of 4 x 4 x 4 cells; the unknown cells touching
    # both lie in two bricks the map never wrote (their cells read from the shared brick)
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (4, 4, 4))

    def cell(i, j, k):
        return np.array([[i, j, k]]) * 0.2 + 0.1

    m.update_cells(cell(4, 3, 5), occupied=True)
    m.update_cells(cell(3, 4, 5), occupied=False)
    assert m.grid_bricks == (2, 125)
    t = _core.surface_targets(m, _core.SurfaceObservations(m))
    assert np.all(t.kind == 2)  # frontier
    found = sorted(map(tuple, np.round(t.positions / 0.2 - 0.5).astype(int)))
    assert found == [(3, 3, 5), (4, 4, 5)]


def test_frontier_views_face_their_targets_and_the_valid_ones_are_collision_free():
    cfg = load_config(
        overrides=[
            "scenario=surface_nbv",
            "map.resolution=0.4",
            "progress=false",
            "max_iterations=1",
        ]
    )
    mesh = box_mesh((-3, -3, 0), (3, 3, 4))
    m = Mission(cfg, mesh=mesh)
    w = m.world
    w.take_off()
    w.sense("view")
    gen = get_generator("frontier", cfg)
    prop = gen.propose(w)
    assert prop is not None and len(prop.poses) > 0
    s = _core.evaluate_views(
        w.map,
        prop.poses,
        w.state.pose,
        camera=w.view_camera,
        utility=cfg.utility.options(),
        validity=w.validity(),
        surface=w.surface,
    )
    valid = prop.poses[s["status"] == 0]
    assert len(valid) > 0
    for p in valid:
        assert _core.sphere_is_free(w.map, p[:3], cfg.vehicle.collision_radius)
    # each view faces the target patch it was placed for, inside the camera's field of view
    assert prop.aims.shape == (len(prop.poses), 3)
    for p, aim in zip(prop.poses, prop.aims):
        to_aim = aim - p[:3]
        heading = np.array([math.cos(p[3]), math.sin(p[3])])
        assert heading @ to_aim[:2] / np.linalg.norm(to_aim[:2]) > math.cos(1e-6)
        elevation = math.degrees(math.atan2(to_aim[2], np.linalg.norm(to_aim[:2])))
        pitch = math.degrees(p[4]) if len(p) > 4 else 0.0  # > 0 looks down
        assert abs(elevation + pitch) <= cfg.camera.vfov_deg / 2 + 1e-9
        # and is near the structure: the patch lies on or next to the box's surface
        assert np.all(aim >= np.array([-3, -3, 0]) - 0.5) and np.all(
            aim <= np.array([3, 3, 4]) + 0.5
        )


# ------------------------------------------------------------------ missions

QUICK = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=50",
    "evaluation.coverage_every=2",
    "profiling.sweep_step=0.25",
    "symmetry.voxel_size=0.4",
]


@pytest.mark.slow
@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_every_scenario_flies_end_to_end(scenario, tmp_path):
    cfg = load_config(overrides=[f"scenario={scenario}", "max_iterations=6", *QUICK])
    s = Mission(cfg).run(tmp_path)
    d = json.loads((tmp_path / "summary.json").read_text())
    assert d["scenario"] == scenario
    if scenario == "profile":
        assert d["termination"] == "profile_only" and d["iterations"] == 0
    else:
        assert 1 <= d["iterations"] <= 6
        assert d["views"] == d["iterations"] + 1  # the first frame, then one per iteration
    assert s["coverage"]["0.5"] > 0 and s["distance_m"] > 0
    assert (tmp_path / "iterations.csv").exists()
    # the paper's Fig. 3 where a symmetry stage ran (drawn with the results, not in the flight)
    assert (tmp_path / "figures" / "symmetry.png").exists() == ("symmetry" in d), d.keys()


def test_a_tour_that_flew_nothing_is_replanned_over_reachable_views_then_the_planner_says_why():
    # After the profile round an 8 x 6 x 5 m box: a plan over the views a path through known
    # free space can reach (the vehicle's free component) considers fewer candidates, and every
    # view it keeps is in that component. A tour none of whose views was flown is followed by
    # such a plan; when that one flies nothing either, the mission stops with the reason.
    cfg = load_config(overrides=["max_iterations=0", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    m.run()
    w = m.world
    tour = next(g for g in m.planner.generators if hasattr(g, "plans"))
    comp = _core.FreeComponent(w.map, w.state.pose[:3], cfg.vehicle.collision_radius)
    every = tour.plan(w)
    reach = tour.plan(w, reachable_only=True)
    a, b = tour.plans
    assert not a["reachable_only"] and b["reachable_only"]
    assert 0 < b["candidates"] < a["candidates"]
    assert len(reach) > 0 and comp.contains(w.map, reach[:, :3]).all()
    # the last tour (every) flew nothing: the next plan is over reachable views only
    tour.plans = [{**a, "kept": len(every), "flown": 0}]
    tour.views, tour.next = every, len(every)
    assert tour.propose(w) is not None and tour.plans[-1]["reachable_only"]
    assert tour.stop_reason is None
    tour.next = len(tour.views)  # and it flew nothing either
    assert m.planner.next_view(w) == "no_reachable_view" and tour.stop_reason == "no_reachable_view"
    # a tour that flew nothing, then no view reachable at all (the plan over reachable views has
    # no candidate): the same reason, not coverage_complete
    tour.stop_reason = None
    tour.plans = [{**a, "kept": len(every), "flown": 0}]
    tour.views, tour.next = every, len(every)
    nowhere = type("Nowhere", (), {"contains": lambda self, m, p: np.zeros(len(p), bool)})()
    w.free_component = lambda: nowhere
    assert tour.propose(w) is None and tour.stop_reason == "no_reachable_view"
    assert tour.plans[-1]["reachable_only"] and tour.plans[-1]["candidates"] == 0
    del w.free_component  # asked again, a plan flies: the reason given before is not kept
    assert tour.propose(w) is not None and tour.stop_reason is None


@pytest.mark.slow
def test_the_surface_planner_tours_and_stops_by_itself():
    cfg = load_config(overrides=["max_iterations=400", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    s = m.run()
    assert s["termination"] == "coverage_complete"
    assert len(s["tours"]) >= 1 and s["tours"][0]["flown"] >= 1
    assert 0 < s["tours"][0]["scale"] < 1  # a box of 236 m^2 < planner.reference_area
    # the 8 x 6 x 5 m box's bottom (48 of its 236 m^2) lies on the ground: 79.7 % is observable;
    # the tour must see nearly all of that
    assert s["area_coverage"]["0.1"] > 0.7
    sources = {r.source for r in m.records}
    assert sources == {"tour"}
    # ms_per_stage counts the plan that ended the mission (no view, so no row) as well
    rows_ms = sum(getattr(r, f"t_{st}_ms") for r in m.records for st in STAGES)
    assert s["final_plan_ms"] > 0
    assert s["ms_per_iteration"] * s["iterations"] == pytest.approx(rows_ms + s["final_plan_ms"])
    assert s["ms_per_stage"]["sampling"] * s["iterations"] > sum(r.t_sampling_ms for r in m.records)


@pytest.mark.slow
def test_with_a_final_rate_the_views_that_did_not_pay_for_their_flight_are_flown_at_the_end():
    """tour.final_rate: once no plan keeps a view at tour.rate, plans go on at the final rate.
    At a rate no far view pays (50 m^2 a metre) the box is left early; with final_rate 0 the
    plans that follow, all at the final rate, fly more views and cover more of it (75.1 against
    73.2 % at 0.1 m, of the 79.7 % observable)."""
    box = box_mesh((-4, -3, 0), (4, 3, 5))
    dear = ["max_iterations=400", "tour.rate=50", *QUICK]
    s = Mission(load_config(overrides=dear), mesh=box).run()
    t = Mission(load_config(overrides=[*dear, "tour.final_rate=0"]), mesh=box).run()
    assert not any(p["final"] for p in s["tours"])
    final = [p["final"] for p in t["tours"]]
    first = final.index(True)  # after the plan at tour.rate that kept no view
    assert t["tours"][first - 1]["kept"] == 0 and all(final[first:])
    assert sum(p["flown"] for p in t["tours"][first:]) >= 1
    assert t["iterations"] > s["iterations"]
    assert t["area_coverage"]["0.1"] > s["area_coverage"]["0.1"] + 0.01
    # the dear mission ended with views it did not fly, and says so; the other flew them all
    left = s["tours"][-1]
    assert left["kept"] == 0 and left["unpaid"] >= 1
    assert left["unpaid_m2"] >= left["unpaid"] * left["min_gain_m2"]
    assert "tour.rate" in budget_note(s) and "tour.final_rate" in budget_note(s)
    assert t["tours"][-1]["unpaid"] == 0 and budget_note(t) is None
    with pytest.raises(ValueError, match="tour.final_rate"):
        load_config(overrides=["tour.final_rate=-1"])


@pytest.mark.slow
def test_with_replan_views_no_tour_flies_more_views_before_the_next_plan():
    """tour.replan_views: a tour is planned again once that many of its views were flown, so no
    plan flies more; the box is covered as with whole tours."""
    cfg = load_config(overrides=["max_iterations=400", "tour.replan_views=2", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    s = m.run()
    assert s["termination"] == "coverage_complete"
    flown = [t["flown"] for t in s["tours"]]
    assert max(flown) == 2 and sum(flown) == s["iterations"], flown
    # a plan cut short kept more views than it flew: the rest was planned again
    assert any(t["kept"] > t["flown"] == 2 for t in s["tours"]), s["tours"]
    assert s["area_coverage"]["0.1"] > 0.7
    # with tour.max_plans reached, the last tour is flown to its end, not cut short
    cfg = load_config(
        overrides=["max_iterations=400", "tour.replan_views=2", "tour.max_plans=1", *QUICK]
    )
    (only,) = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5))).run()["tours"]
    assert only["flown"] > 2, only


@pytest.mark.slow
def test_with_the_fallback_placement_every_flown_view_was_feasible_when_planned():
    """placement.fallback in a mission: the box on the ground's lower patches get views from
    tilted directions where their own leave the navigation space; each plan reports the patches
    no direction serves, and the mission covers the box as without it."""
    cfg = load_config(overrides=["max_iterations=400", "placement.fallback=true", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    s = m.run()
    assert s["termination"] == "coverage_complete"
    assert all(isinstance(t["unplaced_patches"], int) for t in s["tours"])
    assert s["area_coverage"]["0.1"] > 0.7
    flown = np.array([[r.x, r.y, r.z] for r in m.records])
    assert m.world.can_hold(flown).all()  # the map at the end holds every view's sphere free


@pytest.mark.slow
def test_on_a_large_workspace_blocked_patches_get_tilted_views_once_no_other_view_is_left():
    """placement.fallback null (shipped): on a workspace longer than 6 camera ranges (a 60 m
    wall), the flight is the one without tilted views until a plan keeps nothing; then the plans
    look at blocked patches from tilted directions too, and the mission goes on. (No frames on
    the legs: they see the blocked patches in passing, and no tilted view is left to fly. No
    saturation, and tour.rate 0.75, as measured: at the defaults the plain plans leave no blocked
    patch that a tilted view still pays for.)"""
    over = ["max_iterations=400", "planner.frame_step=0", "utility.saturation_hits=0"]
    # and the ground removal it was measured with: without it the plain plans fly 74 views (83 %
    # of the area, against 24 views and 70 %) and leave no blocked patch a tilted view pays for
    over += ["tour.rate=0.75", "cloud.min_z=0.3", *QUICK]
    wall = box_mesh((-30, -1, 0), (30, 1, 4))
    runs = {}
    for fallback in ("false", "null"):
        m = Mission(load_config(overrides=over + [f"placement.fallback={fallback}"]), mesh=wall)
        runs[fallback] = (m.run(), [(r.x, r.y, r.z, r.yaw) for r in m.records])
    (plain, plain_poses), (s, poses) = runs["false"], runs["null"]
    n = len(plain["tours"])
    assert plain["tours"][-1]["kept"] == 0 and not any(t["refit"] for t in plain["tours"])
    assert s["tours"][:n] == plain["tours"]  # the same plans and flight up to its end
    np.testing.assert_array_equal(poses[: len(plain_poses)], plain_poses)
    assert len(s["tours"]) > n and all(t["refit"] for t in s["tours"][n:])
    assert s["termination"] == "coverage_complete"
    assert len(poses) > len(plain_poses)  # the tilted views served patches left before
    assert s["area_coverage"]["0.05"] >= plain["area_coverage"]["0.05"]


@pytest.mark.slow
def test_exploration_is_planned_only_after_a_surface_plan_with_nothing_worth_flying():
    # With tour.explore, a plan over the surface the map shows that keeps no view is followed by
    # plans over views of the unknown space within the structure's extent as well; the mission
    # ends when such a plan keeps nothing. Until then the flight is the one without it.
    over = ["max_iterations=400", *QUICK]
    runs = {}
    for explore in (False, True):
        cfg = load_config(overrides=over + [f"tour.explore={explore}"])
        m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
        runs[explore] = (m.run(), [(r.x, r.y, r.z, r.yaw) for r in m.records])
    (plain, plain_poses), (s, poses) = runs[False], runs[True]
    n = len(plain["tours"])
    assert not any(p["explore"] for p in plain["tours"]) and plain["tours"][-1]["kept"] == 0
    tours = s["tours"]
    assert s["termination"] == "coverage_complete"
    assert tours[:n] == plain["tours"]  # the same plans and flight up to the fallback
    np.testing.assert_array_equal(poses[: len(plain_poses)], plain_poses)
    assert len(tours) > n and all(p["explore"] for p in tours[n:])
    assert tours[-1]["kept"] == 0
    # tour.explore_first: every plan weighs the unknown space, the first one included
    cfg = load_config(overrides=over + ["tour.explore_first=true"])
    first = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5))).run()
    assert first["termination"] == "coverage_complete"
    assert all(p["explore"] for p in first["tours"])


@pytest.mark.slow
def test_the_surface_planner_flies_the_same_mission_with_and_without_its_coverage_memo():
    runs = []
    for keep in (True, False):
        cfg = load_config(overrides=["max_iterations=400", *QUICK])
        m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
        tour = next(g for g in m.planner.generators if hasattr(g, "plans"))
        if not keep:
            tour.memo = None
        s = m.run()
        runs.append((s, [(r.x, r.y, r.z, r.yaw) for r in m.records], tour.memo))
    (a, poses_a, memo), (b, poses_b, _) = runs
    assert len(a["tours"]) >= 2 and a["tours"] == b["tours"]
    np.testing.assert_array_equal(poses_a, poses_b)
    for key in ("distance_m", "entropy_final", "coverage", "area_coverage", "termination"):
        assert a[key] == b[key], key
    assert memo.stats()["reused"] > 0


def test_an_exploring_plan_adds_views_facing_the_unknown_after_the_surfaces(monkeypatch):
    # After the profile round a box, one unknown cell 2 m off its +x face looking back at -x (a
    # stand-in for exploration_targets' answer): the candidates are the surface's, in the same
    # order, then views of that cell's patch, straight on (no azimuth spread), facing it.
    from nbvkit.planning.generators import tour as tour_module

    cfg = load_config(overrides=["max_iterations=0", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    m.run()
    t = next(g for g in m.planner.generators if hasattr(g, "plans"))
    targets, patches, surface, owner, _ = t.candidates(m.world)
    # what a plugin reads (docs/PLUGINS.md): the same targets the tour's candidates aim at
    mine = nbvkit.surface_targets(m.world.map, m.world.surface, t.ctx.targets)
    assert isinstance(mine, nbvkit.SurfaceTargets) and len(mine) == len(targets) > 0
    np.testing.assert_array_equal(mine.positions, targets.positions)
    np.testing.assert_allclose(np.linalg.norm(mine.normals, axis=1), 1.0)
    cell = np.array([[6.2, 0.2, 2.6]])
    fake = _core.SurfaceTargets(cell, [[-1.0, 0.0, 0.0]], np.ones(1), kind=[3])
    monkeypatch.setattr(
        tour_module, "exploration_targets", lambda _map, _box=None, _within=None: fake
    )
    _, both, views, of, _ = t.candidates(m.world, explore=True)
    k = len(surface)
    np.testing.assert_array_equal(views[:k], surface)
    np.testing.assert_array_equal(of[:k], owner)
    assert len(both.weights) == len(patches.weights) + 1
    np.testing.assert_allclose(both.centers[-1], cell[0])
    extra, owners = views[k:], of[k:]
    assert len(extra) == len(cfg.placement.standoffs) and (owners == len(patches.weights)).all()
    to_cell = cell[0, :2] - extra[:, :2]
    np.testing.assert_allclose(np.arctan2(to_cell[:, 1], to_cell[:, 0]), extra[:, 3], atol=1e-9)
    assert (extra[:, 0] < cell[0, 0]).all()  # on the free side


@pytest.mark.slow
def test_budget_stops_a_mission():
    cfg = load_config(overrides=["max_iterations=400", "budget.max_views=5", *QUICK])
    s = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5))).run()
    assert s["termination"] == "budget_views" and s["views"] == 5


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    "override, message",
    [
        ("scenario=nope", "scenario"),
        ("planner.generators=[lattice, nope]", "planner generator 'nope'"),
        ("planner.terminations=[nope]", "planner termination 'nope'"),
        ("planner.generators=lattice", "planner.generators"),
        ("utility.name=nope", "utility.name"),
        ("utility.weight_density=-1", "weight_density"),
        ("utility.frontier_prior=.nan", "utility.frontier_prior"),
        ("tour.rate=-1", "tour.rate"),
        ("planner.travel_lambda=.inf", "planner.travel_lambda"),
        ("planner.reference_area=-1", "planner.reference_area"),
        ("placement.standoffs=[0.5, 2.0]", "placement.standoffs"),
        ("targets.frontier_weight=3", "frontier_weight"),
        ("stall.window=0", "stall.window"),
    ],
)
def test_bad_planner_configuration_fails_before_any_work(override, message):
    with pytest.raises((ValueError, KeyError), match=message):
        load_config(overrides=[override])


def test_scenario_presets_yield_to_what_the_user_sets():
    c = load_config(overrides=["scenario=3", "lattice.sigma=2"])
    assert c.lattice.method == "agvs" and c.lattice.sigma == 2.0  # preset + user
    assert c.utility.name == "ig" and c.planner.generators == ("lattice",)
    c2 = load_config(overrides=["scenario=5", "utility.name=four_term"])
    assert c2.utility.name == "four_term" and c2.symmetry.mode == "predict"
    assert Config().scenario == "surface" and Config().utility.name == "surface"
    back = Config.from_dict(c2.to_dict())
    assert back == c2  # a written config.yaml reproduces the run


def _box_seen_from_two_sides():
    """(map, surface, 60 candidate poses round it, the current pose, view_coverage's keywords):
    a box seen from two sides, frontier and unknown cells all round it."""
    m = nbvkit.OccupancyMap(0.2, (-6, -6, 0), (6, 6, 5))
    cam = nbvkit.DepthCamera(box_mesh((-1.5, -1.5, 0), (1.5, 1.5, 2.5)), max_range=8.0)
    surface = _core.SurfaceObservations(m)
    for pose in ([-5.0, 0.0, 1.5, 0.0], [0.0, -5.0, 2.0, math.pi / 2]):
        m.mark_free_segment(pose[:3], pose[:3], 1.0)
        scan = cam.scan_pose(pose)
        m.integrate(scan)
        surface.add_scan(scan)
    rng = np.random.default_rng(3)
    xy = rng.uniform(-5.5, 5.5, (60, 2))
    poses = np.column_stack([xy, rng.uniform(0.5, 4.5, 60), np.arctan2(-xy[:, 1], -xy[:, 0])])
    kw = dict(
        camera=_core.ViewCameraModel(rays_x=24, rays_y=18, max_range=8.0),
        utility=dict(name="surface", require_occupied=False),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
    )
    return m, surface, poses, [-5.0, 0.0, 1.5, 0.0], kw


def _set_sums(cov):
    """Each view's coverage weights summed (in double), from view_coverage's CSR arrays."""
    off = cov.offsets
    return np.array([cov.weights[a:b].astype(float).sum() for a, b in zip(off[:-1], off[1:])])


def _assert_walked_sets_exact(coarse, exact):
    """Every view `coarse` walked (not pruned) holds its set of `exact` (the call without a
    prescreen), element for element; the pruned ones hold none."""
    pruned = coarse.pruned
    sizes, exact_sizes = np.diff(coarse.offsets), np.diff(exact.offsets)
    assert (sizes[pruned] == 0).all()
    np.testing.assert_array_equal(sizes[~pruned], exact_sizes[~pruned])
    held = np.repeat(~pruned, exact_sizes)
    np.testing.assert_array_equal(coarse.elements, exact.elements[held])
    np.testing.assert_array_equal(coarse.weights, exact.weights[held])


def test_view_coverage_sets_hold_what_the_surface_utility_credits_each_view():
    # view_coverage walks with its own packed copy of the grid (one byte a cell); each view's
    # set must hold the cells the surface utility credits walking the grid itself, and weigh
    # them alike
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    cov = _core.view_coverage(m, surface, poses, current, **kw)
    scores = _core.evaluate_views(m, poses, current, surface=surface, **kw)
    np.testing.assert_array_equal(cov.status, scores["status"])
    sizes = np.diff(cov.offsets)
    sums = _set_sums(cov)
    valid = scores["status"] == 0
    assert valid.sum() >= 10 and (sizes[valid] > 0).sum() >= 10
    # each cell once per view, so the set has one element per credited cell; weights are floats
    np.testing.assert_array_equal(sizes[valid], scores["cells"][valid])
    np.testing.assert_allclose(sums[valid], scores["gain"][valid], rtol=1e-5)


def _other_box_seen_from_two_sides():
    """(map, surface) of the same size as _box_seen_from_two_sides', another box seen from other
    sides."""
    other = nbvkit.OccupancyMap(0.2, (-6, -6, 0), (6, 6, 5))
    cam = nbvkit.DepthCamera(box_mesh((-0.5, -2.5, 0), (2.5, 0.5, 4.0)), max_range=8.0)
    other_surface = _core.SurfaceObservations(other)
    for pose in ([5.0, 0.0, 2.0, math.pi], [0.0, 5.0, 1.0, -math.pi / 2]):
        other.mark_free_segment(pose[:3], pose[:3], 1.0)
        scan = cam.scan_pose(pose)
        other.integrate(scan)
        other_surface.add_scan(scan)
    return other, other_surface


def test_view_coverage_reads_each_map_afresh_after_a_call_on_another():
    # the packed grid's buffer is kept from one call to the next and filled brick by brick as
    # the walks read it: calls alternating between two maps of the same size each credit what
    # the surface utility credits walking that map's grid
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    other, other_surface = _other_box_seen_from_two_sides()
    sums = []
    for grid, seen in ((m, surface), (other, other_surface)) * 2:
        cov = _core.view_coverage(grid, seen, poses, current, **kw)
        scores = _core.evaluate_views(grid, poses, current, surface=seen, **kw)
        valid = scores["status"] == 0
        assert valid.sum() >= 10
        np.testing.assert_array_equal(np.diff(cov.offsets)[valid], scores["cells"][valid])
        np.testing.assert_allclose(_set_sums(cov)[valid], scores["gain"][valid], rtol=1e-5)
        sums.append(_set_sums(cov))
    assert not np.array_equal(sums[0], sums[1])


def test_view_coverage_calls_at_once_on_two_maps_answer_as_one_after_the_other():
    # the calls release the GIL: run at once from threads, each takes its own packed buffer
    from concurrent.futures import ThreadPoolExecutor

    m, surface, poses, current, kw = _box_seen_from_two_sides()
    other, other_surface = _other_box_seen_from_two_sides()
    maps = [(m, surface), (other, other_surface)] * 4

    def call(pair):
        return _core.view_coverage(pair[0], pair[1], poses, current, **kw)

    alone = [call(pair) for pair in maps[:2]]
    with ThreadPoolExecutor(max_workers=4) as pool:
        together = list(pool.map(call, maps))
    for k, cov in enumerate(together):
        for field in ("offsets", "elements", "weights", "status"):
            np.testing.assert_array_equal(getattr(cov, field), getattr(alone[k % 2], field))


def test_view_coverage_with_a_min_gain_hands_out_only_the_sets_a_selection_could_take():
    # A valid candidate whose weights sum below min_gain keeps its status and gets an empty set;
    # the others keep theirs; select_tours at that min_gain or above chooses the same views, in
    # the same order, with the same gains, as over the whole sets
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    whole = _core.view_coverage(m, surface, poses, current, **kw)
    sizes, sums = np.diff(whole.offsets), _set_sums(whole)
    valid = whole.status == 0
    mg = float(np.median(sums[valid & (sizes > 0)]))
    cut = _core.view_coverage(m, surface, poses, current, min_gain=mg, **kw)
    np.testing.assert_array_equal(cut.status, whole.status)
    keep = sums >= mg
    assert 0 < (valid & keep).sum() < (valid & (sizes > 0)).sum()
    np.testing.assert_array_equal(np.diff(cut.offsets), np.where(keep, sizes, 0))
    held = np.repeat(keep, sizes)
    np.testing.assert_array_equal(cut.elements, whole.elements[held])
    np.testing.assert_array_equal(cut.weights, whole.weights[held])
    for at in (mg, 1.5 * mg):
        a = _core.select_tours(whole, poses[:, :3], current[:3], rate=0.5, min_gain=at)
        b = _core.select_tours(cut, poses[:, :3], current[:3], rate=0.5, min_gain=at)
        assert [(list(v), list(g)) for v, g in a] == [(list(v), list(g)) for v, g in b]
        assert len(a[0][0]) > 0
    with pytest.raises(ValueError, match="min_gain"):
        _core.view_coverage(m, surface, poses, current, min_gain=float("nan"), **kw)


def test_view_coverage_pools_unknown_space_per_brick():
    # pool_unknown: a view's credits of unknown cells away from surface (unknown_prior) become
    # one element per brick of 4 x 4 x 4 cells (2 x the grid's storage cells + the brick),
    # weighing their sum; every other element is the cell's own, with its weight. Status and
    # gain are those without pooling; a memo hands back pooled sets only to pooled calls.
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    cells = _core.view_coverage(m, surface, poses, current, **kw)
    pooled = _core.view_coverage(m, surface, poses, current, pool_unknown=True, **kw)
    np.testing.assert_array_equal(pooled.status, cells.status)
    np.testing.assert_array_equal(pooled.gain, cells.gain)
    base = 2 * 64 * m.grid_bricks[1]
    priors = pools = 0
    co, po = cells.offsets, pooled.offsets
    for k in range(len(poses)):
        ue, uw = cells.elements[co[k] : co[k + 1]], cells.weights[co[k] : co[k + 1]]
        pe, pw = pooled.elements[po[k] : po[k + 1]], pooled.weights[po[k] : po[k + 1]]
        assert (np.diff(pe) > 0).all()
        own = pe < base
        mine = np.isin(ue, pe[own])
        np.testing.assert_array_equal(ue[mine], pe[own])
        np.testing.assert_array_equal(uw[mine], pw[own])
        bricks, at = np.unique(ue[~mine] // 2 // 64, return_inverse=True)
        np.testing.assert_array_equal(pe[~own], base + bricks)
        sums = np.bincount(at, weights=uw[~mine].astype(float), minlength=len(bricks))
        np.testing.assert_allclose(pw[~own], sums, rtol=1e-5)
        assert (uw[~mine] <= 0.005 + 1e-9).all()  # unknown_prior x visibility x density
        priors, pools = priors + (~mine).sum(), pools + (~own).sum()
    assert priors > 1000 and pools < priors / 4  # most of the sets, far fewer elements
    memo = _core.CoverageMemo()
    for pool in (False, True, True):  # the memo's records are of one kind of set
        a = _core.view_coverage(m, surface, poses, current, memo=memo, pool_unknown=pool, **kw)
        for key in ("offsets", "elements", "weights", "status", "gain"):
            np.testing.assert_array_equal(getattr(a, key), getattr(pooled if pool else cells, key))
    assert memo.stats()["reused"] > 0
    views, gains = _core.select_tours(pooled, poses[:, :3], current[:3], rate=0.5, min_gain=5)[0]
    assert len(views) > 0 and min(gains) >= 5


def test_a_pooled_brick_is_covered_by_shares_of_its_cap():
    # a cell's element adds what its weight exceeds the most it was taken with; a pooled brick
    # (elements from pooled_from on) adds w (1 - F), F the share of its cap covered, which grows
    # by w / cap of what is left: view 1 (0.5 of a brick 0.6 covered) adds 0.5 x 0.4 = 0.2
    cov = dict(
        offsets=np.array([0, 2, 3, 5]),
        elements=np.array([1, 100, 100, 1, 2], np.int32),
        weights=np.array([1.0, 0.6, 0.5, 0.5, 0.3], np.float32),
        status=np.zeros(3, np.int8),
        pooled_from=100,
        pool_cap=1.0,
    )
    views, gains = _core.select_cover(cov, min_gain=0.1)
    assert list(views) == [0, 2, 1]
    np.testing.assert_allclose(gains, [1.6, 0.3, 0.2], rtol=1e-6)
    here = np.zeros((3, 3))
    found = _core.select_tours(cov, here, [0, 0, 0], rate=0.0, min_gain=0.1, charges=[True])
    (tour, tour_gains) = found[0]
    assert sorted(zip(tour, np.round(tour_gains, 6))) == [(0, 1.6), (1, 0.2), (2, 0.3)]
    cells = {k: v for k, v in cov.items() if k not in ("pooled_from", "pool_cap")}
    assert list(_core.select_cover(cells, min_gain=0.1)[0]) == [0, 2]  # 100 a cell: 0.5 < 0.6
    with pytest.raises(ValueError, match="pool_cap"):
        _core.select_cover(dict(cov, pool_cap=float("nan")), min_gain=0.1)
    with pytest.raises(ValueError, match="pooled_from"):  # every element would count as pooled
        _core.select_cover(dict(cov, pooled_from=-1), min_gain=0.1)


def test_view_coverage_prescreen_leaves_only_views_its_coarse_rays_estimate_below_min_gain():
    # With coarse_stride, a view estimated below min_gain by its coarse rays (their gain and one
    # more cell, scaled to all rays) is left unwalked (pruned, empty set, its estimate as gain);
    # every other set is the exact one. Stride 1 walks
    # every ray: a view is pruned where its gain and one cell fall below min_gain, and the arrays
    # are those of the exact cut. No view is pruned without min_gain, and a negative stride is
    # refused. Each set is sorted by element, and a walked view's gain is its weights' sum.
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    whole = _core.view_coverage(m, surface, poses, current, **kw)
    sums = _set_sums(whole)
    valid = whole.status == 0
    np.testing.assert_allclose(whole.gain[valid], sums[valid], rtol=1e-5)
    assert (whole.gain[~valid] == 0).all()
    off = whole.offsets
    assert all((np.diff(whole.elements[a:b]) > 0).all() for a, b in zip(off[:-1], off[1:]))
    mg = float(np.median(sums[valid & (sums > 0)]))
    exact = _core.view_coverage(m, surface, poses, current, min_gain=mg, **kw)
    assert not exact.pruned.any() and not whole.pruned.any()
    one = _core.view_coverage(m, surface, poses, current, min_gain=mg, coarse_stride=1, **kw)
    for key in ("offsets", "elements", "weights", "status"):
        np.testing.assert_array_equal(getattr(one, key), getattr(exact, key))
    np.testing.assert_array_equal(one.pruned, valid & (sums + 1 < mg))
    assert one.pruned.sum() >= 5
    coarse = _core.view_coverage(m, surface, poses, current, min_gain=mg, coarse_stride=3, **kw)
    np.testing.assert_array_equal(coarse.status, whole.status)
    pruned = coarse.pruned
    assert pruned.sum() >= 5 and not pruned[~valid].any()
    _assert_walked_sets_exact(coarse, exact)
    assert (coarse.gain[pruned] < mg).all()
    # the estimate errs high: most views below min_gain are pruned, few above it
    below = valid & (sums < mg)
    assert pruned[below].mean() >= 0.5 and pruned[valid & ~below].mean() <= 0.2
    none = _core.view_coverage(m, surface, poses, current, coarse_stride=3, **kw)
    assert not none.pruned.any()
    # a memo keeps the estimates of the views left unwalked: a call over the same map prunes
    # them again without their coarse walks, and at a lower min_gain walks those above it; the
    # same arrays as without the memo each time
    memo = _core.CoverageMemo()
    for gain, estimated in ((mg, 0), (mg, pruned.sum()), (mg / 2, 0)):
        a = _core.view_coverage(
            m, surface, poses, current, min_gain=gain, coarse_stride=3, memo=memo, **kw
        )
        b = _core.view_coverage(m, surface, poses, current, min_gain=gain, coarse_stride=3, **kw)
        for key in ("offsets", "elements", "weights", "status", "pruned", "gain"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        stats = memo.stats()
        if estimated:
            assert stats["estimated"] == estimated
    assert stats["estimated"] < 2 * pruned.sum()  # at mg / 2, some views are walked instead
    assert stats["stale"] == 0
    with pytest.raises(ValueError, match="coarse_stride"):
        _core.view_coverage(m, surface, poses, current, min_gain=mg, coarse_stride=-1, **kw)


def test_view_coverage_coarse_margin_walks_only_views_estimated_above_its_multiple():
    # coarse_margin m: a view is walked whole only where its coarse estimate reaches m x
    # min_gain. At 2 the views pruned are those estimated below twice min_gain (a superset of
    # margin 1's), every walked view keeps its exact set, and a margin not finite and > 0 is
    # refused before any work.
    m, surface, poses, current, kw = _box_seen_from_two_sides()
    whole = _core.view_coverage(m, surface, poses, current, **kw)
    valid, sums = whole.status == 0, _set_sums(whole)
    mg = float(np.median(sums[valid & (sums > 0)])) / 2
    exact = _core.view_coverage(m, surface, poses, current, min_gain=mg, **kw)
    one, two = (
        _core.view_coverage(
            m, surface, poses, current, min_gain=mg, coarse_stride=3, coarse_margin=c, **kw
        )
        for c in (1.0, 2.0)
    )
    assert (two.gain[two.pruned] < 2 * mg).all()
    assert (one.pruned <= two.pruned).all() and two.pruned.sum() > one.pruned.sum()
    # those left out at 2 and not at 1 are the views estimated between min_gain and twice it
    newly = two.pruned & ~one.pruned
    assert ((two.gain[newly] >= mg) & (two.gain[newly] < 2 * mg)).all()
    _assert_walked_sets_exact(two, exact)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="coarse_margin"):
            _core.view_coverage(
                m, surface, poses, current, min_gain=mg, coarse_stride=3, coarse_margin=bad, **kw
            )


def _unseen_wall(x):
    """(map, surface record, kw): in a 16 x 12 x 8 m map, a wall of occupied cells across
    x = `x` that no camera has seen, the camera's cell at the origin known free; a surface
    utility that credits the wall alone (unknown cells weigh nothing), the default camera
    (47 x 34 rays, 60 x 45 deg, 8 m)."""
    lo, hi = (-5.0, -6.0, -4.0), (11.0, 6.0, 4.0)
    m = nbvkit.OccupancyMap(0.2, lo, hi)
    y, z = np.meshgrid(np.arange(lo[1] + 0.1, hi[1], 0.2), np.arange(lo[2] + 0.1, hi[2], 0.2))
    m.update_cells(np.column_stack([np.full(y.size, x), y.ravel(), z.ravel()]), occupied=True)
    m.mark_free_segment((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.3)
    kw = dict(
        camera=_core.ViewCameraModel(),
        utility=dict(name="surface", require_occupied=False, unknown_prior=0.0, frontier_prior=0.0),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
    )
    return m, _core.SurfaceObservations(m), kw


def test_max_incidence_credits_a_densely_sampled_surface_cell_only_for_rays_near_its_normal():
    # A slab 1 m thick across x = 4.1..5.1: its front cells' open faces give the normal -x. From
    # the origin looking along +x, with utility.max_incidence_deg = 20, a front cell whose face
    # holds no camera hit is credited as by the default (90: every cell in view); so is one whose
    # face holds hits in 15 of its 16 squares. Once all 16 hold one (incidence_min_patches, the
    # default), exactly the cells whose rays meet the slab within 20 deg of the normal are
    # credited (up to a cell's width of angle at the boundary), the weights unchanged; the same
    # view turned 55 deg meets none so closely. incidence_min_patches=0 applies the rule to every
    # cell. The hits come from far off to the side (their direction bin +y), outside the
    # coverage cone of the test's rays. Out of range: refused by name.
    m, surface, kw = _unseen_wall(4.1)
    for x in np.arange(4.3, 5.1, 0.2):
        y, z = np.meshgrid(np.arange(-5.9, 6.0, 0.2), np.arange(-3.9, 4.0, 0.2))
        m.update_cells(np.column_stack([np.full(y.size, x), y.ravel(), z.ravel()]), occupied=True)
    pose = np.array([[0.0, 0.0, 0.0, 0.0]])
    kw["utility"]["coverage_cone_deg"] = 30.0

    def credited(pose, **utility):
        u = dict(kw["utility"], **utility)
        c = _core.view_coverage(m, surface, pose, pose[0], **dict(kw, utility=u))
        e, w = np.asarray(c.elements), np.asarray(c.weights)
        return dict(zip(e[w > 0].tolist(), w[w > 0].tolist()))  # the slab (unknown cells: 0)

    def sample_face(squares):
        """Camera hits on the front face (x = 4.01), one at the centre of each of `squares`
        ((u, v): quarters along y and z) of every front cell."""
        cy, cz = np.meshgrid(np.arange(-5.9, 6.0, 0.2), np.arange(-3.9, 4.0, 0.2))
        hits = [
            np.column_stack(
                [
                    np.full(cy.size, 4.01),
                    cy.ravel() - 0.075 + 0.05 * u,
                    cz.ravel() - 0.075 + 0.05 * v,
                ]
            )
            for u, v in squares
        ]
        surface.add_points((3.9, 60.0, 0.0), np.vstack(hits))

    every = credited(pose)
    assert credited(pose, max_incidence_deg=20.0) == every  # no face sampled yet
    ruled = credited(pose, max_incidence_deg=20.0, incidence_min_patches=0)
    squares = [(u, v) for u in range(4) for v in range(4)]
    sample_face(squares[:15])
    assert credited(pose, max_incidence_deg=20.0) == every  # 15 of 16 squares: not yet dense
    sample_face(squares[15:])
    near = credited(pose, max_incidence_deg=20.0)
    assert near == ruled and credited(pose) == every
    assert len(every) > 300 and 0 < len(near) < len(every) / 2
    assert all(every[e] == w for e, w in near.items())
    # where the hits fell: in a front cell, all 16 squares seen along x, and along y and z the
    # quarter x = 0 (x = 4.01 in 4.0..4.2) by each quarter of the other axis
    patches = surface.patches_grid()
    front = patches[45, 30, 20]  # the cell at (4.1, 0.1, 0.1)
    assert int(front) == 0xFFFF | 0xF << 16 | 0xF << 32
    assert not patches[46, 30, 20] and np.count_nonzero(patches) == 60 * 40
    # the credited cells' centres, by the elements' cell ids (cell * 2 + side)
    lo, n = np.array([-5.0, -6.0, -4.0]), np.array([80, 60, 40])
    bricks = (n + 3) // 4

    def angle_deg(elements):
        cell = np.array(sorted(elements)) // 2
        b, r = cell >> 6, cell & 63
        ijk = np.column_stack(
            [
                4 * (b % bricks[0]) + (r & 3),
                4 * (b // bricks[0] % bricks[1]) + (r >> 2 & 3),
                4 * (b // (bricks[0] * bricks[1])) + (r >> 4),
            ]
        )
        c = lo + 0.2 * (ijk + 0.5)
        assert np.allclose(c[:, 0], 4.1, atol=0.11)  # the front face only: rays stop there
        return np.degrees(np.arctan2(np.hypot(c[:, 1], c[:, 2]), c[:, 0]))

    assert angle_deg(near).max() <= 20.0 + 2.0
    outside = angle_deg(set(every) - set(near))
    assert outside.min() >= 20.0 - 2.0 and outside.max() > 30.0
    turned = np.array([[0.0, 0.0, 0.0, math.radians(55.0)]])
    assert len(credited(turned)) > 100 and not credited(turned, max_incidence_deg=20.0)
    for bad in (
        dict(max_incidence_deg=0.0),
        dict(max_incidence_deg=95.0),
        dict(max_incidence_deg=float("nan")),
        dict(incidence_min_patches=-1),
        dict(incidence_min_patches=17),
    ):
        with pytest.raises(ValueError, match=next(iter(bad))):
            credited(pose, **bad)
    with pytest.raises(ValueError, match="max_incidence_deg"):
        load_config(overrides=["utility.max_incidence_deg=120"])


def test_the_coverage_memo_keeps_a_record_through_changes_outside_its_view_only():
    # A record holds while nothing within the view's frustum (its field of view out to
    # max_range) changes: hits behind the camera or beyond its range keep it; one within the
    # frustum drops it, even behind the wall its rays stop at (the memo does not know where they
    # stopped). Every call gives the arrays of a call without the memo.
    m, surface, kw = _unseen_wall(4.1)
    pose = np.array([[0.0, 0.0, 0.0, 0.0]])
    memo = _core.CoverageMemo()

    def call():
        a = _core.view_coverage(m, surface, pose, pose[0], memo=memo, **kw)
        b = _core.view_coverage(m, surface, pose, pose[0], **kw)
        for key in ("offsets", "elements", "weights", "status"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        return memo.stats()

    assert call()["walked"] == 1
    for outside in ([-3.5, 0.0, 0.0], [9.9, 0.0, 0.0], [2.0, 5.5, 0.0]):
        m.update_cells(np.array([outside]), occupied=True)
        stats = call()
        assert stats["stale"] == 0 and stats["walked"] == 1, outside
    m.update_cells(np.array([[6.0, 0.5, 0.3]]), occupied=True)  # behind the wall, in view
    assert call() == dict(reused=stats["reused"], walked=2, stale=1, evicted=0, estimated=0)


def test_the_coverage_memo_answers_as_walking_again():
    """view_coverage with a CoverageMemo gives the arrays of a call without one, call after call,
    while the map and the camera observations change between calls: a record is used only while
    no brick near its frustum has changed; another map clears it."""
    mesh = box_mesh((-1.5, -1.5, 0), (1.5, 1.5, 2.5))
    m = nbvkit.OccupancyMap(0.2, (-6, -6, 0), (6, 6, 5))
    cam = nbvkit.DepthCamera(mesh, max_range=8.0)
    surface = _core.SurfaceObservations(m)
    scan = cam.scan_pose([-5.0, 0.0, 1.5, 0.0])
    m.mark_free_segment((-5.0, 0.0, 1.5), (-5.0, 0.0, 1.5), 1.0)
    m.integrate(scan)
    surface.add_scan(scan)
    rng = np.random.default_rng(5)
    ring = np.linspace(0, 2 * np.pi, 17)  # a flight round the box: free space to view from
    path = np.column_stack([4.5 * np.cos(ring), 4.5 * np.sin(ring), np.full(17, 2.0)])
    for a, b in zip(path[:-1], path[1:]):
        m.mark_free_segment(a, b, 1.2)
    angle = rng.uniform(0, 2 * np.pi, 40)
    xy = 4.5 * np.column_stack([np.cos(angle), np.sin(angle)]) + rng.uniform(-0.5, 0.5, (40, 2))
    poses = np.column_stack([xy, rng.uniform(1.5, 2.5, 40), np.arctan2(-xy[:, 1], -xy[:, 0])])
    kw = dict(
        camera=_core.ViewCameraModel(rays_x=24, rays_y=18, max_range=8.0),
        utility=dict(name="surface", require_occupied=False),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
    )
    memo = _core.CoverageMemo(keep_calls=2)
    current = [-5.0, 0.0, 1.5, 0.0]
    # a memo held to half of what one call records drops records, and answers the same
    probe = _core.CoverageMemo()
    _core.view_coverage(m, surface, poses, current, memo=probe, **kw)
    capped = _core.CoverageMemo(keep_calls=2, max_bytes=probe.bytes // 2)

    def check(m, surface):
        a = _core.view_coverage(m, surface, poses, current, memo=memo, **kw)
        b = _core.view_coverage(m, surface, poses, current, **kw)
        c = _core.view_coverage(m, surface, poses, current, memo=capped, **kw)
        for key in ("offsets", "elements", "weights", "status"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
            np.testing.assert_array_equal(getattr(c, key), getattr(b, key))
        assert capped.bytes <= capped.max_bytes
        return a

    first = check(m, surface)
    assert (first.status == 0).sum() >= 10
    walked = memo.stats()["walked"]
    check(m, surface)  # nothing changed: every valid view from its record
    assert memo.stats() == dict(reused=walked, walked=walked, stale=0, evicted=0, estimated=0)
    held = capped.stats()
    assert held["evicted"] > 0 and 0 < held["reused"] < walked
    for pose in ([0.0, -5.0, 2.0, math.pi / 2], [5.0, 0.5, 1.0, math.pi]):
        scan = cam.scan_pose(pose)  # a frame changes the map and the observations near it
        m.integrate(scan)
        surface.add_scan(scan)
        check(m, surface)
        # hits in a corner of the workspace: the views whose rays pass near it walk again
        m.update_cells(rng.uniform([3.5, 3.5, 0.5], [5.5, 5.5, 4.5], (5, 3)), occupied=True)
        check(m, surface)
    stats = memo.stats()
    assert stats["reused"] > walked + 10 and stats["stale"] > 10
    assert memo.entries <= len(poses) and memo.bytes > 0
    # the same geometry, another map: nothing is taken from the first map's records
    other = nbvkit.OccupancyMap(0.2, (-6, -6, 0), (6, 6, 5))
    other.integrate(cam.scan_pose([-5.0, 0.0, 1.5, 0.0]))
    reused = memo.stats()["reused"]
    check(other, _core.SurfaceObservations(other))
    assert memo.stats()["reused"] == reused
    with pytest.raises(ValueError, match="keep_calls"):
        _core.CoverageMemo(keep_calls=0)


def _stranded_scene(cands, hole=None):
    """(map, patches, view_coverage of cands from (3, 3.1, 2.1)) over a 12 x 6 x 4 m map: known
    free air within 2.5 m of (2.5, 3, 2), unknown beyond, a wall at x = 10 and, with `hole`, a
    second wall at x = 6 holed round the line y = 3.1, z = 2.1 (a square `hole` m wide); patch 0
    on the far wall (weight 40), patch 1 behind the vehicle (10)."""
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (12, 6, 4))
    m.mark_free_segment((2.5, 3.0, 2.0), (2.5, 3.0, 2.0), 2.5)
    grid = [(y, z) for y in np.arange(0.1, 6, 0.2) for z in np.arange(0.1, 4, 0.2)]
    cells = [[10.1, y, z] for y, z in grid]
    if hole is not None:
        cells += [[6.1, y, z] for y, z in grid if max(abs(y - 3.1), abs(z - 2.1)) > hole / 2]
    m.update_cells(np.array(cells), occupied=True)
    patches = Patches(
        np.array([[10.0, 3.0, 2.0], [2.0, 3.0, 2.0]]), -np.eye(3)[[0, 0]], np.array([40.0, 10.0])
    )
    cov = _core.view_coverage(
        m,
        _core.SurfaceObservations(m),
        cands,
        [3.0, 3.1, 2.1, 0.0],
        camera=_core.ViewCameraModel(rays_x=13, rays_y=9, max_range=8.0),
        utility=dict(name="surface", require_occupied=False),
        validity=dict(collision_radius=0.8, blocked_path="plan"),
    )
    return m, patches, cov


def test_a_view_that_reaches_where_a_stranded_patchs_views_would_be_is_credited_with_it():
    # Known free air for x < 5, unknown beyond, a wall at x = 10. A patch on the wall can only be
    # looked at from the unknown air: its view at x = 8 fails the collision test for want of known
    # free space, the one at x = 9.6 because the wall is within its collision radius. A view at
    # x = 3 facing the wall reaches the cell at x = 8 (unknown space its frame would make known)
    # and is credited with access_weight x the patch's weight, once; the same view facing away
    # is not, and once credited to a chosen view the place is not credited again.

    cands = np.array(
        [
            [8.1, 3.1, 2.1, math.pi],
            [9.6, 3.1, 2.1, math.pi],
            [3.0, 3.1, 2.1, 0.0],
            [3.0, 3.1, 2.1, math.pi],
        ]
    )
    owner = np.array([0, 0, 1, 1])
    m, patches, cov = _stranded_scene(cands)
    assert cov.status.tolist() == [2, 2, 0, 0]
    cfg = Config().with_overrides(["tour.access_weight=0.5"])
    tour = get_generator("tour", cfg)
    world = _access_world(m, [3.0, 3.1, 2.1, 0.0])
    out, opens = tour._access(world, cov, cands, owner, patches)
    size = np.diff(cov.offsets)
    new_size = np.diff(out.offsets)
    assert new_size.tolist() == [0, 0, size[2] + 1, size[3]]
    last = out.offsets[3] - 1  # the facing view's extra element, after its own
    assert out.elements[last] > cov.elements.max() and out.weights[last] == 20.0
    keep = np.delete(np.arange(len(out.elements)), last)
    np.testing.assert_array_equal(out.elements[keep], cov.elements)
    assert list(opens) == [2] and len(opens[2]) == 1  # the cell at x = 8, not the one at 9.6
    tour.opened.update(opens[2])
    again, _ = tour._access(world, cov, cands, owner, patches)
    np.testing.assert_array_equal(again.offsets, cov.offsets)
    tour_off = get_generator("tour", Config())  # access weight 0: off
    off = tour_off._access(world, cov, cands, owner, patches)[0]
    np.testing.assert_array_equal(off.elements, cov.elements)


def _access_world(occupancy_map, pose):
    from types import SimpleNamespace

    lo, hi = (np.asarray(b, float) for b in occupancy_map.bounds)
    return SimpleNamespace(
        map=occupancy_map,
        state=SimpleNamespace(pose=np.asarray(pose, float)),
        workspace=SimpleNamespace(nav_min=lo, nav_max=hi),
    )


@pytest.mark.parametrize("gap, credited", [(1.0, False), (3.2, True)])
def test_a_stranded_place_behind_a_wall_with_a_gap_narrower_than_the_vehicle_is_not_credited(
    gap, credited
):
    # The scene above with a second wall at x = 6 between the vehicle and the stranded view's
    # place (x = 8), holed round the line of sight: the view's rays reach the place through the
    # hole either way, but the vehicle (0.8 m collision radius) could pass only the 3.2 m one.
    from nbvkit.planning.generators.access import reachable

    cands = np.array([[8.1, 3.1, 2.1, math.pi], [3.0, 3.1, 2.1, 0.0]])
    owner = np.array([0, 1])
    m, patches, cov = _stranded_scene(cands, hole=gap)
    assert cov.status.tolist() == [2, 0]
    place = m.storage_index(cands[:1, :3])[0]
    assert place in np.asarray(cov.elements) // 2  # the rays reach it through the hole
    world = _access_world(m, [3.0, 3.1, 2.1, 0.0])
    reach = reachable(world, 0.8)
    assert reach[15, 15, 10] and not reach[30, 2, 2]  # by the vehicle; in the wall at x = 6
    assert reach[40, 15, 10] == credited  # the stranded view's cell
    tour = get_generator("tour", Config().with_overrides(["tour.access_weight=0.5"]))
    out, opens = tour._access(world, cov, cands, owner, patches)
    assert (list(opens) == [1]) == credited
    assert len(out.elements) == len(cov.elements) + int(credited)


@pytest.mark.parametrize("far_corner", [True, False])
def test_exploration_targets_are_the_unknown_face_of_known_free_space_within_the_structure(
    far_corner,
):
    # A 5 m cube of 0.5 m cells: the half x < 2.5 m known free, the other half unknown, one
    # occupied cell in the free half's corner. With a second occupied cell on the unknown face's
    # far edge the structure's extent reaches past that face, and the targets are its 10 x 10
    # unknown cells at x = 2.75 m looking back at the free half (-x), less that occupied cell
    # and its two neighbours on the face (surface_targets' frontier). Without it the extent ends
    # at x = 0.75 m and no unknown space within it borders free space.
    m = _core.OccupancyMap(0.5, (0, 0, 0), (5, 5, 5))
    g = (np.arange(10) + 0.5) * 0.5
    cells = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    m.update_cells(cells[cells[:, 0] < 2.5], occupied=False)
    solid = [[0.25, 0.25, 0.25]] + ([[2.75, 4.75, 4.75]] if far_corner else [])
    m.update_cells(np.array(solid), occupied=True)
    t = exploration_targets(m)
    if not far_corner:
        assert len(t) == 0
        return
    assert len(t) == 97 and isinstance(t, _core.SurfaceTargets)
    assert (t.kind == 3).all()  # exploration
    assert (t.positions[:, 0] == 2.75).all()
    for beside in ([2.75, 4.75, 4.25], [2.75, 4.25, 4.75]):
        assert not np.isclose(t.positions, beside).all(axis=1).any()
    np.testing.assert_array_equal(t.normals, np.tile([-1.0, 0.0, 0.0], (97, 1)))
    np.testing.assert_array_equal(t.weight, np.ones(97))


def test_exploration_targets_within_a_distance_of_the_mapped_surface():
    # The cube above with both occupied cells: its box holds 97 targets on the face x = 2.75 m.
    # Within 1 m of an occupied cell only 3 remain, all beside the far corner's cell (2.75, 4.75,
    # 4.75): (4.25, 4.25) at 0.71 m, (4.75, 3.75) and (3.75, 4.75) at 1 m in (y, z) (its face
    # neighbours are surface_targets' frontier, not exploration targets); the near corner's cell
    # is farther than 2.5 m from the face.
    m = _core.OccupancyMap(0.5, (0, 0, 0), (5, 5, 5))
    g = (np.arange(10) + 0.5) * 0.5
    cells = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    m.update_cells(cells[cells[:, 0] < 2.5], occupied=False)
    m.update_cells(np.array([[0.25, 0.25, 0.25], [2.75, 4.75, 4.75]]), occupied=True)
    assert len(exploration_targets(m)) == 97
    t = exploration_targets(m, within=1.0)
    assert isinstance(t, _core.SurfaceTargets) and (t.kind == 3).all()
    got = sorted(map(tuple, t.positions[:, 1:].tolist()))
    assert got == [(3.75, 4.75), (4.25, 4.25), (4.75, 3.75)]
    np.testing.assert_array_equal(t.normals, np.tile([-1.0, 0.0, 0.0], (3, 1)))
    assert len(exploration_targets(m, within=0.4)) == 0


def test_near_surface_is_the_distance_to_the_occupied_cells_within_its_grid():
    # Random occupied cells and points: a point is kept when its distance to the nearest
    # occupied cell centre is within `within`, up to the grid of within / 4 (a quarter of
    # `within` times sqrt(3) either way); an empty map keeps nothing.
    rng = np.random.default_rng(5)
    m = _core.OccupancyMap(0.2, (-10, -10, 0), (10, 10, 6))
    solid = m.cell_center(rng.uniform((-9, -9, 0.5), (9, 9, 5.5), (40, 3)))
    pts = rng.uniform((-10, -10, 0), (10, 10, 6), (3000, 3))
    assert not _core.near_surface(m, pts, 3.0).any()
    m.update_cells(solid, occupied=True)
    for within in (1.0, 3.0):
        keep = _core.near_surface(m, pts, within)
        d = np.linalg.norm(pts[:, None] - solid[None], axis=2).min(axis=1)
        slack = within / 4 * np.sqrt(3)
        assert (d[keep] <= within + slack).all() and (d[~keep] >= within - slack).all()
        assert keep.any() and (~keep).any()


def test_near_surface_is_scipys_distance_transform_on_its_grid():
    # The reference: scipy's exact Euclidean distance transform of the occupied cells on the
    # grid of max(within / 4, resolution) that spans them and the points. Fewer points than
    # occupied cells (each point's ball searched) and more (each cell's ball filled) alike.
    from scipy import ndimage

    def reference(m, points, within):
        occupied = m.occupied_cells()
        step = max(within / 4.0, m.resolution)
        lo = np.minimum(occupied.min(axis=0), points.min(axis=0))
        hi = np.maximum(occupied.max(axis=0), points.max(axis=0))
        solid = np.zeros(np.floor((hi - lo) / step).astype(int) + 1, bool)
        solid[tuple(np.floor((occupied - lo) / step).astype(int).T)] = True
        distance = ndimage.distance_transform_edt(~solid, sampling=step)
        return distance[tuple(np.floor((points - lo) / step).astype(int).T)] <= within

    rng = np.random.default_rng(11)
    for cells, points in ((300, 40), (30, 4000)):
        for res in (0.1, 0.5):
            m = _core.OccupancyMap(res, (-10, -10, 0), (10, 10, 6))
            m.update_cells(rng.uniform((-9, -9, 0.5), (9, 9, 5.5), (cells, 3)), occupied=True)
            pts = rng.uniform((-12, -12, -1), (12, 12, 7), (points, 3))
            for within in (0.3, res, 2.0, 3.7):
                got = _core.near_surface(m, pts, within)
                np.testing.assert_array_equal(got, reference(m, pts, within))
    for within in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="within"):
            _core.near_surface(m, pts, within)
    with pytest.raises(ValueError, match="points"):
        _core.near_surface(m, [[0.0, np.inf, 1.0]], 1.0)
    with pytest.raises(ValueError, match="larger within"):  # a grid too big to hold
        _core.near_surface(m, [[5e4, 5e4, 5e4]], 0.4)


def test_append_elements_keeps_each_views_set_in_order():
    from nbvkit.planning.generators.access import append_elements

    cov = _core.CoverageSets(
        offsets=[0, 2, 2, 5],
        elements=[1, 3, 0, 4, 9],
        weights=np.array([1.0, 2.0, 3.0, 4.0, 5.0], np.float32),
        status=[0, 2, 0],
    )
    out = append_elements(cov, np.array([0, 0, 2]), np.array([10, 11, 12]), [0.1, 0.2, 0.3])
    assert isinstance(out, _core.CoverageSets)
    assert out.offsets.tolist() == [0, 4, 4, 8]
    assert out.elements.tolist() == [1, 3, 10, 11, 0, 4, 9, 12]
    np.testing.assert_allclose(out.weights, [1, 2, 0.1, 0.2, 3, 4, 5, 0.3], rtol=1e-6)
    assert out.status.tolist() == [0, 2, 0]
    np.testing.assert_allclose(out.gain, [3.3, 0.0, 12.3], rtol=1e-6)  # the valid views' sums
    # view_coverage's elements are int32: appended ones keep that type, or say they do not fit
    out = append_elements(cov, np.array([1]), np.array([2**31 - 1]), [1.0])
    assert out.elements.dtype == np.int32 and out.elements[2] == 2**31 - 1
    with pytest.raises(OverflowError, match="int32"):
        append_elements(cov, np.array([1]), np.array([2**31]), [1.0])


def test_append_elements_and_elements_in_cells_equal_a_plain_construction(monkeypatch):
    import nbvkit.planning.generators.access as access

    monkeypatch.setattr(access, "_CHUNK", 37)  # several chunks
    rng = np.random.default_rng(11)
    for _ in range(20):
        sizes = rng.integers(0, 9, size=rng.integers(1, 30))
        sets = [np.sort(rng.choice(200, size=k, replace=False)) for k in sizes]
        cov = _core.CoverageSets(
            offsets=np.concatenate([[0], np.cumsum(sizes)]),
            elements=np.concatenate(sets).astype(np.int32),
            weights=rng.random(sizes.sum()).astype(np.float32),
            status=np.zeros(len(sizes), np.int8),
        )
        cells = np.unique(rng.integers(0, 120, size=rng.integers(0, 40)))
        hit = access.elements_in_cells(cov.elements, cells)
        np.testing.assert_array_equal(hit, np.flatnonzero(np.isin(cov.elements // 2, cells)))
        views = np.sort(rng.integers(0, len(sizes), size=rng.integers(0, 12)))
        extra = 200 + np.arange(len(views))
        w = rng.random(len(views))
        out = access.append_elements(cov, views, extra, w)
        want_el, want_w = [], []  # each view's set, then its extras in the order given
        for v, s in enumerate(sets):
            o = cov.offsets[v]
            want_el += [*s, *extra[views == v]]
            want_w += [*cov.weights[o : o + len(s)], *w[views == v].astype(np.float32)]
        assert out.elements.tolist() == want_el and out.elements.dtype == np.int32
        assert out.weights.tolist() == want_w
        assert out.offsets.tolist() == [
            0,
            *np.cumsum(sizes + np.bincount(views, minlength=len(sizes))),
        ]


def test_the_vehicle_can_plan_its_way_back_along_its_own_flight():
    # Nothing sensed: the only known free space is the volume the vehicle swept (and the
    # take-off's, not made here). A* tests the collision sphere at cell centres, and a path off
    # the centres leaves every centre's sphere reaching past a corridor of the collision radius
    # into unknown cells: no way back. Widened by half a cell diagonal, the corridor holds the
    # cells the flight crossed, and the way back is found, no longer than the flight.
    mesh = box_mesh((-2, -2, 0), (2, 2, 4))
    legs = [(5.07, -5.11, 2.57, 0.0), (5.11, 5.03, 2.21, 0.0)]
    for widen in (False, True):
        over = ["progress=false", f"vehicle.widen_swept_volume={widen}"]
        m = Mission(Config().with_overrides(over + ["start_pose=[-4.93,-5.07,2.13,0.0]"]), mesh)
        w = m.world
        start = w.state.pose.copy()
        flown = sum(w.fly_to(np.array(p), "nbv") for p in legs)
        path = w.plan_path(start)
        if not widen:
            assert path is None
            continue
        assert path is not None
        np.testing.assert_allclose(path[0], w.state.pose[:3])
        np.testing.assert_allclose(path[-1], start[:3])
        assert np.linalg.norm(np.diff(path, axis=0), axis=1).sum() <= flown + 1e-9
        assert (w.map.state(path) == 0).all()  # waypoints in known free cells


def test_paths_to_one_goal_refuse_bad_input_by_name_and_answer_each_start():
    """plan_paths_to (many starts, one goal, one search): a ValueError naming what is wrong; no
    starts, no paths; a start in sight of the goal flies straight, one round a corner of an L
    corridor by a searched path, one in unknown space has none - each as plan_path answers."""
    m = _core.OccupancyMap(0.2, (0, 0, 0), (12, 12, 4))
    m.mark_free_segment((2, 2, 2), (10, 2, 2), 1.2)
    m.mark_free_segment((10, 2, 2), (10, 10, 2), 1.2)
    goal = (2.5, 2, 2)
    for starts, g, r, words in (
        ([[np.nan, 1, 1]], goal, 0.35, "starts contains NaN"),
        ([[1, 1]], goal, 0.35, "starts must have shape"),
        ([[3, 2, 2]], (np.inf, 1, 1), 0.35, "goal contains NaN"),
        ([[3, 2, 2]], goal, -1.0, "radius must be finite"),
    ):
        with pytest.raises(ValueError, match=words):
            _core.plan_paths_to(m, starts, g, r)
    assert _core.plan_paths_to(m, np.zeros((0, 3)), goal, 0.35).paths == []
    starts = np.array([[6, 2, 2], [10, 9.5, 2], [6, 8, 2]])
    found = _core.plan_paths_to(m, starts, goal, 0.35)
    for k, a in enumerate(starts):
        one = _core.plan_path(m, a, goal, 0.35)
        assert len(found.paths[k]) == len(one) if len(one) <= 2 else len(found.paths[k]) > 2
    assert [len(p) for p in found.paths][::2] == [2, 0]
    assert found.cells_cost[1] == pytest.approx(
        _core.search_path(m, starts[1], goal, 0.35).cells_cost
    )


def test_a_search_cut_short_by_its_cap_is_searched_again_when_the_view_is_reachable():
    # The way back along two legs flown through unknown space (as above) takes A* more than 5
    # expanded cells. With vehicle.path_expansions = 5 the first search fails; the view lies in
    # the vehicle's free component, so the selection searches again without the cap and flies
    # the same path as with the default cap.
    from nbvkit.planning.selection import Selector

    mesh = box_mesh((-2, -2, 0), (2, 2, 4))
    legs = [(5.07, -5.11, 2.57, 0.0), (5.11, 5.03, 2.21, 0.0)]
    paths = []
    for cap in (5, 200000):
        over = ["progress=false", f"vehicle.path_expansions={cap}"]
        m = Mission(Config().with_overrides(over + ["start_pose=[-4.93,-5.07,2.13,0.0]"]), mesh)
        w = m.world
        start = w.state.pose.copy()
        for p in legs:
            w.fly_to(np.array(p), "nbv")
        assert (w.plan_path(start) is None) == (cap == 5)
        sel = Selector(PlanningContext.of(m.config))
        sel.begin()
        one = np.ones(1)
        scores = {"status": np.zeros(1, np.int8), "gain": 1e9 * one, "utility": one}
        choice = sel.choose(w, start[None], scores)
        assert choice is not None and choice.path is not None
        paths.append(choice.path)
    np.testing.assert_array_equal(*paths)


def _looks_at(pose, point, vfov_deg=45.0):
    """(angle off the optical axis in elevation, horizontal bearing error), radians, of `point`
    seen from the (x, y, z, yaw, pitch) view (level mount)."""
    d = point - pose[:3]
    el = math.atan2(d[2], math.hypot(d[0], d[1]))  # elevation of the line of sight
    off = el - (-pose[4])  # against the optical axis' elevation (pitch > 0 looks down)
    bearing = math.remainder(math.atan2(d[1], d[0]) - pose[3], 2 * math.pi)
    return off, bearing


def test_the_gimbal_faces_a_roof_from_above_and_clamps_an_underside_at_its_limit():
    """Issue 33, placement contract: beside the level camera's views, an upward-facing patch is
    also looked at straight down from its stand-offs above it (one view each, pitch 90 deg); a
    downward-facing one cannot be faced head-on (the gimbal looks up 30 deg at most): its pitch
    is clamped at -30 deg and the patch is kept in the field of view from six azimuths; a wall,
    which the level camera faces head-on, gets the level views alone."""
    patches = Patches(
        centers=np.array([[0.0, 0, 3], [5, 5, 4], [-3, 0, 4]]),
        normals=np.array([[0.0, 0, 1], [0, 0, -1], [1.0, 0, 0]]),
        weights=np.ones(3),
    )
    level, level_owner = place_views(patches, _Cam, _Place)
    assert level.shape == (6 * 2 + 6 * 2 + 3 * 2, 4)  # the level camera's views stay (K, 4)
    assert place_views(patches, _Gimbal, _Place)[0].shape == level.shape  # placement.gimbal off
    poses, owner = place_views(patches, _Gimbal, _PlaceGimbal)
    assert poses.shape == (len(level) + 2 + 6 * 2, 5)
    assert np.array_equal(poses[poses[:, 4] == 0, :4], level)  # the level views, unchanged
    half = math.radians(45 / 2 - 4.0)
    for pose, i in zip(poses, owner):
        c = patches.centers[i]
        assert min(abs(np.linalg.norm(c - pose[:3]) - d) for d in (4.0, 6.0)) < 1e-9
        assert math.radians(-30) - 1e-12 <= pose[4] <= math.radians(90) + 1e-12
        off, bearing = _looks_at(pose, c)
        assert abs(off) <= half + 1e-9  # in the vertical field of view, margin kept
        if pose[4] == 0:
            continue
        if i == 0:  # the roof: straight above, looking straight down
            assert np.allclose(pose[:2], c[:2]) and pose[4] == pytest.approx(math.pi / 2)
        else:  # the underside: clamped at the gimbal's limit, looking up at it
            assert i == 1 and pose[4] == pytest.approx(math.radians(-30)) and pose[2] < c[2]
            assert abs(bearing) < 1e-9


def test_a_view_above_the_ceiling_is_brought_down_and_keeps_its_patch_in_view():
    """The roof's straight-down view above the navigation box's ceiling comes down to it and
    moves aside only as far as the clamped pitch's field of view needs."""
    patches = Patches(
        centers=np.array([[0.0, 0, 8]]), normals=np.array([[0.2, 0, 1.0]]), weights=np.ones(1)
    )
    patches.normals /= np.linalg.norm(patches.normals, axis=1)[:, None]
    box = (np.array([-20.0, -20, 0]), np.array([20.0, 20, 10]))
    poses, owner = place_views(patches, _Gimbal, _PlaceGimbal, box)
    for pose in poses:
        assert pose[2] <= 10.0 + 1e-9
        off, _ = _looks_at(pose, patches.centers[0])
        assert abs(off) <= math.radians(45 / 2 - 4.0) + 1e-9


def test_a_blocked_patch_is_looked_at_from_the_nearest_direction_that_can_fly_or_reported():
    """Issue 33, placement contract: patch 0's views all lie in a slab the vehicle cannot hold
    (|y| < 3.5 m: straight on, and 30 deg either side at 4 and 6 m); tilted 15 and 30 deg its
    views stay in the slab, tilted 45 deg sideways the far stand-off (6 m, y = +-4.24) leaves
    it: those two views are added, facing the patch. Patch 1 has feasible views and keeps
    exactly its own; patch 2 lies in a region nothing can hold and is reported."""
    patches = Patches(
        centers=np.array([[0.0, 0, 3], [0.0, 30, 3], [0.0, -60, 3]]),
        normals=np.array([[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]]),
        weights=np.ones(3),
    )

    def feasible(p):
        slab = (np.abs(p[:, 1]) < 3.5) & (np.abs(p[:, 1] - 30) > 12)
        return ~slab & (np.linalg.norm(p - patches.centers[2], axis=1) > 15)

    place = PlacementConfig(standoffs=(0.5, 0.75), fallback=True)  # _Place's, as a config
    poses, owner = place_views(patches, _Cam, place)
    out, out_owner, unplaced = refit_blocked(poses, owner, patches, _Cam, place, None, feasible)
    assert np.array_equal(out[: len(poses)], poses)  # the placed views stay, in order
    assert np.array_equal(out_owner[: len(poses)], owner)
    added, of = out[len(poses) :], out_owner[len(poses) :]
    assert list(unplaced) == [2]
    assert list(of) == [0, 0]
    assert np.all(feasible(added[:, :3]))
    for pose in added:
        to_view = pose[:3] - patches.centers[0]
        assert np.linalg.norm(to_view) == pytest.approx(6.0)
        tilt = math.degrees(math.acos(to_view @ patches.normals[0] / 6.0))
        assert tilt == pytest.approx(45.0)
        off, bearing = _looks_at(np.append(pose, 0.0), patches.centers[0])
        assert abs(off) < 1e-9 and abs(bearing) < 1e-9
    # nothing blocked: the views come back as they were, and no patch is reported
    same, same_owner, none = refit_blocked(poses, owner, patches, _Cam, place, None, _anywhere)
    assert np.array_equal(same, poses) and np.array_equal(same_owner, owner) and len(none) == 0


def _anywhere(p):
    return np.ones(len(p), bool)


def test_a_view_search_over_ever_new_rejected_proposals_ends():
    """A generator whose exclusive proposals are all rejected, each with new poses (inside the
    structure), is tried a bounded number of times: next_view answers "no_valid_viewpoint"
    rather than looping for ever."""
    from nbvkit.planning.parts import Proposal

    cfg = load_config(overrides=["max_iterations=0", *QUICK])
    m = Mission(cfg, mesh=box_mesh((-4, -3, 0), (4, 3, 5)))
    m.run()

    class Endless:
        calls = 0

        def propose(self, world):
            self.calls += 1  # a pose inside the box, a little different each time
            return Proposal(np.array([[1e-4 * self.calls, 0.0, 2.5, 0.0]]), "x", exclusive=True)

        def feedback(self, world, proposal, step):
            pass

    endless = Endless()
    m.planner.generators = [endless]
    assert m.planner.next_view(m.world) == "no_valid_viewpoint"
    assert endless.calls == 10_000


@pytest.mark.parametrize("radius", [30.0, 3.0])
def test_the_take_off_clearing_stops_short_of_the_structure(radius):
    """vehicle.start_clear_radius marks the start's surroundings free, never the structure:
    with a radius reaching past a box, the box's inside stays unknown (probability 0.5) and
    the free sphere stops a cell short of its nearest face; half way there is free."""
    cfg = load_config(overrides=[*QUICK, f"vehicle.start_clear_radius={radius}"])
    m = Mission(cfg, mesh=box_mesh((-2, -2, 0), (2, 2, 4)))
    w = m.world
    p = w.start_pose[:3]
    d = np.linalg.norm(p[:2]) - 2.0  # the start is beside the box, level with its middle
    assert 0 < d < radius or radius == 3.0
    w.take_off()
    inside = np.array([[0.0, 0.0, 2.0], [1.5, 0.0, 1.0], [0.0, -1.5, 3.0]])
    np.testing.assert_allclose(w.map.probability(inside), 0.5)
    toward = p - (p - [0.0, 0.0, p[2]]) / np.linalg.norm(p[:2]) * min(radius, d) * 0.5
    assert w.map.probability(toward[None])[0] < 0.5  # cleared, half way to the box
