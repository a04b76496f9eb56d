"""OccupancyMap: analytic rays, entropy bookkeeping, agreement with OctoMap, predictions, files,
errors."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

import nbvkit
from conftest import ROOT, box_mesh
from nbvkit import CellFlag, CellState, OccupancyMap, OccupancyMapOptions

LN2 = math.log(2.0)


def h_nats(p: float) -> float:
    return -p * math.log(p) - (1 - p) * math.log(1 - p)


def logodds_f32(p: float) -> float:
    """OctoMap's log-odds, rounded to float32 as the octree stores it."""
    return float(np.float32(math.log(p / (1 - p))))


def p_of(logodds: float) -> float:
    return 1.0 - 1.0 / (1.0 + math.exp(logodds))


def small_map(**kw) -> OccupancyMap:
    return OccupancyMap(0.2, (-2, -2, -2), (6, 2, 2), **kw)


def touched_agreement(a: OccupancyMap, b: OccupancyMap) -> float:
    sa, sb = a.state_grid(), b.state_grid()
    touched = (sa != CellState.UNKNOWN) | (sb != CellState.UNKNOWN)
    assert touched.sum() > 0
    return float((sa[touched] == sb[touched]).mean())


@pytest.fixture(scope="module")
def box_scene_scans():
    """Camera frames of two boxes on the ground from a few poses (hits and free rays)."""
    v1, f1 = _box_arrays((-3, -2, 0), (3, 2, 3))
    v2, f2 = _box_arrays((4, 3, 0), (6, 6, 5))
    mesh = nbvkit.Mesh(np.vstack([v1, v2]), np.vstack([f1, f2 + len(v1)]).astype(np.int32))
    cam = nbvkit.DepthCamera(mesh)
    poses = [(-8.0, 0.5, 2.0, 0.0), (0.3, -7.0, 2.5, math.pi / 2), (9.0, 1.0, 3.0, math.pi - 0.3)]
    return [cam.scan_pose(p) for p in poses]


def _box_arrays(lo, hi):
    m = box_mesh(lo, hi)
    return np.asarray(m.vertices), np.asarray(m.faces)


# ---- analytic micro-scenes ------------------------------------------------------------------


@pytest.mark.parametrize("method", ["integrate", "integrate_exact"])
def test_one_ray_end_occupied_path_free_elsewhere_unknown(method):
    m = small_map()
    origin = (0.1, 0.1, 0.1)
    getattr(m, method)(origin, [[3.1, 0.1, 0.1]])
    xs = np.arange(0.1, 3.0, 0.2)  # cells 0..14 along +x: the origin cell up to the end cell
    path = np.c_[xs, np.full_like(xs, 0.1), np.full_like(xs, 0.1)]
    assert (m.state(path) == CellState.FREE).all()
    assert m.state([3.1, 0.1, 0.1]) == CellState.OCCUPIED
    assert m.state([3.3, 0.1, 0.1]) == CellState.UNKNOWN  # beyond the hit
    assert m.state([0.1, 1.1, 0.1]) == CellState.UNKNOWN  # elsewhere
    assert m.counts() == {"free": 15, "occupied": 1, "unknown": m.num_cells - 16, "predicted": 0}
    assert m.probability([3.1, 0.1, 0.1]) == pytest.approx(0.7, abs=1e-6)
    assert m.probability(path) == pytest.approx(np.full(15, 0.4), abs=1e-6)
    assert m.probability([0.1, 1.1, 0.1]) == 0.5


@pytest.mark.parametrize("method", ["integrate", "integrate_exact"])
def test_free_end_clears_its_end_cell_and_hit_wins_over_free(method):
    m = small_map()
    # a free ray along +x to x = 2.1 and a hit at x = 1.1 on the same line: the hit cell is
    # passed through by the free ray but counts as hit only, updated once
    getattr(m, method)((0.1, 0.1, 0.1), [[1.1, 0.1, 0.1]], [[2.1, 0.1, 0.1]])
    assert m.state([2.1, 0.1, 0.1]) == CellState.FREE  # the free end's own cell
    assert m.state([2.3, 0.1, 0.1]) == CellState.UNKNOWN
    assert m.probability([1.1, 0.1, 0.1]) == pytest.approx(0.7, abs=1e-6)
    assert m.counts()["free"] == 10 and m.counts()["occupied"] == 1


