"""Profiling (Algorithm 1): waypoints on the recomputed circle, a radius that encloses the growing
profile, clearance from the structure, the bounding-box method, and the profile's own summary."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.profiling import Profiler, _Circle, _GrownHull, run_profiling

FAST = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=100",
    "profiling.sweep_step=0.25",
]


@pytest.fixture(scope="module")
def profiled():
    m = Mission(Config().with_overrides(FAST + ["scenario=profile"]))
    s = m.run()
    return m, s


def test_profile_summary_and_symmetry_report(profiled):
    m, s = profiled
    p = s["profile"]
    assert s["termination"] == "profile_only" and s["iterations"] == 0
    assert p["distance_m"] > 2 * math.pi * 20  # at least a turn around a 35 m aircraft
    assert p["entropy_reduction"] > 0.3 * s["entropy_initial"]  # the laser clears most free space
    assert p["coverage"]["0.5"] > 0.6 and p["coverage"]["0.05"] < p["coverage"]["0.5"]
    assert p["clearance_m"] > m.config.vehicle.collision_radius
    sym = s["symmetry"]
    assert sym["accepted"] and not sym["written"] and sym["cells_set"] == 0
    n = np.array(sym["plane"][:3])
    assert abs(abs(n[1]) - 1) < 1e-3  # the airliner's mirror plane y = 0
    assert m.map.counts()["predicted"] == 0


def test_camera_frames_taken_in_flight_during_the_profile(profiled):
    """profiling.camera_step: the RGB-D camera takes a frame each time that many metres have been
    flown. The flight is the same; the frames add camera points and dense coverage, and they are
    not views (the paper's profile is the laser alone: camera_step 0, no camera point)."""
    base, b = profiled
    assert len(base.world.camera_cloud) == 0 and b["profile"]["camera_frames"] == 0
    step = 4.0
    m = Mission(
        Config().with_overrides(FAST + ["scenario=profile", f"profiling.camera_step={step}"])
    )
    s = m.run()
    p = s["profile"]
    assert p["distance_m"] == pytest.approx(b["profile"]["distance_m"], rel=1e-9)
    flown = p["distance_m"] + p["return_distance_m"]  # the frames go on while it flies back
    assert flown / step - 1 <= p["camera_frames"] <= flown / step
    assert s["views"] == 0 and len(m.world.camera_cloud) > 0
    assert p["coverage"]["0.05"] > b["profile"]["coverage"]["0.05"] + 0.02


def test_waypoints_lie_on_the_recomputed_circle(profiled):
    m, s = profiled
    p = s["profile"]
    wps, circles = np.array(p["waypoints"]), np.array(p["circles"])
    assert len(wps) == m.config.profiling.waypoints == len(circles)
    # sweep k+1 happens on circle k (centre and radius recomputed after sweep k), N angles apart
    for k in range(len(wps) - 1):
        c, r = circles[k, :2], circles[k, 2]
        assert np.linalg.norm(wps[k + 1] - c) == pytest.approx(r, abs=1e-6)
    start = m.world.start_pose[:2]
    np.testing.assert_allclose(wps[0], start, atol=1e-9)  # the first sweep is at the start
    ang = [math.atan2(w[1] - c[1], w[0] - c[0]) for w, c in zip(wps[1:], circles[:-1, :2])]
    steps = np.diff(np.unwrap(ang))
    np.testing.assert_allclose(steps, 2 * math.pi / len(wps), atol=0.15)


def test_radius_encloses_the_profile_and_grows_with_it():
    class Stub:  # the circle computation on its own
        pass

    m = Stub()
    m.config = Config()
    m.workspace = None
    prof = Profiler.__new__(Profiler)
    prof.m, prof.cfg = m, m.config.profiling
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(200, 3))
    radii = []
    for grow in (1.0, 2.0, 3.0):
        m.laser_cloud = type(
            "C", (), {"points": np.vstack([pts, grow * np.array([[4, 0, 0], [-4, 0, 0]])])}
        )()
        c, r = prof._circle(np.zeros(3), 1.0)
        xy = m.laser_cloud.points[:, :2]
        assert np.all(np.linalg.norm(xy - c, axis=1) <= r - prof.cfg.margin + 1e-9)
        radii.append(r)
    assert radii[0] < radii[1] < radii[2]


