"""The camera gimbal (issue 33, part 1): a view is (x, y, z, yaw, pitch), pitch > 0 looking down.

Analytic pixels of a pitched camera, the 4-vector as the 5-vector with pitch 0 bit for bit,
scoring a pitched view as a level view whose mount holds the pitch, the memos keeping pitches
apart, the pitch in the mission's files and the report's arrows, and bad input refused."""
from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pytest

import nbvkit
from nbvkit import _core
from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.scenarios import SCENARIOS, TABLE2
from conftest import TINY_RUN, box_mesh

DEG = math.pi / 180


def floor_mesh(half=100.0, z=0.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], float)
    return nbvkit.Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int32))


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def project(cam, view, point):
    """(u, v, depth) of a world point for a camera at view (x, y, z, yaw, pitch) with an
    identity mount, written out independently of the core: p_s = (Rz Ry)^T (point - o), then
    u + 0.5 - W/2 = -fx y_s / x_s, v + 0.5 - H/2 = -fy z_s / x_s."""
    R = rot_z(view[3]) @ rot_y(view[4])
    ps = R.T @ (np.asarray(point, float) - np.asarray(view[:3], float))
    u = cam.width / 2 - cam.fx * ps[1] / ps[0] - 0.5
    v = cam.height / 2 - cam.fy * ps[2] / ps[0] - 0.5
    return u, v, ps[0]


