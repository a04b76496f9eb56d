"""The mission runner end to end (shortened: coarse map, few iterations) and its bad input."""
from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest

import nbvkit
from nbvkit.config import Config
from nbvkit.mission import Mission, MissionError
from nbvkit.workspace import make_workspace, start_poses

FAST = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=100",
    "max_iterations=12",
    "evaluation.coverage_every=4",
]


def cfg(*extra):
    return Config().with_overrides(FAST + list(extra))


def test_the_paper_scenarios_workspace_is_the_papers_for_the_airliner():
    mesh = nbvkit.load_mesh(nbvkit.default_mesh_path())
    ws = make_workspace(mesh.bounds, Config().with_overrides(["scenario=5"]))
    np.testing.assert_allclose(ws.size, [40.0, 40.0, 10.0], atol=0.1)
    assert ws.bounds_min[2] == 0.0
    starts = start_poses(ws)
    assert starts.shape == (5, 4)
    for s in starts:  # just inside the boundary, mid height, facing the centre
        assert ws.contains(s)
        assert s[2] == pytest.approx(ws.center[2])
        to_c = ws.center[:2] - s[:2]
        assert np.dot([np.cos(s[3]), np.sin(s[3])], to_c / np.linalg.norm(to_c)) > 0.99
    np.testing.assert_allclose(
        starts[0, :2], [0.0, ws.nav_min[1]], atol=0.1
    )  # (0, -19.1): authors' (0, -20)


def test_a_workspace_beside_the_structure_is_refused_before_any_work(tmp_path):
    """Explicit workspace bounds that hold no part of the structure: refused by name before
    any work (a mission there saw nothing and blamed its start), part of it flies."""
    box = ["workspace.bounds_min=[100,100,0]", "workspace.bounds_max=[130,130,10]"]
    with pytest.raises(ValueError, match="holds no part of the structure"):
        Mission(cfg(*box)).run(tmp_path / "out")
    assert not (tmp_path / "out").exists()
    mesh = nbvkit.load_mesh(nbvkit.default_mesh_path())
    lo = np.asarray(mesh.bounds[0])
    part = Config().with_overrides(
        [f"workspace.bounds_min={(lo - 3).tolist()}", f"workspace.bounds_max={[0, 0, 8]}"]
    )
    assert make_workspace(mesh.bounds, part).contains(np.array([-1.0, -1.0, 1.0]))


def test_scenario1_runs_end_to_end_and_writes_results(tmp_path):
    m = Mission(cfg("scenario=1"))
    m.run(tmp_path)
    for f in (
        "summary.json",
        "iterations.csv",
        "config.yaml",
        "cloud.ply",
        "map.ot",
        "trajectory.csv",
        "figures/trajectory.png",
        "figures/progress.png",
    ):
        assert (tmp_path / f).stat().st_size > 0, f
    d = json.loads((tmp_path / "summary.json").read_text())
    for k in (
        "scenario",
        "start",
        "iterations",
        "distance_m",
        "entropy_initial",
        "entropy_final",
        "entropy_reduction",
        "coverage",
        "area_coverage",
        "termination",
        "wall_time_s",
        "ms_per_iteration",
        "peak_memory_mb",
    ):
        assert k in d, k
    assert 50 < d["peak_memory_mb"] < 64 * 1024  # a Python process with the core: tens of MB up
    assert d["scenario"] == "1" and 1 <= d["iterations"] <= 12
    assert d["termination"] in ("max_iterations", "entropy_converged", "no_valid_viewpoint")
    assert d["entropy_reduction"] > 0 and d["distance_m"] > 0
    assert 0 < d["coverage"]["0.5"] <= 1 and set(d["coverage"]) == {"0.05", "0.1", "0.5"}
    rows = list(csv.DictReader(open(tmp_path / "iterations.csv")))
    assert len(rows) == d["iterations"]
    dist = [float(r["distance_m"]) for r in rows]
    assert dist == sorted(dist) and dist[-1] == pytest.approx(d["distance_m"])
    # distance equals the path flown (the trajectory's segment lengths)
    traj = np.array(
        [
            [float(r[k]) for k in ("x", "y", "z")]
            for r in csv.DictReader(open(tmp_path / "trajectory.csv"))
        ]
    )
    assert np.linalg.norm(np.diff(traj, axis=0), axis=1).sum() == pytest.approx(d["distance_m"])
    assert Config.from_yaml(tmp_path / "config.yaml").scenario == "1"
    back = nbvkit.OccupancyMap.load(str(tmp_path / "map.ot"))
    assert back.counts()["occupied"] > 0