def test_ray_along_diagonal_through_cell_corners_matches_exact():
    # rays through grid corners are where DDA tie-breaking matters: the fast walker must pick the
    # same cells as OctoMap's computeRayKeys
    ends = [[2.0, 2.0 - 1e-7, 1.0], [1.0, 1.0, 1.0], [-1.6, 1.6, 0.8], [3.0, -1.0, -1.0]]
    for e in ends:
        a = small_map(deduplicate_end_points=False)
        b = small_map()
        a.integrate((0.0, 0.0, 0.0), [e])
        b.integrate_exact((0.0, 0.0, 0.0), [e])
        np.testing.assert_array_equal(a.state_grid(), b.state_grid())
        np.testing.assert_array_equal(a.log_odds_grid(), b.log_odds_grid())


def test_max_range_cuts_rays_like_octomap():
    for method in ("integrate", "integrate_exact"):
        m = small_map()
        getattr(m, method)((0.1, 0.1, 0.1), [[5.1, 0.1, 0.1]], [[0.1, 0.1, 1.5]], max_range=2.0)
        # the hit at 5 m is beyond max_range: cells up to (not including) the cell at 2 m are free,
        # its own cell is not marked occupied
        assert m.state([1.9, 0.1, 0.1]) == CellState.FREE
        assert m.state([2.1, 0.1, 0.1]) == CellState.UNKNOWN
        assert m.state([5.1, 0.1, 0.1]) == CellState.UNKNOWN
        assert m.state([0.1, 0.1, 1.5]) == CellState.FREE  # free end within range: end cell too
        assert m.counts()["occupied"] == 0


def test_cells_outside_workspace_live_in_octree_but_not_in_totals():
    clipped = OccupancyMap(0.2, (0, 0, 0), (2, 2, 2))  # the default: the workspace only
    clipped.integrate((1.1, 1.1, 1.1), [[5.1, 1.1, 1.1]])
    assert clipped.state([4.1, 1.1, 1.1]) == CellState.UNKNOWN
    assert clipped.counts() == {**clipped.counts(), "free": 5}
    m = OccupancyMap(0.2, (0, 0, 0), (2, 2, 2), clip_to_workspace=False)
    n = m.num_cells
    assert n == 1000
    m.integrate((1.1, 1.1, 1.1), [[5.1, 1.1, 1.1]])  # leaves the workspace at x = 2
    assert m.state([4.1, 1.1, 1.1]) == CellState.FREE  # outside, answered by the octree
    assert m.state([5.1, 1.1, 1.1]) == CellState.OCCUPIED
    c = m.counts()
    assert c["free"] == 5 and c["occupied"] == 0 and c["free"] + c["occupied"] + c["unknown"] == n
    assert m.in_workspace([[1.9, 1, 1], [2.0, 1, 1], [-1e-9, 1, 1]]).tolist() == [
        True,
        False,
        False,
    ]
    assert m.total_entropy() == pytest.approx(
        (n - 5) * LN2 + 5 * h_nats(p_of(logodds_f32(0.4))), rel=1e-12
    )


# ---- grid, keys, layout ---------------------------------------------------------------------


def test_default_workspace_is_papers_two_million_cells():
    m = OccupancyMap()
    assert m.resolution == 0.2
    assert m.shape == (200, 200, 50) and m.num_cells == 2_000_000
    lo, hi = m.bounds
    np.testing.assert_allclose(lo, [-20, -20, 0], atol=1e-12)
    np.testing.assert_allclose(hi, [20, 20, 10], atol=1e-12)
    assert m.min_key == (32768 - 100, 32768 - 100, 32768)


def test_bounds_snap_to_grid_and_cover_partial_cells():
    m = OccupancyMap(0.1, (-0.3, 0.0, 0.0), (0.3, 0.25, 0.1))  # 0.25 is mid-cell: covered
    assert m.shape == (6, 3, 1)
    np.testing.assert_allclose(m.bounds[1], [0.3, 0.3, 0.1], atol=1e-12)


def test_keys_and_centres_at_negative_coordinates_and_bounds_edges():
    m = OccupancyMap(0.2, (-1, -1, -1), (1, 1, 1))
    k = m.key([[-0.1, 0.1, -0.3], [0.0, -0.0, -1e-7]])
    assert k.dtype == np.int32
    assert k.tolist() == [[32767, 32768, 32766], [32768, 32768, 32767]]
    np.testing.assert_allclose(m.cell_center([-0.1, 0.1, -0.3]), [-0.1, 0.1, -0.3], atol=1e-12)
    np.testing.assert_allclose(m.cell_center([-0.39, 0.01, 0.2]), [-0.3, 0.1, 0.3], atol=1e-12)
    idx = m.index_of([[-1, -1, -1], [0.99, 0.99, 0.99], [1.0, 0, 0], [-1.0001, 0, 0]])
    assert idx.tolist() == [0, m.num_cells - 1, -1, -1]