def test_a_pitched_camera_sees_a_floor_point_at_the_predicted_pixel():
    cam = nbvkit.DepthCamera(floor_mesh(), width=65, height=49, min_range=0.1, max_range=60)
    for view in ([0, 0, 4, 0, 30 * DEG], [2, -1, 6, 2.0, 55 * DEG], [1, 1, 3, -0.7, 90 * DEG]):
        scan = cam.scan_pose(view)
        assert len(scan.hits) > 0
        for k in range(0, len(scan.hits), max(1, len(scan.hits) // 40)):
            # every hit lies on the floor and projects back onto its own pixel
            p = scan.hits[k]
            assert abs(p[2]) < 1e-9
            u, v, depth = project(cam, view, p)
            r = scan.hit_rays[k]
            assert (u, v) == pytest.approx((r % cam.width, r // cam.width), abs=1e-6)
            assert scan.depth[r // cam.width, r % cam.width] == pytest.approx(depth, rel=1e-9)
    # a known point: 4 m up, pitched down 30 deg, yaw 0: the optical axis meets the floor at
    # x = 4 / tan(30 deg), seen at the image centre (32, 24) at depth 4 / sin(30 deg) = 8 m
    d = cam.scan_pose([0, 0, 4, 0, 30 * DEG]).depth
    assert d[24, 32] == pytest.approx(8.0, rel=1e-12)
    assert project(cam, [0, 0, 4, 0, 30 * DEG], [4 / math.tan(30 * DEG), 0, 0]) == pytest.approx(
        (32, 24, 8.0)
    )
    # pitched up 30 deg, a ceiling 4 m above is seen at the centre at 8 m too
    up = nbvkit.DepthCamera(floor_mesh(z=8.0), width=65, height=49, max_range=60)
    assert up.scan_pose([0, 0, 4, 0, -30 * DEG]).depth[24, 32] == pytest.approx(8.0, rel=1e-12)
    assert np.isinf(up.scan_pose([0, 0, 4, 0, 30 * DEG]).depth[24, 32])


def test_four_numbers_are_pitch_zero_bit_for_bit():
    cam = nbvkit.DepthCamera(box_mesh((3, -2, 0), (6, 2, 3)), width=80, height=60)
    for pose in ([0.0, 0.5, 2.0, 0.1], [1.0, -3.0, 4.0, 1.1]):
        a = cam.scan_pose(pose)
        for zero in (0.0, -0.0):
            b = cam.scan_pose([*pose, zero])
            np.testing.assert_array_equal(a.hits, b.hits)
            np.testing.assert_array_equal(a.free_ends, b.free_ends)
            np.testing.assert_array_equal(a.depth, b.depth)
        T = nbvkit.pose_to_transform(pose)
        mount = nbvkit.mount_transform([0.1, 0, 0.2], 0, 10, 5)
        np.testing.assert_array_equal(nbvkit.gimbal_transform([*pose, 0.0], mount), T @ mount)
        np.testing.assert_array_equal(nbvkit.gimbal_transform(pose), T)


def test_a_pitch_past_90_degrees_by_a_hair_shows_the_digits_that_refuse_it():
    """A float32 pi/2 is 4e-8 rad past pi/2: the message read "got 1.5708 rad (90 deg)"."""
    with pytest.raises(ValueError, match=r"got 1\.5707963705062866 rad \(90\.0000025\d* deg\)"):
        nbvkit.gimbal_transform([0, 0, 0, 0, float(np.float32(np.pi / 2))])
    with pytest.raises(ValueError, match=r"got 1\.7 rad \(97\.4028 deg\)"):  # short where it can
        nbvkit.gimbal_transform([0, 0, 0, 0, 1.7])
    nbvkit.gimbal_transform([0, 0, 0, 0, np.pi / 2])  # pi/2 itself is within


def test_gimbal_transform_is_yaw_then_pitch_then_mount():
    mount = nbvkit.mount_transform([0.3, -0.1, 0.2], 1.0, 8.0, -4.0)
    for view in ([1, 2, 3, 0.4, 0.3], [-5, 0, 2, -2.0, -0.5], [0, 0, 9, 3.0, math.pi / 2]):
        G = np.eye(4)
        G[:3, :3] = rot_z(view[3]) @ rot_y(view[4])
        G[:3, 3] = view[:3]
        np.testing.assert_allclose(nbvkit.gimbal_transform(view, mount), G @ mount, atol=1e-14)
        # the body does not pitch
        np.testing.assert_array_equal(
            nbvkit.pose_to_transform(view), nbvkit.pose_to_transform(view[:4])
        )
    # pitch > 0 looks down, as a mount's pitch does
    axis = nbvkit.gimbal_transform([0, 0, 0, 0, 0.4])[:3, 0]
    np.testing.assert_allclose(axis, nbvkit.mount_transform(pitch_deg=0.4 / DEG)[:3, 0])
    assert axis[2] < 0


def _scene():
    """A map of a box scanned from three views (one pitched), its camera observations, and
    candidate views around it."""
    mesh = box_mesh((4, -2, 0), (7, 2, 2.5))
    cam = nbvkit.DepthCamera(mesh, width=120, height=90)
    m = nbvkit.OccupancyMap(0.2, (-4, -8, 0), (12, 8, 8))
    surface = _core.SurfaceObservations(m)
    for view in ([0, 0, 2, 0], [0, -4, 4, 0.6, 0.4], [1, 4, 3, -0.5, 0.2]):
        s = cam.scan_pose(view)
        m.integrate(s)
        surface.add_scan(s)
    m.mark_free_segment((0, -3, 3), (0, 3, 3), 1.0)
    rng = np.random.default_rng(4)
    cand = np.column_stack(
        [rng.uniform(-0.5, 0.5, 14), rng.uniform(-3, 3, 14), rng.uniform(2.5, 3.5, 14)]
    )
    cand = np.column_stack([cand, rng.uniform(-0.6, 0.6, 14)])
    return m, surface, cand


CAMERA = dict(rays_x=40, rays_y=30, mount=nbvkit.mount_transform([0.1, 0, 0], 0, 5, 0))
VALIDITY = dict(collision_radius=0.3, blocked_path="plan")


def _score(m, surface, cand, camera=CAMERA, memo=None, **utility):
    utility.setdefault("require_occupied", False)
    return _core.evaluate_views(
        m,
        cand,
        (0, 0, 3, 0),
        camera=camera,
        utility=utility,
        validity=VALIDITY,
        surface=surface,
        memo=memo,
    )


def _same(a, b):
    """The same arrays: two dicts of scores, or two CoverageSets."""
    if isinstance(a, dict):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
        return
    for k in ("offsets", "elements", "weights", "status", "pruned", "gain", "pooled_from"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)


def _pitched(cand, pitch):
    return np.column_stack([cand, np.full(len(cand), pitch)])


def test_a_pitched_view_scores_as_a_level_view_with_the_pitch_in_its_mount():
    m, surface, cand = _scene()
    for name in ("ig", "surface", "rear_side_voxel"):
        level = _score(m, surface, cand, name=name)
        assert (level["status"] == 0).sum() >= 8
        for pitch in (-25 * DEG, 20 * DEG, 60 * DEG):
            mount = nbvkit.gimbal_transform([0, 0, 0, 0, pitch], CAMERA["mount"])
            a = _score(m, surface, _pitched(cand, pitch), name=name)
            b = _score(m, surface, cand, camera={**CAMERA, "mount": mount}, name=name)
            _same(a, b)
            assert not np.array_equal(a["gain"], level["gain"]), (name, pitch)
        # the octree backend reads the same
        a = _score(m, surface, _pitched(cand, 0.3), name=name)
        b = _core.evaluate_views(
            m,
            _pitched(cand, 0.3),
            (0, 0, 3, 0),
            camera=CAMERA,
            utility={"name": name, "require_occupied": False},
            validity=VALIDITY,
            surface=surface,
            backend="octree",
        )
        _same(a, b)
    pitch = 40 * DEG
    mount = nbvkit.gimbal_transform([0, 0, 0, 0, pitch], CAMERA["mount"])
    kw = dict(utility={"name": "surface"}, validity=VALIDITY)
    a = _core.view_coverage(m, surface, _pitched(cand, pitch), (0, 0, 3, 0), camera=CAMERA, **kw)
    b = _core.view_coverage(m, surface, cand, (0, 0, 3, 0), camera={**CAMERA, "mount": mount}, **kw)
    _same(a, b)
    assert len(a.elements) > 0


def test_level_candidates_score_as_pitch_zero_bit_for_bit():
    m, surface, cand = _scene()
    for name in ("ig", "surface"):
        memo4, memo5 = _core.ViewMemo(), _core.ViewMemo()
        for _ in range(2):
            _same(
                _score(m, surface, cand, memo=memo4, name=name),
                _score(m, surface, _pitched(cand, 0.0), memo=memo5, name=name),
            )
    c4, c5 = _core.CoverageMemo(), _core.CoverageMemo()
    for _ in range(2):
        a = _core.view_coverage(m, surface, cand, (0, 0, 3, 0), camera=CAMERA, memo=c4)
        b = _core.view_coverage(m, surface, _pitched(cand, -0.0), (0, 0, 3, 0), CAMERA, memo=c5)
        _same(a, b)
    assert c5.stats()["reused"] > 0


def test_the_memos_keep_pitches_apart():
    m, surface, cand = _scene()
    memo, cover = _core.ViewMemo(), _core.CoverageMemo(keep_calls=8)

    def coverage(c, memo=None):
        return _core.view_coverage(
            m, surface, c, (0, 0, 3, 0), CAMERA, validity=VALIDITY, memo=memo
        )

    for pitch in (0.0, 0.5, -0.3, 0.5):
        c = _pitched(cand, pitch)
        _same(_score(m, surface, c, memo=memo), _score(m, surface, c))
        _same(coverage(c, cover), coverage(c))
    valid = int((_score(m, surface, cand)["status"] == 0).sum())
    assert memo.entries == 3 * valid and memo.stats()["reused"] == valid
    assert cover.entries == 3 * valid and cover.stats()["reused"] == valid


def test_the_laser_ignores_the_pitch():
    las = nbvkit.LaserScanner(box_mesh((4, -2, 0), (7, 2, 2.5)))
    a, b = las.scan_pose([0, 0, 2, 0.1]), las.scan_pose([0, 0, 2, 0.1, 0.8])
    np.testing.assert_array_equal(a.hits, b.hits)


def test_bad_pitches_are_refused_naming_the_pitch():
    cam = nbvkit.DepthCamera(floor_mesh(), width=8, height=6)
    las = nbvkit.LaserScanner(floor_mesh())
    m, surface, cand = _scene()
    for bad in (np.nan, np.inf, -np.inf, math.pi / 2 + 1e-6, -2.0, 4.0):
        for sensor in (cam, las):
            with pytest.raises(ValueError, match="pitch"):
                sensor.scan_pose([0, 0, 4, 0, bad])
        with pytest.raises(ValueError, match="pitch"):
            nbvkit.gimbal_transform([0, 0, 4, 0, bad])
        with pytest.raises(ValueError, match="candidates row 1.*pitch"):
            _score(m, surface, np.array([[0, 0, 3, 0, 0.1], [0, 0, 3, 0, bad]]))
        with pytest.raises(ValueError, match="pitch"):
            _core.view_coverage(m, surface, [[0, 0, 3, 0, bad]], (0, 0, 3, 0))
        with pytest.raises(ValueError, match="current pose.*pitch"):
            _core.evaluate_views(m, cand[:1], (0, 0, 3, 0, bad))
    cam.scan_pose([0, 0, 4, 0, math.pi / 2])  # the limits themselves hold
    cam.scan_pose([0, 0, 4, 0, -math.pi / 2])
    with pytest.raises(ValueError, match=r"4 numbers \(x, y, z, yaw\) or 5"):
        cam.scan_pose([0, 0, 4, 0, 0, 0])
    with pytest.raises(ValueError, match=r"\(K, 4\).*\(K, 5\)"):
        _score(m, surface, np.zeros((2, 6)))


# ---------------------------------------------------------------------------------- config


def test_gimbal_range_defaults_sign_and_the_paper_scenarios_keep_the_level_camera():
    assert Config().camera.gimbal_pitch_deg == (-30.0, 90.0)  # 30 up to straight down
    for s in TABLE2:
        assert Config(scenario=s).camera.gimbal_pitch_deg == (0.0, 0.0), s
        assert SCENARIOS[s].settings["camera.gimbal_pitch_deg"] == (0.0, 0.0)
    assert Config(scenario="surface_nbv").camera.gimbal_pitch_deg == (-30.0, 90.0)
    c = Config.from_dict({"scenario": "5", "camera": {"gimbal_pitch_deg": [-10, 45]}})
    assert c.camera.gimbal_pitch_deg == (-10.0, 45.0)  # the user's wins over the preset


@pytest.mark.parametrize(
    "value, message",
    [
        ([60, 10], "min 60 > max 10"),
        ([-30, 95], r"within \[-90, 90\]"),
        ([-91, 0], r"within \[-90, 90\]"),
        ([float("nan"), 90], "finite"),
        ([0, float("inf")], "finite"),
        ([0], r"2 numbers \[min, max\]"),
        ([0, 10, 20], r"2 numbers \[min, max\]"),
        ([10, 90], "include 0"),
        ("down", "list of numbers"),
    ],
)
def test_a_bad_gimbal_range_is_a_clear_error_before_any_work(value, message):
    with pytest.raises(ValueError, match="camera.gimbal_pitch_deg") as e:
        Config.from_dict({"camera": {"gimbal_pitch_deg": value}})
    assert re.search(message, str(e.value)), str(e.value)


def test_a_start_pose_may_hold_a_pitch_within_the_gimbal_range():
    c = Config.from_dict({"start_pose": [1, 2, 3, 0.5, 0.4]})
    assert c.start_pose == (1.0, 2.0, 3.0, 0.5, 0.4)
    with pytest.raises(ValueError, match="outside camera.gimbal_pitch_deg"):
        Config.from_dict({"start_pose": [1, 2, 3, 0.5, 0.4], "scenario": "1"})  # level only
    with pytest.raises(ValueError, match="outside camera.gimbal_pitch_deg"):
        Config.from_dict({"start_pose": [1, 2, 3, 0.5, -1.0]})  # -57 deg: beyond 30 deg up
    with pytest.raises(ValueError, match="start_pose.*finite"):
        Config.from_dict({"start_pose": [1, 2, 3, 0.5, float("nan")]})
    with pytest.raises(ValueError, match="start_pose"):
        Config.from_dict({"start_pose": [1, 2, 3]})


# ---------------------------------------------------------------------------------- mission


def _tiny(*sets):
    return Config().with_overrides([*TINY_RUN, "progress=false", "report.enabled=false", *sets])


def test_the_mission_writes_a_pitch_column_and_starts_from_a_pitched_view(tmp_path):
    probe = Mission(_tiny("scenario=surface"))
    start = probe.world.start_pose
    pitch = 0.35
    m = Mission(_tiny("scenario=surface", f"start_pose=[{','.join(map(str, start))},{pitch}]"))
    assert len(m.world.state.pose) == 5 and m.world.state.pose[4] == pitch
    m.run(tmp_path)
    traj = list(csv.DictReader(open(tmp_path / "trajectory.csv")))
    assert list(traj[0]) == ["stage", "x", "y", "z", "yaw", "pitch", "distance_m"]
    assert float(traj[0]["pitch"]) == pitch
    assert all(float(r["pitch"]) == 0.0 for r in traj[1:])  # the planners fly level views
    its = list(csv.DictReader(open(tmp_path / "iterations.csv")))
    assert its and list(its[0])[:6] == ["iteration", "x", "y", "z", "yaw", "pitch"]
    assert all(float(r["pitch"]) == 0.0 for r in its)


def test_a_view_outside_the_gimbal_range_is_not_flown():
    m = Mission(_tiny("scenario=1"))
    w = m.world
    with pytest.raises(ValueError, match="outside camera.gimbal_pitch_deg"):
        w.fly_to([*w.state.pose[:4], 0.2], "nbv")
    w.fly_to(w.state.pose[:4], "nbv")  # 4 numbers: level
    assert w.state.pose[4] == 0.0 and len(w.state.trajectory[-1]) == 7


def test_the_reports_view_arrows_follow_the_pitch(tmp_path):
    from nbvkit.report import write_run_report

    rows = [
        dict(
            iteration=1,
            x=0,
            y=0,
            z=5,
            yaw=0.0,
            pitch=math.pi / 2,
            source="s",
            entropy=1,
            distance_m=1,
        ),
        dict(
            iteration=2,
            x=1,
            y=0,
            z=5,
            yaw=math.pi / 2,
            pitch=-30 * DEG,
            source="s",
            entropy=1,
            distance_m=2,
        ),
        dict(iteration=3, x=2, y=0, z=5, yaw=0.0, pitch=0.0, source="s", entropy=1, distance_m=3),
    ]
    with open(tmp_path / "iterations.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    path = write_run_report(tmp_path, {}, np.zeros((3, 3)), np.zeros(3, int))
    html = path.read_text()
    cone = json.loads(re.search(r'(\{"type":"cone".*?\})', html).group(1))
    np.testing.assert_allclose(cone["u"], [0, 0, 1], atol=1e-3)
    np.testing.assert_allclose(cone["v"], [0, math.cos(30 * DEG), 0], atol=1e-3)
    np.testing.assert_allclose(cone["w"], [-1, 0.5, 0], atol=1e-3)  # down, up, level


def test_the_lattice_around_a_pitched_view_is_the_lattice_around_its_pose():
    from nbvkit.sampling import candidate_poses

    pose = [1.0, 2.0, 3.0, 0.4]
    a, b = candidate_poses(pose), candidate_poses([*pose, 0.3])
    np.testing.assert_array_equal(a, b)
    assert a.shape == (80, 4)
    with pytest.raises(ValueError, match="or 5"):
        candidate_poses([*pose, 0.3, 0.0])


def test_the_camera_observations_record_the_pitched_direction():
    # straight down from 4 m, the camera 0.3 m ahead of and 0.1 m below the gimbal's axis:
    # Ry(90 deg) takes that offset to 0.1 m behind and 0.3 m below, the camera at (-0.1, 0, 3.7)
    mount = nbvkit.mount_transform([0.3, 0.0, -0.1])
    cam = nbvkit.DepthCamera(floor_mesh(), width=64, height=48, mount=mount)
    scan = cam.scan_pose([0, 0, 4, 0, math.pi / 2])
    np.testing.assert_allclose(scan.origin, [-0.1, 0, 3.7], atol=1e-12)
    m = nbvkit.OccupancyMap(0.2, (-6, -6, -1), (6, 6, 5))
    surface = _core.SurfaceObservations(m)
    surface.add_scan(scan)
    seen = surface.seen_grid().reshape(-1, order="F")
    ids = np.asarray(m.index_of(scan.hits))
    expect = np.zeros_like(seen)
    for i, h in zip(ids, scan.hits):  # each hit marks its cell seen from the bin of (origin - hit)
        expect[i] |= np.uint32(1) << np.uint32(_core.direction_bin(scan.origin - h))
    np.testing.assert_array_equal(seen, expect)
    up = 1 << _core.direction_bin([0, 0, 1])
    assert seen[m.index_of([[-0.1, 0, 0.0]])[0]] == up  # the cell below, seen from straight above


def test_the_lattice_samples_the_gimbals_pitches_and_the_paper_stays_level():
    """Issue 33: with lattice.delta_pitch_deg, nbvkit's greedy planner samples each lattice view
    at the gimbal's pitches (30 deg apart, 0 included); the paper's scenarios (a level camera)
    keep (K, 4) views whatever it says."""
    from nbvkit.config import load_config
    from nbvkit.planning.generators.lattice import gimbal_pitches
    from nbvkit.planning.registry import get_generator

    assert np.allclose(np.degrees(gimbal_pitches((-30, 90), 30)), [-30, 0, 30, 60, 90])
    assert np.allclose(np.degrees(gimbal_pitches((-45, 80), 30)), [-30, 0, 30, 60])
    assert np.array_equal(gimbal_pitches((0, 0), 30), [0.0])

    class World:
        class state:
            pose = np.array([1.0, 2.0, 3.0, 0.5, 0.0])

    paper_cfg = load_config(overrides=["scenario=5", "lattice.delta_pitch_deg=30"])
    paper = get_generator("lattice", paper_cfg).propose(World)
    assert paper.poses.shape[1] == 4
    level = get_generator("lattice", load_config(overrides=["scenario=surface_nbv"]))
    assert level.propose(World).poses.shape == paper.poses.shape  # level unless asked
    cfg = load_config(overrides=["scenario=surface_nbv", "lattice.delta_pitch_deg=30"])
    pitched = get_generator("lattice", cfg).propose(World)
    assert pitched.poses.shape == (len(paper.poses) * 5, 5)
    assert np.allclose(np.unique(np.round(np.degrees(pitched.poses[:, 4]))), [-30, 0, 30, 60, 90])
    # every position of the level lattice, at each pitch
    assert np.allclose(pitched.poses[::5, :4], paper.poses)


def test_the_flight_envelope_reaches_the_far_standoff_above_the_top_and_a_ground_clearance():
    """Issue 33, part 2: workspace.margin_z null lets the vehicle fly the camera's far stand-off
    above the structure's top; the profile's sweeps and the starts keep to the structure's
    height (the same starts as without the envelope); vehicle.min_altitude raises the floor."""
    from nbvkit.config import load_config
    from nbvkit.world import World

    flat = World(load_config(overrides=["scenario=surface"]))
    env = World(load_config(overrides=["scenario=surface_gimbal"]))
    top = env.mesh.bounds[1][2]
    far = max(env.config.placement.standoffs) * env.config.camera.max_range
    assert env.workspace.nav_max[2] == pytest.approx(top + far)
    assert env.workspace.nav_max[2] > flat.workspace.nav_max[2]
    assert env.workspace.structure_nav_max[2] == pytest.approx(flat.workspace.nav_max[2])
    assert np.allclose(env.starts, flat.starts)
    low = World(load_config(overrides=["scenario=surface_gimbal", "vehicle.min_altitude=3"]))
    assert low.workspace.nav_min[2] == pytest.approx(low.workspace.bounds_min[2] + 3.0)
    with pytest.raises(ValueError, match="'vehicle.min_altitude' must be >= 0"):
        load_config(overrides=["vehicle.min_altitude=-1"])
    with pytest.raises(ValueError, match="vehicle.min_altitude"):
        load_config(overrides=["vehicle.min_altitude=.nan"])


QUICK_RUN = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=50",
    "evaluation.coverage_every=0",
    "profiling.sweep_step=0.25",
    "symmetry.mode=none",
    "report.enabled=false",
    "observability.enabled=false",
    "max_iterations=40",
]


def test_a_short_mission_with_the_gimbal_looks_down_at_a_flat_roof():
    """surface_gimbal on a low wide box (a flat roof 1.5 m up): a view pitched down is flown,
    within the gimbal's limits, and what a camera can see of the box is covered (its floor, a
    third of its area, cannot be)."""
    from conftest import box_mesh
    from nbvkit.config import load_config
    from nbvkit.mission import Mission

    mesh = box_mesh((-4, -3, 0), (4, 3, 1.5))
    # without saturation: with it the profile's frames and the first view leave the roof done
    # (below), and no view is planned for it
    plain = ["scenario=surface_gimbal", *QUICK_RUN, "utility.saturation_hits=0"]
    m = Mission(load_config(overrides=plain), mesh=mesh)
    s = m.run()
    pitch = np.degrees([r.pitch for r in m.records])
    assert np.all((pitch >= -30 - 1e-9) & (pitch <= 90 + 1e-9))
    assert np.any(pitch > 20)  # a view looks down at the roof
    assert s["coverage"]["0.1"] > 0.55
    # with saturation (the default) the same coverage in fewer views
    m2 = Mission(load_config(overrides=plain[:-1]), mesh=mesh)
    s2 = m2.run()
    assert s2["views"] < s["views"]
    assert s2["area_coverage"]["0.05"] >= s["area_coverage"]["0.05"] - 0.005


def test_the_model_planner_plans_from_the_mesh_and_flies_with_the_real_camera():
    """--planner model on a box: the map knows the structure before the first view (no
    profile), the tours plan over all of it, the real camera covers what it can see (the box's
    floor, a quarter of its area, it cannot)."""
    from conftest import box_mesh
    from nbvkit.config import load_config
    from nbvkit.mission import Mission

    mesh = box_mesh((-3, -2, 0), (3, 2, 2.5))
    m = Mission(load_config(overrides=["scenario=model", *QUICK_RUN]), mesh=mesh)
    s = m.run()
    assert s["profiling"] is False and s["generators"] == ["model"]
    assert {r.source for r in m.records} == {"model"}
    assert s["termination"] in ("coverage_complete", "no_reachable_view")
    assert s["coverage"]["0.1"] > 0.65
    assert s["tours"] and s["tours"][0]["kept"] > 0
    assert s["tours"][0]["targets"] > 200  # the whole model is a target from the first plan


def test_the_known_model_marks_every_cell_of_its_observable_surface_occupied(monkeypatch):
    """write_model on a box: every cell holding a sample of the box's sides (seen head-on from
    the navigation space, which reaches 1.6 m above the box's top) is occupied before the first
    view, though the coarse frames alone leave some free (grazing rays along the walls carve
    them), and the box's inside stays unknown (no ray enters it)."""
    from conftest import box_mesh
    from nbvkit.config import load_config
    from nbvkit.planning.generators import model
    from nbvkit.planning.parts import PlanningContext
    from nbvkit.world import World

    cfg = load_config(overrides=["scenario=model", *QUICK_RUN])
    mesh = box_mesh((-3.1, -2.3, 0), (2.9, 1.7, 2.5))
    pts = mesh.sample_surface(20000, 3)
    sides = pts[(pts[:, 2] > 0.45) & (pts[:, 2] < 2.5 - 1e-9)]  # above the lowest cells
    free = []
    for mark in (False, True):
        world = World(cfg, mesh=mesh)
        with monkeypatch.context() as m:
            if not mark:  # the coarse frames alone
                m.setattr(model, "mark_occupied", lambda *a, **k: None)
            frames = model.write_model(world, cfg.model, PlanningContext.of(cfg))
        assert frames > 0
        free.append(np.count_nonzero(world.map.state(sides) != 1))
        assert np.all(world.map.state(np.array([[-0.1, -0.3, 1.25]])) == -1)  # the inside
    assert free[0] > 0.01 * len(sides)  # the frames alone miss some: what this test is about
    assert free[1] == 0, f"{free[1]} of {len(sides)} side samples' cells not occupied"


def well_mesh(inner=3.6, wall=0.3, height=5.0, floor=0.3):
    """An open-topped square well on the ground: four walls `wall` thick round an `inner` x
    `inner` m shaft `height` m deep, on a floor slab `floor` m thick; (mesh, inside) where inside
    is a function of points (N, 3) -> bool: on the shaft's walls or its floor."""
    from conftest import box_mesh

    a, b = inner / 2, inner / 2 + wall
    parts = [
        box_mesh((-b, -b, 0), (b, -a, height)),
        box_mesh((-b, a, 0), (b, b, height)),
        box_mesh((-b, -a, 0), (-a, a, height)),
        box_mesh((a, -a, 0), (b, a, height)),
        box_mesh((-a, -a, 0), (a, a, floor)),
    ]
    v = np.vstack([p.vertices for p in parts])
    f = np.vstack([p.faces + 8 * k for k, p in enumerate(parts)])

    def inside(p):
        within = np.all(np.abs(p[:, :2]) < a + 1e-6, axis=1)
        return within & (p[:, 2] > floor - 1e-6) & (p[:, 2] < height - 1e-6)

    return nbvkit.Mesh(v, f), inside


def test_views_of_unknown_space_look_down_into_an_open_top():
    """An open-topped well 5 m deep (its shaft 3.6 m across): the recommended planner's level
    views see only the shaft's top; with placement.explore_gimbal (the default) its views of
    the unknown space look down into it, never up, and the camera covers the shaft's walls and
    floor. Other views stay level."""
    from nbvkit.config import load_config

    mesh, inside = well_mesh()
    pts = mesh.sample_surface(20000, 5)
    shaft = pts[inside(pts)]
    seen = {}
    for on in (False, True):
        flag = f"placement.explore_gimbal={str(on).lower()}"
        m = Mission(load_config(overrides=["scenario=surface", *QUICK_RUN, flag]), mesh=mesh)
        m.run()
        seen[on] = float(np.mean(_core.nearest_distances(m.world.cloud_points(), shaft) < 0.1))
        pitch = np.array([r.pitch for r in m.records])
        if on:  # down into the shaft, never up
            assert np.any(pitch > 0.3) and np.all(pitch >= 0.0), pitch
        else:
            assert np.all(pitch == 0.0)
        assert np.any(pitch == 0.0)  # the surface's views
    assert seen[True] > seen[False] + 0.3, seen


def test_a_floor_at_the_ground_is_reconstructed_where_the_papers_drop_it_as_ground():
    """The same well on a floor 0.1 m thick: the simulated world has no ground, and the
    recommended planner's clouds drop nothing as ground, so the camera cloud holds the shaft's
    floor; the paper's ground removal (cloud.min_z = 0.3 m) would drop all of it."""
    from nbvkit.config import load_config

    mesh, inside = well_mesh(floor=0.1)
    pts = mesh.sample_surface(20000, 5)
    floor = pts[inside(pts) & (pts[:, 2] < 0.1 + 1e-6)]
    m = Mission(load_config(overrides=["scenario=surface", *QUICK_RUN]), mesh=mesh)
    m.run()
    cloud = m.world.cloud_points()
    assert float(np.mean(_core.nearest_distances(cloud, floor) < 0.1)) > 0.8
    assert np.all(cloud[:, 2] >= -1e-6) and np.any(cloud[:, 2] < 0.3)


def test_views_of_unknown_space_are_pitched_down_only_where_the_gimbal_can():
    """explore_placement: the recommended planner's views of unknown space take the gimbal's
    range above level, straight on; surface_gimbal's keep its whole range; a camera that cannot
    look down, and the paper's level camera, stay level."""
    from nbvkit.config import load_config
    from nbvkit.planning.placement import explore_placement

    def of(*sets):
        cfg = load_config(overrides=list(sets))
        at, cam = explore_placement(cfg.placement, cfg.camera)
        return at.gimbal, tuple(cam.gimbal_pitch_deg), at.azimuth_spread_deg

    assert of("scenario=surface") == (True, (0.0, 90.0), 0.0)
    assert of("scenario=surface_gimbal") == (True, (-30.0, 90.0), 0.0)
    assert of("scenario=surface", "placement.explore_gimbal=false")[0] is False
    assert of("scenario=surface", "camera.gimbal_pitch_deg=[-30,0]")[0] is False
    assert of("scenario=5")[1] == (0.0, 0.0)  # place_views keeps it level
