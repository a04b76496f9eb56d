"""nbvkit.evaluate: coverage / area coverage / precision on the origin-anchored grid, completeness /
accuracy / F-score / Chamfer with exact nearest neighbours, determinism, bad input, and the
`nbvkit evaluate` command."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import nbvkit
from nbvkit import Evaluator, evaluate
from nbvkit.evaluation import DEFAULT_GT_DENSITY, SUMMARY_KEYS as KEYS
from conftest import box_mesh as box, eval_cells, shared_mesh

ROOT = Path(__file__).resolve().parent.parent


def square_x(x, lo, hi):
    """The square {x} x [lo, hi]^2 as two triangles."""
    v = np.array([[x, lo, lo], [x, hi, lo], [x, hi, hi], [x, lo, hi]], float)
    return nbvkit.Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int32))


def reference_metrics(gt, cloud, resolutions, taus):
    """The definitions, in plain numpy with brute-force distances (small inputs only)."""
    out = {k: {} for k in ("coverage", "area_coverage", "precision", "completeness", "accuracy")}
    for r in resolutions:
        kg = {tuple(k) for k in eval_cells(gt, r)}
        kc = {tuple(k) for k in eval_cells(cloud, r)}
        per_sample = [tuple(k) in kc for k in eval_cells(gt, r)]
        out["coverage"][f"{r:g}"] = len(kg & kc) / len(kg)
        out["area_coverage"][f"{r:g}"] = float(np.mean(per_sample))
        out["precision"][f"{r:g}"] = len(kg & kc) / len(kc)
    d = np.linalg.norm(gt[:, None, :] - cloud[None, :, :], axis=2)
    d_gt, d_cloud = d.min(axis=1), d.min(axis=0)
    for t in taus:
        out["completeness"][f"{t:g}"] = float(np.mean(d_gt <= t))
        out["accuracy"][f"{t:g}"] = float(np.mean(d_cloud <= t))
    out["chamfer_m"] = 0.5 * (d_gt.mean() + d_cloud.mean())
    return out


# A 2 m cube placed so that its faces lie mid-cell of the 0.05 m grid (x, y, z in [0.025, 2.025]):
# no sample sits on a cell boundary, so the cell counts are exact: a face crosses 41 x 41 cells,
# the cube 6 * 41^2 - 12 * 41 + 8 = 9602 (edge cells shared by two faces, corners by three).
CUBE_LO, CUBE_HI = 0.025, 2.025


@pytest.fixture(scope="module")
def cube():
    return box([CUBE_LO] * 3, [CUBE_HI] * 3)


@pytest.fixture(scope="module")
def cube_face_cloud():
    """Dense samples of the cube's x = 2.025 face alone."""
    return square_x(CUBE_HI, CUBE_LO, CUBE_HI).sample_surface(200_000, seed=5)


# ------------------------------------------------------------------------------ analytic scenes


def test_ground_truth_itself_scores_100_percent(cube):
    ev = Evaluator(cube, gt_density=2000, seed=1)
    r = ev(ev.gt_points)
    for k in ("coverage", "area_coverage", "precision"):
        assert r[k] == {"0.05": 1.0, "0.1": 1.0, "0.5": 1.0}
    for k in ("completeness", "accuracy", "fscore"):
        assert r[k] == {"0.05": 1.0, "0.1": 1.0}
    assert r["chamfer_m"] == 0.0
    assert r["n_points"] == r["n_gt_points"] == round(24 * 2000)
    assert r["gt_area_m2"] == pytest.approx(24.0)
    assert r["gt_density"] == pytest.approx(2000, rel=1e-9)


def test_one_cube_face_gives_a_sixth(cube, cube_face_cloud):
    r = evaluate(cube, cube_face_cloud, gt_density=20_000, seed=0)
    # Cells: the face's 41^2 of the cube's 9602 (exact: every cell holds samples at this density).
    assert r["gt_cells"]["0.05"] == 9602
    assert r["coverage"]["0.05"] == pytest.approx(41**2 / 9602, abs=1e-12)
    assert r["coverage"]["0.05"] == pytest.approx(1 / 6, abs=0.01)
    # Area: the face's layer of cells (x in [2.0, 2.05)) also holds 0.025 m strips of the four
    # neighbouring faces: (1 + 4 * 0.025 / 2) / 6 = 0.175 of the area. 480k samples: sigma 0.0006.
    assert r["area_coverage"]["0.05"] == pytest.approx(0.175, abs=0.003)
    assert r["area_coverage"]["0.05"] == pytest.approx(1 / 6, abs=0.01)
    assert r["precision"] == {"0.05": 1.0, "0.1": 1.0, "0.5": 1.0}
    # Within tau of the face: the face and tau-wide strips of its 4 neighbours: (1 + 4 tau / 2) / 6.
    for tau in (0.05, 0.1):
        assert r["completeness"][f"{tau:g}"] == pytest.approx((1 + 2 * tau) / 6, abs=0.003)
    assert r["accuracy"] == {"0.05": 1.0, "0.1": 1.0}
    P, R = r["accuracy"]["0.05"], r["completeness"]["0.05"]
    assert r["fscore"]["0.05"] == pytest.approx(2 * P * R / (P + R), rel=1e-12)


