"""Hostile input (issue 10): every case a hostile user found gets a clear message naming the
problem, a non-zero exit that is not a signal, and no traceback. Each test fails if its fix is
undone. Cases that once killed the process run in a subprocess, so a regression fails the test
instead of the test run."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import pytest
import yaml

import nbvkit
from nbvkit.config import load_config
from conftest import TINY_RUN, as_from_a_terminal

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

from fuzz_meshes import F as CUBE_F, V as CUBE_V, cube_ply, dae_file, obj_file  # noqa: E402


def cli(*args, timeout=120, cwd=None):
    """Runs `nbvkit ARGS` in a subprocess: (returncode, stdout, stderr)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=cwd,
        env=env,
    )
    return p.returncode, p.stdout, p.stderr


def scan_cli(mesh, out, timeout=120):
    """`nbvkit scan` of `mesh` from a pose facing the unit cube: (returncode, stdout, stderr)."""
    return cli("scan", "--mesh", mesh, "--pose", 0.5, -3, 0.5, 1.57, "--out", out, timeout=timeout)


def expect_error(rc, err, *needles):
    """A clean failure: exit 2 (not a signal, not a crash), no traceback, the message naming the
    problem."""
    assert rc == 2, (rc, err)
    assert "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)


def python(code: str, timeout=120):
    """Runs Python code in a subprocess (a crash there fails the test, not the test run)."""
    p = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert p.returncode == 0, (p.returncode, p.stdout, p.stderr)
    return p.stdout


@pytest.fixture
def cube_obj():
    return ROOT / "meshes" / "fixtures" / "cube.obj"


# ------------------------------------------------------------------------ 1-4: crashes, hangs


def test_case1_hostile_ply_files_give_clean_errors(tmp_path):
    good = cube_ply()
    cases = {
        "truncated_data.ply": (good[:300], "truncated"),
        "truncated_header.ply": (good[:60], "end_header"),
        "short_ascii.ply": (cube_ply("ascii")[:-60], "truncated"),
        "huge_count.ply": (cube_ply(nv=10**9)[:240], "declares 1000000000"),
        "bad_index.ply": (cube_ply(faces=CUBE_F[:-1] + [(1, 6, 8)]), "out of range"),
    }
    for name, (data, needle) in cases.items():
        (tmp_path / name).write_bytes(data)
        t0 = time.perf_counter()
        rc, _, err = scan_cli(tmp_path / name, tmp_path / "x.npy")
        assert time.perf_counter() - t0 < 60
        expect_error(rc, err, name, needle)
    # the valid file loads through the same reader
    (tmp_path / "good.ply").write_bytes(good)
    assert nbvkit.load_mesh(tmp_path / "good.ply").faces.shape == (12, 3)
    with pytest.raises(ValueError, match="out of range"):  # never remapped to vertex 0
        nbvkit.load_mesh(tmp_path / "bad_index.ply")


def test_case1_collada_files_that_crash_or_hang_assimp_are_refused(tmp_path):
    """Found by bench/fuzz_meshes.py: assimp 5.2 segfaults on a <float_array> with a missing or
    wrong count and loops forever on a non-integer index; they are refused before assimp."""
    good = dae_file().decode()
    cases = {
        "nocount.dae": (good.replace(' count="24"', ' counT="24"'), "without a count"),
        "count0.dae": (good.replace(' count="24"', ' count="0"'), "count=0"),
        "countneg.dae": (good.replace(' count="24"', ' count="-1e300"'), "unsigned integer"),
        "float_index.dae": (good.replace("<p>0 2 1", "<p>0 2 1e9"), "unsigned integers"),
        "nan_index.dae": (good.replace("<p>0 2 1", "<p>0 nan 1"), "unsigned integers"),
        "huge_stride.dae": (good.replace('stride="3"', 'stride="2147483648"'), "below 1e9"),
        "overread.dae": (good.replace('stride="3"', 'stride="4"'), "<accessor> reads 32"),
    }
    for name, (text, needle) in cases.items():
        (tmp_path / name).write_text(text)
        rc, _, err = scan_cli(tmp_path / name, tmp_path / "x.npy", timeout=60)
        expect_error(rc, err, name, needle)
    (tmp_path / "good.dae").write_text(good)
    assert nbvkit.load_mesh(tmp_path / "good.dae").faces.shape == (12, 3)