def test_bounding_box_profiler():
    m = Mission(Config().with_overrides(FAST + ["scenario=profile", "profiling.method=bbox"]))
    s = m.run()
    p = s["profile"]
    assert p["method"] == "bbox" and len(p["waypoints"]) == 9  # start + 4 corners + 4 mid-faces
    assert p["coverage"]["0.5"] > 0.5 and p["clearance_m"] > m.config.vehicle.collision_radius


def test_grown_hull_of_a_square_is_at_the_margin_from_it():
    """Analytic: the 2 x 2 square grown by d = 1 has straight faces at x = +-2, y = +-2 and arcs
    of radius 1 round its corners; the vehicle faces the nearest point of the square."""
    sq = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1], [0, 0], [0.5, -0.2]], float)
    h = _GrownHull(sq, 1.0)
    np.testing.assert_allclose(h.c, [0, 0], atol=1e-12)  # interior points are not vertices
    np.testing.assert_allclose(h.at(0.0), [2, 0], atol=1e-9)
    np.testing.assert_allclose(h.at(math.pi / 2), [0, 2], atol=1e-9)
    np.testing.assert_allclose(h.at(math.pi / 4), [1 + 0.5**0.5, 1 + 0.5**0.5], atol=1e-9)
    np.testing.assert_allclose(h.facing(np.array([2.0, 0.3])), [1, 0.3], atol=1e-12)
    np.testing.assert_allclose(h.facing(np.array([1.7, 1.7])), [1, 1], atol=1e-12)
    assert h.summary()[2] == pytest.approx((8 + 2 * math.pi) / (2 * math.pi))


def test_grown_hull_of_random_points_keeps_the_margin_all_round():
    rng = np.random.default_rng(3)
    xy = rng.normal(size=(300, 2)) * [6.0, 2.0] + [10.0, -4.0]  # elongated, off the origin
    d = 2.5
    h = _GrownHull(xy, d)
    # the distance to the hull is the distance to its dense boundary samples (outside it)
    v = h.v
    e = np.roll(v, -1, axis=0) - v
    t = np.linspace(0, 1, 400)
    boundary = (v[:, None, :] + t[None, :, None] * e[:, None, :]).reshape(-1, 2)
    for theta in np.linspace(0, 2 * math.pi, 37):
        p = h.at(theta)
        assert np.linalg.norm(boundary - p, axis=1).min() == pytest.approx(d, abs=2e-3)
        assert math.atan2(*(p - h.c)[::-1]) == pytest.approx(
            math.atan2(math.sin(theta), math.cos(theta)), abs=1e-9
        )
    # chords of at most d / 2 between neighbouring points stay within 0.13 d of the margin
    pts = np.array([h.at(0.0)] + h.arc(0.0, 2 * math.pi, 7.0))
    np.testing.assert_allclose(pts[-1], pts[0], atol=1e-9)
    assert np.linalg.norm(np.diff(pts, axis=0), axis=1).max() <= d / 2 + 1e-9
    mids = (pts[1:] + pts[:-1]) / 2
    near = np.array([np.linalg.norm(boundary - q, axis=1).min() for q in mids])
    assert near.min() > 0.87 * d


def test_hull_profile_falls_back_to_the_circle_on_a_collinear_profile():
    class Stub:
        pass

    m = Stub()
    m.config = Config().with_overrides(["profiling.method=hull"])
    prof = Profiler.__new__(Profiler)
    prof.m, prof.cfg = m, m.config.profiling
    line = np.array([[x, 2 * x, 1.0] for x in range(5)], float)
    m.laser_cloud = type("C", (), {"points": line, "__len__": lambda self: len(line)})()
    region = prof._region(np.zeros(3), 1.0)
    c, r = prof._circle(np.zeros(3), 1.0)
    assert isinstance(region, _Circle) and region.summary() == [c[0], c[1], r]