def test_shifted_cloud_gives_zero_at_fine_resolution(cube):
    ev = Evaluator(cube, gt_density=5000)
    shift = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)  # 1 m, off every face plane
    r = ev(ev.gt_points + shift)
    assert r["coverage"]["0.05"] < 0.02 and r["area_coverage"]["0.05"] < 0.02
    assert r["precision"]["0.05"] < 0.02
    assert r["coverage"]["0.5"] > r["coverage"]["0.05"]
    # The shifted faces cross the original ones along lines only: few points within 5 cm.
    assert r["completeness"]["0.05"] < 0.05 and r["accuracy"]["0.05"] < 0.05
    assert r["chamfer_m"] > 0.2


def test_far_cloud_scores_zero_and_fscore_is_zero(cube):
    r = evaluate(cube, np.full((10, 3), 50.0), gt_density=500)
    for k in ("coverage", "area_coverage", "precision"):
        assert all(v == 0 for v in r[k].values())
    assert r["accuracy"] == r["completeness"] == r["fscore"] == {"0.05": 0.0, "0.1": 0.0}
    # Chamfer: each far point is ~sqrt(3) * 48 m from the nearest cube corner region.
    assert r["chamfer_m"] > 80


def test_empty_cloud_scores_zero_without_error(cube):
    for empty in (np.zeros((0, 3)), [], nbvkit.PointCloud()):
        r = evaluate(cube, empty, gt_density=500)
        assert r["n_points"] == 0 and r["chamfer_m"] is None
        assert r["mean_dist_cloud_to_gt_m"] is None
        for k in ("coverage", "area_coverage", "precision", "completeness", "accuracy", "fscore"):
            assert all(v == 0.0 for v in r[k].values()), k
        assert r["gt_cells"]["0.05"] > 0
        json.dumps(r, allow_nan=False)


def test_precision_counts_outlier_cells():
    rng = np.random.default_rng(0)
    gt = rng.uniform(0, 1, size=(3000, 3)) * [4, 4, 0] + [0, 0, 1.01]  # a plane at z = 1.01
    good = gt[:1000]
    outliers = rng.uniform(-20, 20, size=(500, 3)) + [0, 0, 30]  # far away, all in distinct cells
    r = evaluate(gt, np.vstack([good, outliers]), resolutions=(0.05,), taus=(0.05,))
    good_cells = len(np.unique(np.floor(good / 0.05), axis=0))
    assert r["cloud_cells"]["0.05"] == good_cells + 500
    assert r["precision"]["0.05"] == pytest.approx(good_cells / (good_cells + 500), abs=1e-12)
    assert r["accuracy"]["0.05"] == pytest.approx(1000 / 1500, abs=1e-12)


def test_matches_the_definitions_on_random_data():
    rng = np.random.default_rng(7)
    gt = rng.normal(size=(1500, 3)) * [2, 1, 0.5] - [0.3, 0.2, 0.1]  # negative coordinates too
    cloud = np.vstack(
        [gt[::3] + rng.normal(scale=0.03, size=(500, 3)), rng.uniform(-3, 3, size=(300, 3))]
    )
    res, taus = (0.05, 0.1, 0.5, 1.3), (0.02, 0.05, 0.1, 0.4)
    ref = reference_metrics(gt, cloud, res, taus)
    # one kd-tree over the cloud, and the cloud scored in parts of 77 points (11 trees)
    for r in (evaluate(gt, cloud, resolutions=res, taus=taus, part_points=n) for n in (None, 77)):
        for k in ("coverage", "area_coverage", "precision", "completeness", "accuracy"):
            assert r[k].keys() == ref[k].keys()
            for key in r[k]:
                assert r[k][key] == pytest.approx(ref[k][key], abs=1e-12), (k, key)
        assert r["chamfer_m"] == pytest.approx(ref["chamfer_m"], rel=1e-12)
    for key, f in r["fscore"].items():
        P, R = r["accuracy"][key], r["completeness"][key]
        assert f == pytest.approx(2 * P * R / (P + R) if P + R else 0.0, rel=1e-12)
    assert r["gt_source"] == "points" and r["gt_density"] is None and r["gt_area_m2"] is None
    assert r["n_gt_points"] == 1500 and r["n_points"] == 800


def test_nearest_distances_are_exact():
    rng = np.random.default_rng(1)
    targets = np.vstack([rng.normal(size=(3000, 3)), np.zeros((50, 3))])  # duplicates too
    queries = np.vstack([rng.normal(size=(400, 3)) * 3, [[100, 100, 100]]])
    d = nbvkit.nearest_distances(targets, queries)
    ref = np.linalg.norm(queries[:, None] - targets[None], axis=2).min(axis=1)
    np.testing.assert_allclose(d, ref, rtol=1e-14, atol=0)
    assert np.isinf(nbvkit.nearest_distances(np.zeros((0, 3)), queries)).all()


