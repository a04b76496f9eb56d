"""The observable surface: analytic scenes (a sealed hollow box, a plate on the ground, a tower
taller than the navigation space), the Evaluator's observable figures, the cache, the CLI."""
from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import CUBE_MESH, TINY_RUN, box_mesh

import nbvkit
from nbvkit import _core
from nbvkit.config import load_config
from nbvkit import observable_surface


def merge(*meshes) -> nbvkit.Mesh:
    v, f, off = [], [], 0
    for m in meshes:
        v.append(np.asarray(m.vertices))
        f.append(np.asarray(m.faces) + off)
        off += len(m.vertices)
    return nbvkit.Mesh(np.vstack(v), np.vstack(f).astype(np.int32))


def inverted(m: nbvkit.Mesh) -> nbvkit.Mesh:
    return nbvkit.Mesh(m.vertices, np.asarray(m.faces)[:, ::-1].copy())


def samples(mesh, n=4000, seed=1):
    p, fid = mesh.sample_surface(n, seed, return_faces=True)
    return p, fid


def cfg(*over):
    return load_config(None, ["observability.pose_spacing=0.5", *over])


def test_a_sealed_hollow_box_is_seen_outside_and_never_inside():
    # walls 0.3 m thick around a 5 x 5 x 3.4 m hall: large enough to hold free lattice points,
    # which the flood fill must find unreachable
    outer = box_mesh((-3, -3, 0.0), (3, 3, 4.0))
    inner = inverted(box_mesh((-2.7, -2.7, 0.3), (2.7, 2.7, 3.7)))
    mesh = merge(outer, inner)
    p, fid = samples(mesh)
    r = observable_surface(mesh, cfg(), points=p, face_ids=fid)
    assert r.stats["unreachable"] > 0  # free positions inside the hall exist and are dropped
    inside = fid >= 12
    assert not r.observable[inside].any()
    floor = fid < 2  # the outer box's faces 0, 1 lie on the ground
    assert r.observable[~inside & ~floor].mean() > 0.99
    assert not r.observable[floor].any()


def _hall_with_window(w: float) -> nbvkit.Mesh:
    """A 5.4 x 5.4 x 3.4 m hall inside 0.3 m walls, a w x w window in its +x wall at 2 m up."""
    h = w / 2
    return merge(
        box_mesh((-3, -3, 0), (3, 3, 0.3)),
        box_mesh((-3, -3, 3.7), (3, 3, 4)),
        box_mesh((-3, -3, 0), (-2.7, 3, 4)),
        box_mesh((-3, -3, 0), (3, -2.7, 4)),
        box_mesh((-3, 2.7, 0), (3, 3, 4)),
        box_mesh((2.7, -3, 0), (3, 3, 2 - h)),
        box_mesh((2.7, -3, 2 + h), (3, 3, 4)),
        box_mesh((2.7, -3, 2 - h), (3, -h, 2 + h)),
        box_mesh((2.7, h, 2 - h), (3, 3, 2 + h)),
    )


def test_a_window_narrower_than_the_vehicle_lets_the_camera_look_in_but_not_the_vehicle_fly_in():
    # The vehicle's collision sphere (0.8 m) passes a 2.4 m window, not a 1 m one. Through the
    # small window only what a camera outside sees through it is observable; the hall's free
    # positions, which see out through the window, are not reachable (they were, by a ray).
    inner = {}
    for w in (1.0, 2.4):
        mesh = _hall_with_window(w)
        p, fid = samples(mesh, 20000)
        lo, hi = np.array([-2.7, -2.7, 0.3]) - 1e-6, np.array([2.7, 2.7, 3.7]) + 1e-6
        walls = ((p >= lo) & (p <= hi)).all(axis=1)  # the hall's inner faces
        r = observable_surface(mesh, cfg(), points=p, face_ids=fid)
        inner[w] = (r.observable[walls].mean(), r.stats["unreachable"])
    assert inner[2.4][0] > 0.99 and inner[2.4][1] == 0  # flown in: every inner face seen
    assert inner[1.0][1] > 0  # the hall's positions: free, but the vehicle cannot get there
    assert 0.2 < inner[1.0][0] < 0.9  # the inner faces a camera outside sees through it


