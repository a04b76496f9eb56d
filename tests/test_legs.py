"""Camera frames in flight along a leg to a view (planner.frame_step, planning/legs.py)."""
import math

import numpy as np
import pytest

from conftest import box_mesh, seen_box_world
from nbvkit import _core
from nbvkit.planning.legs import leg_pieces, retreat


def _length(pts):
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


@pytest.mark.parametrize("seed", range(20))
def test_pieces_follow_the_path_a_frame_every_step(seed):
    rng = np.random.default_rng(seed)
    path = np.cumsum(rng.uniform(-3, 3, size=(rng.integers(2, 7), 3)), axis=0)
    start = np.array([*path[0], rng.uniform(-math.pi, math.pi), rng.uniform(-0.5, 1.5)])
    target = np.array([*path[-1], rng.uniform(-math.pi, math.pi), rng.uniform(-0.5, 1.5)])
    step = rng.uniform(0.3, 2.0)
    pieces = leg_pieces(start, target, path, step)
    total = _length(path)
    # the pieces, joined, are the path: the same length, each starting where the last ended
    assert sum(_length(w) for _, w in pieces) == pytest.approx(total)
    np.testing.assert_allclose(pieces[0][1][0], path[0])
    for (pose, _), (_, nxt) in zip(pieces[:-1], pieces[1:]):
        np.testing.assert_allclose(nxt[0], pose[:3])
    np.testing.assert_array_equal(pieces[-1][0], target)
    # a frame every step metres flown, none within step / 2 of the view
    frames = pieces[:-1]
    assert len(frames) == max(0, math.floor((total - 0.5 * step) / step))
    flown = np.cumsum([_length(w) for _, w in pieces])
    np.testing.assert_allclose(flown[:-1], step * np.arange(1, len(frames) + 1))
    turn = math.remainder(target[3] - start[3], 2 * math.pi)
    for (pose, _), s in zip(frames, flown):
        f = s / total
        # the camera turns in proportion to the distance, the shorter way round
        assert math.cos(pose[3] - (start[3] + f * turn)) == pytest.approx(1.0)
        assert -math.pi <= pose[3] <= math.pi
        assert pose[4] == pytest.approx(start[4] + f * (target[4] - start[4]))


def test_straight_leg_and_the_yaw_across_pi():
    pieces = leg_pieces([0, 0, 0, 3.0], [5, 0, 0, -3.0], None, 1.0)
    assert [p[0][0] for p in pieces] == pytest.approx([1, 2, 3, 4, 5])
    # 3.0 -> -3.0 turns 0.283 rad through pi, not 6 rad the long way
    yaws = [p[0][3] for p in pieces[:-1]]
    assert all(abs(math.remainder(y - 3.0, 2 * math.pi)) < 0.3 for y in yaws)
    assert all(len(p[0]) == 5 and p[0][4] == 0.0 for p in pieces)  # 4 numbers: level


def test_no_frames_when_off_or_the_leg_is_short():
    path = np.array([[0.0, 0, 0], [1.2, 0, 0]])
    for step in (0.0, 1.0):  # off; a leg under 1.5 steps
        (only,) = leg_pieces([0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0], path, step)
        np.testing.assert_array_equal(only[1], path)


def test_waypoints_of_a_bent_path_stay_in_their_piece():
    path = np.array([[0.0, 0, 0], [2, 0, 0], [2, 2, 0]])
    pieces = leg_pieces([0, 0, 0, 0, 0], [2, 2, 0, 1, 0], path, 1.5)
    assert len(pieces) == 3
    np.testing.assert_allclose(pieces[1][1], [[1.5, 0, 0], [2, 0, 0], [2, 1, 0]])


