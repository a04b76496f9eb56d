"""View utilities on analytic scenes: one ray along a row of cells with known states, where each
utility has a closed form (cpp/src/utilities/*.hpp)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import nbvkit
from nbvkit import _core
from nbvkit.config import load_config

RES = 0.2
LN2 = math.log(2.0)


def logodds(p):
    return math.log(p / (1 - p))


def sig(x):
    return 1.0 / (1.0 + math.exp(-x))


def h(p):
    return -(p * math.log(p) + (1 - p) * math.log(1 - p))


def cell_map(nx, cells, clamped_entropy_zero=False):
    """A 0.2 m map of nx x 5 x 5 cells; `cells` maps (i, j, k) to 'F' free after 2 misses, 'f'
    free after 1 miss, 'U' unknown, 'O' occupied after 1 hit, 'P' predicted at 0.6; every other
    cell is 'F'."""
    m = nbvkit.OccupancyMap(
        RES, (0, 0, 0), (RES * nx, RES * 5, RES * 5), clamped_entropy_zero=clamped_entropy_zero
    )
    center = lambda ijk: (np.asarray([ijk], float) + 0.5) * RES  # noqa: E731
    for ijk in ((i, j, k) for i in range(nx) for j in range(5) for k in range(5)):
        s = cells.get(ijk, "F")
        if s in "Ff":
            for _ in range(2 if s == "F" else 1):
                m.update_cells(center(ijk), occupied=False)
        elif s == "O":
            m.update_cells(center(ijk), occupied=True)
        elif s == "P":
            m.set_unknown_cells(center(ijk), 0.6)
    return m


def row_map(states, clamped_entropy_zero=False):
    """cell_map with `states` along the row (i, 2, 2), i = 0..; returns the map and the
    probabilities of the row's cells."""
    m = cell_map(
        len(states) + 1, {(i, 2, 2): s for i, s in enumerate(states)}, clamped_entropy_zero
    )
    probs = [
        float(m.probability((np.array([[i, 2, 2]]) + 0.5) * RES)[0]) for i in range(len(states))
    ]
    return m, probs


def score_row(m, name, max_cells, surface=None, **utility):
    """One ray from the centre of cell (0, 2, 2) along +x through max_cells cells."""
    cam = _core.ViewCameraModel(
        rays_x=1, rays_y=1, hfov_deg=1.0, vfov_deg=1.0, max_range=RES * (max_cells - 0.6)
    )  # ends inside the last cell
    s = _core.evaluate_views(
        m,
        [[0.5 * RES, 2.5 * RES, 2.5 * RES, 0.0]],
        [0.1, 0.5, 0.5, 0.0],
        camera=cam,
        utility=dict(name=name, require_occupied=False, **utility),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
        surface=surface,
    )
    assert s["status"][0] == 0
    return float(s["gain"][0])


def test_information_gain_sums_entropy_up_to_the_first_occupied_cell():
    m, p = row_map("FUfOU")
    expected = h(p[0]) + LN2 + h(p[2]) + h(p[3])  # the ray ends at the occupied cell
    assert score_row(m, "ig", 5) == pytest.approx(expected, rel=1e-6)


def test_occlusion_aware_gain_is_its_closed_form():
    m, p = row_map("FUfOUU")
    occ = [pi if s != "U" else 0.5 for pi, s in zip(p, "FUfOUU")]
    vis, expected = 1.0, 0.0
    for pi in occ:
        expected += vis * h(pi)
        vis *= 1 - pi  # P(visible) = product of the free probabilities before the cell
    assert score_row(m, "occlusion_aware", 6, min_visibility=1e-9) == pytest.approx(
        expected, rel=1e-6
    )


def test_unobserved_voxel_counts_visibility_of_unknown_cells():
    m, p = row_map("FUfUOU")
    occ = [0.5 if s == "U" else pi for pi, s in zip(p, "FUfUOU")]
    vis, expected = 1.0, 0.0
    for pi, s in zip(occ, "FUfUOU"):
        expected += vis if s == "U" else 0.0
        vis *= 1 - pi
    assert score_row(m, "unobserved_voxel", 6, min_visibility=1e-9) == pytest.approx(
        expected, rel=1e-6
    )