def test_grid_layout_is_x_fastest_fortran_order():
    m = OccupancyMap(0.5, (0, 0, 0), (2, 1.5, 1))
    nx, ny, nz = m.shape
    assert (nx, ny, nz) == (4, 3, 2)
    p = np.array([1.25, 0.75, 0.25])  # cell (2, 1, 0)
    m.integrate((0.25, 0.75, 0.25), [p])
    g = m.state_grid()
    assert g.shape == (4, 3, 2) and g.flags.f_contiguous
    assert g[2, 1, 0] == CellState.OCCUPIED
    assert m.index_of(p) == 2 + nx * (1 + ny * 0)
    assert g.ravel(order="F")[m.index_of(p)] == CellState.OCCUPIED
    assert m.log_odds_grid()[2, 1, 0] == pytest.approx(logodds_f32(0.7))
    assert (
        m.flag_grid()[2, 1, 0] == CellFlag.OBSERVED and m.flag_grid()[0, 0, 1] == CellFlag.UNKNOWN
    )
    np.testing.assert_array_equal(m.occupied_cells(), [[1.25, 0.75, 0.25]])


def test_occupied_cells_lists_every_occupied_cell_in_grid_order():
    # a grid whose sides are not whole bricks (4 cells), with occupied cells scattered by rays
    m = OccupancyMap(0.25, (-1.3, -0.7, 0.0), (2.2, 1.9, 1.45))
    rng = np.random.default_rng(5)
    lo, hi = np.asarray(m.bounds[0]), np.asarray(m.bounds[1])
    for origin in rng.uniform(lo + 0.1, hi - 0.1, (6, 3)):
        m.integrate(origin, rng.uniform(lo + 0.01, hi - 0.01, (40, 3)))
    g = m.state_grid()  # (nx, ny, nz); C order of the cells is k, then j, then i fastest
    kji = np.argwhere(g.transpose(2, 1, 0) == CellState.OCCUPIED)
    expected = lo + (kji[:, ::-1] + 0.5) * m.resolution
    assert len(expected) > 20 and len(expected) < g.size / 2
    np.testing.assert_allclose(m.occupied_cells(), expected, atol=1e-9)


def test_query_shapes_are_preserved():
    m = small_map()
    pts = np.zeros((4, 5, 3))
    assert m.state(pts).shape == (4, 5) and m.state(pts).dtype == np.int8
    assert m.probability(pts).shape == (4, 5)
    assert m.entropy(pts).shape == (4, 5)
    assert m.cell_center(pts).shape == (4, 5, 3)
    assert m.state([0.0, 0.0, 0.0]).shape == ()
    assert m.state([]).shape == (0,)
    assert m.is_predicted(pts).dtype == bool


# ---- entropy --------------------------------------------------------------------------------


def test_empty_workspace_entropy_is_cells_ln2_and_one_bit_each():
    m = OccupancyMap()
    assert m.total_entropy() == pytest.approx(2_000_000 * LN2, rel=1e-15)
    assert m.recompute_total_entropy() == m.total_entropy()
    b = OccupancyMap(entropy_unit="bits")
    assert b.total_entropy() == 2_000_000
    assert b.entropy([0.1, 0.1, 0.1]) == 1.0
    assert m.entropy([0.1, 0.1, 0.1]) == pytest.approx(LN2)


def test_entropy_after_one_scan_is_the_analytic_sum(box_scene_scans):
    # From an empty map one scan updates every touched cell exactly once: free cells hold 0.4,
    # occupied ones 0.7. The total must be exactly that sum, and lower than before.
    for unit, scale in (("nats", 1.0), ("bits", 1 / LN2)):
        m = OccupancyMap(0.2, (-10, -10, 0), (10, 10, 6), entropy_unit=unit)
        before = m.total_entropy()
        m.integrate(box_scene_scans[0])
        c = m.counts()
        assert c["free"] > 1000 and c["occupied"] > 100
        expected = scale * (
            c["unknown"] * LN2
            + c["free"] * h_nats(p_of(logodds_f32(0.4)))
            + c["occupied"] * h_nats(p_of(logodds_f32(0.7)))
        )
        assert m.total_entropy() == pytest.approx(expected, rel=1e-12)
        assert m.total_entropy() < before