def test_hull_profiler_flies_shorter_than_the_circle_and_keeps_clear():
    """The grown hull lies inside the circle Algorithm 1 would fly round the same cloud, so the
    profile is shorter; it keeps the margin from what it has seen and faces the structure."""
    circ = Mission(
        Config().with_overrides(FAST + ["profiling.method=circular", "max_iterations=0"])
    )
    c = circ.run()["profile"]
    m = Mission(Config().with_overrides(FAST + ["profiling.method=hull", "max_iterations=0"]))
    s = m.run()
    p = s["profile"]
    assert p["method"] == "hull" and len(p["waypoints"]) == m.config.profiling.waypoints
    assert p["distance_m"] < 0.9 * c["distance_m"]
    assert p["clearance_m"] > m.config.vehicle.collision_radius
    assert p["coverage"]["0.05"] > 0.5 * c["coverage"]["0.05"]


def test_the_profile_goes_round_a_part_its_laser_has_not_seen_instead_of_through_it():
    # An L-shaped block (24 x 8 m and 8 x 14 m, 8 m tall) seen by a laser of 12 m range: the
    # grown hull of a partial profile cuts across the far wing, and the curve flown on it met
    # the wing (before the range check, 0.02-0.05 m from its walls on four starts of five).
    from scipy.spatial import cKDTree

    from conftest import box_mesh

    a, b = box_mesh((0, 0, 0), (24, 8, 8)), box_mesh((0, 8, 0), (8, 22, 8))
    v = np.vstack([a.vertices, b.vertices])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    import nbvkit

    mesh = nbvkit.Mesh(v, f)
    surface = cKDTree(np.asarray(mesh.sample_surface(100000)))
    blocked = 0
    for start in (2, 4):
        over = FAST + [f"start={start}", "laser.max_range=12"]
        m = Mission(Config().with_overrides(over), mesh=mesh)
        m.world.take_off()
        s = run_profiling(m.world)
        blocked += s["blocked_steps"]
        path = np.array([r[1:4] for r in m.world.state.trajectory], float)
        flown = np.vstack([np.linspace(p, q, 20) for p, q in zip(path[:-1], path[1:])])
        assert surface.query(flown)[0].min() > 0.5  # off the walls (collision radius 0.8 m)
        assert s["distance_m"] > 2 * (24 + 22)  # and still round the whole structure
    assert blocked > 0  # the range check is what kept it off


def test_descending_arcs_cross_every_height_between_two_sweeps():
    # A 16 x 16 x 16 m block, profiled round its grown hull with camera frames: with level arcs
    # (Algorithm 1) each arc is flown at the height where the last sweep ended, and the camera
    # sees only a band at the top or bottom of the faces between two sweeps. Descending arcs go
    # from one end of the sweep to the other on the way, so every sweep runs the same way, the
    # camera sees more of the block, and the flight is longer by no more than the climb.
    from conftest import box_mesh

    mesh = box_mesh((-8, -8, 0), (8, 8, 16))
    runs = {}
    for arcs in ("level", "descending"):
        over = FAST + [f"profiling.arcs={arcs}", "max_iterations=0", "start=0"]
        m = Mission(Config().with_overrides(over), mesh=mesh)
        s = m.run()
        rows = np.array([r[1:4] for r in m.world.state.trajectory if r[0] == "profile"])
        runs[arcs] = (s["profile"], rows, Profiler(m.world))
    lo, hi = runs["level"][2].z_min, runs["level"][2].z_max
    for arcs, (p, rows, _) in runs.items():
        assert len(p["waypoints"]) == 4
        moving = np.linalg.norm(np.diff(rows[:, :2], axis=0), axis=1) > 1e-6  # arc legs
        dz = np.diff(rows[:, 2])[moving]
        if arcs == "level":
            assert np.abs(dz).max() < 1e-9
        else:  # down (or up) all the way: each of the 3 arcs spans the sweep's height
            assert np.all(dz <= 1e-9) or np.all(dz >= -1e-9)
            assert abs(dz.sum()) == pytest.approx(3 * (hi - lo), abs=1e-6)
    level, desc = runs["level"][0], runs["descending"][0]
    assert desc["distance_m"] > level["distance_m"]
    assert desc["distance_m"] < level["distance_m"] + 3 * (hi - lo)
    assert desc["coverage"]["0.05"] > level["coverage"]["0.05"] + 0.05  # 49.0 against 35.4 %