def test_case1_fuzz_smoke_no_crash_hang_or_blowup():
    from fuzz_meshes import fuzz

    res = fuzz(per_format=12, seed=int(time.time()) % 1000, timeout=30, mem_mb=2048)
    for fmt, counts in res.items():
        assert set(counts) <= {"ok", "error"}, (fmt, counts)


def test_case2_unrepresentable_pose_is_a_value_error(tmp_path, cube_obj):
    rc, _, err = cli(
        "scan", "--mesh", cube_obj, "--pose", "2e18", 0, 4, 0, "--out", tmp_path / "x.npy"
    )
    expect_error(rc, err, "--pose")
    out = python(
        f"""
        import numpy as np, nbvkit
        scene = nbvkit.RaycastScene(nbvkit.load_mesh({str(cube_obj)!r}))
        calls = [
            lambda: nbvkit.DepthCamera(scene).scan_pose([2e18, 0, 4, 0]),
            lambda: nbvkit.LaserScanner(scene).scan_pose([0, -3e18, 4, 0]),
            lambda: scene.intersect(np.array([[0, 0, 2e18]]), np.array([[0, 0, -1.0]])),
        ]
        for call in calls:
            try:
                call()
                print("no error")
            except ValueError as e:
                print("ValueError:", e)
        """
    )
    lines = out.strip().splitlines()
    assert len(lines) == 3 and all(ln.startswith("ValueError") for ln in lines), out
    assert "pose" in lines[0] and "pose" in lines[1] and "ray origin" in lines[2]


def test_case3_derived_counts_are_bounded(tmp_path, cube_obj):
    for res in ("1e-9", "1e-7"):
        t0 = time.perf_counter()
        rc, _, err = cli("run", "--set", f"laser.resolution_deg={res}", "--out", tmp_path / "r")
        assert time.perf_counter() - t0 < 60
        expect_error(rc, err, "resolution_deg")
    out = python(
        f"""
        import nbvkit
        scene = nbvkit.RaycastScene(nbvkit.load_mesh({str(cube_obj)!r}))
        for kw in (dict(resolution_deg=1e-9), dict(resolution_deg=1e-7)):
            try:
                nbvkit.LaserScanner(scene, **kw).scan_pose([0.5, -3, 0.5, 1.57])
                print("no error")
            except ValueError as e:
                print("ValueError:", e)
        try:
            nbvkit.DepthCamera(scene, width=100000, height=100000)
            print("no error")
        except ValueError as e:
            print("ValueError:", e)
        """
    )
    lines = out.strip().splitlines()
    assert all(ln.startswith("ValueError") for ln in lines), out
    assert "resolution_deg" in lines[0] and "resolution_deg" in lines[1] and "pixels" in lines[2]
    assert not (tmp_path / "r").exists()


def test_case4_huge_mesh_scale_fails_fast_on_the_map_size(tmp_path):
    # 1e9: coordinates beyond the core's 1e9 m, named at the mesh's loading by its scale
    cases = (("1e9", ("mesh coordinates reach", "scale 1e+09")), ("1e2", ("workspace", "cells")))
    for scale, needles in cases:
        t0 = time.perf_counter()
        rc, _, err = cli("run", "--mesh-scale", scale, "--out", tmp_path / "r", timeout=120)
        assert time.perf_counter() - t0 < 60, f"--mesh-scale {scale} took too long"
        expect_error(rc, err, *needles)