def test_rear_side_voxel_and_entropy_look_behind_the_first_surface():
    m, p = row_map("FfOUU")
    vis = (1 - p[0]) * (1 - p[1])  # the visibility of the occupied cell
    assert score_row(m, "rear_side_voxel", 5) == pytest.approx(vis, rel=1e-6)
    assert score_row(m, "rear_side_entropy", 5) == pytest.approx(vis * LN2, rel=1e-6)
    # a known cell behind the surface: no rear-side voxel, its (lower) entropy for rear-side entropy
    m2, p2 = row_map("FfOfU")
    assert score_row(m2, "rear_side_voxel", 5) == 0.0
    assert score_row(m2, "rear_side_entropy", 5) == pytest.approx(
        (1 - p2[0]) * (1 - p2[1]) * h(p2[3]), rel=1e-6
    )


def test_proximity_count_counts_unknown_cells_next_to_surface():
    m, p = row_map("FUUOU")  # cell 2 touches the occupied cell 3; cell 1 does not
    vis2 = (1 - p[0]) * 0.5  # visibility at cell 2 (behind cells 0 and 1) ...
    vis4 = vis2 * 0.5 * (1 - p[3])  # ... and at cell 4, behind the surface
    assert score_row(m, "proximity_count", 5, min_visibility=1e-9) == pytest.approx(
        vis2 + vis4, rel=1e-6
    )


def test_average_entropy_is_the_mean_over_traversed_cells():
    m, p = row_map("FUfOU")
    hs = [h(p[0]), LN2, h(p[2]), h(p[3])]
    assert score_row(m, "average_entropy", 5) == pytest.approx(np.mean(hs), rel=1e-6)


def test_four_term_utility_is_zero_with_one_occupied_cell():
    # log10(N_occ) with N_occ = 1: the ray ends at its occupied cell, the cell behind is not seen
    m, p = row_map("FUOPU")
    surface = _core.SurfaceObservations(m)
    surface.add_points([0.1, 0.5, 0.5], np.tile([[2.5 * RES, 2.5 * RES, 2.5 * RES]], (20, 1)))
    assert score_row(m, "four_term", 5, surface=surface) == 0.0


def test_four_term_terms_with_two_rays():
    # two rows, y = 2 and y = 3: free, unknown, then an observed occupied cell (20 camera hits)
    # ending one ray and a predicted cell ending the other
    m = cell_map(4, {(1, 2, 2): "U", (2, 2, 2): "O", (1, 3, 2): "U", (2, 3, 2): "P"})
    surface = _core.SurfaceObservations(m)
    surface.add_points([0.1, 0.5, 0.5], np.tile([[2.5 * RES, 2.5 * RES, 2.5 * RES]], (20, 1)))
    tan = 0.25  # the two rays leave at y slopes +-0.125 and stay in their rows to x = 0.6
    cam = _core.ViewCameraModel(
        rays_x=2, rays_y=1, hfov_deg=2 * math.degrees(math.atan(tan)), vfov_deg=1.0, max_range=0.5
    )
    s = _core.evaluate_views(
        m,
        [[0.1, 0.6, 0.5, 0.0]],
        [0.1, 0.6, 0.5, 0.0],
        camera=cam,
        utility=dict(
            name="four_term", require_occupied=False, distance_lambda=0.0, density_target=50.0
        ),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
        surface=surface,
    )
    assert s["status"][0] == 0 and s["cells"][0] == 2  # two occupied cells reached
    p_free = sig(2 * logodds(0.4))
    # reached: (0,2),(1,2),(2,2) and (0,3),(1,3),(2,3): 2 free, 2 unknown, 2 occupied
    h_mean = (2 * h(p_free) + 2 * LN2 + h(0.7) + h(0.6)) / 6
    n_occ, rho, p_hat = 2, 20 / 50.0, 0.5
    expected = math.log10(n_occ) * (1 + h_mean / LN2) * ((1 - rho) + p_hat)
    assert s["gain"][0] == pytest.approx(expected, rel=1e-5)