def test_a_plate_on_the_ground_has_an_unobservable_underside():
    mesh = box_mesh((-2, -2, 0.0), (2, 2, 0.1))
    p, fid = samples(mesh)
    r = observable_surface(mesh, cfg(), points=p, face_ids=fid)
    # (occlusion rays start 0.5 mm off the surface: ignore samples within 1 mm of the rim)
    inner = np.abs(p[:, :2]).max(axis=1) < 2 - 1e-3
    under = (p[:, 2] < 1e-9) & inner
    top = p[:, 2] > 0.1 - 1e-9
    assert under.sum() > 100 and top.sum() > 100
    assert not r.observable[under].any()
    assert r.observable[top].all()


def test_the_top_of_a_tower_taller_than_the_navigation_space_is_unobservable():
    mesh = box_mesh((-1, -1, 0.0), (1, 1, 20.0))
    box = ("workspace.bounds_min=[-8,-8,0]", "workspace.bounds_max=[8,8,10]")
    c = cfg(*box, "camera.gimbal_pitch_deg=[0,0]")  # the fixed level camera
    p, fid = samples(mesh, 8000)
    r = observable_surface(mesh, c, points=p, face_ids=fid)
    top = p[:, 2] > 20 - 1e-9
    assert top.sum() > 20
    assert not r.observable[top].any()
    # a horizontal camera at most 9.1 m up sees the walls up to 9.1 + 8 tan(22.5 deg) ~ 12.4 m
    low_wall = (p[:, 2] > 1.5) & (p[:, 2] < 9.0)
    assert r.observable[low_wall].mean() > 0.99
    assert not r.observable[(p[:, 2] > 13.0) & ~top].any()
    # pitched 30 deg up, the camera reaches higher up the walls but still not the roof
    up = observable_surface(
        mesh,
        cfg(*box, "camera.mount_rpy_deg=[0,-30,0]", "camera.gimbal_pitch_deg=[0,0]"),
        points=p,
        face_ids=fid,
    )
    assert up.observable.sum() > r.observable.sum()
    assert not up.observable[top].any()
    # the gimbal (30 deg up to straight down, the default) reaches as high as that mount
    gimbal = observable_surface(mesh, cfg(*box), points=p, face_ids=fid)
    assert np.all(gimbal.observable >= up.observable) and not gimbal.observable[top].any()


def test_an_open_mesh_works_and_the_range_limits_apply():
    # a single wall (no interior at all): observable from in front, within range
    v = np.array([[0, -1, 1], [0, 1, 1], [0, 1, 3], [0, -1, 3]], float)
    mesh = nbvkit.Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int32))
    p, fid = samples(mesh, 500)
    r = observable_surface(mesh, cfg(), points=p, face_ids=fid)
    assert r.observable.all()
    # with a max range shorter than the clearance the camera can keep, nothing is seen
    near = observable_surface(
        mesh, cfg("camera.max_range=0.7", "camera.min_range=0.1"), points=p, face_ids=fid
    )
    assert not near.observable.any()


def test_the_lattice_reaches_the_navigation_boxs_faces():
    """A slab's underside 0.8 m above the navigation box's floor, seen only from below: the
    lattice's lowest level lies on the floor (the box split evenly, faces included). A lattice
    about the box's centre (levels 1.05, 3.05, ... m for a floor at 0.2 m) flew none below the
    slab and counted its underside unseeable. One sample per 0.2 m of the underside's rim."""
    slab = box_mesh((-2.0, -2.0, 1.0), (2.0, 2.0, 1.3))
    scene = _core.RaycastScene(slab)
    cam = _core.DepthCamera(scene)
    x = np.arange(-1.9, 1.95, 0.2)
    rim = np.c_[
        np.r_[x, x, np.full_like(x, 1.9)], np.r_[np.zeros_like(x), x, x], np.ones(3 * len(x))
    ]
    down = np.tile([0.0, 0.0, -1.0], (len(rim), 1))
    r = _core.observable_samples(
        scene, rim, down, cam, [-6, -6, 0.2], [6, 6, 9.9], pose_spacing=2.0, collision_radius=0.3
    )
    assert r.poses[:, 2].min() == 0.2 and r.poses[:, 2].max() == 9.9  # on the faces, exactly
    odd = _core.observable_samples(  # a side whose steps do not add up to it exactly in floats
        scene, rim, down, cam, [-6, -6, 0.3], [6, 6, 0.3 + 6.000000000000001], pose_spacing=2.0
    )
    assert odd.poses[:, 2].max() == 0.3 + 6.000000000000001  # within the box, not an ulp past it
    assert r.lattice_points == 7 * 7 * 6  # 12 m in 6 steps of 2, 9.7 m in 5 of 1.94
    assert np.asarray(r.observable).any()  # the rim near the box's sides, from below
    centred = _core.observable_samples(  # the levels a lattice about the centre had
        scene, rim, down, cam, [-6, -6, 1.05], [6, 6, 9.05], pose_spacing=2.0, collision_radius=0.3
    )
    assert np.isclose(centred.poses[:, 2].min(), 1.05) and not np.asarray(centred.observable).any()