def test_clamped_cells_count_zero_entropy_unless_disabled():
    rays = [[3.1, 0.1, 0.1]] * 1
    m, plain = small_map(), small_map(clamped_entropy_zero=False)
    for _ in range(8):  # 8 misses clamp at 0.12, 8 hits clamp at 0.97
        m.integrate((0.1, 0.1, 0.1), rays)
        plain.integrate((0.1, 0.1, 0.1), rays)
    assert m.probability([1.1, 0.1, 0.1]) == pytest.approx(0.12, abs=1e-6)
    assert m.probability([3.1, 0.1, 0.1]) == pytest.approx(0.97, abs=1e-6)
    assert m.entropy([[1.1, 0.1, 0.1], [3.1, 0.1, 0.1]]).tolist() == [0.0, 0.0]
    assert m.total_entropy() == pytest.approx((m.num_cells - 16) * LN2, rel=1e-14)
    e = plain.entropy([[1.1, 0.1, 0.1], [3.1, 0.1, 0.1]])
    np.testing.assert_allclose(e, [h_nats(0.12), h_nats(0.97)], rtol=1e-5)
    assert plain.total_entropy() == pytest.approx(
        (m.num_cells - 16) * LN2 + 15 * e[0] + e[1], rel=1e-12
    )


def test_incremental_total_equals_recompute_after_many_random_scans():
    rng = np.random.default_rng(7)
    m = OccupancyMap(0.25, (-4, -4, -1), (4, 4, 3))
    for i in range(60):
        origin = rng.uniform([-5, -5, -2], [5, 5, 4])  # sometimes outside the workspace
        hits = origin + rng.normal(size=(200, 3)) * 3
        free = origin + rng.normal(size=(50, 3)) * 4
        if i % 3 == 0:
            m.integrate_exact(origin, hits, free, max_range=6.0)
        else:
            m.integrate(origin, hits, free)
        if i % 10 == 0:
            m.set_unknown_cells(rng.uniform([-4, -4, -1], [4, 4, 3], size=(30, 3)), 0.6)
    assert m.total_entropy() == m.recompute_total_entropy()
    assert m.counts() == m.recompute_counts()
    assert m.verify_mirror() == 0
    # and the mirror agrees with the octree's own answers: the grids against per-point queries
    lo, _ = m.bounds
    idx = np.argwhere(np.ones(m.shape, bool))
    centres = lo + (idx + 0.5) * m.resolution
    np.testing.assert_array_equal(m.state(centres), m.state_grid()[tuple(idx.T)])
    np.testing.assert_allclose(m.entropy(centres), m.entropy_grid()[tuple(idx.T)], rtol=1e-6)


# ---- fast path against OctoMap --------------------------------------------------------------


def test_fast_integrate_agrees_with_plain_octomap_on_camera_frames(box_scene_scans):
    fast = OccupancyMap(0.2, (-12, -12, 0), (12, 12, 8))
    exact = OccupancyMap(0.2, (-12, -12, 0), (12, 12, 8))
    for scan in box_scene_scans:
        st = fast.integrate(scan)
        exact.integrate_exact(scan)
        assert st.rays == 640 * 480 and st.traced_rays < st.rays / 10
        assert touched_agreement(fast, exact) >= 0.99
    assert fast.verify_mirror() == 0 and exact.verify_mirror() == 0


def test_fast_integrate_agrees_on_airliner_frame():
    path = ROOT / "meshes" / "airliner.obj"
    if not path.exists():
        pytest.skip("meshes/airliner.obj not generated")
    cam = nbvkit.DepthCamera(nbvkit.load_mesh(str(path)))
    scan = cam.scan_pose((7.07, 7.07, 4.0, math.radians(225)))
    fast, exact = OccupancyMap(), OccupancyMap()
    fast.integrate(scan)
    exact.integrate_exact(scan)
    assert touched_agreement(fast, exact) >= 0.99


def test_without_deduplication_fast_path_equals_octomap_exactly(box_scene_scans):
    # Tracing every ray, the parallel walker + stamp merge + batched tree update must give the
    # very same octree values as OctoMap's computeUpdate + updateNode loop.
    fast = OccupancyMap(0.2, (-12, -12, 0), (12, 12, 8), deduplicate_end_points=False)
    exact = OccupancyMap(0.2, (-12, -12, 0), (12, 12, 8))
    for scan in box_scene_scans[:2]:
        fast.integrate(scan, max_range=6.0)
        exact.integrate_exact(scan, max_range=6.0)
    np.testing.assert_array_equal(fast.log_odds_grid(), exact.log_odds_grid())
    np.testing.assert_array_equal(fast.flag_grid(), exact.flag_grid())
    assert fast.total_entropy() == exact.total_entropy()