def test_surface_utility_credits_unseen_sides_predictions_and_frontier():
    # an occupied cell the camera has not seen: 1 (then the ray ends)
    m, p = row_map("FFOU", clamped_entropy_zero=True)
    surface = _core.SurfaceObservations(m)
    assert score_row(m, "surface", 4, surface=surface) == pytest.approx(1.0)
    # seen from the same side (a hit from the camera's side): nothing new
    surface.add_points([0.1, 0.5, 0.5], [[2.5 * RES, 2.5 * RES, 2.5 * RES]])
    assert score_row(m, "surface", 4, surface=surface) == pytest.approx(0.0)
    # seen only from the far side (+x): the camera's side is still new
    s2 = _core.SurfaceObservations(m)
    s2.add_points([2.0, 0.5, 0.5], [[2.5 * RES, 2.5 * RES, 2.5 * RES]])
    assert score_row(m, "surface", 4, surface=s2) == pytest.approx(1.0)
    # a predicted cell (p 0.6) then unknown cells: 0.6, then the prior through 1 - 0.6
    m3, p3 = row_map("FFPUU", clamped_entropy_zero=True)
    s3 = _core.SurfaceObservations(m3)
    fp, up = 0.5, 0.005
    # cell 3 touches the predicted cell (frontier prior), cell 4 does not (unknown prior)
    expected = 0.6 + 0.4 * fp + 0.4 * (1 - fp) * up
    assert score_row(
        m3, "surface", 5, surface=s3, frontier_prior=fp, unknown_prior=up, min_visibility=1e-9
    ) == pytest.approx(expected, rel=1e-6)


def test_surface_utility_weighs_a_credit_by_the_cameras_sampling_density():
    # A camera whose pixels are 5 deg apart, needing samples 0.01 m apart: a face-on cell is
    # sampled densely enough within k = 0.01 / (5 deg in rad) = 0.115 m. The ray starts at the
    # centre of cell 0 (x = 0.1) and enters cell 2 at x = 0.4, 0.3 m away, cell 3 0.5 m, 4 0.7 m.
    k = 0.01 / math.radians(5.0)

    def w(r, cos_i=1.0):
        return min(1.0, k * cos_i / r)

    def score(m, max_cells, **utility):
        cam = _core.ViewCameraModel(
            rays_x=1,
            rays_y=1,
            hfov_deg=1.0,
            vfov_deg=1.0,
            max_range=RES * (max_cells - 0.6),
            pixel_pitch_deg=5.0,
        )
        s = _core.evaluate_views(
            m,
            [[0.5 * RES, 2.5 * RES, 2.5 * RES, 0.0]],
            [0.1, 0.5, 0.5, 0.0],
            camera=cam,
            utility=dict(name="surface", require_occupied=False, min_visibility=1e-9, **utility),
            validity=dict(collision_radius=0.0, blocked_path="plan"),
            surface=_core.SurfaceObservations(m),
        )
        return float(s["gain"][0])

    # face on: cell 2's open faces (free neighbours) are -x and both of y and of z, which
    # cancel: its normal is -x, the ray's incidence 0
    face = cell_map(5, {(2, 2, 2): "O", (3, 2, 2): "O"}, clamped_entropy_zero=True)
    assert score(face, 4) == pytest.approx(1.0)  # no density weight by default
    assert score(face, 4, dense_spacing=0.01) == pytest.approx(w(0.3), rel=1e-9)
    assert score(face, 4, dense_spacing=1.0) == pytest.approx(1.0)  # dense enough: at most 1
    # open towards -x and +y only (+x and -y occupied): the normal is (-1, 1, 0) / sqrt(2),
    # 45 deg from the ray
    corner = cell_map(
        5, {(2, 2, 2): "O", (3, 2, 2): "O", (2, 1, 2): "O"}, clamped_entropy_zero=True
    )
    assert score(corner, 4, dense_spacing=0.01) == pytest.approx(w(0.3, math.sqrt(0.5)), rel=1e-9)
    # open on every side: no direction to measure incidence from, the range alone
    alone = cell_map(5, {(2, 2, 2): "O"}, clamped_entropy_zero=True)
    assert score(alone, 4, dense_spacing=0.01) == pytest.approx(w(0.3), rel=1e-9)
    # predicted and unknown cells: their surface probability, weighted by range alone
    m3, _ = row_map("FFPUU", clamped_entropy_zero=True)
    fp, up = 0.5, 0.005
    expected = 0.6 * w(0.3) + 0.4 * fp * w(0.5) + 0.4 * (1 - fp) * up * w(0.7)
    got = score(m3, 5, dense_spacing=0.01, frontier_prior=fp, unknown_prior=up)
    assert got == pytest.approx(expected, rel=1e-6)  # p = 0.6 held as float log-odds
    with pytest.raises(ValueError, match="dense_spacing"):
        score(face, 4, dense_spacing=-0.1)
    with pytest.raises(ValueError, match="pixel_pitch_deg"):
        _core.ViewCameraModel(pixel_pitch_deg=0.0)