def test_a_vehicle_a_scan_closed_in_on_flies_back_along_its_flight():
    w = seen_box_world()
    r = w.config.vehicle.collision_radius
    start = w.state.pose.copy()
    assert retreat(w, r) == 0.0  # free where it is: it stays
    # two legs on, then surface appears beside the last stretch of the flight (a scan finds it)
    a = start[:3] + np.array([0.0, 0.0, 1.0])
    b = a + np.array([2.0, 0.0, 0.0])
    w.fly_to([*a, start[3]], "nbv")
    w.fly_to([*b, start[3], 0.2], "nbv")
    close = b + np.array([0.0, r * 0.5, 0.0])
    for _ in range(10):
        w.map.update_cells(close[None], occupied=True)

    def sphere_free(p):
        return bool(_core.spheres_are_free(w.map, np.asarray(p, float)[None], r)[0])

    assert not sphere_free(b) and sphere_free(a)
    before, rows = w.state.distance_m, len(w.state.flight)
    flown = retreat(w, r)
    here = w.state.pose
    # back along its own flight to the last point whose sphere is free: the first leg's end
    assert sphere_free(here[:3])
    np.testing.assert_allclose(here[:3], a)
    assert flown == pytest.approx(np.linalg.norm(b - a))
    assert w.state.distance_m == pytest.approx(before + flown)
    assert here[3] == pytest.approx(start[3]) and here[4] == pytest.approx(0.2)  # camera kept
    assert len(w.state.flight) > rows  # the way back is flown and logged


def test_no_retreat_where_no_point_of_the_flight_is_free():
    w = seen_box_world()
    r = w.config.vehicle.collision_radius
    here = w.state.pose[:3].copy()
    for _ in range(10):
        w.map.update_cells(here[None], occupied=True)
    assert retreat(w, r) == 0.0
    np.testing.assert_allclose(w.state.pose[:3], here)