def test_case4_a_mesh_in_another_unit_is_told_the_scale_that_flies_it_in_metres(tmp_path):
    """A CAD mesh in millimetres (a 20 m cube written as 20,000 units) fails on the map's size,
    a model normalized to a quarter of a metre on the ground removal: each error says how large
    the structure is and the mesh.scale to fly it in metres. Sizes a metre makes likely keep
    their errors as they were, hint-free."""
    from nbvkit.world import MissionError, World

    mm = tmp_path / "cube_mm.obj"
    mm.write_bytes(obj_file([(20000.0 * x, 20000.0 * y, 20000.0 * z) for x, y, z in CUBE_V]))
    rc, _, err = cli("run", "--mesh", mm, "--out", tmp_path / "r", timeout=120)
    expect_error(rc, err, "too large for the map", "the structure is 20,000 m across")
    assert "millimetres, mesh.scale = 0.001 makes it 20 m across" in err
    cube = ROOT / "meshes" / "fixtures" / "cube.obj"
    for path, scale, kind, needle in (
        (mm, 0.001, None, None),  # as the hint says: 20 m, flown
        (cube, 0.25, MissionError, "0.25 m across at mesh.scale = 0.25 (nbvkit works in metres"),
        (cube, 1.0, MissionError, None),  # 1 m: the ground removal's error alone
        (cube, 300.0, ValueError, None),  # 300 m: the map's limit alone
    ):
        over = [f"mesh.path={path}", f"mesh.scale={scale}", "cloud.min_z=0.3"]
        if scale == 1.0:
            over.append("cloud.min_z=2")
        if scale == 300.0:
            over.append("map.resolution=0.05")
        cfg = load_config(overrides=over)
        if kind is None:
            assert World(cfg).mesh.bounds[1][0] == pytest.approx(20.0)
            continue
        with pytest.raises(kind) as e:
            World(cfg)
        assert (needle in str(e.value)) if needle else "across" not in str(e.value), e.value


def test_case4_a_georeferenced_mesh_is_told_its_shift_and_flies_with_it(tmp_path):
    far = tmp_path / "utm_cube.obj"  # the unit cube (fixtures/cube.obj's) in UTM coordinates
    far.write_bytes(obj_file([(x + 500000.0, y + 4000000.0, float(z)) for x, y, z in CUBE_V]))
    common = (
        "--mesh",
        far,
        "--scenario",
        "profile",
        "--no-progress",
        "--set",
        "report.enabled=false",
    )
    rc, _, err = cli("run", *common, "--out", tmp_path / "a", timeout=120)
    expect_error(rc, err, "addressable range", "mesh.shift=[-500000,-4000000,0]")
    rc, out, err = cli(
        "run", *common, "--mesh-shift", "-500000", "-4000000", "0", "--out", tmp_path / "b"
    )
    assert rc == 0, err
    cfg = yaml.safe_load((tmp_path / "b" / "config.yaml").read_text())
    assert cfg["mesh"]["shift"] == [-500000.0, -4000000.0, 0.0]


def test_a_scan_at_utm_coordinates_is_as_exact_as_at_the_origin():
    """`nbvkit scan` takes a mesh at any position (no map to address): Embree's float32 was
    0.5 m apart at 5e6 m, and hits fell on the planes of triangles the rays passed beside, up
    to 6.8 cm off the surface. The scene is now held relative to the mesh's centre."""
    import numpy as np

    off = np.array([500000.123, 5000000.37, 300.0])
    near = nbvkit.load_mesh(nbvkit.default_mesh_path())
    far = nbvkit.load_mesh(nbvkit.default_mesh_path(), shift=off)
    hits = []
    for mesh, at in ((near, np.zeros(3)), (far, off)):
        cam = nbvkit.DepthCamera(nbvkit.RaycastScene(mesh), noise_k=0.0)
        hits.append(cam.scan_pose([*(at + [-4.0, -12.0, 4.0]), np.pi / 2]).hits - at)
    assert len(hits[0]) > 10000 and len(hits[0]) == len(hits[1])
    assert np.abs(hits[1] - hits[0]).max() < 1e-3  # (float32 at 5e6 m: 0.5 m)


def test_case4_a_mesh_given_in_altitudes_is_told_the_shift_that_grounds_it(tmp_path):
    """A structure whose z is an altitude (the unit cube 300 m up, far from the origin): the
    map's error gives the shift that brings it near and onto the ground; near the origin but
    still 300 m up, it flies with a warning naming that shift; grounded, without one. A cube on
    the ground, or on a mast of its own height, is not warned about."""
    from nbvkit import World

    def cube_at(name, dx, dy, dz, size=1.0):
        path = tmp_path / name
        v = [(size * x + dx, size * y + dy, size * z + dz) for x, y, z in CUBE_V]
        path.write_bytes(obj_file(v))
        return path

    far = cube_at("utm_alt.obj", 500000.0, 4000000.0, 300.0)
    rc, _, err = cli("run", "--mesh", far, "--out", tmp_path / "a", timeout=120)
    expect_error(rc, err, "addressable range", "mesh.shift=[-500000,-4000000,-300]")
    over = ["cloud.min_z=0.3", "profiling.enabled=false"]
    with pytest.warns(
        RuntimeWarning, match=r"lies 300 m above .*mesh.shift=\[-500000,-4000000,-300\]"
    ):
        World(load_config(overrides=[f"mesh.path={far}", "mesh.shift=[-500000,-4000000,0]", *over]))
    with warnings.catch_warnings():
        # grounded as told: no warning of it (the unit cube is warned of as coarse on 0.2 m)
        warnings.filterwarnings("error", message="the structure's lowest point")
        w = World(
            load_config(overrides=[f"mesh.path={far}", "mesh.shift=[-500000,-4000000,-300]", *over])
        )
        assert w.workspace.bounds_max[2] < 10.0 and w.mesh.bounds[0][2] == pytest.approx(0.0)
        for name, dz, size in (("ground.obj", 0.0, 1.0), ("mast.obj", 12.0, 12.0)):
            World(load_config(overrides=[f"mesh.path={cube_at(name, 0, 0, dz, size)}", *over]))