# ------------------------------------------------------------------------------ contracts


def test_same_seed_same_numbers_and_threads_do_not_matter(cube, cube_face_cloud):
    a = evaluate(cube, cube_face_cloud, gt_density=3000, seed=4)
    b = evaluate(cube, cube_face_cloud, gt_density=3000, seed=4)
    assert a == b
    c = evaluate(cube, cube_face_cloud, gt_density=3000, seed=5)
    assert c != a and c["n_gt_points"] == a["n_gt_points"]
    n = nbvkit.get_num_threads()
    try:
        nbvkit.set_num_threads(1)
        assert evaluate(cube, cube_face_cloud, gt_density=3000, seed=4) == a
    finally:
        nbvkit.set_num_threads(0 if n > 1 else n)


def test_evaluator_reuse_equals_evaluate(cube, cube_face_cloud):
    ev = Evaluator(cube, gt_density=1500, seed=2)
    assert ev(cube_face_cloud) == evaluate(cube, cube_face_cloud, gt_density=1500, seed=2)
    assert ev.evaluate(cube_face_cloud[:100]) == evaluate(
        cube, cube_face_cloud[:100], gt_density=1500, seed=2
    )
    np.testing.assert_array_equal(ev.gt_points, cube.sample_surface(ev.num_gt_points, 2))
    assert "Evaluator" in repr(ev)


def test_options_object_with_keyword_overrides(cube, cube_face_cloud):
    opts = nbvkit.EvaluationOptions(gt_density=1500, seed=7, taus=[0.1])
    ev = Evaluator(cube, opts, seed=2)
    assert ev.options == opts.copy(seed=2) and opts.seed == 7
    expected = evaluate(cube, cube_face_cloud, gt_density=1500, seed=2, taus=0.1)
    assert ev(cube_face_cloud) == expected
    assert evaluate(cube, cube_face_cloud, {"gt_density": 1500, "seed": 2, "taus": [0.1]}) == (
        expected
    )
    assert Evaluator(cube, gt_density=None).options.gt_density == DEFAULT_GT_DENSITY
    with pytest.raises(ValueError, match="unknown EvaluationOptions option 'density'"):
        Evaluator(cube, density=1500)


def test_cell_figures_alone_equal_the_full_evaluation(cube, cube_face_cloud):
    ev = Evaluator(cube, gt_density=2000, seed=3)
    rng = np.random.default_rng(1)
    noisy = cube_face_cloud + rng.normal(0, 0.03, cube_face_cloud.shape)
    for cloud in (cube_face_cloud, noisy, np.zeros((0, 3))):
        full, cells = ev(cloud), ev.coverage(cloud)
        for key in ("coverage", "area_coverage", "precision", "gt_cells", "covered_cells"):
            assert cells[key] == full[key], key
    half = ev.coverage(cube_face_cloud[::2])["coverage"]["0.05"]
    assert 0 < half <= ev.coverage(cube_face_cloud)["coverage"]["0.05"]  # a subset covers less
    with pytest.raises(ValueError, match="cloud"):
        ev.coverage(np.array([[0.0, np.nan, 0.0]]))


CELL_KEYS = ("coverage", "area_coverage", "precision", "gt_cells", "cloud_cells", "covered_cells")


def test_a_face_on_a_cell_boundary_is_one_layer_of_cells_whatever_the_last_bits():
    """A face on a boundary plane of the grid (z = 12.4: cell 248 at 0.05 m; x = -3: cell -60), as
    modelled structures have them: its ground-truth samples and the points reconstructed on it
    are off the plane by a few ulps, either way (interpolation, ray casting). Each is counted
    in the cell above the plane, so the face is covered; floor(p / r) alone split both between
    two layers and left about half the face uncovered. A point a micrometre below the plane
    stays below it."""
    rng = np.random.default_rng(3)
    ulps = rng.integers(-4, 5, size=(4000, 2))  # each point's offset from the plane, in ulps
    for axis, at in ((2, 12.4), (0, -3.0)):
        uv = rng.uniform(0.0, 2.0, size=(4000, 2)) + 0.0123
        pts = np.insert(uv, axis, at, axis=1)
        gt, cloud = pts.copy(), pts.copy()
        gt[:, axis] += ulps[:, 0] * np.spacing(at)
        cloud[:, axis] += ulps[:, 1] * np.spacing(at)
        assert len(np.unique(np.floor(gt[:, axis] / 0.05))) == 2  # both sides of the plane
        r = evaluate(gt, cloud, resolutions=(0.05, 0.1), taus=(0.05,))
        for res in ("0.05", "0.1"):
            assert r["area_coverage"][res] == 1.0 and r["coverage"][res] == 1.0, (axis, res)
        layer = len(np.unique(np.floor(np.delete(gt, axis, axis=1) / 0.05), axis=0))
        assert r["gt_cells"]["0.05"] == layer  # one layer of cells
        # the same count kept between calls (a camera cloud read in place)
        camera = nbvkit._core.SurfaceCloud(voxel_size=0.025, min_z=float("-inf"))
        camera.add(cloud)
        ev = Evaluator(gt, resolutions=(0.05,), taus=(0.05,))
        assert ev.coverage([camera])["area_coverage"]["0.05"] == 1.0
        below = pts[:1].copy()
        below[0, axis] -= 1e-6
        assert evaluate(pts[:1], below, resolutions=(0.05,), taus=(0.05,))["coverage"]["0.05"] == 0


