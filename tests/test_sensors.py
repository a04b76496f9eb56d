"""Sensors against analytic scenes with known answers, frames and mounts, noise, and bad input."""
from __future__ import annotations

import numpy as np
import pytest

import nbvkit
from conftest import box_mesh, wall_mesh


def test_single_triangle_known_depth_and_miss():
    tri = nbvkit.Mesh([[3.0, -1, -1], [3.0, 1, -1], [3.0, 0, 1]], [[0, 1, 2]])
    scene = nbvkit.RaycastScene(tri)
    t, prim = scene.intersect([[0.0, 0.0, 0.0]], [[1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0.9]])
    assert t[0] == pytest.approx(3.0, abs=1e-12) and prim[0] == 0
    assert np.isinf(t[1]) and prim[1] == -1
    assert np.isinf(t[2]) and prim[2] == -1  # passes above the triangle's apex region
    t, _ = scene.intersect([[0.0, 0, 0]], [[1.0, 0, 0]], 0.0, 2.5)  # beyond t_far
    assert np.isinf(t[0])


def test_hit_is_exact_far_from_origin():
    # A slanted triangle 1 km away: double-precision refinement keeps the hit on the plane.
    off = np.array([1000.0, -2000.0, 300.0])
    v = off + np.array([[5.0, -3, -3], [6.0, 3, -3], [5.5, 0, 3]])
    scene = nbvkit.RaycastScene(nbvkit.Mesh(v, [[0, 1, 2]]))
    o = off + np.array([0.0, 0.1, 0.2])
    d = np.array([[1.0, 0.01, -0.02]])
    d /= np.linalg.norm(d)
    t, _ = scene.intersect(o[None], d)
    p = o + t[0] * d[0]
    n = np.cross(v[1] - v[0], v[2] - v[0])
    assert abs(np.dot(p - v[0], n / np.linalg.norm(n))) < 1e-9


def test_a_scan_is_the_same_wherever_the_structure_lies():
    """The airliner moved 2 to 40 km from the origin and scanned from the same relative pose
    gives the scan it gives at the origin: Embree's float32 coordinates are taken about the
    mesh's centre beyond 1 km (before: only beyond 32.8 km; at 30 km depths moved 1.2 mm)."""
    scans = []
    for s in (0.0, 2e3, 3e4, 4e4):
        m = nbvkit.load_mesh(nbvkit.default_mesh_path(), shift=[s, -s, s / 10])
        lo, hi = np.asarray(m.bounds)
        c = (lo + hi) / 2
        depth = nbvkit.DepthCamera(m).scan_pose([c[0] + 3, c[1] - 7, c[2] + 1, np.pi / 2]).depth
        scans.append(depth)
    hit = np.isfinite(scans[0])
    assert hit.sum() > 10_000
    for depth in scans[1:]:
        assert np.array_equal(np.isfinite(depth), hit)
        assert np.abs(depth[hit] - scans[0][hit]).max() < 1e-8


def test_camera_plane_gives_constant_depth():
    d = 5.0
    cam = nbvkit.DepthCamera(wall_mesh(x=d))
    s = cam.scan(np.eye(4))
    assert s.depth.shape == (480, 640)
    np.testing.assert_allclose(s.depth, d, atol=1e-9)
    assert len(s.hits) == 640 * 480 and len(s.free_ends) == 0
    # every hit at range d / cos(angle to the optical axis), on the wall
    dirs = cam.directions[s.hit_rays]
    r = np.linalg.norm(s.hits - s.origin, axis=1)
    np.testing.assert_allclose(r, d / dirs[:, 0], atol=1e-9)
    np.testing.assert_allclose(s.hits[:, 0], d, atol=1e-9)
    # field of view: the extreme pixel rays span 60 x 45 degrees (to pixel centres)
    half_h = np.degrees(np.arctan(np.abs(s.hits[:, 1]).max() / d))
    half_v = np.degrees(np.arctan(np.abs(s.hits[:, 2]).max() / d))
    assert 29.9 < half_h < 30.0 and 22.4 < half_v < 22.5
    # image orientation: u grows to the right (-y), v grows downward (-z)
    img_y = s.hits[:, 1].reshape(480, 640)
    img_z = s.hits[:, 2].reshape(480, 640)
    assert img_y[0, 0] > img_y[0, -1] and img_z[0, 0] > img_z[-1, 0]