# ------------------------------------------------------------------------ 5-7: lost results


def test_case5_output_paths_are_checked_before_any_work(tmp_path):
    existing = tmp_path / "file.txt"
    existing.write_text("x")
    for out, needle in ((existing, "not a folder"), ("/proc/nbvkit/x", "cannot be written")):
        t0 = time.perf_counter()
        rc, _, err = cli("run", "--out", out)
        assert time.perf_counter() - t0 < 30, "the mission ran before the check"
        expect_error(rc, err, "--out", str(out), needle)
    with pytest.raises(ValueError, match="not a folder"):
        nbvkit.Mission(load_config(overrides=["max_iterations=1"])).run(existing)


def _sweep_file(tmp_path, runs=5):
    """A sweep of `runs` tiny airliner missions (scenario 1, two views each)."""
    (tmp_path / "sweep.yaml").write_text(
        textwrap.dedent(
            f"""
            scenarios: ["1"]
            starts: {runs}
            set: {{map.resolution: 0.4, evaluation.gt_density: 50, max_iterations: 2,
                   evaluation.coverage_every: 1, profiling.sweep_step: 0.5,
                   profiling.waypoints: 3}}
            """
        )
    )
    return tmp_path / "sweep.yaml"


def _finished(out):
    """Finished run folders (not the hidden temporary ones of runs in progress)."""
    runs = (out / "runs").glob("*/summary.json")
    return [r for r in runs if not r.parent.name.startswith(".")]


def test_case6_ctrl_c_stops_a_sweep_and_keeps_what_finished(tmp_path):
    sweep = _sweep_file(tmp_path)
    out = tmp_path / "out"
    stale = out / "runs" / ".airliner_s1_start0_deadbeef.tmp999999999"
    stale.mkdir(parents=True)
    p = subprocess.Popen(
        [sys.executable, "-m", "nbvkit.cli", "sweep", sweep, "--out", out, "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, MPLBACKEND="Agg"),
    )
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 240:  # until the first run is finished
        if _finished(out) or p.poll() is not None:
            break
        time.sleep(0.2)
    assert not stale.exists(), "stale .tmp<pid> folder of a dead run not cleaned"
    assert p.poll() is None, "the sweep ended before it could be interrupted"
    p.send_signal(signal.SIGINT)
    t1 = time.perf_counter()
    _, err = p.communicate(timeout=60)
    assert time.perf_counter() - t1 < 20, "workers did not stop promptly"
    assert p.returncode == 130, (p.returncode, err)
    assert "Traceback" not in err, err
    assert "interrupted" in err and "resume" in err
    finished = _finished(out)
    rows = (out / "results.csv").read_text().strip().splitlines()
    assert 1 <= len(rows) - 1 <= len(finished) < 5  # the partial table: runs that finished
    # resuming cleans the killed runs' temporary folders and finishes the rest
    rc, _, err = cli("sweep", sweep, "--out", out, "--workers", "1", timeout=600)
    assert rc == 0, err
    assert not list((out / "runs").glob(".*.tmp*"))
    assert len((out / "results.csv").read_text().strip().splitlines()) == 1 + 5


def _start_table(out) -> subprocess.Popen:
    """A small Table 2 (one start, two workers) in its own process."""
    cmd = ["table", "--starts", "1", "--workers", "2", "--set", *TINY_RUN, "--out", str(out)]
    return subprocess.Popen(
        [sys.executable, "-m", "nbvkit.cli", *cmd],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, MPLBACKEND="Agg"),
        start_new_session=True,  # its own process group, as a terminal's job
        preexec_fn=as_from_a_terminal,  # hung up on below (case 6), as a terminal's job is
    )