def test_a_centroid_that_moves_to_another_cell_uncovers_the_cell_it_left():
    # GT: one sample in the 0.5 m cell [0, 0.5)^3 and one in [0.5, 1) x [0, 0.5)^2. A camera-cloud
    # voxel of 1 m holds the centroid of its points: first (0.45, .2, .2), then, with a point at
    # (0.65, .2, .2), their mean (0.55, .2, .2): the covered 0.5 m cell is now the second one.
    gt = np.array([[0.2, 0.2, 0.2], [0.7, 0.2, 0.2]])
    ev = Evaluator(gt, resolutions=(0.5,), taus=(0.1,))
    cloud = nbvkit._core.SurfaceCloud(voxel_size=1.0, min_z=-1.0)
    cloud.add(np.array([[0.45, 0.2, 0.2]]))
    first = ev.coverage([cloud])
    assert first["covered_cells"]["0.5"] == 1 and first["area_coverage"]["0.5"] == 0.5
    cloud.add(np.array([[0.65, 0.2, 0.2]]))
    np.testing.assert_allclose(cloud.points, [[0.55, 0.2, 0.2]])
    second = ev.coverage([cloud])
    assert second["covered_cells"]["0.5"] == 1 and second["cloud_cells"]["0.5"] == 1
    assert second == ev.coverage(cloud.points)  # the cell it left is no longer covered
    assert ev._tracker is not None  # served by the tracker kept between calls
    ev.forget_clouds()
    assert ev.coverage([cloud], track=False) == second and ev._tracker is None  # one pass


def test_progress_refreshes_of_growing_clouds_equal_a_fresh_count(cube):
    """Evaluator.coverage of SurfaceClouds keeps a CoverageTracker between calls: centroids move
    between cells as points are added, a cloud is cleared, another replaces it, the observable
    mask changes, the list of clouds changes. Every call equals a count from scratch."""
    ev = Evaluator(cube, gt_density=3000, seed=2)
    gt = ev.gt_points
    rng = np.random.default_rng(5)
    cam = nbvkit._core.SurfaceCloud(voxel_size=0.02, min_z=-1.0)
    las = nbvkit._core.SurfaceCloud(voxel_size=0.1, min_z=-1.0)
    clouds = [cam, las]
    for step in range(24):
        near = gt[rng.integers(0, len(gt), 3000)] + rng.normal(0, 0.03, (3000, 3))
        clouds[step % len(clouds)].add(near)
        if step == 9:
            cam.clear()
        if step == 12:
            clouds = [nbvkit._core.SurfaceCloud(voxel_size=0.05, min_z=-1.0), las]
            clouds[0].add(near)
        if step == 15:
            ev.set_observable(rng.random(len(gt)) < 0.6)
        if step == 18:
            clouds = [las]
        if step == 21:
            ev.set_observable(None)
        got = ev.coverage(clouds)
        want = nbvkit.evaluation._to_dict(ev._core.evaluate_cells_of(clouds))
        for key in CELL_KEYS + nbvkit.evaluation._OBSERVABLE_KEYS:
            assert got.get(key) == want.get(key), (step, key)
    assert got["covered_cells"]["0.05"] > 0
    # a point too far from the origin for the grids: an error, and nothing counted
    far = nbvkit._core.SurfaceCloud(voxel_size=1.0, min_z=-1.0)
    far.add(np.array([[2e5, 0.0, 0.0]]))  # inside the 1 m cloud grid, outside the 0.05 m one
    with pytest.raises(ValueError, match="too far from the origin"):
        ev.coverage([las, far])
    with pytest.raises(ValueError, match="too far from the origin"):
        ev._core.evaluate_cells_of([las, far])
    assert ev.coverage([las]) == got  # the failed call changed nothing


def test_reference_cloud_mode(cube):
    gt = cube.sample_surface(20000, seed=3)
    r = evaluate(gt, gt[:10000])
    assert r["gt_source"] == "points" and r["gt_density"] is None and r["seed"] is None
    assert r["n_gt_points"] == 20000 and r["accuracy"]["0.05"] == 1.0
    assert 0.5 < r["area_coverage"]["0.05"] < 1.0 and r["coverage"]["0.5"] > 0.95
    pc = nbvkit.PointCloud(gt, voxel_size=1e-5, min_z=float("-inf"))  # keeps every sample
    assert evaluate(pc, gt[:10000]) == r  # a PointCloud is a reference cloud too


