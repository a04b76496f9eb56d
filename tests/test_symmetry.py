"""Symmetry detection and prediction (paper sec. 3.2.2): geometry helpers, the FPFH mirror map,
mean shift, detection on synthetic clouds and simulated laser profiles in arbitrary poses, ICP
correction, prediction, the mission hook, figures and bad input."""
from __future__ import annotations

import json
import math
import re
import time
from dataclasses import fields
from types import SimpleNamespace

import numpy as np
import pytest

import nbvkit
from nbvkit import _core
from nbvkit import symmetry as sym
from nbvkit.config import Config, SymmetryConfig

from conftest import box_mesh, shared_mesh

# ------------------------------------------------------------------------------ helpers


def rotation(axis, deg):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    a = math.radians(deg)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def random_rotation(rng):
    """A uniformly random 3 x 3 rotation."""
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=rng).as_matrix()


def plane_errors(plane, true, at):
    """(angle in degrees, offset in metres) of `plane` from `true`, the offset measured at the
    projection of `at` on the true plane."""
    plane, true = np.asarray(plane, float), np.asarray(true, float)
    n, d = plane[:3] / np.linalg.norm(plane[:3]), plane[3] / np.linalg.norm(plane[:3])
    nt, dt = true[:3] / np.linalg.norm(true[:3]), true[3] / np.linalg.norm(true[:3])
    if n @ nt < 0:
        n, d = -n, -d
    angle = math.degrees(math.acos(min(1.0, abs(float(n @ nt)))))
    q = at - (nt @ at - dt) * nt
    return angle, abs(float(n @ q - d))


def moved_plane(plane, R, t):
    """The plane after x -> R x + t."""
    n = R @ plane[:3]
    return np.r_[n, plane[3] + n @ t]


def simulate_profile(mesh, waypoints=10, radius=25.0, center=None):
    """A laser profile: waypoints on a circle around the structure's centre, each sweeping z from
    0.5 to 10 m in 0.5 m steps facing the centre; hits voxelised at 0.1 m, ground below 0.3 m
    removed. Returns (points, scans)."""
    lo, hi = mesh.bounds
    c = (lo + hi) / 2 if center is None else np.asarray(center, float)
    laser = nbvkit.LaserScanner(mesh)
    cloud = _core.SurfaceCloud(voxel_size=0.1, min_z=0.3)
    scans = []
    for k in range(waypoints):
        th = 2 * math.pi * k / waypoints
        x, y = c[0] + radius * math.cos(th), c[1] + radius * math.sin(th)
        yaw = math.atan2(c[1] - y, c[0] - x)
        for z in np.arange(0.5, 10.0001, 0.5):
            scan = laser.scan_pose([x, y, z, yaw])
            cloud.add(scan.hits)
            scans.append(scan)
    return cloud.points, scans


def uv_sphere(center, r, nu=24, nv=12):
    c = np.asarray(center, float)
    verts = [c + [0, 0, r], c - [0, 0, r]]
    for i in range(1, nv):
        th = math.pi * i / nv
        for j in range(nu):
            ph = 2 * math.pi * j / nu
            verts.append(
                c
                + r
                * np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
            )

    def idx(i, j):
        return 2 + (i - 1) * nu + (j % nu)

    faces = []
    for j in range(nu):
        faces += [[0, idx(1, j), idx(1, j + 1)], [1, idx(nv - 1, j + 1), idx(nv - 1, j)]]
    for i in range(1, nv - 1):
        for j in range(nu):
            a, b, c2, d = idx(i, j), idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)
            faces += [[a, c2, b], [b, c2, d]]
    return np.array(verts), np.array(faces, np.int32)


def merge_meshes(*parts):
    V, F, off = [], [], 0
    for v, f in parts:
        V.append(np.asarray(v, float))
        F.append(np.asarray(f) + off)
        off += len(v)
    return nbvkit.Mesh(np.vstack(V), np.vstack(F).astype(np.int32))


def box(lo, hi):
    m = box_mesh(lo, hi)
    return m.vertices, m.faces


def l_block_with_sphere():
    """A clearly asymmetric structure: an L of two blocks of different heights, a sphere beside."""
    return merge_meshes(
        box((-8, -2, 0), (8, 2, 4)), box((4, 2, 0), (8, 12, 6)), uv_sphere((-5, -5, 2.5), 2.5)
    )