def test_case6_ctrl_c_stops_a_table_and_writes_the_partial_table(tmp_path):
    out = tmp_path / "t"
    p = _start_table(out)
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 240 and p.poll() is None:
        if (out / "runs").is_dir() and _finished(out):
            break
        time.sleep(0.2)
    assert p.poll() is None, "the table ended before it could be interrupted"
    p.send_signal(signal.SIGINT)
    t1 = time.perf_counter()
    _, err = p.communicate(timeout=60)
    assert time.perf_counter() - t1 < 20, "workers did not stop promptly"
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err)
    assert "resume" in err
    assert (out / "runs.csv").exists() and (out / "table2.md").exists()
    assert len(_finished(out)) < 6
    rows = len((out / "runs.csv").read_text().splitlines()) - 1  # the table says it is partial
    assert f"Partial: {rows} of 6 runs finished" in (out / "table2.md").read_text()


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _table_with_workers(out):
    """A table started in its own process, once its two workers are flying: (process, workers)."""
    p = _start_table(out)
    t0 = time.perf_counter()
    workers: list[int] = []
    while time.perf_counter() - t0 < 120 and p.poll() is None:
        # the pool's workers (spawned interpreters), once runs have started
        workers = [c for c in _children(p.pid) if "spawn_main" in _cmdline(c)]
        started = list((out / "runs").glob(".*.tmp*")) if (out / "runs").is_dir() else []
        if len(workers) == 2 and len(started) == 2:  # both flying a run
            break
        time.sleep(0.2)
    assert p.poll() is None and len(workers) == 2, "the table ended before it could be stopped"
    return p, workers


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")
    except OSError:
        return ""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_case6_kill_stops_a_table_and_its_workers(tmp_path):
    # SIGTERM (`kill`) is handled as Ctrl-C: workers stopped, partial table, a resume hint
    p, workers = _table_with_workers(tmp_path / "t")
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err)
    assert "interrupted" in err and "resume" in err
    time.sleep(1)
    assert not [w for w in workers if _alive(w)], "workers outlived the table"
    # SIGKILL cannot be handled: the workers die with their parent (parent-death signal)
    p, workers = _table_with_workers(tmp_path / "k")
    p.kill()
    p.wait(timeout=30)  # (not communicate: workers left running would hold its pipes open)
    p.stdout.close()
    p.stderr.close()
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 10 and any(_alive(w) for w in workers):
        time.sleep(0.2)
    assert not [w for w in workers if _alive(w)], "workers flew on after their parent was killed"


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_case6_a_hang_up_stops_a_table_and_its_workers(tmp_path):
    # the terminal closed: SIGHUP to the whole process group; the table stops as on a kill
    out = tmp_path / "h"
    p, workers = _table_with_workers(out)
    os.killpg(p.pid, signal.SIGHUP)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err)
    assert "interrupted" in err and "resume" in err
    time.sleep(1)
    assert not [w for w in workers if _alive(w)], "workers outlived the table"


def test_case7_whole_config_is_validated_before_any_work(tmp_path):
    for override, key in (
        ("entropy.window=0", "entropy.window"),
        ("utility.rays_x=-3", "utility.rays_x"),
        ("lattice.stuck_window=0", "lattice.stuck_window"),
    ):
        t0 = time.perf_counter()
        rc, _, err = cli("run", "--set", override, "--out", tmp_path / "r")
        assert time.perf_counter() - t0 < 30
        expect_error(rc, err, key)
        assert not (tmp_path / "r").exists(), "a partial output folder was left"


# ------------------------------------------------------------------------ 8-12: messages