def test_result_keys_and_json(cube, cube_face_cloud):
    r = evaluate(cube, cube_face_cloud[:5000], gt_density=500)
    for k in KEYS + ("n_gt_points", "gt_area_m2", "resolutions", "taus", "seed"):
        assert k in r
    assert list(r["coverage"]) == ["0.05", "0.1", "0.5"] and list(r["fscore"]) == ["0.05", "0.1"]
    assert r["resolutions"] == [0.05, 0.1, 0.5] and r["taus"] == [0.05, 0.1]
    json.loads(json.dumps(r, allow_nan=False))
    r2 = evaluate(cube, cube_face_cloud[:5000], resolutions=0.2, taus=[0.3], gt_density=500)
    assert list(r2["coverage"]) == ["0.2"] and list(r2["accuracy"]) == ["0.3"]


def test_default_density_is_documented():
    assert DEFAULT_GT_DENSITY == 1000
    assert "1000" in evaluate.__doc__
    assert "--stability" in nbvkit.evaluation.__doc__  # the measurement that chose it
    config = pytest.importorskip("nbvkit.config")
    if hasattr(config, "EvaluationConfig"):
        d = config.EvaluationConfig().gt_density
        assert d is None or d == DEFAULT_GT_DENSITY


def test_gt_cap_warns(cube):
    with pytest.warns(RuntimeWarning, match="capped at 1000"):
        r = evaluate(cube, np.zeros((0, 3)), gt_density=1e6, max_gt_points=1000)
    assert r["n_gt_points"] == 1000 and r["gt_density"] == pytest.approx(1000 / 24)


def test_bad_input(cube):
    good = np.ones((5, 3))
    with pytest.raises(ValueError, match="cloud contains NaN"):
        evaluate(cube, [[0, 0, np.nan]])
    with pytest.raises(ValueError, match="cloud contains NaN or infinite"):
        evaluate(good, [[0, 0, np.inf]])
    with pytest.raises(ValueError, match="ground truth contains NaN"):
        evaluate([[0, np.nan, 0]], good)
    with pytest.raises(ValueError, match="ground truth point cloud is empty"):
        evaluate(np.zeros((0, 3)), good)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        evaluate(cube, np.ones((4, 2)))
    for res in (0, -0.05, float("nan"), [0.05, float("inf")], "fine"):
        with pytest.raises(ValueError, match="resolutions"):
            evaluate(good, good, resolutions=res)
    with pytest.raises(ValueError, match="duplicate"):
        evaluate(good, good, resolutions=(0.1, 0.1))
    for tau in (0, -1, [float("nan")]):
        with pytest.raises(ValueError, match="taus"):
            evaluate(good, good, taus=tau)
    for d in (0, -10, float("nan"), float("inf"), "dense"):
        with pytest.raises(ValueError, match="gt_density"):
            evaluate(cube, good, gt_density=d)
    with pytest.raises(ValueError, match="no ground-truth samples"):
        evaluate(cube, good, gt_density=1e-3)
    for seed in (-1, 1.5, True):
        with pytest.raises(ValueError, match="seed"):
            evaluate(cube, good, seed=seed)
    with pytest.raises(ValueError, match="too far from the origin"):
        evaluate(good, [[1e6, 0, 0]], resolutions=(0.05,))


# ------------------------------------------------------------------------------ the twinjet


def camera_cloud(mesh, views):
    cam = nbvkit.DepthCamera(nbvkit.RaycastScene(mesh))
    cloud = nbvkit.PointCloud()
    for pose in views:
        cloud.add(cam.scan_pose(pose))
    return cloud


def test_twinjet_coverage_is_stable_across_gt_seeds():
    mesh = nbvkit.load_mesh(shared_mesh("twinjet.obj"))
    cloud = camera_cloud(
        mesh,
        [(x, -7.0, 3.0, math.pi / 2) for x in (-10, -5, 0, 5, 10)]
        + [(x, 7.0, 3.0, -math.pi / 2) for x in (-5, 5)],
    )
    ev0, ev1 = Evaluator(mesh, seed=0), Evaluator(mesh, seed=1)
    a, b = ev0(cloud), ev1(cloud)
    assert a["n_gt_points"] == round(mesh.area * DEFAULT_GT_DENSITY)
    assert 0.05 < a["coverage"]["0.05"] < 0.5  # one side of the fuselage, some wing
    for key in ("0.05", "0.1", "0.5"):
        assert abs(a["coverage"][key] - b["coverage"][key]) < 0.005
        assert abs(a["area_coverage"][key] - b["area_coverage"][key]) < 0.005
    assert a["accuracy"]["0.05"] > 0.99  # exact scans of the same surface
    assert ev0(cloud) == a


# ------------------------------------------------------------------------------ command line