def test_camera_ranges_and_free_rays():
    far = nbvkit.DepthCamera(wall_mesh(x=9.0))  # beyond 8 m: nothing hit, all rays free
    s = far.scan(np.eye(4))
    assert len(s.hits) == 0 and len(s.free_ends) == 640 * 480
    assert np.all(np.isinf(s.depth))
    # free ends lie on the far plane, depth 8 m along the axis
    np.testing.assert_allclose(s.free_ends[:, 0], 8.0, atol=1e-9)
    near = nbvkit.DepthCamera(wall_mesh(x=0.3))  # nearer than 0.5 m: no valid return, not free
    s = near.scan(np.eye(4))
    assert len(s.hits) == 0 and len(s.free_ends) == 0 and np.all(np.isinf(s.depth))
    edge = nbvkit.DepthCamera(wall_mesh(x=8.0))  # exactly at max range is within range
    assert len(edge.scan(np.eye(4)).hits) == 640 * 480


def test_vehicle_pose_and_yaw():
    cam = nbvkit.DepthCamera(box_mesh((-1, 6, -1), (1, 8, 11)), width=64, height=48)
    s = cam.scan_pose([0.0, 0.0, 5.0, np.pi / 2])  # facing +y, 6 m to the box face
    assert len(s.hits) > 0
    np.testing.assert_allclose(s.origin, [0, 0, 5])
    np.testing.assert_allclose(s.hits[:, 1], 6.0, atol=1e-9)
    assert s.depth[24, 32] == pytest.approx(6.0)
    # the box spans x in [-1, 1]: image columns whose rays pass |x| > 1 at 6 m see nothing
    assert np.isinf(s.depth[24, 0]) and np.isinf(s.depth[24, -1])
    T = nbvkit.pose_to_transform([0.0, 0.0, 5.0, np.pi / 2])
    np.testing.assert_allclose(cam.scan(T).hits, s.hits)


def test_camera_noise_is_seeded_and_scales_with_depth_squared():
    mesh = wall_mesh(x=6.0)
    a = nbvkit.DepthCamera(mesh, noise_k=0.0025, seed=3)
    b = nbvkit.DepthCamera(mesh, noise_k=0.0025, seed=3)
    s1, s2 = a.scan(np.eye(4)), b.scan(np.eye(4))
    np.testing.assert_array_equal(s1.depth, s2.depth)
    assert not np.array_equal(s1.depth, a.scan(np.eye(4)).depth)  # next frame, new noise
    err = s1.depth[np.isfinite(s1.depth)] - 6.0
    assert err.std() == pytest.approx(0.0025 * 36, rel=0.02)
    assert abs(err.mean()) < 0.001
    a.reset_noise(3)
    np.testing.assert_array_equal(a.scan(np.eye(4)).depth, s1.depth)


def test_laser_beams_angles_and_range():
    las = nbvkit.LaserScanner(wall_mesh(x=10.0), mount=np.eye(4))
    assert las.num_beams == 721
    np.testing.assert_allclose(np.degrees(las.angles[[0, 360, 720]]), [-90, 0, 90], atol=1e-12)
    np.testing.assert_allclose(np.diff(np.degrees(las.angles)), 0.25, atol=1e-9)
    s = las.scan(np.eye(4))
    assert s.depth.shape == (1, 721)
    # beams at |angle| < ~73 deg reach the wall within 30 m: range = 10 / cos(angle)
    ang = las.angles
    expect = 10.0 / np.cos(ang)
    hit = expect <= 30.0
    np.testing.assert_allclose(s.depth[0, hit], expect[hit], rtol=1e-12)
    assert np.all(np.isinf(s.depth[0, ~hit]))
    assert len(s.hits) == hit.sum() and len(s.free_ends) == (~hit).sum()
    np.testing.assert_allclose(np.linalg.norm(s.free_ends, axis=1), 30.0)


def test_laser_mount_pitch_is_applied():
    las = nbvkit.LaserScanner(box_mesh((-50, -50, -1), (50, 50, 0)))  # ground slab, top at z = 0
    np.testing.assert_allclose(las.mount, nbvkit.mount_transform(pitch_deg=10.0))
    s = las.scan_pose([0.0, 0.0, 2.0, 0.0])
    # the central beam is pitched 10 deg down: it meets z = 0 at 2 / sin(10 deg)
    assert s.depth[0, 360] == pytest.approx(2.0 / np.sin(np.radians(10)), rel=1e-9)
    np.testing.assert_allclose(s.hits[:, 2], 0.0, atol=1e-9)
    forward = s.hits[np.argmin(np.abs(s.hits[:, 1]))]
    assert forward[0] > 0  # it looks forward along body +x