def test_case8_scientific_notation_is_a_number():
    assert load_config(overrides=["map.resolution=2.5e-1"]).map.resolution == 0.25
    with pytest.raises(ValueError) as e:  # read as a number, then refused for what it is
        load_config(overrides=["map.resolution=1e-4"])
    assert "must be a number" not in str(e.value) and "map.resolution = 0.0001" in str(e.value)
    assert load_config(overrides=["mesh.scale=2E3"]).mesh.scale == 2000.0
    from nbvkit.cli import build_parser
    from nbvkit.commands.run import config_from_args

    args = build_parser().parse_args(["run", "--mesh-scale", "1e-9"])
    assert config_from_args(args).mesh.scale == 1e-9
    from nbvkit.config import parse_yaml

    assert parse_yaml("a: 1e-4\nb: -2.5E+3\nc: 1_0\nd: '1e-4'") == {
        "a": 1e-4,
        "b": -2500.0,
        "c": 10,
        "d": "1e-4",
    }


def test_case9_negative_seed_is_named(tmp_path, cube_obj):
    rc, _, err = cli("run", "--set", "seed=-1", "--out", tmp_path / "r")
    expect_error(rc, err, "seed")
    rc, _, err = cli(
        "scan",
        "--mesh",
        cube_obj,
        "--pose",
        0.5,
        -3,
        0.5,
        1.57,
        "--seed",
        -1,
        "--out",
        tmp_path / "x.npy",
    )
    expect_error(rc, err, "--seed")
    scene = nbvkit.RaycastScene(nbvkit.load_mesh(cube_obj))
    with pytest.raises(ValueError, match="seed"):
        nbvkit.DepthCamera(scene, seed=-1)
    with pytest.raises(ValueError, match="seed"):
        nbvkit.LaserScanner(scene, seed=-1)
    with pytest.raises(ValueError, match="seed"):
        nbvkit.load_mesh(cube_obj).sample_surface(10, seed=-1)


def test_a_sample_count_past_the_memory_limit_is_refused(cube_obj):
    """sample_surface(10**12) raised MemoryError (std::bad_alloc) after trying, and 2e9 (within
    its int32 face ids) asked for 48 GB, for the OOM killer to stop: a count past 2e8 (4.8 GB)
    is refused by name before any work."""
    mesh = nbvkit.load_mesh(cube_obj)
    with pytest.raises(ValueError, match="number of samples must be at most 200,000,000"):
        mesh.sample_surface(10**12)
    for n in (2**31, 2 * 10**9, 200_000_001):
        with pytest.raises(ValueError, match="at most 200,000,000 .4.8 GB"):
            mesh.sample_surface(n, return_faces=True)
    assert len(mesh.sample_surface(5, return_faces=True)[1]) == 5


def test_case10_bad_yaml_gives_file_and_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("max_iterations: 5\nmap:\n  resolution: [0.2\n")
    rc, _, err = cli("run", "--config", bad, "--out", tmp_path / "r")
    expect_error(rc, err, f"{bad}:")
    assert any(f"{bad}:{n}:" in err for n in (3, 4)), err
    rc, _, err = cli("sweep", bad)
    expect_error(rc, err, f"{bad}:")
    setlist = tmp_path / "setlist.yaml"
    setlist.write_text("set: [1, 2]\n")
    rc, _, err = cli("sweep", setlist)
    expect_error(rc, err, "'set'")


def test_case11_config_mistakes_are_rejected(tmp_path, cube_obj):
    typo = tmp_path / "typo.yaml"
    typo.write_text(f"meshes: [{{pth: {cube_obj}}}]\n")
    rc, _, err = cli("sweep", typo, "--out", tmp_path / "o")
    expect_error(rc, err, "pth")
    scen = tmp_path / "scen.yaml"
    scen.write_text('scenarios: "15"\n')
    rc, _, err = cli("sweep", scen, "--out", tmp_path / "o")
    expect_error(rc, err, "scenarios")
    # repeated --set accumulates: a bad key in the first is reported
    rc, _, err = cli("run", "--set", "nosuch.key=1", "--set", "max_iterations=5")
    expect_error(rc, err, "nosuch")
    from nbvkit.cli import build_parser

    args = build_parser().parse_args(["run", "--set", "a=1", "--set", "b=2", "c=3"])
    assert args.set == ["a=1", "b=2", "c=3"]


