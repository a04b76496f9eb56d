"""Regions of a large workspace (issue 37): the grid, the order a tour takes them in, the pass
over them, and the patch size that follows the camera."""
from __future__ import annotations

import numpy as np
import pytest

from nbvkit.config import load_config
from nbvkit.planning.generators.regions import Regions
from nbvkit.workspace import is_large
from nbvkit.planning.generators.exploration import exploration_targets
from nbvkit.workspace import Workspace


def _workspace(lo, hi) -> Workspace:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Workspace(lo, hi, lo + 0.5, hi - 0.5)


def test_the_grid_has_equal_regions_no_longer_than_the_size():
    r = Regions((-10, 0, 0), (110, 50, 12), 48.0)
    assert r.shape.tolist() == [3, 2, 1] and r.count == 6
    assert np.allclose(r.cell, [40.0, 25.0, 12.0])
    ids = r.ids([[-10, 0, 0], [29.9, 24.9, 5], [30.1, 25.1, 5], [109.9, 49.9, 11.9], [500, -9, 99]])
    # row-major over (3, 2, 1): region (i, j) is 2 i + j; points outside are clipped in
    assert ids.tolist() == [0, 0, 3, 5, 4]


def test_large_workspaces_are_those_longer_than_six_camera_ranges_and_regions_are_opt_in():
    cam = load_config().camera  # the paper's 8 m camera: large beyond 48 m
    aircraft = _workspace((-22.5, -22.5, 0), (22.5, 22.5, 10))  # the airliner's 45 m
    plant = _workspace((0, 0, 0), (110, 110, 50))
    assert not is_large(aircraft, cam) and is_large(plant, cam)
    wide = load_config(overrides=["camera.preset=inspection"]).camera  # 24 m: beyond 144 m
    assert not is_large(plant, wide)
    assert Regions.of(plant, None) is None  # regions only when tour.region_size is set
    assert Regions.of(plant, 48.0).shape.tolist() == [3, 3, 2]
    assert Regions.of(aircraft, 48.0) is None  # one region


def test_the_current_region_goes_first_then_a_tour_over_the_rest():
    r = Regions((0, 0, 0), (100, 10, 10), 10.0)  # ten regions along x
    centers = np.array([[5.0, 5, 5], [95, 5, 5], [45, 5, 5], [25, 5, 5], [65, 5, 5]])
    weights = np.array([10.0, 10, 10, 10, 0.5])
    here = [50.0, 5, 5]
    order = r.order(here, centers, weights, min_value=1.0)
    assert 6 not in order  # region 6 holds less than min_value
    assert order[0] == 4  # the nearest first
    assert sorted(order) == [0, 2, 4, 9]
    r.current = 9
    assert r.order(here, centers, weights, 1.0)[0] == 9  # the current region while it holds value
    r.done.update({9, 4})
    assert 9 not in r.order(here, centers, weights, 1.0)
    assert r.order(here, centers, weights, 1.0, skip=[0, 2]) == []


def test_exploration_within_a_box_needs_no_known_structure():
    import nbvkit

    m = nbvkit.OccupancyMap(0.5, (0, 0, 0), (10, 10, 10))
    # nothing known occupied: without a box there is no extent to explore
    assert len(exploration_targets(m)) == 0
    m.mark_free_segment((2.0, 5.0, 5.0), (4.0, 5.0, 5.0), 1.0)  # a flight through the open
    t = exploration_targets(m, ((0, 0, 0), (10, 10, 10)))
    free = m.state(t.positions + t.normals * 0.5)
    assert len(t) > 0 and np.all(m.state(t.positions) == m.UNKNOWN)
    assert np.all(free == m.FREE)  # each looks out of the unknown towards the free space
    assert np.all(np.linalg.norm(t.positions - [3.0, 5.0, 5.0], axis=1) < 3.0)
    inner = exploration_targets(m, ((0, 0, 0), (3, 10, 10)))  # only within the box
    assert 0 < len(inner) < len(t)
    assert np.all(inner.positions[:, 0] <= 3.0 + m.resolution)


def test_exploration_box_must_be_whole_and_finite():
    import nbvkit

    m = nbvkit.OccupancyMap(0.5, (0, 0, 0), (10, 10, 10))
    with pytest.raises(ValueError, match="both lo and hi"):
        nbvkit._core.exploration_targets(m, (0, 0, 0))
    with pytest.raises(ValueError, match="hi"):
        nbvkit._core.exploration_targets(m, (0, 0, 0), (np.nan, 5, 5))
    far = nbvkit._core.exploration_targets(m, (40, 40, 40), (50, 50, 50))  # beyond the grid
    assert len(far) == 0 and far.positions.shape == (0, 3)


def test_patches_follow_the_camera_range_unless_set():
    cfg = load_config()
    assert cfg.placement.cluster(cfg.camera) == 1.5  # the paper's 8 m camera
    wide = load_config(overrides=["camera.preset=inspection"])
    assert wide.placement.cluster(wide.camera) == pytest.approx(4.5)
    fixed = load_config(overrides=["camera.preset=inspection", "placement.cluster_size=2"])
    assert fixed.placement.cluster(fixed.camera) == 2.0


def _two_cubes():
    """Two 4 m cubes 30 m apart along x, as one mesh."""
    import nbvkit
    from conftest import box_mesh

    a, b = box_mesh((0, 0, 0), (4, 4, 4)), box_mesh((30, 0, 0), (34, 4, 4))
    return nbvkit.Mesh(
        np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + len(a.vertices)])
    )