def test_a_mission_saved_after_its_run_is_a_complete_run_folder(tmp_path):
    """Mission.save writes the folder as run(out_dir) does, manifest last: export reads it (it
    refused a saved folder as an unfinished run); a folder holding files is refused unless
    overwrite is given."""
    from nbvkit.export.plan import read_run
    from nbvkit.runfolder import require_complete_run

    m = Mission(cfg("scenario=surface", "max_iterations=2"))
    with pytest.raises(RuntimeError, match="run\\(\\) it first"):  # (an empty folder was written)
        m.save(tmp_path / "a", {})
    s = m.run()
    for summary in ("notadict", None):  # (a summary.json no reader took)
        with pytest.raises(TypeError, match="summary must be the dict run"):
            m.save(tmp_path / "a", summary)
    for flag in ("no", 1):  # ("no" is true: the folder was overwritten, the report written)
        with pytest.raises(TypeError, match="overwrite must be True or False"):
            m.save(tmp_path / "a", s, overwrite=flag)
        with pytest.raises(TypeError, match="finish must be True or False"):
            m.save(tmp_path / "a", s, finish=flag)
    with pytest.raises(TypeError, match="out must be a folder path, got int"):
        m.save(123, s)
    assert not (tmp_path / "a").exists()
    assert m.save(tmp_path / "a", s) == json.loads((tmp_path / "a" / "summary.json").read_text())
    require_complete_run(tmp_path / "a")
    assert len(read_run(tmp_path / "a").xyz) >= 2
    with pytest.raises(ValueError, match="out .*a .*(overwrite|holds)"):
        m.save(tmp_path / "a", s)
    m.save(tmp_path / "a", s, overwrite=np.bool_(True))  # numpy's bool is a bool
    require_complete_run(tmp_path / "a")


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="needs Linux /proc")
def test_the_summarys_peak_memory_includes_the_end_of_run_outputs(tmp_path):
    """summary.json's peak_memory_mb is the run's, its end-of-run outputs included: it was taken
    as the summary was made, before them, and a 100 m plant read 2.83 GB where the process
    peaked at 3.86 GB (the observable surface). Here the observable surface's step touches
    300 MiB over the peak so far (in a process of its own: the peak is the process's; Linux)."""
    import subprocess
    import sys
    import textwrap

    from conftest import CUBE_MESH, TINY_RUN

    script = textwrap.dedent(
        f"""
        import json, resource
        import numpy as np
        import nbvkit.finish as fin
        from nbvkit.config import load_config
        from nbvkit.mission import Mission

        step = fin._observable_figures
        def heavier(*args, **kwargs):
            before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MiB
            now = int(open("/proc/self/statm").read().split()[1]) * resource.getpagesize() / 2**20
            # 300 MiB over the peak so far (an earlier step may have held more than now)
            block = np.ones(int(before - now + 300) * 2**20 // 8)  # every page touched
            del block
            print(json.dumps({{"before": before}}))
            return step(*args, **kwargs)
        fin._observable_figures = heavier
        over = [*{list(TINY_RUN)!r}, "mesh.path={CUBE_MESH}", "report.enabled=false",
                "progress=false"]
        s = Mission(load_config(overrides=over)).run({str(tmp_path / "run")!r}, finish=True)
        print(json.dumps({{"returned": s["peak_memory_mb"]}}))
        """
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    said = {k: v for line in p.stdout.splitlines() for k, v in json.loads(line).items()}
    written = json.loads((tmp_path / "run" / "summary.json").read_text())["peak_memory_mb"]
    assert written >= said["before"] + 290, (written, said)
    assert said["returned"] == written


def test_run_refuses_a_finish_flag_not_a_bool_before_flying(tmp_path):
    """Mission.run(out, finish="no") wrote the end-of-run outputs ("no" is true); now it is
    refused before any flight, and nothing is written."""
    m = Mission(cfg("scenario=surface", "max_iterations=2"))
    with pytest.raises(TypeError, match="finish must be True or False, got 'no'"):
        m.run(tmp_path / "r", finish="no")
    assert m.termination == "not_run" and not (tmp_path / "r").exists()


def test_same_seed_same_mission():
    a = Mission(cfg("scenario=1", "max_iterations=6")).run()
    b = Mission(cfg("scenario=1", "max_iterations=6")).run()
    for k in ("iterations", "distance_m", "entropy_final", "coverage"):
        assert a[k] == b[k], k


def test_a_structure_wholly_within_the_ground_removal_is_refused_before_any_work():
    from conftest import box_mesh

    slab = box_mesh([-3.0, -3.0, 0.0], [3.0, 3.0, 0.2])  # 0.2 m tall; the clouds drop z < 0.3
    run = ("scenario=1", "max_iterations=3", "evaluation.coverage_every=0")
    with pytest.raises(MissionError, match=r"cloud\.min_z = 0\.3 m.*ground at z = 0 m"):
        Mission(cfg(*run), mesh=slab)
    # sunk below z = 0 the ground is its own lowest point: the same refusal
    with pytest.raises(MissionError, match="ground at z = -5 m"):
        Mission(cfg(*run), mesh=box_mesh([-3.0, -3.0, -5.0], [3.0, 3.0, -4.8]))
    # the advice works: with the ground removal lowered, the slab's points enter the cloud
    s = Mission(cfg(*run, "cloud.min_z=-1"), mesh=slab).run()
    assert s["cloud_points"] > 0 and s["coverage"]["0.5"] > 0


def test_nbvkits_planners_keep_the_surface_near_the_ground_that_the_papers_drop_as_ground():
    from conftest import box_mesh
    from nbvkit.world import World

    # the simulated world has no ground: a ground removal drops only the structure's own surface
    low = np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.29], [0.0, 0.0, 0.31], [0.0, 0.0, 2.0]])
    slab = box_mesh([-3.0, -3.0, 0.0], [3.0, 3.0, 0.2])  # wholly within the paper's 0.3 m
    kept = {}
    for scenario in ("surface", "1"):
        world = World(cfg(f"scenario={scenario}"), mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
        for cloud in world.clouds:
            cloud.add(low)
        kept[scenario] = [len(c) for c in world.clouds]
    assert kept == {"surface": [4, 4], "1": [2, 2]}  # the paper's: the authors' 0.3 m
    World(cfg(), mesh=slab)  # a slab 0.2 m tall is flown by default; the paper's refuse it
    with pytest.raises(MissionError, match="ground removal"):
        World(cfg("scenario=1"), mesh=slab)


def test_a_georeferenced_mesh_is_named_too_far_and_flies_as_at_the_origin_with_mesh_shift(tmp_path):
    from conftest import box_mesh

    def write_box(path, offset):  # a 6 x 4 x 3 m box, whole metres: shifts are exact
        m = box_mesh(np.array([-3.0, -2, 0]) + offset, np.array([3.0, 2, 3]) + offset)
        lines = [f"v {x:.1f} {y:.1f} {z:.1f}" for x, y, z in np.asarray(m.vertices)]
        lines += ["f " + " ".join(str(i + 1) for i in f) for f in np.asarray(m.faces)]
        path.write_text("\n".join(lines) + "\n")
        return str(path)

    near = write_box(tmp_path / "near.obj", np.zeros(3))
    utm = write_box(tmp_path / "utm.obj", np.array([500000.0, 4000000.0, 0.0]))
    run = ("scenario=1", "max_iterations=4", "evaluation.coverage_every=0")
    with pytest.raises(MissionError, match=r"mesh\.shift=\[-500000,-4000000,0\]"):
        Mission(cfg(f"mesh.path={utm}", *run))
    a = Mission(cfg(f"mesh.path={near}", *run)).run()
    b = Mission(cfg(f"mesh.path={utm}", "mesh.shift=[-500000,-4000000,0]", *run)).run()
    for k in ("iterations", "distance_m", "entropy_final", "coverage", "start_pose"):
        assert a[k] == b[k], k
    with pytest.raises(ValueError, match="mesh.shift"):
        cfg("mesh.shift=[1, .nan, 0]")


def test_the_fast_scoring_flies_the_same_mission_as_the_reference_reads(monkeypatch):
    """Scenario 5 (profile, symmetry, AGVS, the paper's IG) chooses the same views, flies the same
    distance and ends at the same entropy whether its candidates are scored by the grid walk (with
    the planner's memo of earlier walks) or through OctoMap's search per cell for every view (the
    reference path kept beside the fast one)."""
    from nbvkit import _core
    from nbvkit.planning import scoring

    def fly(backend):
        calls = []

        class Core:  # the planner's _core with every scoring call sent to `backend`
            def __getattr__(self, name):
                return getattr(_core, name)

            @staticmethod
            def evaluate_views(*args, **kw):
                calls.append(backend)
                if backend == "octree":
                    kw.pop("memo")
                return _core.evaluate_views(*args, backend=backend, **kw)

        monkeypatch.setattr(scoring, "_core", Core())
        m = Mission(cfg("scenario=5", "max_iterations=10", "profiling.sweep_step=0.5"))
        summary = m.run()
        poses = np.array([[r.x, r.y, r.z, r.yaw] for r in m.records])
        return summary, poses, len(calls), m.planner.score.memo.stats()

    fast, fast_poses, n_fast, memo = fly("grid")
    ref, ref_poses, n_ref, _ = fly("octree")
    assert memo["reused"] > 0  # the memo served views
    assert n_fast == n_ref >= 10
    assert fast["iterations"] == ref["iterations"] == 10
    np.testing.assert_array_equal(fast_poses, ref_poses)
    for k in ("distance_m", "entropy_final", "coverage"):
        assert fast[k] == ref[k], k


def test_bad_input_fails_before_any_work():
    with pytest.raises(MissionError, match="inside the structure|collision radius"):
        Mission(cfg("scenario=1", "start_pose=[0.0, 0.0, 3.5, 0.0]"))  # inside the fuselage
    with pytest.raises(MissionError, match="outside the navigation bounds"):
        Mission(cfg("scenario=1", "start_pose=[100.0, 0.0, 5.0, 0.0]"))
    with pytest.raises(ValueError, match=r"utility.name.*surface \(one of your own: register it"):
        cfg("utility.name=nope")
    with pytest.raises(KeyError, match="bogus"):
        cfg("bogus=1")
    with pytest.raises(ValueError, match="map.resolution"):
        cfg("map.resolution=-0.2")
    with pytest.raises(FileNotFoundError):
        Mission(cfg("mesh.path=/nonexistent/mesh.obj"))


def test_the_inside_test_does_not_read_the_faces_winding():
    # a 4 m canyon between two 20 x 3 x 10 m blocks: the blocks fill most directions from its
    # middle, so a test that counted back faces met first took it for "inside" once the faces
    # were wound the other way; the parity of each ray's crossings does not care
    from conftest import box_mesh

    a, b = box_mesh((-10, -5, 0), (10, -2, 10)), box_mesh((-10, 2, 0), (10, 5, 10))
    v, f = np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + 8])
    windings = {"outward": f, "reversed": f[:, ::-1], "both": np.vstack([f, f[:, ::-1]])}
    for name, faces in windings.items():
        mesh = nbvkit.Mesh(v, np.ascontiguousarray(faces))
        m = Mission(cfg("scenario=1", "start_pose=[0.0, 0.0, 5.0, 1.5708]"), mesh=mesh)
        assert m.world.start_pose[1] == 0.0, name
        with pytest.raises(MissionError, match="inside the structure"):
            Mission(cfg("scenario=1", "start_pose=[0.0, -3.5, 5.0, 0.0]"), mesh=mesh)