def test_bad_arguments_raise_value_errors():
    mesh = box_mesh((0, 0, 0), (1, 1, 1))
    scene = _core.RaycastScene(mesh)
    cam = _core.DepthCamera(scene, width=8, height=6)
    p = np.zeros((3, 3))
    with pytest.raises(ValueError, match="normals"):
        _core.observable_samples(scene, p, np.zeros((2, 3)), cam, [0, 0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match="pose_spacing"):
        _core.observable_samples(scene, p, p, cam, [0, 0, 0], [1, 1, 1], pose_spacing=0)
    with pytest.raises(ValueError, match="navigation box"):
        _core.observable_samples(scene, p, p, cam, [0, 0, 0], [-1, 1, 1])
    # finite, but beyond any position the ray caster takes (Embree aborted the process)
    for lo, hi in (([-1e300, 0, 0], [1, 1, 1]), ([0, 0, 0], [1e19, 1, 1])):
        with pytest.raises(ValueError, match="nav_m.. .*not a usable position"):
            _core.observable_samples(scene, p, p, cam, lo, hi)
    # a usable box whose lattice would overflow a 64-bit count: refused by its size
    with pytest.raises(ValueError, match="candidate positions"):
        _core.observable_samples(scene, p, p, cam, [-1e9] * 3, [1e9] * 3, pose_spacing=1e-3)


def test_another_meshs_evaluator_or_scene_and_bad_face_ids_are_refused():
    # (another mesh's scene gave 1.0 observable where 0.835 was; a negative face id picked a
    # triangle from the end)
    mesh = box_mesh((-1, -1, 0), (1, 1, 2))
    bigger = nbvkit.Mesh(np.asarray(mesh.vertices) * 2, mesh.faces)
    cfg = load_config(overrides=["evaluation.gt_density=20"])
    with pytest.raises(ValueError, match="evaluator was built of another mesh: its surface is 96"):
        observable_surface(mesh, cfg, evaluator=nbvkit.Evaluator(bigger, gt_density=20))
    with pytest.raises(ValueError, match="scene was built of another mesh"):
        observable_surface(mesh, cfg, scene=nbvkit.RaycastScene(bigger))
    p = np.array(mesh.sample_surface(3, 0))
    for ids, needle in (
        ([-1, -2, 0], r"in \[0, 12\), got -2..0"),
        ([0, 1, 12], r"in \[0, 12\), got 0..12"),
        ([0, 1], r"must be \(3,\) integers, one triangle a point, got shape \(2,\)"),
        ([0.5, 1, 2], "got shape .3,. of float64"),
    ):
        with pytest.raises(ValueError, match=needle):
            observable_surface(mesh, cfg, points=p, face_ids=ids)
    whole = observable_surface(mesh, cfg, points=p, face_ids=[0.0, 1.0, 2.0])  # as the core takes
    assert whole.observable.shape == (3,)
    same = nbvkit.RaycastScene(nbvkit.Mesh(mesh.vertices, mesh.faces))  # an equal mesh: its own
    assert observable_surface(mesh, cfg, scene=same).observable.shape == (20 * 24,)


def test_the_evaluator_counts_coverage_relative_to_the_observable_samples():
    gt = np.array([[0.05, 0.05, 0.05], [1.05, 0.05, 0.05], [2.05, 0.05, 0.05], [3.05, 0.05, 0.05]])
    ev = nbvkit.Evaluator(gt, resolutions=(0.1, 0.5), taus=(0.05,))
    assert "coverage_observable" not in ev(gt[:1])
    ev.set_observable([True, True, False, False])
    r = ev(gt[[0, 2]])  # one observable cell and one unobservable one covered
    assert r["coverage"]["0.1"] == pytest.approx(0.5)
    assert r["coverage_observable"]["0.1"] == pytest.approx(0.5)
    assert r["area_coverage_observable"]["0.5"] == pytest.approx(0.5)
    assert r["observable_fraction"]["0.1"] == pytest.approx(0.5)
    assert r["observable_area_fraction"] == pytest.approx(0.5)
    c = ev.coverage(gt[[2, 3]])  # only unobservable samples covered
    assert c["coverage_observable"]["0.1"] == 0.0 and c["coverage"]["0.1"] == 0.5
    assert ev(gt[:2])["coverage_observable"]["0.1"] == 1.0
    with pytest.raises(ValueError, match="shape"):
        ev.set_observable([True])
    for bad in ([0.5, 1, 0, 0], [np.nan, 1, 0, 0], ["yes", "", "", ""]):
        with pytest.raises(ValueError, match="must be bool"):
            ev.set_observable(bad)
    ev.set_observable([1, 1, 0, 0])  # 0/1 is bool's meaning
    assert ev(gt[:2])["coverage_observable"]["0.1"] == 1.0
    ev.set_observable(None)
    assert "coverage_observable" not in ev(gt)


def test_the_cache_is_reused_and_keyed_by_the_settings(tmp_path):
    mesh = box_mesh((-2, -2, 0.0), (2, 2, 0.1))
    c = load_config(None, ["evaluation.gt_density=100"])
    a = observable_surface(mesh, c, cache_dir=tmp_path)
    b = observable_surface(mesh, c, cache_dir=tmp_path)
    assert not a.cached and b.cached
    np.testing.assert_array_equal(a.observable, b.observable)
    assert len(list(tmp_path.glob("observable-*.npz"))) == 1
    d = observable_surface(
        mesh,
        load_config(None, ["evaluation.gt_density=100", "camera.max_range=4"]),
        cache_dir=tmp_path,
    )
    assert not d.cached and len(list(tmp_path.glob("observable-*.npz"))) == 2
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".npz", ".npz"]  # no lock file left