# ---- predictions ----------------------------------------------------------------------------


def test_set_unknown_cells_sets_only_unknown_cells_and_observation_overrides():
    m = small_map()
    m.integrate((0.1, 0.1, 0.1), [[1.1, 0.1, 0.1]])  # cells x 0.1..0.9 free, 1.1 occupied
    pts = [
        [0.5, 0.1, 0.1],  # observed free: untouched
        [1.1, 0.1, 0.1],  # observed occupied: untouched
        [2.1, 0.1, 0.1],
        [2.15, 0.12, 0.05],  # one unknown cell, twice
        [2.1, 1.1, 0.1],  # another unknown cell
        [50.0, 0.0, 0.0],
    ]  # outside the workspace: ignored
    h0 = m.total_entropy()
    assert m.set_unknown_cells(pts, 0.6) == 2
    assert m.probability([0.5, 0.1, 0.1]) == pytest.approx(0.4, abs=1e-6)
    assert m.probability([1.1, 0.1, 0.1]) == pytest.approx(0.7, abs=1e-6)
    assert m.probability([[2.1, 0.1, 0.1], [2.1, 1.1, 0.1]]) == pytest.approx([0.6, 0.6], abs=1e-6)
    assert m.state([2.1, 0.1, 0.1]) == CellState.OCCUPIED  # 0.6 >= threshold 0.6
    assert m.is_predicted([[2.1, 0.1, 0.1], [0.5, 0.1, 0.1]]).tolist() == [True, False]
    assert m.state([50.0, 0.0, 0.0]) == CellState.UNKNOWN
    c = m.counts()
    assert c["predicted"] == 2 and c["occupied"] == 3
    assert m.total_entropy() == pytest.approx(
        h0 - 2 * LN2 + 2 * h_nats(p_of(logodds_f32(0.6))), rel=1e-12
    )
    # a ray through one predicted cell and a hit on the other: both restart from unknown
    m.integrate((0.1, 1.1, 0.1), [[2.1, 1.1, 0.1]], [[3.1, 0.1 + 1e-3, 0.1]])
    m.integrate((2.1, -1.5, 0.1), [], [[2.1, 0.3, 0.1]])
    assert m.probability([2.1, 1.1, 0.1]) == pytest.approx(
        0.7, abs=1e-6
    )  # not 0.6 combined with a hit
    assert m.probability([2.1, 0.1, 0.1]) == pytest.approx(
        0.4, abs=1e-6
    )  # not 0.6 combined with a miss
    assert not m.is_predicted([[2.1, 0.1, 0.1], [2.1, 1.1, 0.1]]).any()
    assert m.counts()["predicted"] == 0
    assert m.set_unknown_cells([[2.1, 0.1, 0.1]]) == 0  # observed now
    assert m.total_entropy() == m.recompute_total_entropy() and m.verify_mirror() == 0


def test_update_cells_clears_cells_once():
    m = small_map()
    n = m.update_cells([[0.1, 0.1, 0.1], [0.15, 0.12, 0.1], [0.5, 0.1, 0.1]])
    assert n == 2
    assert m.probability([[0.1, 0.1, 0.1], [0.5, 0.1, 0.1]]) == pytest.approx([0.4, 0.4], abs=1e-6)
    assert m.update_cells([[0.5, 0.1, 0.1]], occupied=True) == 1
    assert m.probability([0.5, 0.1, 0.1]) == pytest.approx(
        p_of(logodds_f32(0.4) + logodds_f32(0.7)), abs=1e-6
    )


def test_mark_free_segment_clears_a_capsule_of_unknown_cells_only():
    m = small_map()
    n = m.mark_free_segment((0.1, 0.1, 0.1), (2.1, 0.1, 0.1), 0.25)
    # cells touching the 0.25 m capsule around the x-axis segment through cell centres at
    # y = z = 0.1: a 3 x 3 cross-section (the side and diagonal neighbours are 0.1 and 0.14 m
    # away, the next ones 0.3 m) along the 11 cells of the segment plus one cap cell each end
    assert n == 13 * 9
    assert m.counts()["free"] == 117
    assert m.state(
        [[1.1, 0.3, 0.3], [1.1, 0.5, 0.1], [2.3, 0.1, 0.1], [2.5, 0.1, 0.1]]
    ).tolist() == [0, -1, 0, -1]
    # repeating it changes nothing: observed cells are left alone (their entropy stays put)
    e = m.total_entropy()
    assert m.mark_free_segment((0.1, 0.1, 0.1), (2.1, 0.1, 0.1), 0.25) == 0
    assert m.total_entropy() == e
    assert m.mark_free_segment((-1.1, 0.1, 0.1), (-1.1, 0.1, 0.1), 0.0) == 1