def test_utilities_that_read_camera_observations_need_them():
    m, _ = row_map("FUO")
    with pytest.raises(ValueError, match="needs the camera observations"):
        score_row(m, "surface", 3)
    with pytest.raises(ValueError, match="unknown utility 'nope'"):
        score_row(m, "nope", 3)
    with pytest.raises(ValueError, match="frontier_prior"):
        score_row(m, "surface", 3, surface=_core.SurfaceObservations(m), frontier_prior=-1.0)
    with pytest.raises(ValueError, match="weight_density"):
        score_row(
            m, "four_term", 3, surface=_core.SurfaceObservations(m), weight_density=float("nan")
        )


@pytest.mark.parametrize("name", _core.utility_names())
def test_every_utility_scores_grid_and_octree_alike(name):
    m, _ = row_map("FUfOUfU")
    surface = _core.SurfaceObservations(m)
    cam = _core.ViewCameraModel(rays_x=5, rays_y=3, hfov_deg=20, vfov_deg=10, max_range=1.3)
    kw = dict(
        camera=cam,
        utility=dict(name=name, require_occupied=False, min_visibility=1e-9),
        validity=dict(collision_radius=0.0, blocked_path="plan"),
        surface=surface,
    )
    pose = [[0.5 * RES, 2.5 * RES, 2.5 * RES, 0.0]]
    a = _core.evaluate_views(m, pose, [0.1, 0.5, 0.5, 0.0], backend="grid", **kw)
    b = _core.evaluate_views(m, pose, [0.1, 0.5, 0.5, 0.0], backend="octree", **kw)
    np.testing.assert_allclose(a["gain"], b["gain"], rtol=1e-6)
    np.testing.assert_array_equal(a["cells"], b["cells"])


# ------------------------------------------------------------------ saturation


def _square_hits(x=0.1):
    """16 points at x in the cell [0, 0.2)^3, one in each 0.05 m square of its face along x."""
    q = (np.arange(4) + 0.5) * 0.05
    y, z = np.meshgrid(q, q, indexing="ij")
    return np.column_stack([np.full(16, x), y.ravel(), z.ravel()])


def test_a_cell_is_saturated_when_a_new_side_finds_no_new_square():
    m = _core.OccupancyMap(0.2, (-4, -4, -4), (4, 4, 4))
    s = _core.SurfaceObservations(m, saturation_hits=8)
    hits = _square_hits()
    front, side, top = (-3.0, 0.1, 0.1), (-3.0, 3.0, 0.1), (-3.0, 0.1, 3.0)
    s.add_points(front, hits)  # every square new
    s.add_points(front, hits)  # nothing new, but from the same side: not yet
    assert s.saturated_cells() == 0
    s.add_points(side, hits[:4])  # a new side finds no new square, with too few hits
    assert s.saturated_cells() == 0
    s.add_points(top, hits)  # a new side, 16 hits, every one in a square already hit
    assert s.saturated_cells() == 1
    # a scan that finds a square nobody had hit (another quarter of the cell along x) clears it
    s.add_points((-3.0, -3.0, 0.1), _square_hits(x=0.02)[:1])
    assert s.saturated_cells() == 0
    never = _core.SurfaceObservations(m)  # saturation_hits 0: never marked
    for o in (front, front, side, top):
        never.add_points(o, hits)
    assert never.saturated_cells() == 0 and never.saturation_hits == 0