def test_cli_evaluate_observable_json(tmp_path):
    from nbvkit.cli import main

    mesh = box_mesh((-2, -2, 0.0), (2, 2, 0.12))
    obj = tmp_path / "plate.obj"
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    obj.write_text(
        "".join(f"v {x} {y} {z}\n" for x, y, z in v)
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)
    )
    g = np.arange(-1.99, 2, 0.025)
    top = np.array([[x, y, 0.12] for x in g for y in g])
    np.save(tmp_path / "top.npy", top)
    out = tmp_path / "r.json"
    args = ["evaluate", "--mesh", str(obj), str(tmp_path / "top.npy"), "--gt-density", "200"]
    assert main([*args, "--observable", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    for k in ("coverage_observable", "area_coverage_observable", "observable_fraction"):
        assert set(r[k]) == {"0.05", "0.1", "0.5"}, k
    # top 16 m^2 (covered) + rim 1.92 m^2 (observable, missed) of 33.92 m^2; underside unseen
    assert r["observable_area_fraction"] == pytest.approx(17.92 / 33.92, abs=0.03)
    assert r["area_coverage_observable"]["0.05"] == pytest.approx(16 / 17.92, abs=0.03)
    assert r["area_coverage"]["0.05"] == pytest.approx(16 / 33.92, abs=0.03)
    # a mesh as the reconstruction: its surface is sampled
    assert (
        main(["evaluate", "--mesh", str(obj), str(obj), "--gt-density", "200", "--json", str(out)])
        == 0
    )
    r = json.loads(out.read_text())
    assert r["reconstruction"].startswith("mesh") and r["coverage"]["0.05"] > 0.95
    # observability needs the mesh
    ref = str(tmp_path / "top.npy")
    assert main(["evaluate", "--reference-cloud", ref, ref, "--observable"]) != 0


def test_cli_evaluate_observable_of_a_run_uses_the_runs_settings(tmp_path):
    """A run's cloud scored with --observable and no --config: the observable surface is the
    one the run computed (its own camera, workspace and gimbal), not the default
    configuration's."""
    from nbvkit.cli import main

    run = tmp_path / "level"
    level = ["camera.gimbal_pitch_deg=[0,0]", "report.enabled=false"]
    argv = ["run", "--mesh", str(CUBE_MESH), "--no-progress", "--out", str(run), "--set"]
    assert main([*argv, *TINY_RUN, *level]) == 0
    summary = json.loads((run / "summary.json").read_text())
    out = tmp_path / "e.json"
    assert main(["evaluate", str(run), "--observable", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["observability"]["settings"] == summary["observability"]["settings"]
    assert r["observability"]["settings"]["gimbal_pitch_deg"] == [0.0, 0.0]
    assert r["observable_fraction"] == summary["observable_fraction"]
    # --config still names another configuration: the default one's gimbal
    default = tmp_path / "default.yaml"
    default.write_text("seed: 0\n")
    assert (
        main(["evaluate", str(run), "--observable", "--config", str(default), "--json", str(out)])
        == 0
    )
    assert json.loads(out.read_text())["observability"]["settings"]["gimbal_pitch_deg"] == [-30, 90]


def test_python_defaults_equal_the_cpp_defaults():
    from nbvkit.config import Config

    cpp = _core.ObservabilityOptions()
    o, v = Config().observability, Config().vehicle
    assert o.options() == cpp  # the section's keys come from the bound options
    assert v.collision_radius == cpp.collision_radius  # the radius comes from the vehicle


def test_a_roof_seen_only_by_a_pitched_camera_is_observable_with_the_gimbal():
    """Issue 33, part 4: a 4 x 4 m plate whose centre the vehicle can only be right above (the
    navigation box ends 1 m beyond its edges, 1.5-3 m over it) is outside a level camera's
    45 deg vertical field of view, and inside it once the gimbal pitches down."""
    from conftest import box_mesh

    plate = box_mesh((-2, -2, 4.9), (2, 2, 5.0))
    scene = nbvkit.RaycastScene(plate)
    pts = np.array([[x, y, 5.0] for x in np.linspace(-1, 1, 5) for y in np.linspace(-1, 1, 5)])
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    camera = nbvkit.DepthCamera(scene, width=16, height=12, noise_k=0.0)
    lo, hi = np.array([-2.5, -2.5, 6.5]), np.array([2.5, 2.5, 8.0])

    def observable(g):
        opts = _core.ObservabilityOptions(
            pose_spacing=0.5, gimbal_min_deg=g[0], gimbal_max_deg=g[1]
        )
        r = _core.observable_samples(
            scene, pts, normals, camera, lo, hi, options=opts, collision_radius=0.8
        )
        return np.asarray(r.observable, bool)

    level = observable((0.0, 0.0))
    pitched = observable((-30.0, 90.0))
    assert not level[12]  # the centre: straight below every reachable position's reach
    assert pitched.all()
    assert np.all(pitched >= level)  # the gimbal only adds
    with pytest.raises(ValueError, match="gimbal_min_deg"):
        _core.ObservabilityOptions(gimbal_min_deg=10, gimbal_max_deg=5)


@pytest.mark.parametrize("mount_pitch", [0.0, 20.0, -40.0])
@pytest.mark.parametrize(
    "gimbal", [(0.0, 0.0), (-30.0, 90.0), (0.0, 30.0), (20.0, 60.0), (-90.0, 0.0), (70.0, 80.0)]
)
def test_a_sample_is_seen_exactly_within_the_gimbal_range_widened_by_half_the_fov(
    gimbal, mount_pitch
):
    """One vehicle position, samples 5 m away at depression angles every 5 deg (facing it, no
    occluder): seen exactly where the centring pitch, clamped to [min, max], brings the sample
    within half the 45 deg vertical field of view. With the camera mounted pitched m deg down:
    depressions in [min + m - 22.5, max + m + 22.5] (the ranges that clamp at either end, and
    mounts whose clamping bounds lie past straight up or down)."""
    far = box_mesh((90, 90, 0), (91, 91, 1))  # the scene's only surface, out of every ray's way
    scene = nbvkit.RaycastScene(far)
    dep = np.radians(np.arange(-85.0, 90.0, 5.0))  # > 0 below; 2.5 deg or more off each bound
    here = np.array([0.0, 0.0, 20.0])
    pts = here + 5.0 * np.stack([np.cos(dep), np.zeros_like(dep), -np.sin(dep)], axis=1)
    normals = (here - pts) / 5.0
    mount = _core.mount_transform((0.0, 0.0, 0.0), 0.0, mount_pitch, 0.0)
    camera = nbvkit.DepthCamera(scene, width=16, height=12, noise_k=0.0, mount=mount)
    opts = _core.ObservabilityOptions(
        pose_spacing=1.0, gimbal_min_deg=gimbal[0], gimbal_max_deg=gimbal[1]
    )
    r = _core.observable_samples(
        scene, pts, normals, camera, here, here, options=opts, collision_radius=0.8
    )
    assert len(r.poses) == 1
    d = np.degrees(dep)
    lo, hi = gimbal[0] + mount_pitch - 22.5, gimbal[1] + mount_pitch + 22.5
    np.testing.assert_array_equal(np.asarray(r.observable, bool), (d >= lo) & (d <= hi))


def test_sample_normals_are_their_triangles_unit_normals_with_few_or_many_samples():
    """Per sample when there are fewer samples than triangles (a scanned mesh), per triangle
    when there are more: the unit normals of the samples' triangles, outwards on a box, each
    either way, and zero for a degenerate triangle."""
    from nbvkit.observability import sample_normals

    box = box_mesh((0, 0, 0), (2, 3, 4))
    flat = nbvkit.Mesh(np.vstack([box.vertices, [[5, 5, 5]]]), np.vstack([box.faces, [[8, 8, 8]]]))
    centre = np.array([1.0, 1.5, 2.0])
    for n in (3, 5000):  # fewer and more samples than the 13 triangles
        p, fid = flat.sample_surface(n, 2, return_faces=True)
        fid = np.append(fid, 12)  # the degenerate one too
        got = sample_normals(flat, fid)
        np.testing.assert_allclose(np.linalg.norm(got[:-1], axis=1), 1.0)
        assert np.all(np.einsum("ij,ij->i", got[:-1], p - centre) > 0)  # outwards
        np.testing.assert_array_equal(got[-1], 0.0)
        np.testing.assert_array_equal(got, sample_normals(flat, fid[::-1])[::-1])


def test_a_small_structure_gets_a_lattice_fine_enough_to_see_its_top(monkeypatch):
    """A small structure's lattice is finer than observability.pose_spacing (its box's diagonal
    / 16, not under 0.5 m): a 7 x 7 x 2 m block's top is seen from above, every sample of it
    observable. The 2 m lattice, split evenly between the box's floor and top, sees it too (a
    lattice about the box's centre held one level, 0.3 m above the top, and counted the top's
    middle unseeable: seen only at grazing incidence). A large structure's spacing is the
    configured one."""
    from nbvkit.observability import pose_spacing

    block = box_mesh((-3.5, -3.5, 0.0), (3.5, 3.5, 2.0))
    c = load_config(None, [])
    assert c.observability.pose_spacing == 2.0
    assert pose_spacing(c, block.bounds) == pytest.approx(np.sqrt(7**2 + 7**2 + 2**2) / 16)
    assert pose_spacing(c, ((0, 0, 0), (1, 1, 1))) == 0.5
    assert pose_spacing(c, ((0, 0, 0), (60, 40, 10))) == 2.0
    assert pose_spacing(cfg(), block.bounds) == 0.5  # finer when asked
    p, fid = samples(block, 3000)
    top = fid == 3  # box_mesh's faces 2, 3: the top
    assert np.allclose(p[top | (fid == 2), 2], 2.0) and top.sum() > 100
    r = observable_surface(block, c, points=p, face_ids=fid)
    assert r.stats["settings"]["pose_spacing"] == 2.0
    assert r.stats["settings"]["fine_pose_spacing"] == pytest.approx(0.6312, abs=1e-4)
    assert r.observable[top].all()
    from nbvkit import work_limits as limits

    monkeypatch.setattr(limits, "MIN_POSE_SPACING", 2.0)  # the 2 m lattice as it was
    coarse = observable_surface(block, c, points=p, face_ids=fid)
    assert coarse.stats["settings"]["fine_pose_spacing"] == 2.0
    assert coarse.observable[top].all()
    assert not (coarse.observable & ~r.observable).any()  # the fine search only adds


def test_no_fine_lattice_of_nearly_the_configured_spacing():
    """A fine lattice that would not hold twice the configured one's positions is not searched:
    a structure whose diagonal / 16 is 0.79 of the 2 m spacing or more gets the 2 m lattice
    alone (one search of its samples), one under it its own diagonal / 16."""
    from nbvkit.work_limits import pose_spacing

    c = load_config(None, [])
    edge = 2.0 * 2 ** (-1 / 3) * 16 / np.sqrt(3)  # a cube whose diagonal / 16 is 0.79 x 2 m
    assert pose_spacing(c, ((0, 0, 0), (edge * 1.01,) * 3)) == 2.0
    assert pose_spacing(c, ((0, 0, 0), (edge * 0.99,) * 3)) == pytest.approx(
        edge * 0.99 * np.sqrt(3) / 16
    )
    assert pose_spacing(c, ((0, 0, 0), (20, 20, 10))) == 2.0  # 1.875 m: nearly 2
    slab = box_mesh((-8.0, -8.0, 0.0), (8.0, 8.0, 6.0))  # diagonal 23.4 m: 1.46 m, within
    p, fid = samples(slab, 500)
    r = observable_surface(slab, c, points=p, face_ids=fid)
    assert r.stats["settings"]["fine_pose_spacing"] == pytest.approx(np.sqrt(2 * 256 + 36) / 16)
    wide = box_mesh((-10.0, -10.0, 0.0), (10.0, 10.0, 8.0))  # 29.4 m: 1.84 m, not searched
    p, fid = samples(wide, 500)
    r = observable_surface(wide, c, points=p, face_ids=fid)
    assert r.stats["settings"]["fine_pose_spacing"] == 2.0
    from nbvkit.workspace import make_workspace

    ws = make_workspace(wide.bounds, c)  # one lattice searched: the 2 m one's positions alone
    nav = ws.nav_max - ws.nav_min
    assert r.stats["lattice_points"] == np.prod([np.ceil(s / 2 - 1e-9) + 1 for s in nav])


def test_the_fine_lattice_adds_to_the_configured_one_and_keeps_within_the_limits():
    """A 12 m cube: the fine lattice's highest level (1.3 m apart) lies 0.45 m above the top,
    nearer than the camera's 0.5 m, but the configured 2 m lattice's positions are searched
    too: the top is seen whole. A small structure in a huge workspace: the fine lattice backs
    off to what the limits allow (it was refused, and no pose_spacing could help)."""
    from nbvkit.work_limits import MAX_OBSERVABILITY_POSES, pose_spacing

    cube = box_mesh((-6, -6, 0), (6, 6, 12))
    p, fid = samples(cube, 3000)
    top = fid == 3
    r = observable_surface(cube, load_config(None, []), points=p, face_ids=fid)
    assert r.stats["settings"]["fine_pose_spacing"] == pytest.approx(np.sqrt(3 * 144) / 16)
    assert r.observable[top].all()
    wide = load_config(
        None, ["workspace.bounds_min=[-60,-60,0]", "workspace.bounds_max=[60,60,40]"]
    )
    from nbvkit.work_limits import check_work
    from nbvkit.workspace import make_workspace

    mesh = box_mesh((-4, -1, 0), (4, 1, 2))
    ws = make_workspace(mesh.bounds, wide)
    nav = list(ws.nav_max - ws.nav_min)
    assert nav[0] > 118
    step = pose_spacing(wide, mesh.bounds, nav, 1000)
    assert 0.5 < step < 2.0
    n = np.prod([np.ceil(s / step - 1e-9) + 1 for s in nav])
    assert MAX_OBSERVABILITY_POSES / 1.2 < n <= MAX_OBSERVABILITY_POSES
    check_work(wide, mesh, ws)  # the configured 2 m lattice fits; the fine one is kept to fit


def test_covered_surface_the_mask_counts_unseeable_is_reported():
    """covered_unobservable_fraction: the share of the area in covered cells that the mask
    holds unobservable (0 for a mask that holds every covered sample)."""
    plate = box_mesh((0, 0, 0), (4, 4, 0.1))
    ev = nbvkit.Evaluator(plate, gt_density=200, seed=0)
    pts = ev.gt_points
    cloud = pts[pts[:, 2] > 0.05]  # the top seen
    ev.set_observable(pts[:, 2] > 0.05)
    assert ev.evaluate(cloud)["covered_unobservable_fraction"]["0.05"] == 0.0
    ev.set_observable(pts[:, 0] < 2)  # half the top held unseeable: a quarter of the area or so
    r = ev.evaluate(cloud)
    on_top_beyond = ((pts[:, 2] > 0.05) & (pts[:, 0] >= 2)).mean()
    assert r["covered_unobservable_fraction"]["0.05"] == pytest.approx(on_top_beyond, abs=0.02)


def _covered_unobservable(pts, cloud, observable, r=0.05):
    """(covered unobservable, of which in cells that hold an observable sample), counted here
    from the cells' keys (conftest.eval_cells), independently of the evaluator."""
    from conftest import eval_cells

    cell = [tuple(k) for k in eval_cells(pts, r)]
    covered_cells = {tuple(k) for k in eval_cells(cloud, r)}
    seen_cells = {c for c, o in zip(cell, observable) if o}
    covered = np.array([c in covered_cells for c in cell])
    shared = np.array([c in seen_cells for c in cell])
    hidden = covered & ~observable
    return hidden.mean(), (hidden & shared).mean()


def test_covered_unobservable_surface_is_split_by_whether_its_cell_holds_observable_surface():
    """covered_unobservable_shared_fraction: the part of covered_unobservable_fraction in cells
    that also hold an observable sample (a part thinner than the cell: its far face shares the
    seen face's cells; an edge), told apart from unseeable surface in cells of its own."""
    from nbvkit.evaluation import unobservable_note

    def split(ev, cloud, observable):
        ev.set_observable(observable)
        r = ev.evaluate(cloud)
        got = [
            r[k]["0.05"]
            for k in ("covered_unobservable_fraction", "covered_unobservable_shared_fraction")
        ]
        assert got == pytest.approx(
            _covered_unobservable(ev.gt_points, cloud, observable), abs=1e-9
        )
        return r, got

    thin = box_mesh((0, 0, 0.01), (1, 1, 0.03))  # within one layer of 0.05 m cells
    ev = nbvkit.Evaluator(thin, gt_density=8000, seed=0)  # 20 samples a cell's face
    pts = ev.gt_points
    top = pts[:, 2] > 0.02
    r, (total, shared) = split(ev, pts[top], top)  # the cloud is the top; the rest unseeable
    assert total == pytest.approx((~top).mean(), abs=0.01)  # the underside, about half
    assert shared == pytest.approx(total, abs=0.01)  # every underside cell holds top surface
    words = unobservable_note(r)
    assert words.startswith(f"{total:.1%} of the area")
    assert f"{shared:.1%} in cells that also hold" in words
    assert "note: " + words in nbvkit.evaluation.format_report(r)  # nbvkit evaluate's table

    thick = box_mesh((0, 0, 0), (1, 1, 1.0))
    ev = nbvkit.Evaluator(thick, gt_density=8000, seed=0)
    pts = ev.gt_points
    top = pts[:, 2] > 0.99
    r, (total, shared) = split(ev, pts[top], top & (pts[:, 0] < 0.5))  # half the top unseeable
    beyond = (top & (pts[:, 0] >= 0.5)).mean()
    # in cells of their own: the unseeable half of the top, and the sides' top edge beside it
    assert beyond <= total - shared <= beyond + 0.025
    assert shared < 0.3 * beyond  # the top's edges and seam: cells shared with the sides
    assert unobservable_note({"covered_unobservable_fraction": {"0.05": 0.01}}) is None