Y0 = np.array([0.0, 1.0, 0.0, 0.0])  # the mirror plane y = 0 of the airliner and the twinjet

# ------------------------------------------------------------------------------ fixtures


@pytest.fixture(scope="module")
def airliner():
    return nbvkit.load_mesh(nbvkit.default_mesh_path())


@pytest.fixture(scope="module")
def airliner_profile(airliner):
    return simulate_profile(airliner)


@pytest.fixture(scope="module")
def airliner_profile_posed(airliner):
    """The airliner yawed by 37 degrees and moved off the origin before the profile is flown (the
    scan pattern is then not mirror-symmetric), then the whole profile rigidly moved in 3D."""
    R = rotation([0, 0, 1], 37.0)
    t = np.array([6.0, -4.0, 0.0])
    mesh = nbvkit.Mesh(airliner.vertices @ R.T + t, airliner.faces)
    points, _ = simulate_profile(mesh, radius=28.0)
    true = moved_plane(Y0, R, t)
    R3, t3 = random_rotation(np.random.default_rng(5)), np.array([120.0, -40.0, 15.0])
    return points @ R3.T + t3, moved_plane(true, R3, t3)


@pytest.fixture(scope="module")
def synthetic_cloud(airliner):
    """Airliner surface samples with 2 cm noise and a missing region (most of one wing and a side
    of the fuselage), in an arbitrary pose. Returns (points, true plane, removed points)."""
    rng = np.random.default_rng(0)
    pts = airliner.sample_surface(25000, seed=0) + rng.normal(0, 0.02, (25000, 3))
    missing = (pts[:, 1] > 3.0) & (pts[:, 0] > -5.0)
    R, t = random_rotation(rng), rng.uniform(-50, 50, 3)
    move = lambda p: p @ R.T + t  # noqa: E731
    return move(pts[~missing]), moved_plane(Y0, R, t), move(pts[missing])


# ------------------------------------------------------------------------------ geometry helpers