def test_a_mission_takes_frames_along_its_legs(tmp_path):
    import csv
    import json

    from nbvkit.config import Config
    from nbvkit.mission import Mission

    fast = ["map.resolution=0.4", "progress=false", "evaluation.gt_density=100"]
    c = Config().with_overrides(fast + ["max_iterations=6", "planner.frame_step=0.5"])
    Mission(c).run(tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    with open(tmp_path / "flight.csv") as f:
        rows = list(csv.DictReader(f))
    on_legs = [r for r in rows if r["stage"] == "nbv" and r["capture"] == "frame"]
    views = [r for r in rows if r["capture"] == "view"]
    assert len(on_legs) > 0 and len(views) == s["views"]
    assert s["camera_frames"] == s["profile"]["camera_frames"] + len(on_legs)
    # a frame every 0.5 m flown along a leg: 0.5 m after the frame before it
    captured = [(r["stage"], r["capture"], float(r["distance_m"])) for r in rows if r["capture"]]
    pairs = zip(captured, captured[1:])
    gaps = [b[2] - a[2] for a, b in pairs if a[:2] == b[:2] == ("nbv", "frame")]
    assert len(gaps) > 0 and gaps == pytest.approx([0.5] * len(gaps))


@pytest.mark.parametrize("bad", ["-1", "0.05", "nan", "inf"])
def test_a_bad_frame_step_is_refused_naming_the_key(bad):
    from nbvkit.config import load_config

    with pytest.raises(ValueError, match="planner.frame_step"):
        load_config(overrides=[f"planner.frame_step={bad}"])


def test_frames_in_flight_are_taken_at_a_stride_of_the_camera_resolution():
    from nbvkit.config import Config
    from nbvkit.world import World

    c = Config().with_overrides(
        [
            "map.resolution=0.4",
            "progress=false",
            "camera.frame_stride=4",
            "camera.width=642",
            "camera.frame_refine=false",
        ]
    )
    w = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    view, frame = w.scan("view"), w.scan("frame")
    assert view.depth.shape == (480, 642) and frame.depth.shape == (120, 160)
    # the same field of view: the frame's hits span the view's on the box's face, and lie on it
    lo, hi = view.hits.min(axis=0), view.hits.max(axis=0)
    np.testing.assert_allclose(frame.hits.min(axis=0), lo, atol=0.1)
    np.testing.assert_allclose(frame.hits.max(axis=0), hi, atol=0.1)
    assert 0.9 < 16 * len(frame.hits) / len(view.hits) < 1.1
    h = frame.hits
    on_face = np.minimum.reduce([3 - np.abs(h[:, 0]), 3 - np.abs(h[:, 1]), h[:, 2], 5 - h[:, 2]])
    assert np.all(np.abs(on_face) < 1e-3)
    # a stride of 1: the camera itself takes the frames, pixel for pixel
    w1 = World(
        Config().with_overrides(["map.resolution=0.4", "camera.frame_stride=1"]), mesh=w.mesh
    )
    assert w1.frame_camera is w1.camera
    np.testing.assert_array_equal(w1.scan("frame").depth, w1.scan("view").depth)


def test_refined_frames_are_full_resolution_where_new_and_coarse_where_known():
    from nbvkit.config import Config
    from nbvkit.world import World

    c = Config().with_overrides(
        ["map.resolution=0.4", "camera.frame_stride=2", "camera.frame_refine=true"]
    )
    w = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    view, coarse = w.scan("view"), w.frame_camera.scan_pose(w.state.pose)
    # nothing seen yet: the frame is the camera's own, hit for hit
    first = w.scan("frame")
    assert first.depth.shape == view.depth.shape
    order = np.argsort(first.hit_rays)
    np.testing.assert_array_equal(first.hit_rays[order], view.hit_rays)
    np.testing.assert_array_equal(first.hits[order], view.hits)
    w.integrate(first, "frame")
    # seen from here: the squares it marked stand coarse, each hit the coarse frame's or the
    # camera's own
    again = w.scan("frame")
    assert len(coarse.hits) <= len(again.hits) < 0.6 * len(view.hits)
    ours = {tuple(p) for p in np.vstack([coarse.hits, view.hits])}
    assert all(tuple(p) in ours for p in again.hits)
    # taken ahead (coarse, while the last capture went in), it is refined when asked for
    w2 = World(c, mesh=w.mesh)
    w2.integrate(w2.scan("view"), "view", ("frame", w2.state.pose))
    cone = c.utility.coverage_cone_deg
    expected = _core.refine_frame(w2.camera, coarse, w2.state.pose, w2.surface, cone)
    np.testing.assert_array_equal(w2.scan("frame").hits, expected.hits)


@pytest.mark.parametrize("bad", ["0", "65", "1.5", "nan"])
def test_a_bad_frame_stride_is_refused_naming_the_key(bad):
    from nbvkit.config import load_config

    with pytest.raises(ValueError, match="camera.frame_stride"):
        load_config(overrides=[f"camera.frame_stride={bad}"])


def test_novelty_is_the_share_of_a_preview_the_record_lacks():
    from nbvkit.config import Config
    from nbvkit.world import World

    c = Config().with_overrides(["map.resolution=0.4", "progress=false"])
    w = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    here = np.array([-7.0, 0.0, 2.5, 0.0, 0.0])  # facing the box's -x face from 4 m
    across = np.array([7.0, 0.0, 2.5, math.pi, 0.0])  # its +x face
    preview = w.preview_camera.scan_pose(here)
    assert preview.depth.shape == (60, 80)
    assert w.novelty(here) == 1.0  # nothing seen yet: every hit is new
    w.fly_to(here, "nbv")
    w.sense("frame")
    assert w.novelty(here) < 0.01  # the frame saw what its preview would
    assert w.novelty(across) > 0.99  # the other face: never seen
    assert w.state.views == 0 and len(w.camera_cloud) > 0  # novelty integrates nothing
    n = len(w.camera_cloud)
    w.novelty(across)
    assert len(w.camera_cloud) == n


def test_a_legs_frames_are_skipped_where_their_previews_find_too_little_new():
    from types import SimpleNamespace

    from nbvkit.planning.legs import fly_leg
    from nbvkit.timing import StageTimers

    w = seen_box_world()
    start = w.state.pose.copy()
    there = start.copy()
    there[1] += 3.0  # 3 m sideways along the face the view saw: frames at 1 and 2 m
    choice = SimpleNamespace(pose=there, path=None)
    flown, _ = fly_leg(w, choice, 1.0, 0.5, StageTimers())  # half of a preview new: none is
    assert flown == pytest.approx(3.0) and w.state.frames_skipped == 2
    assert not any(row[6] == "frame" for row in w.state.flight)
    flown, _ = fly_leg(w, SimpleNamespace(pose=start, path=None), 1.0, 0.0, StageTimers())
    assert w.state.frames_skipped == 2  # novelty 0: every frame taken, none previewed
    assert sum(row[6] == "frame" for row in w.state.flight) == 2


def test_a_mission_reports_the_leg_frames_it_skipped(tmp_path):
    import json

    from nbvkit.config import Config
    from nbvkit.mission import Mission

    fast = ["map.resolution=0.4", "progress=false", "evaluation.gt_density=100"]
    c = Config().with_overrides(fast + ["max_iterations=6", "planner.frame_step=0.5"])
    Mission(c.with_overrides(["planner.frame_novelty=0.05"])).run(tmp_path / "skip")
    s = json.loads((tmp_path / "skip" / "summary.json").read_text())
    assert s["frames_skipped"] > 0 and s["camera_frames"] > s["profile"]["camera_frames"]
    Mission(c).run(tmp_path / "all")
    assert json.loads((tmp_path / "all" / "summary.json").read_text())["frames_skipped"] == 0


@pytest.mark.parametrize("bad", ["-0.1", "1.5", "nan"])
def test_a_bad_frame_novelty_is_refused_naming_the_key(bad):
    from nbvkit.config import load_config

    with pytest.raises(ValueError, match="planner.frame_novelty"):
        load_config(overrides=[f"planner.frame_novelty={bad}"])


def _noisy_box_world():
    from nbvkit.config import Config
    from nbvkit.world import World

    c = Config().with_overrides(["map.resolution=0.4", "progress=false", "camera.noise_k=0.0025"])
    w = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    w.take_off()
    w.sense("view")
    return w


def test_a_leg_takes_each_next_frame_while_it_integrates_the_last():
    # Noisy frames: the leg flown with each next capture taken ahead must draw the camera's
    # noise in the same order as one capture after the other, and keep the same map, cloud,
    # observations and flight.
    from types import SimpleNamespace

    from nbvkit.planning.legs import fly_leg
    from nbvkit.timing import StageTimers

    ahead, turn = _noisy_box_world(), _noisy_box_world()
    there = ahead.state.pose.copy()
    there[1] += 3.5  # frames at 1, 2 and 3 m, then the view
    there[3] += 0.4
    fly_leg(ahead, SimpleNamespace(pose=there, path=None), 1.0, 0.0, StageTimers())
    assert ahead._ahead[0] == "view"  # the view's frame, taken while the last frame went in
    ahead.integrate(ahead.scan("view"), "view")
    assert ahead._ahead is None
    for pose, waypoints in leg_pieces(turn.state.pose, there, None, 1.0)[:-1]:
        turn.fly_to(pose, "nbv", waypoints)
        turn.integrate(turn.scan("frame"), "frame")
    turn.fly_to(there, "nbv")
    turn.integrate(turn.scan("view"), "view")
    assert sum(row[6] == "frame" for row in ahead.state.flight) == 3
    assert ahead.state.flight == turn.state.flight
    np.testing.assert_array_equal(ahead.camera_cloud.points, turn.camera_cloud.points)
    assert ahead.map.total_entropy() == turn.map.total_entropy()
    np.testing.assert_array_equal(ahead.surface.seen_grid(), turn.surface.seen_grid())
    # a capture taken ahead and asked for at another pose is dropped, not returned
    ahead.integrate(ahead.scan("frame"), "frame", ("frame", ahead.state.pose))
    elsewhere = ahead.state.pose + np.array([0.5, 0, 0, 0, 0])
    scan = ahead.scan("frame", elsewhere)
    np.testing.assert_allclose(scan.origin, elsewhere[:3])


def test_a_frame_any_part_would_refuse_changes_nothing():
    w = _noisy_box_world()
    scan = w.scan("frame")
    entropy, points, seen = w.map.total_entropy(), len(w.camera_cloud), w.surface.seen_cells()
    for bad in ([float("nan"), 0, 2, 0], [0, 0, 2, 0, 2.0]):  # not a number; beyond the gimbal
        with pytest.raises(ValueError):
            _core.integrate_frame(
                w.map, w.camera_cloud, w.surface, scan, next_camera=w.camera, next_pose=bad
            )
    with pytest.raises(ValueError, match="camera capture"):
        w.integrate(scan, "frame", ("laser", w.state.pose))
    with pytest.raises(ValueError, match="camera and a pose"):
        _core.integrate_frame(w.map, w.camera_cloud, w.surface, scan, next_camera=w.camera)
    # observations of another map's grid: its hits outside that grid were dropped unsaid
    other = _core.SurfaceObservations(_core.OccupancyMap(0.2, (-1, -1, -1), (1, 1, 1)))
    with pytest.raises(ValueError, match="another map's grid"):
        _core.integrate_frame(w.map, w.camera_cloud, other, scan)
    for cone in (float("nan"), -1.0, 181.0):  # a NaN cone counted every hit novel, or none
        with pytest.raises(ValueError, match="cone_deg must be in .0, 180. degrees"):
            w.surface.novel_hits(scan.origin, scan.hits, cone)
        with pytest.raises(ValueError, match="cone_deg must be in"):
            _core.bin_cone(0, cone)
    assert (w.map.total_entropy(), len(w.camera_cloud), w.surface.seen_cells()) == (
        entropy,
        points,
        seen,
    )
    done = _core.integrate_frame(w.map, w.camera_cloud, w.surface, scan)
    assert done.next_scan is None and done.map.rays == len(scan.hits) + len(scan.free_ends)


def test_the_step_api_refuses_steps_its_record_would_misstate():
    """A script's steps (World.fly_to, sense, integrate) keep the flight record true: a capture
    is recorded where the vehicle is (sense from another pose was recorded at the vehicle's), a
    laser scan is not integrated as a photo, a path starts here and ends at the target (the
    distance summed one path while the vehicle moved to another), a target is finite and a
    pitch within what the camera takes (90 deg + 1e-10 was flown, then refused by the camera)."""
    w = seen_box_world()
    p = w.state.pose.copy()
    views, rows, dist = w.state.views, len(w.state.flight), w.state.distance_m
    with pytest.raises(ValueError, match="sense records a capture where the vehicle is"):
        w.sense("view", pose=[p[0] + 1, p[1], p[2], 0.3])
    with pytest.raises(ValueError, match="'view' capture must be a camera scan; .* 1 x"):
        w.integrate(w.scan("laser"), "view")
    with pytest.raises(ValueError, match="'laser' capture must be a laser scan"):
        w.integrate(w.scan("view"), "laser")
    far = [p[0] + 10, p[1], p[2]]
    with pytest.raises(ValueError, match="path must start where the vehicle is"):
        w.fly_to([p[0] + 2, p[1], p[2], 0], "nbv", path=[far, [p[0] + 2, p[1], p[2]]])
    with pytest.raises(ValueError, match="path must end at the target"):
        w.fly_to([p[0] + 2, p[1], p[2], 0], "nbv", path=[p[:3], far])
    for bad in ([p[0], p[1], p[2], math.nan], [math.inf, p[1], p[2], 0]):
        with pytest.raises(ValueError, match="target must be finite"):
            w.fly_to(bad, "nbv")
    with pytest.raises(ValueError, match="outside camera.gimbal_pitch_deg"):
        w.fly_to([*p[:4], math.radians(90.0000000001)], "nbv")
    assert (w.state.views, len(w.state.flight), w.state.distance_m) == (views, rows, dist)
    # the same steps done right are recorded
    w.sense("view", pose=p)
    assert w.state.views == views + 1 and w.state.flight[-1][6] == "view"
    w.fly_to([p[0], p[1] - 0.5, p[2], p[3]], "nbv", path=[p[:3], [p[0], p[1] - 0.5, p[2]]])
    assert w.state.distance_m == pytest.approx(dist + 0.5)


def test_fly_to_refuses_a_path_through_the_structure():
    """A leg that meets the structure's surface is a crash, not a flight: fly_to raises naming the
    leg and the point where it meets the surface, and nothing moves (pose, distance, flight
    record, and the map: the swept volume would have carved the box's inside free). The same
    target reached over the box is flown."""
    w = seen_box_world()  # the box [-3, 3] x [-3, 3] x [0, 5]
    p = w.state.pose.copy()
    across = np.array([-p[0], -p[1], 2.5])  # the far side, through the box's middle
    before = (w.state.distance_m, len(w.state.flight), w.state.pose.tolist())
    inside = w.map.probability(np.zeros((1, 3)) + [0, 0, 2.5])[0]
    with pytest.raises(ValueError, match=r"passes through the structure: its leg 0 .* meets"):
        w.fly_to([*across, 0.0], "nbv", path=[p[:3], across])
    over = [[p[0], p[1], 8.0], [-p[0], -p[1], 8.0], across]
    with pytest.raises(ValueError, match=r"its leg 1 .* meets its surface at \[.*\]"):
        w.fly_to([*across, 0.0], "nbv", path=[p[:3], over[0], [0.0, 0.0, 2.0], *over[1:]])
    assert (w.state.distance_m, len(w.state.flight), w.state.pose.tolist()) == before
    assert w.map.probability(np.zeros((1, 3)) + [0, 0, 2.5])[0] == inside
    flown = w.fly_to([*across, 0.0], "nbv", path=[p[:3], *over])
    assert flown == pytest.approx(
        float(np.linalg.norm(np.diff([p[:3], *over], axis=0), axis=1).sum())
    )
    np.testing.assert_allclose(w.state.pose[:3], across)