def test_a_profile_started_in_a_courtyard_goes_over_the_wall():
    # Four 6 m walls round a 18 x 18 m courtyard, the vehicle starting inside. The grown hull of
    # what the laser sees lies outside the walls, and every way out at the vehicle's height is
    # blocked: the retries go over the top of the flight volume (stuck inside before, two of
    # the four sweeps at the same place). Every sweep after the first is outside, at a place of
    # its own.
    import nbvkit
    from conftest import box_mesh

    walls = [
        box_mesh((-10, -10, 0), (10, -9, 6)),
        box_mesh((-10, 9, 0), (10, 10, 6)),
        box_mesh((-10, -9, 0), (-9, 9, 6)),
        box_mesh((9, -9, 0), (10, 9, 6)),
    ]
    v = np.vstack([w.vertices for w in walls])
    f = np.vstack([np.asarray(w.faces) + 8 * i for i, w in enumerate(walls)])
    over = FAST + ["profiling.method=hull", "start_pose=[0,-3,3,1.5708]"]
    m = Mission(Config().with_overrides(over), mesh=nbvkit.Mesh(v, f))
    m.world.take_off()
    s = run_profiling(m.world)
    wps = np.array(s["waypoints"])
    assert len(wps) == 4
    assert np.all(np.abs(wps[1:]).max(axis=1) > 10 + m.config.vehicle.collision_radius)
    assert min(np.linalg.norm(a - b) for i, a in enumerate(wps) for b in wps[i + 1 :]) > 5
    assert s["blocked_steps"] > 0  # the walls did stand in the way


def test_the_range_check_keeps_the_collision_radius_off_a_part_thinner_than_its_rays():
    # A 0.2 m blade 1.4 m beside a 7 m step, between the rays along the step (its centre and a
    # ring at the 2 m radius) and the 32 directions round its ends: the rays pass it by, and a
    # profile flew 1.6 m from a turned Cessna's wing with a 2 m radius. Sensing the structure
    # within the radius along the step blocks it; a vehicle already that near may move away.
    import nbvkit
    from conftest import box_mesh

    box = box_mesh((-2, -2, 0), (2, 2, 4))
    c = np.array([10.5, -1.4 * math.cos(math.pi / 8), 5 - 1.4 * math.sin(math.pi / 8)])
    blade = c + np.array([[0.0, 0, 0], [0.2, 0, 0], [0, 0.1, 0.1]])
    mesh = nbvkit.Mesh(np.vstack([box.vertices, blade]), np.vstack([box.faces, [[8, 9, 10]]]))
    cfg = Config().with_overrides(FAST + ["vehicle.collision_radius=2", "max_iterations=0"])
    p = Profiler(Mission(cfg, mesh=mesh).world)
    a, b = np.array([7.0, 0, 5]), np.array([14.0, 0, 5])
    t, _ = p.m.scene.intersect(np.vstack([a, b]), np.array([[1.0, 0, 0], [-1, 0, 0]]), 0, 7)
    assert np.isinf(t).all()  # (the blade is beside the step, not on it)
    assert p.m.scene.within(c[None], 0.01).tolist() == [True]
    assert not p.clear(a, b)  # within 2 m of the blade on the way
    assert p.clear(a + [0, 5, 0], b + [0, 5, 0])  # 5 m off: clear
    near = c + [0, 0.5, 0.5]  # already within the radius: moving away is let through
    assert p.clear(near, near + [0, 1, 1])
    # ... but not on into the radius of another part: from 1.6 m beside a blade behind it, out
    # of its radius, then 1.4 m past the first blade (the rays miss both)
    behind = c + np.array([[-4.5, 1.6, 0.0], [-4.3, 1.6, 0.0], [-4.5, 1.7, 0.1]])
    mesh2 = nbvkit.Mesh(np.vstack([mesh.vertices, behind]), np.vstack([mesh.faces, [[11, 12, 13]]]))
    p2 = Profiler(Mission(cfg, mesh=mesh2).world)
    start = np.array([6.0, 0, 5])
    assert p2.m.scene.within(start[None], 2.0).tolist() == [True]
    assert not p.clear(start, b) and not p2.clear(start, b)