# ---- files ----------------------------------------------------------------------------------


def test_save_load_roundtrip_ot_and_bt(tmp_path: Path, box_scene_scans):
    m = OccupancyMap(0.2, (-12, -12, 0), (12, 12, 8))
    for s in box_scene_scans:
        m.integrate(s)
    for _ in range(6):  # clamp a region so OctoMap prunes it into coarse leaves
        m.integrate(box_scene_scans[0])
    m.save(tmp_path / "map.ot")
    m.save(str(tmp_path / "map.bt"))
    for name in ("map.ot", "map.bt"):
        r = OccupancyMap.load(tmp_path / name, bounds_min=(-12, -12, 0), bounds_max=(12, 12, 8))
        assert r.shape == m.shape and r.resolution == pytest.approx(0.2)
        np.testing.assert_array_equal(r.state_grid(), m.state_grid())
        assert r.verify_mirror() == 0 and r.counts() == m.counts()
        assert r.total_entropy() == r.recompute_total_entropy()
    r = OccupancyMap.load(tmp_path / "map.ot", bounds_min=(-12, -12, 0), bounds_max=(12, 12, 8))
    np.testing.assert_array_equal(r.log_odds_grid(), m.log_odds_grid())  # .ot keeps probabilities
    assert r.total_entropy() == m.total_entropy()
    # without bounds: the tree's bounding box
    r = OccupancyMap.load(tmp_path / "map.ot")
    lo, hi = r.bounds
    assert (lo <= m.occupied_cells().min(axis=0)).all() and (
        hi >= m.occupied_cells().max(axis=0)
    ).all()
    np.testing.assert_array_equal(r.state(m.occupied_cells()), CellState.OCCUPIED)


def test_load_errors(tmp_path: Path):
    with pytest.raises(FileNotFoundError) as e:
        OccupancyMap.load(tmp_path / "missing.ot")
    assert "missing.ot" in str(e.value)
    bad = tmp_path / "garbage.ot"
    bad.write_text("not an octree\n")
    with pytest.raises(ValueError, match="garbage.ot"):
        OccupancyMap.load(bad)
    badbt = tmp_path / "garbage.bt"
    badbt.write_bytes(b"\x00\x01 nonsense")
    with pytest.raises(ValueError, match="garbage.bt"):
        OccupancyMap.load(badbt)
    other = tmp_path / "map.xyz"
    other.write_text("x")
    with pytest.raises(ValueError, match="map.xyz"):
        OccupancyMap.load(other)
    with pytest.raises(ValueError, match="extension"):
        small_map().save(tmp_path / "map.ply")
    empty = tmp_path / "empty.ot"
    small_map().save(empty)
    with pytest.raises(ValueError, match="bounds"):
        OccupancyMap.load(empty)
    assert OccupancyMap.load(empty, (0, 0, 0), (1, 1, 1)).counts()["unknown"] == 125