@pytest.fixture(scope="module")
def cube_files(tmp_path_factory, cube, cube_face_cloud):
    d = tmp_path_factory.mktemp("evalcli")
    v, f = cube.vertices, cube.faces + 1
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in v] + [f"f {a} {b} {c}" for a, b, c in f]
    (d / "cube.obj").write_text("\n".join(lines) + "\n")
    nbvkit.write_points(d / "face.ply", cube_face_cloud[:20000])
    nbvkit.write_points(d / "gt.npy", cube.sample_surface(30000, 0))
    return d


def test_cli_evaluate_warns_when_the_cloud_is_in_another_frame(cube_files, capsys, tmp_path):
    from nbvkit.cli import main

    face = nbvkit.read_points(cube_files / "face.ply")
    args = ["evaluate", "--mesh", str(cube_files / "cube.obj"), "--gt-density", "500"]
    assert main([*args, str(cube_files / "face.ply")]) == 0
    assert "same frame" not in capsys.readouterr().err
    nbvkit.write_points(tmp_path / "moved.ply", face + [0.0, 0.0, 100.0])
    assert main([*args, str(tmp_path / "moved.ply")]) == 0
    err = capsys.readouterr().err
    assert "same frame" in err and "--mesh-shift" in err


def test_cli_prints_its_own_warnings_in_one_line(cube_files, capsys, tmp_path):
    """A warning of nbvkit's own reaches the console as its errors do ("nbvkit evaluate:
    warning: ..."), not as Python's file, line and source of nbvkit's code; and a warning is not
    lost: the points it names are dropped and the rest scored."""
    from nbvkit.cli import main

    face = nbvkit.read_points(cube_files / "face.ply")
    body = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in face[:500])
    header = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
    n = 501
    pcd = header + f"WIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA ascii\n" + body + "nan 0 0\n"
    (tmp_path / "nan.pcd").write_text(pcd)
    args = ["evaluate", "--mesh", str(cube_files / "cube.obj"), "--gt-density", "500"]
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # whatever filter pytest set
        assert main([*args, str(tmp_path / "nan.pcd")]) == 0
    err = capsys.readouterr().err
    line = f"nbvkit evaluate: warning: {tmp_path / 'nan.pcd'}: dropped 1 points with NaN"
    assert line in err and "RuntimeWarning" not in err and ".py:" not in err, err