def test_a_saturated_cell_is_no_target_and_earns_no_view_credit():
    # a wall cell seen from the front and then from a second side that found nothing new: with
    # saturation it leaves the surface targets and a view of it is credited nothing for it
    m = _core.OccupancyMap(0.2, (-4, -4, -4), (4, 4, 4))
    hits = _square_hits()
    view = np.array([[0.1, -3.0, 0.1, math.pi / 2]])  # from -y: a side none of the scans saw
    m.mark_free_segment(view[0, :3], (0.1, -0.35, 0.1), 0.3)  # known free up to the wall
    m.mark_free_segment((-3.0, 0.1, 0.1), (-0.35, 0.1, 0.1), 0.3)  # and in front of it
    m.update_cells(hits, occupied=True)
    plain, sat = _core.SurfaceObservations(m), _core.SurfaceObservations(m, saturation_hits=8)
    for s in (plain, sat):
        s.add_points((-3.0, 0.1, 0.1), hits)
        s.add_points((-3.0, 0.1, 3.0), hits)
    assert sat.saturated_cells() == 1
    opts = dict(frontier=False, predicted=False)
    t_plain, t_sat = (_core.surface_targets(m, s, opts) for s in (plain, sat))
    cell = m.cell_center(hits[:1])[0]
    assert (np.linalg.norm(t_plain.positions - cell, axis=1) < 1e-9).any()
    assert not (np.linalg.norm(t_sat.positions - cell, axis=1) < 1e-9).any()
    a, b = (
        _core.evaluate_views(m, view, view[0], utility=_core.UtilityOptions(name="surface"),
                             validity=_core.ValidityOptions(collision_radius=0.0), surface=s)
        for s in (plain, sat)
    )  # fmt: skip
    assert a["status"][0] == 0 and a["gain"][0] >= 1.0
    assert b["gain"][0] == pytest.approx(a["gain"][0] - 1.0)


def test_saturation_hits_out_of_range_is_refused():
    m = _core.OccupancyMap(0.2, (-4, -4, -4), (4, 4, 4))
    with pytest.raises(ValueError, match="saturation_hits"):
        _core.SurfaceObservations(m, saturation_hits=-1)
    with pytest.raises(ValueError, match="saturation_hits"):
        load_config(overrides=["utility.saturation_hits=-1"])


@pytest.mark.parametrize("utility", ["ig", "surface"])
def test_scorer_in_parts_scores_as_one_call(monkeypatch, utility):
    """A proposal longer than SCORE_CHUNK is scored in parts (so Ctrl-C stops it within a part):
    every array the same as one call over the whole proposal, in its order, the memo shared."""
    from conftest import seen_box_world
    from nbvkit.config import Config
    from nbvkit.planning import scoring

    world = seen_box_world()
    rng = np.random.default_rng(4)
    n = 157
    poses = np.column_stack(
        [rng.uniform(-9, 9, n), rng.uniform(-9, 9, n), rng.uniform(0.5, 8, n)]
        + [rng.uniform(-math.pi, math.pi, n), rng.uniform(-0.5, 1.2, n)]
    )
    cfg = Config().with_overrides([f"utility.name={utility}"]).utility
    one = scoring.Scorer(cfg)
    whole = one(world, poses)
    calls = []
    real = _core.evaluate_views
    monkeypatch.setattr(scoring, "SCORE_CHUNK", 10)  # 16 parts: more than the memo's 8 calls
    monkeypatch.setattr(
        scoring._core,
        "evaluate_views",
        lambda m, p, *a, **k: calls.append(len(p)) or real(m, p, *a, **k),
    )
    in_parts = scoring.Scorer(cfg)
    parts = in_parts(world, poses)
    assert calls == [10] * 15 + [7]
    assert set(parts) == set(whole)
    assert (whole["status"] == 0).any() and (whole["gain"] > 0).any()
    for k in whole:
        np.testing.assert_array_equal(parts[k], whole[k], err_msg=k)
    if utility != "ig":
        return  # the memo holds the ig walks only
    # the memo keeps its records over the proposals, as one call's does (each part is a call)
    for _ in range(3):
        one(world, poses), in_parts(world, poses)
    a, b = in_parts.memo.stats(), one.memo.stats()
    assert a["walked"] <= b["walked"] and a["reused"] >= b["reused"] > 0, (a, b)