@pytest.mark.parametrize("ext", [".ot", ".bt"])
def test_a_damaged_map_file_is_refused_not_loaded_as_another_map(tmp_path: Path, ext):
    # OctoMap's readers check neither the node count nor the stream's end: a file cut short
    # loaded as a smaller map (3 cells turned unknown), a NaN log-odds as a free cell (the
    # entropy -1.15e9), a 1e-9 m resolution gave bounds of +-4.5e31 m; a named pipe blocked.
    m = OccupancyMap(0.2, (-3, -3, 0), (3, 3, 3))
    hits = np.random.default_rng(0).uniform((-2.5, -2.5, 0.2), (2.5, 2.5, 2.8), (500, 3))
    m.integrate((0, 0, 1.5), hits)
    path = tmp_path / f"m{ext}"
    m.save(path)
    data = path.read_bytes()
    n = int(data.split(b"size ")[1].split(b"\n")[0])
    assert OccupancyMap.load(path, (-3, -3, 0), (3, 3, 3)).counts() == m.counts()  # whole: the map
    start = data.index(b"data\n") + 5
    damaged = {
        "cut": (data[:-1], f"ends in node {n - (ext == '.bt')} of the {n} its header counts"),
        "half": (data[: len(data) // 2], "its header counts: a truncated file"),
        "padded": (data + b"\0", f"goes on after its last node \\({n} nodes\\)"),
        "recounted": (
            data.replace(b"size ", b"size 1", 1),
            f"holds {n} nodes where its header counts 1{n}",
        ),
        "res": (data.replace(b"res 0.2", b"res 1e-09"), r"must be within \[0.0001, 100\] m"),
    }
    if ext == ".ot":  # the root's log-odds
        nan = np.float32(np.nan).tobytes()
        damaged["nan"] = (data[:start] + nan + data[start + 4 :], "log-odds value of nan")
    for name, (content, needle) in damaged.items():
        bad = tmp_path / f"{name}{ext}"
        bad.write_bytes(content)
        with pytest.raises(ValueError, match=f"{name}{ext}'.* {needle}"):
            OccupancyMap.load(bad)
    if ext == ".ot":  # another tree type: its nodes hold more than a log-odds
        other = tmp_path / "color.ot"
        other.write_bytes(data.replace(b"id OcTree", b"id ColorOcTree"))
        with pytest.raises(ValueError, match="holds a ColorOcTree, not an OcTree"):
            OccupancyMap.load(other)
    else:  # the root's child 0 inner (code 11), itself without children: log-odds -FLT_MAX
        hollow = tmp_path / "hollow.bt"
        hollow.write_bytes(data[:start].replace(f"size {n}".encode(), b"size 2") + b"\x03\0\0\0")
        with pytest.raises(ValueError, match="has an inner node without children"):
            OccupancyMap.load(hollow)
    fifo = tmp_path / f"pipe{ext}"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="is not a regular file"):
        OccupancyMap.load(fifo)
    folder = tmp_path / f"folder{ext}"
    folder.mkdir()
    with pytest.raises(ValueError, match=f"map file '.*folder{ext}' is a directory"):
        OccupancyMap.load(folder)


# ---- options and bad input ------------------------------------------------------------------


def test_options_defaults_and_overrides():
    o = OccupancyMapOptions()
    assert (o.prob_hit, o.prob_miss, o.clamp_min, o.clamp_max) == (0.7, 0.4, 0.12, 0.97)
    assert o.occupancy_threshold == 0.6 and o.entropy_unit == "nats" and o.clamped_entropy_zero
    assert o.deduplicate_end_points and o.end_point_subdivision == 2
    m = OccupancyMap(0.2, (0, 0, 0), (1, 1, 1), options=o, entropy_unit="bits")
    assert m.entropy_unit == "bits" and m.options.prob_hit == 0.7
    m = OccupancyMap(0.2, (0, 0, 0), (1, 1, 1), options={"occupancy_threshold": 0.8})
    assert m.options.occupancy_threshold == 0.8
    m.integrate((0.1, 0.1, 0.1), [[0.9, 0.1, 0.1]])
    assert m.state([0.9, 0.1, 0.1]) == CellState.FREE  # 0.7 < 0.8


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(resolution=0.0),
        dict(resolution=-0.2),
        dict(resolution=float("nan")),
        dict(resolution=float("inf")),
        dict(bounds_min=(0, 0, float("nan"))),
        dict(bounds_max=(1, 1, float("inf"))),
        dict(bounds_min=(0, 0, 0), bounds_max=(1, 0, 1)),
        dict(bounds_min=(0, 0)),
        dict(resolution=0.001, bounds_min=(-20, -20, 0), bounds_max=(20, 20, 10)),  # 1.6e13 cells
        dict(
            resolution=0.2, bounds_min=(-1e5, 0, 0), bounds_max=(0, 1, 1)
        ),  # beyond OctoMap's range
        dict(prob_hit=0.3),
        dict(prob_miss=0.6),
        dict(clamp_min=0.0),
        dict(clamp_max=1.0),
        dict(occupancy_threshold=1.0),
        dict(entropy_unit="shannons"),
        dict(end_point_subdivision=0),
        dict(end_point_subdivision=5),
    ],
)
def test_constructor_rejects_bad_values(kwargs):
    args = dict(resolution=0.2, bounds_min=(0, 0, 0), bounds_max=(1, 1, 1))
    args.update(kwargs)
    with pytest.raises(ValueError):
        OccupancyMap(args.pop("resolution"), args.pop("bounds_min"), args.pop("bounds_max"), **args)


def test_unknown_option_is_rejected_by_name():
    with pytest.raises(ValueError, match="prob_hitt"):
        OccupancyMap(0.2, (0, 0, 0), (1, 1, 1), prob_hitt=0.7)
    with pytest.raises(ValueError, match="colour"):
        OccupancyMap(0.2, (0, 0, 0), (1, 1, 1), options={"colour": 1})