def test_camera_mount_and_mount_transform_convention():
    T = nbvkit.mount_transform(pitch_deg=90.0)
    np.testing.assert_allclose(
        T[:3, :3] @ [1, 0, 0], [0, 0, -1], atol=1e-12
    )  # pitch > 0 looks down
    cam = nbvkit.DepthCamera(
        box_mesh((-20, -20, -1), (20, 20, 0)),
        width=32,
        height=24,
        mount=nbvkit.mount_transform([0, 0, 0.5], pitch_deg=90.0),
    )
    s = cam.scan_pose([1.0, 2.0, 3.0, 0.3])
    np.testing.assert_allclose(s.origin, [1, 2, 3.5])
    np.testing.assert_allclose(s.depth, 3.5, atol=1e-9)


def test_scene_shared_between_sensors_and_threads():
    scene = nbvkit.RaycastScene(wall_mesh(x=4.0))
    cam = nbvkit.DepthCamera(scene)
    nbvkit.set_num_threads(1)
    try:
        one = cam.scan(np.eye(4)).hits
    finally:
        nbvkit.set_num_threads(0)
    np.testing.assert_array_equal(one, cam.scan(np.eye(4)).hits)
    assert nbvkit.get_num_threads() >= 1


def test_bad_input_is_rejected():
    mesh = wall_mesh()
    cam = nbvkit.DepthCamera(mesh, width=8, height=6)
    las = nbvkit.LaserScanner(mesh)
    bad_T = np.eye(4)
    bad_T[0, 3] = np.nan
    for sensor in (cam, las):
        with pytest.raises(ValueError, match="NaN"):
            sensor.scan(bad_T)
        with pytest.raises(ValueError, match="NaN"):
            sensor.scan_pose([0, 0, np.inf, 0])
        with pytest.raises(ValueError, match="4x4"):
            sensor.scan(np.eye(3))
        with pytest.raises(ValueError, match="rigid"):
            sensor.scan(np.diag([2.0, 1, 1, 1]))
        with pytest.raises(ValueError, match="x, y, z, yaw"):
            sensor.scan_pose([0, 0, 0])
    for kw in (
        dict(width=0),
        dict(hfov_deg=180),
        dict(min_range=-1),
        dict(max_range=0.1),
        dict(noise_k=-1),
        dict(hfov_deg=float("nan")),
    ):
        with pytest.raises(ValueError):
            nbvkit.DepthCamera(mesh, **kw)
    for kw in (dict(fov_deg=0), dict(resolution_deg=0), dict(max_range=0.05), dict(noise_sigma=-1)):
        with pytest.raises(ValueError):
            nbvkit.LaserScanner(mesh, **kw)
    with pytest.raises(TypeError):
        nbvkit.DepthCamera("not a mesh")
    with pytest.raises(ValueError, match="rigid|NaN"):
        nbvkit.DepthCamera(mesh, mount=np.full((4, 4), np.nan))
    camera = nbvkit.DepthCamera(mesh)
    for pose in (np.array([0, -12, 3, np.pi / 2 + 1j]), [0, -12j, 3, 0]):  # not dropped: refused
        with pytest.raises(ValueError, match="must be real numbers, got complex"):
            camera.scan_pose(pose)
    with pytest.raises(ValueError, match="must be real numbers, got complex"):
        camera.scan(np.eye(4, dtype=complex))
    far = type(mesh)(np.asarray(mesh.vertices) + [1e300, 0, 0], mesh.faces)  # (load_mesh refuses)
    with pytest.raises(
        ValueError, match=r"mesh vertices reach 1e\+300 m, beyond"
    ):  # not 301 digits
        nbvkit.RaycastScene(far)
    scene = nbvkit.RaycastScene(mesh)
    with pytest.raises(ValueError, match="must be real numbers, got complex"):
        scene.intersect(np.zeros((1, 3), complex), [[1, 0, 0]])
    with pytest.raises(ValueError, match="origins"):
        scene.intersect(np.zeros((2, 3)), np.ones((3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        scene.intersect([[0, 0, 0]], [[np.nan, 0, 0]])
    # finite, but beyond what Embree takes in single precision (it aborted the process)
    for d in ([1e300, 0, 0], [0, -1e19, 0]):
        with pytest.raises(ValueError, match="ray direction 1 .*too long"):
            scene.intersect([[0, 0, 0]], [[1, 0, 0], d])
    t, prim = scene.intersect([[0, 0, 0]], [[0, 0, 0], [1e-300, 0, 0]])  # no length: no hit
    assert np.isinf(t).all() and (prim == -1).all()
    with pytest.raises(ValueError, match="t_near"):
        scene.intersect([[0, 0, 0]], [[1, 0, 0]], 2.0, 1.0)
    for n in (
        -1,
        nbvkit._core.MAX_THREADS + 1,
        10**7,
        2**31 - 1,
    ):  # TBB's arena crashed at 10**7
        with pytest.raises(ValueError, match="number of threads must be in"):
            nbvkit.set_num_threads(n)
    for n in (True, 2.0, "2", None):  # (True was taken as 1)
        with pytest.raises(TypeError, match="number of threads must be a whole number"):
            nbvkit.set_num_threads(n)


def test_sensor_ranges_noises_and_mounts_a_units_mistake_gives_are_refused_by_name():
    mesh = box_mesh([-1, -1, 0], [1, 1, 2])
    # (each was taken: rays and noise to 1e308 m made points no map can hold)
    with pytest.raises(ValueError, match=r"camera max_range must be at most 1e\+09 m"):
        nbvkit.DepthCamera(mesh, max_range=1e308)
    with pytest.raises(ValueError, match=r"laser max_range must be at most 1e\+09 m"):
        nbvkit.LaserScanner(mesh, max_range=1e308)
    with pytest.raises(ValueError, match=r"noise_k = 0.2 gives a depth noise sigma of 12.8 m"):
        nbvkit.DepthCamera(mesh, max_range=8.0, noise_k=0.2)
    nbvkit.DepthCamera(mesh, max_range=8.0, noise_k=0.125)  # sigma at 8 m: 8 m, the bound
    with pytest.raises(ValueError, match=r"noise_sigma = 1e\+308 m must not exceed max_range"):
        nbvkit.LaserScanner(mesh, noise_sigma=1e308)
    far = np.eye(4)
    far[0, 3] = 1e308
    for sensor in (nbvkit.DepthCamera, nbvkit.LaserScanner):
        with pytest.raises(ValueError, match=r"mount: offset \(1e\+308, 0, 0\)"):
            sensor(mesh, mount=far)
    with pytest.raises(ValueError, match=r"mount_transform: xyz \(1e\+308, 0, 0\)"):
        nbvkit.mount_transform([1e308, 0, 0])


def test_a_scene_tells_which_points_lie_within_a_distance_of_its_mesh_and_how_far():
    # one triangle in z = 0 over x, y in [0, 10] (x + y <= 10), far from the origin too
    for o in (np.zeros(3), np.array([1e5, -2e5, 50.0])):
        mesh = nbvkit.Mesh(o + [[0.0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2]])
        scene = nbvkit.RaycastScene(mesh)
        pts = o + np.array([[2.0, 2, 0.5], [2, 2, -0.5], [8, 8, 0.0], [-1, 0, 0]])
        # above, below, beside the hypotenuse (its nearest point (5, 5, 0): 4.24 m), 1 m off x = 0
        assert scene.within(pts, 0.6).tolist() == [True, True, False, False]
        assert scene.within(pts, 4.3).tolist() == [True, True, True, True]
        assert scene.within(pts, 0.4).tolist() == [False, False, False, False]
        # the distances themselves, and none beyond a bound
        np.testing.assert_allclose(scene.distances(pts), [0.5, 0.5, 18**0.5, 1], atol=1e-9)
        assert scene.distances(pts, 1.0).tolist() == [0.5, 0.5, np.inf, 1.0]
    with pytest.raises(ValueError, match=r"max_distance must be >= 0 m \(or infinity\), got nan"):
        scene.distances(pts, float("nan"))
    with pytest.raises(ValueError, match="max_distance must be >= 0 m"):
        scene.distances(pts, -1.0)
    with pytest.raises(ValueError, match="radius must be finite and >= 0"):
        scene.within(pts, float("nan"))
    with pytest.raises(ValueError, match="points"):
        scene.within(np.zeros((2, 2)), 1.0)