def test_case12_messages_instead_of_tracebacks(tmp_path, cube_obj):
    d = tmp_path / "adir"
    d.mkdir()
    cloud = tmp_path / "c.npy"
    import numpy as np

    np.save(cloud, np.zeros((3, 3)))
    rc, _, err = cli("evaluate", cloud, "--mesh", cube_obj, "--json", d)
    expect_error(rc, err, "--json", "folder")
    rc, _, err = scan_cli(cube_obj, d)
    expect_error(rc, err, "--out")
    rc, _, err = cli("run", "--config", d)
    expect_error(rc, err, "config file", "directory")
    with pytest.raises(TypeError, match="mesh"):
        nbvkit.Mission(load_config(), mesh=str(cube_obj))
    with pytest.raises(TypeError, match="overrides"):
        load_config(overrides="max_iterations=5")
    with pytest.raises(TypeError, match="overrides"):
        load_config(overrides=[5])


def test_api_arguments_of_a_wrong_type_are_named_not_read(cube_obj):
    """Every callable nbvkit exports, given None, a string, a number, a list, an array or an
    object for one required argument (the others valid, or None), raises TypeError / ValueError
    (or a file error for a path): never Python's AttributeError from deep inside."""
    import inspect

    import numpy as np

    cfg = load_config(overrides=[f"mesh.path={cube_obj}", "map.resolution=0.4"])
    mesh = nbvkit.load_mesh(cube_obj)
    world = nbvkit.World(cfg)
    valid = {"mesh": mesh, "config": cfg, "world": world}
    checked = []
    for name in nbvkit.__all__:
        fn = getattr(nbvkit, name)
        try:
            sig = inspect.signature(fn)
        except (TypeError, ValueError):
            continue  # a C++ class or function: pybind11 checks its argument types
        required = [p.name for p in sig.parameters.values() if p.default is p.empty
                    and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]  # fmt: skip
        for i, arg in enumerate(required):
            for bad in (None, "x", 3, [1, 2], np.zeros((2, 2)), object()):
                args = [bad if j == i else valid.get(a) for j, a in enumerate(required)]
                try:
                    fn(*args)
                except (TypeError, ValueError, KeyError, OSError):
                    pass
                checked.append(f"{name}({arg})")
    # the functions that read attributes of what they are given are among those checked
    for call in ("World(config)", "observable_surface(mesh)", "observable_surface(config)",
                 "plan_tour(world)", "mesh_to_open3d(mesh)",
                 "mesh_from_open3d(o3d_mesh)"):  # fmt: skip
        assert call in checked
    with pytest.raises(TypeError, match="config must be an nbvkit.Config"):
        nbvkit.observable_surface(mesh, {"camera": {}})
    with pytest.raises(TypeError, match="world must be an nbvkit.World"):
        nbvkit.plan_tour(None, np.zeros((1, 4)))


@pytest.mark.parametrize(
    "pose, said",
    [
        ([1.0, 2.0, 3.0, 1j], "real numbers"),  # kept its real part (a ComplexWarning alone)
        ([[1.0, 2.0], [3.0, 0.5]], "shape (2, 2)"),  # flattened and flown
        ([True, False, True, True], "real numbers"),  # a mask taken for a pose
        (["1", 2.0, 3.0, 0.0], "real numbers"),  # a string as a coordinate
        ([1.0, 2.0, 3.0], "shape (3,)"),
    ],
)
def test_a_pose_not_four_or_five_real_numbers_is_refused(pose, said):
    """World.fly_to, scan and sense read their poses through vehicle.as_view, which changed
    what it could not use (np.asarray(pose, float).reshape(-1)) instead of refusing it."""
    from nbvkit.vehicle import as_view

    with pytest.raises(ValueError, match=said.replace("(", r"\(").replace(")", r"\)")):
        as_view(pose)
    assert as_view([1, 2, 3, 0]).tolist() == [1.0, 2.0, 3.0, 0.0, 0.0]  # whole numbers are fine