def test_a_workspace_of_several_regions_is_toured_region_by_region_larger_gains_first():
    # Two 4 m cubes 30 m apart, regions of 12 m and a 4 m camera (a large workspace: 6 x 4 m <
    # 44 m): the tours visit both cubes' regions, keep at first only views adding 8 x
    # tour.min_gain, and halve that each time a plan keeps none; they cover as much as the
    # one tour over the whole workspace does (the larger gains first too). (Not in fewer views:
    # from a start that sees a cube, the one tour took 31 views and the regions 39.)
    from conftest import QUICK_MISSION
    from nbvkit.mission import Mission

    mesh = _two_cubes()
    quick = list(QUICK_MISSION)
    runs = {}
    for size in (12, None):
        # (without the last plans' tilted views, placement.fallback null: the tours compared)
        # and without frames on the legs, which the one tour gains more from here (68.8 against
        # 64.6 %): what is compared is the tours
        more = ["camera.max_range=4", "workspace.margin_xy=5", "placement.fallback=false"]
        # at the rate the regions were measured at: at the cheaper default (0.5) the one tour
        # covers 72.5 % here and the regions 64.4 % (docs/RESULTS.md)
        more += ["planner.frame_step=0", "tour.rate=0.75"]
        # and with the ground removal they were measured with (cloud.min_z=0.3: the regions
        # 65.2 %, the one tour 63.3 %); without it the one tour covers 73.9 % in 32 views and
        # the regions 70.7 % in 23
        more += ["cloud.min_z=0.3"]
        more += [f"tour.region_size={size}"] if size else []
        m = Mission(load_config(overrides=quick + more), mesh=mesh)
        runs[size] = (m, m.run())
    m, s = runs[12]
    assert s["termination"] == "coverage_complete"
    plans = s["tours"]
    assert len({p["region"] for p in plans if "region" in p}) >= 2
    xs = np.array([r.x for r in m.records])
    assert (xs < 15).any() and (xs > 15).any()  # views of both cubes
    scale = np.array([p["min_gain_m2"] / p["scale"] for p in plans])  # the multiple of min_gain
    base = load_config().tour.min_gain
    assert scale[0] == pytest.approx(8 * base)
    assert np.all(np.diff(scale) <= 1e-9) and scale[-1] == pytest.approx(base)
    one, whole = runs[None][1], s
    assert "region" not in one["tours"][0]
    assert one["tours"][0]["min_gain_m2"] / one["tours"][0]["scale"] == pytest.approx(8 * base)
    assert whole["area_coverage"]["0.05"] >= one["area_coverage"]["0.05"] - 0.01


def test_the_inspection_camera_scores_one_ray_per_map_cell_at_its_near_standoff():
    from nbvkit.sensors import build_view_camera

    cfg = load_config(overrides=["camera.preset=inspection"])
    cam = build_view_camera(cfg.camera, cfg.utility, cfg.map.resolution)
    near = min(cfg.placement.standoffs) * cfg.camera.max_range  # 10.8 m
    across = [
        2 * near * np.tan(np.radians(f / 2)) for f in (cfg.camera.hfov_deg, cfg.camera.vfov_deg)
    ]
    spacing = np.array(across) / [cam.rays_x, cam.rays_y]
    assert np.all(spacing <= cfg.map.resolution) and np.all(spacing > 0.8 * cfg.map.resolution)


@pytest.mark.parametrize("level_views", [1, 6])
def test_a_plan_that_keeps_too_few_views_halves_its_level(level_views, monkeypatch):
    # The two cubes 30 m apart with a 4 m camera (a large workspace: plans start at 8 x
    # tour.min_gain). A plan above the lowest level keeps at least tour.level_views views, else
    # its level halves and it is planned again: over the sets of the views the lower level adds
    # too, one plan_tour call per level (at min_gain: the views that can be chosen).
    from conftest import QUICK_MISSION
    from nbvkit.mission import Mission
    from nbvkit.planning.generators.tour import CoverageTour

    mesh = _two_cubes()
    scored, base = [], load_config().tour.min_gain
    plan = CoverageTour._plan
    monkeypatch.setattr(
        CoverageTour,
        "_plan",
        lambda self, w, c, cov, g, r: scored.append(g / base) or plan(self, w, c, cov, g, r),
    )
    more = ["camera.max_range=4", "workspace.margin_xy=5", f"tour.level_views={level_views}"]
    s = Mission(load_config(overrides=list(QUICK_MISSION) + more), mesh=mesh).run()
    plans = s["tours"]
    level = np.array([p["min_gain_m2"] / p["scale"] / base for p in plans])
    assert level[0] <= 8 + 1e-9 and level[-1] == pytest.approx(1.0)
    assert np.all(np.diff(level) <= 1e-9)
    above = level > 1 + 1e-9
    assert all(p["kept"] >= level_views for p, up in zip(plans, above) if up)
    # each plan scores at the level the last one ended at, then at each half it goes down to
    expected, start = [], 8.0
    for p, end in zip(plans, level):
        at = start
        while p["candidates"]:
            expected.append(at * p["scale"])
            if at <= end + 1e-9:
                break
            at /= 2
        start = end
    np.testing.assert_allclose(scored, expected)