def test_cli_run_and_help(tmp_path, capsys):
    from nbvkit.cli import main

    with pytest.raises(SystemExit) as e:
        main(["run", "--help"])
    assert e.value.code == 0
    assert "--scenario" in capsys.readouterr().out
    rc = main(
        [
            "run",
            "--scenario",
            "1",
            "--start",
            "2",
            "--set",
            *FAST,
            "max_iterations=3",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    assert json.loads((tmp_path / "summary.json").read_text())["start"] == 2
    assert main(["run", "--scenario", "1", "--set", "nope=1", "--out", str(tmp_path)]) == 2
    assert "unknown config key 'nope'" in capsys.readouterr().err


def test_blocked_legs_can_be_planned_around_and_the_flown_path_is_counted(tmp_path):
    m = Mission(cfg("scenario=1", "vehicle.blocked_path=plan", "max_iterations=8"))
    s = m.run(tmp_path)
    assert s["iterations"] >= 1
    traj = np.array([r[1:4] for r in m.world.state.trajectory], float)
    assert np.linalg.norm(np.diff(traj, axis=0), axis=1).sum() == pytest.approx(s["distance_m"])


def test_starts_move_clear_of_a_structure_that_fills_its_workspace():
    # A 10 m cube with a 1 m margin: the inscribed ellipse of the navigation bounds runs through
    # the cube's sides, so the starts on it collide. Each moves out along its bearing, then up.
    from conftest import box_mesh
    from nbvkit.world import World

    mesh = box_mesh([-5, -5, 0], [5, 5, 10])
    c = Config().with_overrides(FAST + ["workspace.margin_xy=1.0", "workspace.margin_z=3.0"])
    world = World(c, mesh=mesh)
    r = c.vehicle.collision_radius
    for k, s in enumerate(world.starts):
        assert world.workspace.contains(s), k
        assert not world._collides(s), k
        inside = np.all(np.abs(s[:2]) < 5) and s[2] < 10
        assert not inside, k
        d = max(np.abs(s[:2]).max() - 5, s[2] - 10)  # outside the cube: its distance bound
        assert d >= r, (k, s)


def test_ground_removal_is_measured_from_z0_or_from_a_structure_reaching_below_it():
    from conftest import box_mesh
    from nbvkit.workspace import ground_height
    from nbvkit.world import World

    assert ground_height([[-1, -1, 0.03], [1, 1, 7.5]]) == 0.0  # standing on z = 0: z = 0
    assert ground_height([[-1, -1, 15.0], [1, 1, 25.0]]) == 0.0  # floating: still z = 0
    assert ground_height([[-1, -1, -5.0], [1, 1, 5.0]]) == -5.0  # centred on its origin
    c = Config().with_overrides(FAST + ["cloud.min_z=0.3"])  # (the default: no ground removal)
    # a structure centred on its origin keeps its lower half: only 0.3 m above its base is ground
    world = World(c, mesh=box_mesh([-3, -3, -5], [3, 3, 5]))
    for cloud in (world.camera_cloud, world.laser_cloud):
        assert cloud.min_z == pytest.approx(-5.0 + c.cloud.min_z)
    world.camera_cloud.add(np.array([[4.0, 0.0, -2.0], [4.0, 0.0, -4.9]]))
    assert len(world.camera_cloud) == 1  # the point 0.1 m above the base is ground
    world = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    assert world.camera_cloud.min_z == pytest.approx(c.cloud.min_z)


def test_starts_on_the_bounds_stay_inside_them_whatever_the_rounding():
    # a structure placed anywhere (here: the twinjet yawed 200 deg and lifted 15 m): the centre
    # minus the half-size of its navigation bounds rounds 1 ulp below their minimum in y
    mesh_bounds = [[-45.82121534, -3.96087897, 15.00483], [-11.10136336, 26.45899583, 25.52203178]]
    ws = make_workspace(mesh_bounds, Config())
    c, h = (ws.nav_min + ws.nav_max) / 2, (ws.nav_max - ws.nav_min) / 2
    assert c[1] - h[1] < ws.nav_min[1]  # the case this guards against
    for s in start_poses(ws):
        assert ws.contains(s)


def test_stage_timers_lap_counts_every_run_of_a_stage_since_the_last_lap(monkeypatch):
    from nbvkit import timing

    clock = iter(range(100))
    monkeypatch.setattr(timing, "perf_counter", lambda: float(next(clock)))
    t = timing.StageTimers()
    for _ in range(3):  # e.g. three tour views scored and skipped, then one flown
        with t("evaluation"):
            pass  # 1 s each on the fake clock
    with t("sensing"):
        pass
    assert t.lap() == {"evaluation": 3.0, "sensing": 1.0}
    with t("evaluation"):
        pass
    assert t.lap() == {"evaluation": 1.0, "sensing": 0.0}
    assert t.total == {"evaluation": 4.0, "sensing": 1.0}


def test_each_rows_entropy_change_is_the_maps_since_the_row_before(tmp_path):
    """iterations.csv: `entropy_change` is the map's change since the row before, so that it
    sums with `entropy`; a change an after-view hook makes between two views (a symmetry
    re-prediction: unknown cells set to 0.6) counts in the next row, not in none."""
    rng = np.random.default_rng(0)
    marked = []

    def predict(world, step):
        lo, hi = world.workspace.nav_min, world.workspace.nav_max
        marked.append(world.map.set_unknown_cells(rng.uniform(lo, hi, (200, 3)), 0.6))

    m = Mission(cfg("max_iterations=6"))
    m.planner.hooks["predict"] = predict
    m.run(tmp_path)
    rows = list(csv.DictReader(open(tmp_path / "iterations.csv")))
    entropy = np.array([float(r["entropy"]) for r in rows])
    change = np.array([float(r["entropy_change"]) for r in rows])
    assert len(rows) >= 3 and sum(marked[:-1]) > 0
    np.testing.assert_allclose(change[1:], np.diff(entropy), rtol=0, atol=1e-6 * entropy[0])
    c_view = float(rows[0]["entropy_change"]) / -float(rows[0]["delta_ev"])
    assert [float(r["delta_ev"]) for r in rows] == pytest.approx(-change / c_view)


def test_a_start_near_the_structure_moves_to_the_clearance_it_needs_to_fly():
    """A start on the ellipse 1.0 m from a face, out of collision (0.8 m) but under the starts'
    clearance (collision radius + 1 m), moves away until it has it: there, the take-off sphere
    (cleared to a cell short of the surface) left no neighbouring view free of unknown space and
    the paper's Scenario 1 turned on the spot for its whole run (the airliner's start 4)."""
    from conftest import box_mesh
    from nbvkit.world import World

    mesh = box_mesh([-5, -5, 0], [5, 5, 10])
    # margin 1.9: the navigation bounds start 0.9 m inside the workspace, 1.0 m from the cube
    c = Config().with_overrides(FAST + ["workspace.margin_xy=1.9", "workspace.margin_z=3.0"])
    world = World(c, mesh=mesh)
    assert world.workspace.nav_min[1] == pytest.approx(-6.0)  # the case this guards against
    need = c.vehicle.collision_radius + 1.0
    for k, s in enumerate(world.starts):
        outside = np.maximum(np.abs(s[:2]) - 5, 0)
        d = np.linalg.norm([*outside, max(s[2] - 10, 0)])  # its distance to the cube
        assert world.workspace.contains(s) and d >= need - 0.15, (k, s, d)  # (surface samples)
    # a workspace too tight to keep the clearance on most bearings (1.1 m round a round tower,
    # 1.1 m above it): those starts stay where they were, out of collision (they were refused)
    a = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    ring = np.c_[5 * np.cos(a), 5 * np.sin(a)]
    n = len(a)
    v = np.r_[np.c_[ring, np.zeros(n)], np.c_[ring, np.full(n, 20.0)], [[0, 0, 0], [0, 0, 20]]]
    f = [
        t
        for i, j in ((i, (i + 1) % n) for i in range(n))
        for t in ([i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j])
    ]
    tower = nbvkit.Mesh(v, np.array(f, np.int32))
    tight = ["workspace.bounds_min=[-7,-7,0]", "workspace.bounds_max=[7,7,22]"]
    world = World(Config().with_overrides(FAST + tight), mesh=tower)
    for k, s in enumerate(world.starts):
        assert world.workspace.contains(s) and not world._collides(s), (k, s)
        assert np.hypot(*s[:2]) - 5 >= 1.05, (k, s)  # where they were, or farther out


@pytest.mark.parametrize("every", [50, 0])
def test_the_coverage_curve_ends_at_the_runs_coverage(tmp_path, every):
    """A run of fewer views than evaluation.coverage_every had no coverage in iterations.csv, so
    its progress figure, report and notebook drew no curve: the last row now holds the run's
    own coverage (the summary's); coverage_every=0 (no curve) leaves the rows empty."""
    from conftest import TINY_RUN

    over = [*TINY_RUN, "max_iterations=3", "progress=false", f"evaluation.coverage_every={every}"]
    s = Mission(Config().with_overrides(over)).run(tmp_path / "run")
    with open(tmp_path / "run" / "iterations.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == s["iterations"] >= 2
    assert all(r["coverage_005"] == "" for r in rows[:-1])
    last = [rows[-1][c] for c in ("coverage_005", "coverage_01", "coverage_05")]
    if every:
        want = [s["coverage"][k] for k in ("0.05", "0.1", "0.5")]
        assert [float(v) for v in last] == pytest.approx(want, rel=1e-12) and want[0] > 0
    else:
        assert last == ["", "", ""]