def test_a_bool_is_no_resolution_and_no_update_is_made_of_none():
    """pybind took True as 1.0 (OccupancyMap(True) was a map of 1 m cells) and None as False
    (update_cells(occupied=None) a miss): both are refused; numbers of any kind are taken."""
    import numpy as np

    for bad in (True, np.bool_(True), "0.2", None):
        with pytest.raises(TypeError, match="resolution must be a number, got"):
            nbvkit.OccupancyMap(bad)
    for bad in (np.array([0.5, 0.5]), np.array(0.5j), np.complex64(0.5), list(range(10**5))):
        with pytest.raises(TypeError, match="resolution must be a number, got") as e:
            nbvkit.OccupancyMap(bad)
        assert len(str(e.value)) < 200  # (quoted short: a list had been 1.5 MB)
    with pytest.raises(ValueError, match="resolution must be a number a double holds, got ~1e400"):
        nbvkit.OccupancyMap(10**400)  # (pybind's "Unable to cast" RuntimeError)
    for good in (np.float32(0.5), np.array(0.5), 1, np.int16(1)):
        assert nbvkit.OccupancyMap(good).resolution == float(good)
    with pytest.raises(ValueError, match=r"number of threads must be in \[0, \d+\], got ~1e5000"):
        nbvkit.set_num_threads(10**5000)
    m = nbvkit.OccupancyMap(0.5)
    for bad in (None, 1, "yes"):
        with pytest.raises(TypeError):
            m.update_cells(np.zeros((1, 3)), occupied=bad)
    assert m.update_cells(np.zeros((1, 3)), occupied=np.bool_(True)) == 1


def test_the_workspace_and_the_vehicles_pose_cannot_be_written_in_place():
    """A plugin's part is given the world: writing into its workspace's boxes or the vehicle's
    pose changed the mission's state (a summary whose bounds_min lay above bounds_max, a vehicle
    moved with no flight), and a NaN distance was saved as null. Now a clear error."""
    import numpy as np
    from nbvkit.vehicle import VehicleState
    from nbvkit.workspace import Workspace

    given = np.zeros(3)
    ws = Workspace(given, np.ones(3), np.zeros(3), np.ones(3))
    given[:] = 5.0  # its own copies: the caller's array is not the workspace's
    assert ws.bounds_min.tolist() == [0.0, 0.0, 0.0]
    for name in ("bounds_min", "bounds_max", "nav_min", "nav_max"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(ws, name)[:] = 99.0
    s = VehicleState(pose=np.zeros(5))
    with pytest.raises(ValueError, match="read-only"):
        s.pose[:3] = 1.0
    s.pose = np.ones(5)  # moved by assignment (World.fly_to), as before
    assert s.pose.tolist() == [1.0] * 5
    for bad in (float("nan"), float("inf"), "3"):
        with pytest.raises(ValueError, match="distance_m must be a finite number"):
            s.distance_m = bad
    with pytest.raises(ValueError, match="pose must be real numbers, got complex"):  # (not cut)
        s.pose = np.ones(5) + 1j
    with pytest.raises(ValueError, match="bounds_min must be real numbers, got complex"):
        Workspace(np.zeros(3) + 2j, np.ones(3), np.zeros(3), np.ones(3))


def test_a_laser_beam_count_past_its_limit_shows_the_numbers_given(cube_obj):
    """std::to_string printed resolution_deg = 1e-9 as 0.000000 (the value refused looked like
    0) and the map's cell limit as 1000000000.000000: numbers show in their short form."""
    scene = nbvkit.RaycastScene(nbvkit.load_mesh(cube_obj))
    with pytest.raises(ValueError, match=r"resolution_deg = 1e-09 gives more than 1000000 beams"):
        nbvkit.LaserScanner(scene, resolution_deg=1e-9)


def test_candidate_rays_past_half_the_memory_it_may_use_is_refused():
    """candidate_rays (what a Python utility scores) laid out every cell of every candidate
    without a bound: 12,000 views of a 0.1 m map passed 4 GB. Past half the memory the process
    may use (here a 1.5 GiB address-space limit: 8.8 M cells at 91 bytes) it is refused with
    the count; just below it, it is laid out whole."""
    script = textwrap.dedent(
        """
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29))
        import numpy as np
        from conftest import seen_box_world
        from nbvkit import _core
        w = seen_box_world()
        p = w.state.pose
        each = _core.candidate_rays(w.map, p[None, :], p, camera=w.view_camera).num_cells
        cap = (3 << 29) // 2 // 91
        fits = _core.candidate_rays(w.map, np.tile(p, (cap // each, 1)), p, camera=w.view_camera)
        assert fits.num_cells == each * (cap // each) <= cap
        try:
            _core.candidate_rays(w.map, np.tile(p, (cap // each + 1, 1)), p, camera=w.view_camera)
        except ValueError as e:
            print(e)
        """
    )
    tests = str(Path(__file__).parent)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=120, env=dict(os.environ, PYTHONPATH=tests))  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert "rays reach more than 8849520 cells (0.7 GiB, half the memory" in p.stdout, p.stdout