def test_cli_evaluate_writes_json(cube_files, capsys):
    from nbvkit.cli import main

    out = cube_files / "r.json"
    rc = main(
        [
            "evaluate",
            "--mesh",
            str(cube_files / "cube.obj"),
            str(cube_files / "face.ply"),
            "--json",
            str(out),
            "--gt-density",
            "2000",
            "--seed",
            "3",
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "coverage" in text and "0.05 m" in text and "Chamfer" in text
    r = json.loads(out.read_text())
    assert r["gt_density"] == pytest.approx(2000) and r["n_points"] == 20000 and r["seed"] == 3
    assert r["coverage"]["0.05"] == pytest.approx(1 / 6, abs=0.02)
    expected = evaluate(
        nbvkit.load_mesh(cube_files / "cube.obj"),
        nbvkit.read_points(cube_files / "face.ply"),
        gt_density=2000,
        seed=3,
    )
    for k in KEYS:
        assert r[k] == expected[k]


def test_cli_reference_cloud_and_scaled_mesh(cube_files, capsys):
    from nbvkit.cli import main

    out = cube_files / "ref.json"
    assert (
        main(
            [
                "evaluate",
                "--reference-cloud",
                str(cube_files / "gt.npy"),
                str(cube_files / "face.ply"),
                "--json",
                str(out),
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    assert r["gt_density"] is None and r["n_gt_points"] == 30000 and r["gt_source"] == "points"
    assert r["reference_cloud"].endswith("gt.npy")
    # a 2x-scaled mesh no longer contains the face: coverage drops to ~0
    out2 = cube_files / "scaled.json"
    assert (
        main(
            [
                "evaluate",
                "--mesh",
                str(cube_files / "cube.obj"),
                "--mesh-scale",
                "2",
                str(cube_files / "face.ply"),
                "--json",
                str(out2),
                "--gt-density",
                "500",
            ]
        )
        == 0
    )
    assert json.loads(out2.read_text())["coverage"]["0.05"] < 0.01
    capsys.readouterr()


def test_cli_errors(cube_files, capsys):
    from nbvkit.cli import main

    missing = cube_files / "missing_cloud.ply"
    assert main(["evaluate", "--mesh", str(cube_files / "cube.obj"), str(missing)]) != 0
    err = capsys.readouterr().err
    assert "missing_cloud.ply" in err and "error" in err
    assert (
        main(
            [
                "evaluate",
                "--mesh",
                str(cube_files / "cube.obj"),
                "--reference-cloud",
                str(cube_files / "gt.npy"),
                str(cube_files / "face.ply"),
            ]
        )
        != 0
    )
    assert "not both" in capsys.readouterr().err
    assert (
        main(
            [
                "evaluate",
                "--mesh",
                str(cube_files / "cube.obj"),
                str(cube_files / "face.ply"),
                "--resolutions",
                "0",
            ]
        )
        != 0
    )
    assert "resolutions" in capsys.readouterr().err
    (cube_files / "bad.pcd").write_text("not a pcd\n")
    assert (
        main(["evaluate", "--mesh", str(cube_files / "cube.obj"), str(cube_files / "bad.pcd")]) != 0
    )
    assert "bad.pcd" in capsys.readouterr().err


def test_cli_help_explains_every_option():
    proc = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", "evaluate", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0
    for opt in (
        "--mesh",
        "--mesh-scale",
        "--mesh-up",
        "--reference-cloud",
        "--json",
        "--gt-density",
        "--seed",
        "--resolutions",
        "--taus",
        "CLOUD",
    ):
        assert opt in proc.stdout


def test_coverage_of_clouds_read_in_place_equals_that_of_their_points_stacked():
    rng = np.random.default_rng(3)
    mesh = box((0, 0, 0), (4, 3, 2))
    ev = Evaluator(mesh, gt_density=400, seed=1)
    samples = np.asarray(mesh.sample_surface(30000, seed=2))
    near = samples + rng.normal(0, 0.03, samples.shape)  # off the surface by a few cm
    camera = nbvkit.PointCloud(near[:20000], min_z=float("-inf"))
    laser = nbvkit.PointCloud(near[20000:], voxel_size=0.1, min_z=float("-inf"))
    ev.set_observable(np.arange(ev.num_gt_points) % 3 != 0)  # the observable figures too
    stacked = ev.coverage(np.vstack([camera.points, laser.points]))
    in_place = ev.coverage([camera, laser])
    assert in_place == stacked
    assert 0.1 < in_place["coverage"]["0.05"] < in_place["coverage"]["0.5"] <= 1.0
    assert ev.coverage([laser]) == ev.coverage(laser.points)
    with pytest.raises(ValueError, match="SurfaceCloud"):
        ev._core.evaluate_cells_of([camera, None])


def test_a_full_evaluation_of_clouds_read_in_place_equals_that_of_their_points_stacked():
    # the mission's final scoring: no stacked copy held, the same figures (distances included)
    rng = np.random.default_rng(5)
    mesh = box((0, 0, 0), (4, 3, 2))
    ev = Evaluator(mesh, gt_density=400, seed=1)
    near = np.asarray(mesh.sample_surface(20000, seed=2)) + rng.normal(0, 0.03, (20000, 3))
    camera = nbvkit.PointCloud(near[:15000], min_z=float("-inf"))
    laser = nbvkit.PointCloud(near[15000:], voxel_size=0.1, min_z=float("-inf"))
    stacked = np.vstack([camera.points, laser.points])
    assert np.array_equal(nbvkit._core.stack_points([camera, laser]), stacked)
    in_place, of_points = ev.evaluate([camera, laser]), ev.evaluate(stacked)
    assert in_place == of_points
    assert in_place["n_points"] == len(stacked) and in_place["chamfer_m"] > 0
    empty = ev.evaluate([nbvkit.PointCloud()])
    assert empty["n_points"] == 0 and empty["coverage"]["0.05"] == 0.0
    with pytest.raises(ValueError, match="SurfaceCloud"):
        nbvkit._core.stack_points([camera, None])


def _cell_figures(gt, cloud, r):
    """coverage, area coverage and precision at cell size r from their definitions (numpy)."""

    def keys(p):  # the integer cell of each point, packed in one int64 (21 bits an axis)
        c = eval_cells(p, r) + (1 << 20)
        return (c[:, 0] << 42) | (c[:, 1] << 21) | c[:, 2]

    kg, kc = keys(gt), np.unique(keys(cloud))
    cells, inv = np.unique(kg, return_inverse=True)
    hit = np.isin(cells, kc)
    return hit.mean(), float(hit[inv].mean()), int(hit.sum()) / len(kc)


def test_cell_figures_of_a_cloud_of_millions_match_their_definitions():
    # over 3 M points the distinct cells are found in 4 parts in parallel (evaluation.cpp)
    rng = np.random.default_rng(11)
    gt = rng.uniform(-4, 4, size=(200000, 3)) * [1, 1, 0.25]
    cloud = np.vstack(
        [gt[::2] + rng.normal(0, 0.04, (100000, 3)), rng.uniform(-5, 5, (3300000, 3))]
    )
    ev = Evaluator(gt, resolutions=(0.05, 0.1, 0.5))
    figures = ev.coverage(cloud)
    for r in (0.05, 0.1, 0.5):
        cov, area, prec = _cell_figures(gt, cloud, r)
        key = f"{r:g}"
        assert figures["coverage"][key] == pytest.approx(cov, abs=1e-12)
        assert figures["area_coverage"][key] == pytest.approx(area, abs=1e-12)
        assert figures["precision"][key] == pytest.approx(prec, abs=1e-12)


def test_the_ground_truth_is_the_same_before_and_after_its_tree_is_built():
    """The evaluator holds its samples as points until a score needs distances, then as a
    kd-tree: the points, the cell figures and the observable figures do not change."""
    rng = np.random.default_rng(5)
    gt = rng.uniform(-2, 2, size=(2000, 3))
    cloud = gt[:700] + rng.normal(scale=0.02, size=(700, 3))
    mask = gt[:, 0] < 0.5
    ev = Evaluator(gt)
    ev.set_observable(mask)
    before = ev.coverage(cloud)
    np.testing.assert_array_equal(ev.gt_points, gt)
    full = ev(cloud)  # builds the tree
    np.testing.assert_array_equal(ev.gt_points, gt)
    assert ev.coverage(cloud) == before
    ev.set_observable(mask)  # the cells of the observable samples, now read from the tree
    assert ev.coverage(cloud) == before
    assert {k: full[k] for k in before} == before
    np.testing.assert_allclose(ev._core.nearest_to_gt(gt[:5]), 0.0, atol=0)


def test_cli_evaluate_refuses_observable_settings_without_observable(cube_files, capsys):
    """--set, --config and --cache define only the observable surface: given without
    --observable they would be ignored silently, so they are refused, named."""
    from nbvkit.cli import main

    args = ["evaluate", "--mesh", str(cube_files / "cube.obj"), str(cube_files / "face.ply")]
    assert main([*args, "--gt-density", "500", "--set", "camera.max_range=20"]) == 2
    err = capsys.readouterr().err
    assert "--set defines only the observable surface" in err and "--observable" in err
    assert main([*args, "--gt-density", "500", "--cache", str(cube_files / "c")]) == 2
    assert "--cache defines only" in capsys.readouterr().err


def test_cli_evaluate_of_a_run_folder_scores_it_against_the_mesh_it_flew(
    tmp_path, monkeypatch, capsys
):
    """A run's folder names its mesh (config.yaml: path, scale, up, shift): evaluate scores the
    cloud against it (it took the default airliner, and a cube inside the airliner's box scored
    0 % without a warning), reproducing the run's own figures; mesh options without --mesh, or
    a mesh not found from here, are refused."""
    import shutil

    from conftest import TINY_RUN
    from nbvkit import cli

    (tmp_path / "m").mkdir()
    shutil.copy(ROOT / "meshes" / "fixtures" / "cube.obj", tmp_path / "m" / "cube.obj")
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    argv = ["run", "--mesh", "m/cube.obj", "--mesh-scale", "2", "--no-progress", "--out", str(out)]
    assert cli.main([*argv, "--set", *TINY_RUN, "report.enabled=false"]) == 0
    flown = json.loads((out / "summary.json").read_text())
    j = tmp_path / "e.json"
    assert cli.main(["evaluate", str(out), "--json", str(j)]) == 0  # the run's density, seed
    e = json.loads(j.read_text())
    assert (e["mesh"], e["mesh_scale"], e["gt_density"]) == ("m/cube.obj", 2.0, 50.0)
    assert e["coverage"] == flown["coverage"] and min(e["coverage"].values()) > 0
    capsys.readouterr()
    assert cli.main(["evaluate", str(out), "--mesh-scale", "3"]) == 2
    assert "give --mesh too" in capsys.readouterr().err
    monkeypatch.chdir(tmp_path / "m")
    assert cli.main(["evaluate", str(out)]) == 2
    assert "flew the mesh 'm/cube.obj' (its config.yaml), which is not found" in (
        capsys.readouterr().err
    )


def test_a_run_of_the_default_mesh_or_an_in_memory_one_is_scored_as_it_was_flown(tmp_path):
    """The default airliner at the run's scale, up axis and shift (they were dropped with the
    path); a run flown on an in-memory mesh names no file, so a ground truth must be given."""
    from argparse import Namespace

    from nbvkit.commands.evaluate import _settings_of_run

    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.json").write_text('{"mesh": "airliner.obj", "gt_density": 80, "seed": 3}')
    (run / "config.yaml").write_text("mesh: {path: null, scale: 0.5, up: y, shift: [0, 0, 5]}\n")
    keys = ("mesh", "mesh_scale", "mesh_up", "mesh_shift", "reference_cloud", "gt_density", "seed")
    keys += ("observable", "config")
    args = Namespace(**{**dict.fromkeys(keys), "mesh_scale": 1.0, "mesh_up": "auto"})
    _settings_of_run(args, run)
    assert (args.mesh, args.mesh_scale, args.mesh_up, args.mesh_shift) == (
        None,
        0.5,
        "y",
        [0, 0, 5],
    )
    assert (args.gt_density, args.seed) == (80.0, 3)
    (run / "summary.json").write_text('{"mesh": "<in-memory mesh>"}')
    args = Namespace(**{**dict.fromkeys(keys), "mesh_scale": 1.0, "mesh_up": "auto"})
    with pytest.raises(ValueError, match="flew a mesh given in memory"):
        _settings_of_run(args, run)