def test_bad_input_for_every_entry_point(box_scene_scans):
    m = small_map()
    nan3 = [[0.0, float("nan"), 0.0]]
    bad_shape = np.zeros((4, 2))
    for method in (m.integrate, m.integrate_exact):
        with pytest.raises(ValueError, match="NaN"):
            method((0, 0, 0), nan3)
        with pytest.raises(ValueError, match="NaN"):
            method((0, 0, 0), [[1.0, 0, 0]], [[float("inf"), 0, 0]])
        with pytest.raises(ValueError, match="origin"):
            method((0, float("nan"), 0), [[1.0, 0, 0]])
        with pytest.raises(ValueError, match="shape"):
            method((0, 0, 0), bad_shape)
        with pytest.raises(ValueError, match="origin"):
            method((0, 0), [[1.0, 0, 0]])
        with pytest.raises(ValueError, match="max_range"):
            method((0, 0, 0), [[1.0, 0, 0]], max_range=0.0)
        with pytest.raises(ValueError, match="max_range"):
            method((0, 0, 0), [[1.0, 0, 0]], max_range=float("nan"))
        with pytest.raises(ValueError):
            method((0, 0, 0))  # neither a Scan nor hits
        with pytest.raises(TypeError):
            method(box_scene_scans[0], [[1.0, 0, 0]])  # a Scan and hits
        with pytest.raises(ValueError, match="origin"):
            method((1e9, 0, 0), [[1.0, 0, 0]])  # beyond OctoMap's addressable range
        # finite, but infinite in OctoMap's single precision: the exact path dropped the ray
        with pytest.raises(ValueError, match="free-space ray ends lie beyond"):
            method((0, 0, 0), [[1.0, 0, 0]], [[1e300, 0, 0]])
        with pytest.raises(ValueError, match="hit points lie beyond"):
            method((0, 0, 0), [[1.0, 0, 0], [0, -2e9, 0]])
    for query in (
        m.state,
        m.probability,
        m.entropy,
        m.is_predicted,
        m.cell_center,
        m.key,
        m.index_of,
        m.in_workspace,
    ):
        with pytest.raises(ValueError, match="NaN"):
            query(nan3)
        with pytest.raises(ValueError, match="shape"):
            query(bad_shape)
        with pytest.raises(ValueError):
            query(None)
    with pytest.raises(ValueError, match="range"):
        m.key([[1e9, 0, 0]])
    with pytest.raises(ValueError, match="NaN"):
        m.set_unknown_cells(nan3)
    with pytest.raises(ValueError, match="shape"):
        m.set_unknown_cells(bad_shape)
    for p in (0.0, 1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="probability"):
            m.set_unknown_cells([[0.0, 0.0, 0.0]], p)
    with pytest.raises(ValueError, match="NaN"):
        m.update_cells(nan3)
    with pytest.raises(ValueError, match="radius"):
        m.mark_free_segment((0, 0, 0), (1, 0, 0), -1.0)
    with pytest.raises(ValueError, match="NaN"):
        m.mark_free_segment((0, float("nan"), 0), (1, 0, 0), 0.5)
    # nothing above changed the map
    assert m.counts()["unknown"] == m.num_cells
    assert m.total_entropy() == pytest.approx(m.num_cells * LN2, rel=1e-15)


def test_storage_index_names_each_cell_once_by_its_brick():
    # a 15 x 10 x 5 grid is stored in bricks of 4 x 4 x 4 cells (4 x 3 x 2 of them, padded):
    # each cell has its own id below 64 x 24, the cells of one brick share id // 64, -1 outside
    m = nbvkit.OccupancyMap(0.2, (0, 0, 0), (3.0, 2.0, 1.0))
    nx, ny, nz = m.shape
    ijk = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    centres = (ijk.reshape(-1, 3) + 0.5) * 0.2
    ids = m.storage_index(centres)
    assert len(np.unique(ids)) == nx * ny * nz and ids.min() >= 0 and ids.max() < 64 * 4 * 3 * 2
    brick = ijk.reshape(-1, 3) // 4
    np.testing.assert_array_equal(ids // 64, brick[:, 0] + 4 * (brick[:, 1] + 3 * brick[:, 2]))
    assert m.storage_index([[-1.0, 0.5, 0.5], [0.5, 0.5, 5.0]]).tolist() == [-1, -1]