def test_plane_from_pair_and_canonical_sign():
    p, q = np.array([1.0, 2.0, 3.0]), np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(sym.plane_from_pair(p, q), [0, 1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(
        sym.plane_from_pair(q + 5, p + 5), [0, 1, 0, 5], atol=1e-12
    )  # order-free
    np.testing.assert_allclose(sym.canonical_plane([0, -2, 0, -4]), [0, 1, 0, 2])
    np.testing.assert_allclose(
        sym.canonical_plane([-3, 1, 0, 6]), np.array([3, -1, 0, -6]) / math.sqrt(10)
    )
    with pytest.raises(ValueError):
        sym.plane_from_pair(p, p)
    with pytest.raises(ValueError):
        sym.canonical_plane([0, 0, 0, 1])


def test_reflection_and_improper_isometry():
    rng = np.random.default_rng(1)
    plane = sym.canonical_plane(np.r_[rng.normal(size=3), 2.5])
    pts = rng.normal(size=(100, 3)) * 10
    M = sym.reflection_matrix(plane)
    np.testing.assert_allclose(M @ M, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(
        sym.reflect_points(sym.reflect_points(pts, plane), plane), pts, atol=1e-9
    )
    mid = 0.5 * (pts + sym.reflect_points(pts, plane))
    np.testing.assert_allclose(mid @ plane[:3], plane[3], atol=1e-9)  # midpoints on the plane
    got, resid = sym.plane_from_improper_isometry(M)
    np.testing.assert_allclose(got, plane, atol=1e-9)
    assert resid == pytest.approx(0, abs=1e-6)
    # a rotation about the normal after the reflection (a rotoreflection) keeps the plane
    T = np.eye(4)
    T[:3, :3] = rotation(plane[:3], 4.0)
    got, resid = sym.plane_from_improper_isometry(T @ M)
    assert plane_errors(got, plane, np.zeros(3))[0] < 1e-6
    assert resid == pytest.approx(4.0, abs=1e-6)
    with pytest.raises(ValueError):
        sym.plane_from_improper_isometry(np.eye(4))  # proper: no mirror plane


def test_fpfh_mirror_map_matches_the_descriptor_of_the_mirror_image():
    """FPFH is not mirror-invariant; the FPFH of a point's mirror image equals the point's FPFH
    with the f2 sub-histogram reversed (PCL: f1 = atan2(w.n_t, u.n_t) and f3 = u.d are
    unchanged, f2 = v.n_t changes sign) — and no other choice of reversed sub-histograms fits."""
    cloud = l_block_with_sphere().sample_surface(20000, seed=1)
    plane = sym.canonical_plane([0.3, -0.5, 0.8, 1.7])
    mirror = sym.reflect_points(cloud, plane)
    idx = np.arange(0, len(cloud), 97)
    F = sym.compute_fpfh(cloud, idx)
    G = sym.compute_fpfh(mirror, idx)
    assert F.shape == (len(idx), 33) and F.dtype == np.float32
    scale = np.median(np.linalg.norm(F, axis=1))
    plain = np.median(np.linalg.norm(F - G, axis=1))
    mirrored = np.median(np.linalg.norm(F - sym.mirror_fpfh(G), axis=1))
    assert plain > 1e-2 * scale  # not mirror-invariant
    assert mirrored < 1e-5 * scale  # the mirror map is exact up to float rounding
    np.testing.assert_array_equal(sym.mirror_fpfh(sym.mirror_fpfh(F)), F)  # an involution

    def flipped(D, subs):
        D = D.copy()
        for s in subs:
            D[:, 11 * s : 11 * s + 11] = D[:, 11 * s : 11 * s + 11][:, ::-1]
        return D

    for subs in [(0,), (2,), (0, 1), (1, 2), (0, 2), (0, 1, 2)]:
        assert np.median(np.linalg.norm(F - flipped(G, subs), axis=1)) > 100 * mirrored


# ------------------------------------------------------------------------------ mean shift


def test_mean_shift_finds_the_dominant_mode_across_sign_flips():
    rng = np.random.default_rng(2)
    center, scale = np.array([3.0, -1.0, 2.0]), 10.0

    def cluster(n, normal, d, count, flip_half=False):
        normal = np.asarray(normal, float) / np.linalg.norm(normal)
        out = []
        for k in range(count):
            nn = normal + rng.normal(0, 0.01, 3)
            nn /= np.linalg.norm(nn)
            pl = np.r_[nn, d + rng.normal(0, 0.05)]
            out.append(-pl if flip_half and k % 2 else pl)
        return out

    dominant = cluster(
        0, [0.2, 1.0, 0.1], 1.5, 60, flip_half=True
    )  # half stored with the other sign
    second = cluster(0, [1.0, 0.0, 0.3], -2.0, 40)
    third = cluster(0, [0.0, 0.3, 1.0], 4.0, 25)
    noise = [np.r_[v / np.linalg.norm(v), rng.uniform(-20, 20)] for v in rng.normal(size=(100, 3))]
    planes = np.array(dominant + second + third + noise)
    planes = planes[rng.permutation(len(planes))]
    cl = sym.mean_shift_planes(planes, center, scale)
    true = sym.canonical_plane(
        np.r_[np.array([0.2, 1.0, 0.1]) / np.linalg.norm([0.2, 1.0, 0.1]), 1.5]
    )
    ang, off = plane_errors(cl.plane, true, center)
    assert ang < 1.0 and off < 0.1
    assert 55 <= cl.support <= 65
    assert cl.inliers.shape == (len(planes),) and cl.inliers.sum() == cl.support
    assert cl.modes.shape[1] == 4 and cl.mode_support[0] == cl.support
    assert np.all(np.diff(cl.mode_support) <= 0)
    # the second cluster is found as the next mode
    assert (
        plane_errors(
            cl.modes[1],
            sym.canonical_plane(
                np.r_[np.array([1.0, 0, 0.3]) / np.linalg.norm([1.0, 0, 0.3]), -2.0]
            ),
            center,
        )[0]
        < 1.0
    )
    empty = sym.mean_shift_planes(np.zeros((0, 4)), center, scale)
    assert empty.support == 0 and np.all(np.isnan(empty.plane))


# ------------------------------------------------------------------------------ detection


def test_synthetic_cloud_with_noise_and_missing_region(synthetic_cloud):
    points, true, _ = synthetic_cloud
    res = nbvkit.detect_symmetry(points)
    ang, off = plane_errors(res.plane, true, points.mean(0))
    assert ang < 2.0 and off < 0.2, (ang, off, res)
    assert res.accepted, res.reason
    assert np.linalg.norm(res.plane[:3]) == pytest.approx(1.0)
    assert res.support >= 8 and 0.7 <= res.confidence <= 1.0
    K, P = len(res.keypoints), len(res.pairs)
    assert (
        res.keypoints.shape == (K, 3)
        and res.pairs.shape == (P, 2)
        and res.pair_planes.shape == (P, 4)
    )
    assert (
        res.pairs.min() >= 0 and res.pairs.max() < K and np.all(res.pairs[:, 0] < res.pairs[:, 1])
    )
    assert res.inliers.sum() == res.support
    for stage in ("normals", "keypoints", "descriptors", "matching", "mean_shift", "total"):
        assert res.timings[stage] >= 0


def test_airliner_profile(airliner_profile):
    points, _ = airliner_profile
    res = nbvkit.detect_symmetry(points)
    ang, off = plane_errors(res.plane, Y0, points.mean(0))
    assert ang < 2.0 and off < 0.2, (ang, off, res)
    assert res.accepted, res.reason
    again = nbvkit.detect_symmetry(points)  # deterministic
    np.testing.assert_array_equal(again.plane, res.plane)


def test_results_do_not_depend_on_the_thread_count(airliner_profile):
    # the parallel stages (SIFT, nearest neighbours, ICP correspondences) keep PCL's serial order
    points, _ = airliner_profile
    n = nbvkit.get_num_threads()
    runs = []
    try:
        for threads in (1, 2):
            nbvkit.set_num_threads(threads)
            res = nbvkit.detect_symmetry(points)
            pred = nbvkit.predict_symmetric(points, res.plane)
            runs.append((res, pred))
    finally:
        nbvkit.set_num_threads(0 if n > 1 else n)
    (a, pa), (b, pb) = runs
    np.testing.assert_array_equal(a.keypoints, b.keypoints)
    np.testing.assert_array_equal(a.plane, b.plane)
    np.testing.assert_array_equal(pa.plane, pb.plane)
    np.testing.assert_array_equal(pa.predicted, pb.predicted)


def test_airliner_profile_in_an_arbitrary_pose(airliner_profile_posed):
    points, true = airliner_profile_posed
    res = nbvkit.detect_symmetry(points)
    ang, off = plane_errors(res.plane, true, points.mean(0))
    assert ang < 2.0 and off < 0.2, (ang, off, res)
    assert res.accepted, res.reason


@pytest.mark.parametrize("keypoints", ["iss", "uniform"])
def test_other_keypoint_detectors(airliner_profile, keypoints):
    points, _ = airliner_profile
    res = nbvkit.detect_symmetry(points, keypoints=keypoints)
    ang, off = plane_errors(res.plane, Y0, points.mean(0))
    assert ang < 2.0 and off < 0.2 and res.accepted


def test_twinjet_profile():
    mesh = nbvkit.load_mesh(str(shared_mesh("twinjet.obj")))
    points, _ = simulate_profile(mesh)
    res = nbvkit.detect_symmetry(points)
    ang, off = plane_errors(res.plane, Y0, points.mean(0))
    assert ang < 2.0 and off < 0.2, (ang, off, res)
    assert res.accepted, res.reason


def test_asymmetric_shape_is_rejected():
    points, _ = simulate_profile(l_block_with_sphere())
    res = nbvkit.detect_symmetry(points)
    assert not res.accepted
    assert res.confidence < 0.5, res
    assert "confidence" in res.reason or "support" in res.reason


# ------------------------------------------------------------------------------ ICP and prediction


def planted(true, at, deg, offset, seed):
    """`true` tilted by `deg` about an axis in the plane (through the projection of `at`) and
    shifted by `offset` metres."""
    rng = np.random.default_rng(seed)
    n = true[:3] / np.linalg.norm(true[:3])
    axis = np.cross(n, rng.normal(size=3))
    n2 = rotation(axis, deg) @ n
    q = at - (n @ at - true[3]) * n
    return np.r_[n2, n2 @ q + offset]


def test_icp_corrects_a_planted_error(airliner_profile, synthetic_cloud):
    for points, true in ((airliner_profile[0], Y0), synthetic_cloud[:2]):
        c = points.mean(0)
        bad = planted(true, c, 3.0, 0.3, seed=3)
        assert plane_errors(bad, true, c)[0] == pytest.approx(3.0, abs=1e-6)
        out = nbvkit.predict_symmetric(points, bad)
        ang, off = plane_errors(out.plane, true, c)
        assert ang < 0.5 and off < 0.05, (ang, off)
        assert out.icp_converged and out.icp_applied
        assert np.linalg.det(out.transform[:3, :3]) == pytest.approx(-1.0, abs=1e-6)
        np.testing.assert_allclose(out.input_plane, sym.canonical_plane(bad))
        # without ICP the plane is kept as given
        raw = nbvkit.predict_symmetric(points, bad, icp=False)
        np.testing.assert_allclose(raw.plane, sym.canonical_plane(bad), atol=1e-9)
        assert not raw.icp_applied


def test_prediction_fills_the_missing_region(synthetic_cloud):
    points, true, removed = synthetic_cloud
    # 25k random samples over 743 m^2 leave gaps of ~0.3 m between observed samples: a reflection
    # falling in such a gap is explained by the observed surface around it
    predicted, plane = nbvkit.predict_symmetric(points, true, explained_tolerance=0.3)
    assert predicted.ndim == 2 and predicted.shape[1] == 3 and len(predicted) > 500
    d_obs = nbvkit.nearest_distances(points, predicted)
    assert d_obs.min() > 0.3  # nothing already explained by an observation
    d_removed = nbvkit.nearest_distances(removed, predicted)
    assert np.mean(d_removed < 0.3) > 0.9  # predictions lie in the missing region
    covered = nbvkit.nearest_distances(predicted, removed)
    assert np.mean(covered < 0.3) > 0.8  # and fill it
    # a complete symmetric cloud predicts (almost) nothing
    full = np.vstack([points, removed])
    assert len(
        nbvkit.predict_symmetric(full, true, explained_tolerance=0.3).predicted
    ) < 0.01 * len(full)


# ----------------------------------------------------------------------- mission hook and figures


def test_run_symmetry_prediction_writes_the_map(airliner, tmp_path):
    """A sparse profile (5 waypoints, the airliner yawed so the pattern is not symmetric) leaves
    holes; the hook detects the plane, predicts, and sets unknown cells to 0.6."""
    R = rotation([0, 0, 1], 20.0)
    mesh = nbvkit.Mesh(airliner.vertices @ R.T, airliner.faces)
    points, scans = simulate_profile(mesh, waypoints=5, radius=28.0)
    lo, hi = mesh.bounds
    m = _core.OccupancyMap(0.2, lo - [2.5, 2.5, 0.0], hi + [2.5, 2.5, 2.5])
    for s in scans:
        m.integrate(s)
    cloud = _core.SurfaceCloud(voxel_size=0.1, min_z=0.3)
    cloud.add(points)
    mission = SimpleNamespace(config=Config(), laser_cloud=cloud, map=m)
    states_before = m.state_grid()
    summary = sym.run_symmetry_prediction(mission)
    json.dumps(summary, allow_nan=False)  # JSON-safe
    assert (
        summary["accepted"] and summary["support"] >= 8 and 0.7 <= summary["confidence"] <= 1
    ), summary
    changed = m.state_grid() != states_before
    assert changed.sum() <= summary["cells_set"]
    assert np.all(states_before[changed] == -1)  # only unknown cells changed
    true = moved_plane(Y0, R, np.zeros(3))
    ang, off = plane_errors(summary["plane"], true, points.mean(0))
    assert ang < 2.0 and off < 0.2
    assert summary["predicted_points"] > 500
    pred = mission.symmetry_prediction.predicted
    assert 0 < summary["cells_set"] <= len(pred)
    flagged = m.is_predicted(pred)
    assert flagged.sum() > 0.5 * summary["cells_set"]  # (several points can share a cell)
    np.testing.assert_allclose(m.probability(pred[flagged]), 0.6, atol=1e-6)
    np.testing.assert_array_equal(mission.symmetry_profile, cloud.points)
    line = sym.summary_line(summary)  # the console's: the plane, as the summary gives it
    a, b, c, d = (round(v, n) + 0.0 for v, n in zip(summary["plane"], (3, 3, 3, 2)))
    assert line.startswith(f"symmetry: mirror plane {a:.3f} x {b:+.3f} y {c:+.3f} z = {d:.2f}")
    # the equation holds on the plane (n . p = d): it said "... z +4001.98 = 0" for y = 4001.98
    eq = re.search(
        r"plane (\S+) x (\S+) y (\S+) z = (\S+) \(",
        sym.summary_line({**summary, "plane": [0.0, 1.0, 0.0, 4001.98]}),
    )
    assert [float(v) for v in eq.groups()] == [0.0, 1.0, 0.0, 4001.98]
    assert line.endswith(f"{summary['support']} pairs), {summary['cells_set']:,} cells predicted")
    assert sym.summary_line({**summary, "written": False}).endswith("pairs), nothing written")
    assert "-0.00" not in sym.summary_line({**summary, "plane": [-1e-9, 1.0, -1e-9, -0.004]})
    # later observations override predictions: fly the full 10-waypoint profile
    _, more = simulate_profile(mesh, waypoints=10, radius=28.0)
    for s in more:
        m.integrate(s)
    assert m.is_predicted(pred).sum() < 0.5 * flagged.sum()


def test_run_symmetry_prediction_rejects_without_touching_the_map():
    points, _ = simulate_profile(l_block_with_sphere())
    cloud = _core.SurfaceCloud(voxel_size=0.1, min_z=0.3)
    cloud.add(points)
    m = _core.OccupancyMap(0.2, [-12, -10, 0], [12, 16, 8])
    total = m.total_entropy()
    mission = SimpleNamespace(config=Config(), laser_cloud=cloud, map=m)
    summary = sym.run_symmetry_prediction(mission)
    json.dumps(summary, allow_nan=False)
    assert not summary["accepted"] and summary["plane"] is None
    assert summary["cells_set"] == 0 and summary["predicted_points"] == 0
    assert m.total_entropy() == total
    said = sym.summary_line(summary)  # why, with its numbers short: 0.41, not 0.412345
    assert said.startswith("symmetry: no mirror plane accepted (") and "nothing predicted" in said
    assert summary["reason"] and not re.search(r"\.\d{3,}", said), (summary["reason"], said)
    # too few points: reported, not raised
    empty = SimpleNamespace(config=Config(), laser_cloud=_core.SurfaceCloud(voxel_size=0.1), map=m)
    out = sym.run_symmetry_prediction(empty)
    assert not out["accepted"] and out["reason"]
    # a bad option is an error, not a rejection: the configuration refuses it before any work
    with pytest.raises(ValueError, match="min_confidence"):
        Config.from_dict({"symmetry": {"min_confidence": 2.0}})


def test_plot_symmetry(synthetic_cloud, tmp_path):
    points, true, _ = synthetic_cloud
    res = nbvkit.detect_symmetry(points)
    pred = nbvkit.predict_symmetric(points, res.plane)
    path = sym.plot_symmetry(points, res, pred, tmp_path / "fig" / "symmetry.png")
    assert path.exists() and path.stat().st_size > 10_000
    sym.plot_symmetry(points, None, None, tmp_path / "bare.png")  # no plane: panels still drawn
    assert (tmp_path / "bare.png").exists()


def test_config_defaults_equal_the_cpp_defaults():
    det, pre = sym.SymmetryOptions(), sym.SymmetricPredictionOptions()
    cfg = SymmetryConfig()
    assert cfg.prediction_probability == 0.6  # the paper
    dopts, popts = sym.detection_options(cfg), sym.prediction_options(cfg)
    assert dopts == det.to_dict() and popts == pre.to_dict()
    # every option has one config key of the same name; the rest are the mission's
    mission_keys = {"prediction_probability", "mode", "refresh_every"}
    assert {f.name for f in fields(SymmetryConfig)} == mission_keys | set(dopts) | set(popts)
    assert not set(dopts) & set(popts)
    # a changed key reaches its call
    changed = Config.from_dict({"symmetry": {"fpfh_radius": 1.5, "icp_voxel_size": 0.2}}).symmetry
    assert sym.detection_options(changed)["fpfh_radius"] == 1.5
    assert sym.prediction_options(changed)["icp_voxel_size"] == 0.2
    with pytest.raises(ValueError):
        Config.from_dict({"symmetry": {"keypoints": "harris"}})
    with pytest.raises(ValueError, match="icp_normal_k"):
        Config.from_dict({"symmetry": {"icp_normal_k": 2}})


def test_options_objects_and_keywords_agree(synthetic_cloud):
    points = synthetic_cloud[0]
    a = nbvkit.detect_symmetry(points, sym.SymmetryOptions(fpfh_radius=1.2))
    b = nbvkit.detect_symmetry(points, {"fpfh_radius": 1.2})
    c = nbvkit.detect_symmetry(points, fpfh_radius=1.2, bandwidth=None)
    assert np.array_equal(a.plane, b.plane) and np.array_equal(a.plane, c.plane)
    assert sym.SymmetryOptions().keypoints == "sift"
    assert "fpfh_radius" in nbvkit.detect_symmetry.__doc__
    assert "icp_max_correspondence" in nbvkit.predict_symmetric.__doc__


# ------------------------------------------------------------------------------ bad input


def test_bad_input_raises_value_error():
    good = np.random.default_rng(0).normal(size=(200, 3))
    plane = [0, 1, 0, 0]
    bad_points = [
        np.full((200, 3), np.nan),
        np.r_[good[:-1], [[np.inf, 0, 0]]],
        good[:5],
        good[:, :2],
        good.ravel(),
        None,
        "points",
        np.zeros((0, 3)),
    ]
    for p in bad_points:
        with pytest.raises(ValueError):
            nbvkit.detect_symmetry(p)
        with pytest.raises(ValueError):
            nbvkit.predict_symmetric(p, plane)
    for pl in ([0, 0, 0, 1], [0, 1, 0], [np.nan, 1, 0, 0], [[0, 1, 0, 0]], None):
        with pytest.raises(ValueError):
            nbvkit.predict_symmetric(good, pl)
    for opts in (
        {"voxel_size": -1},
        {"keypoints": "harris"},
        {"no_such_option": 1},
        {"normal_k": 2.5},
        {"bandwidth": 2.0},
        {"min_confidence": 1.5},
        {"mirror_descriptors": "yes"},
        {"fpfh_radius": float("nan")},
    ):
        with pytest.raises(ValueError):
            nbvkit.detect_symmetry(good, **opts)
    with pytest.raises(ValueError):
        nbvkit.predict_symmetric(good, plane, icp_max_correspondence=0)
    with pytest.raises(ValueError):
        sym.mean_shift_planes(np.zeros((3, 3)), [0, 0, 0], 1.0)
    with pytest.raises(ValueError):
        sym.mean_shift_planes(np.zeros((3, 4)), [0, 0, 0], 0.0)
    for radius in (0.0, -1.0, float("nan"), float("inf")):  # inf searched the whole cloud, forever
        with pytest.raises(ValueError, match="radius"):
            sym.compute_fpfh(good, [0, 1], radius=radius)


def test_a_radius_spanning_the_cloud_is_refused_at_once_with_one_that_fits():
    # 27,000 points 1 m apart: a search radius spanning them puts every point in every
    # neighbourhood (7.3e8 pairs, minutes of FPFH); refused before any work, naming the option
    # and a radius within the limit, which then runs
    g = np.arange(30.0)
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    for key, opts in (
        ("fpfh_radius", {"fpfh_radius": 1e12}),
        ("normal_radius", {"normal_radius": 1e6}),
        ("iss_salient_radius", {"keypoints": "iss", "iss_salient_radius": 500.0}),
    ):
        t = time.perf_counter()
        with pytest.raises(ValueError, match=f"{key} = .* quadratic .* use {key} about") as e:
            nbvkit.detect_symmetry(lattice, **opts)
        assert time.perf_counter() - t < 5.0, key  # not a search of minutes
        fits = float(str(e.value).split(f"use {key} about ")[1].split()[0])
        assert 1.0 < fits < 30.0
    with pytest.raises(ValueError, match="radius = 1e\\+19 m"):
        sym.compute_fpfh(lattice, [0, 1], radius=1e19)


def test_degenerate_clouds_report_no_plane():
    # 1000 points on a line: no normals, no pairs; reported, not a garbage plane
    line = np.c_[np.linspace(0, 10, 1000), np.zeros(1000), np.zeros(1000)]
    res = nbvkit.detect_symmetry(line)
    assert not res.accepted
    # everything in one voxel
    res = nbvkit.detect_symmetry(np.random.default_rng(0).uniform(0, 0.01, (50, 3)))
    assert not res.accepted and res.support == 0 and np.all(np.isnan(res.plane)) and res.reason
