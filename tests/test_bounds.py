"""Bounds on inputs (issue 36, "Inputs"): every configured value has a range, every file read is
a regular file of sane size, meshes reach C++ only finite and with a surface, and the work a
configuration implies is checked before any work. The fast cases of bench/hostile_battery.py;
each fails if its fix is undone."""
from __future__ import annotations

import math
import os
import pickle
import re
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import nbvkit
from nbvkit.config import Config, load_config
from nbvkit.config_docs import bounds_table, documented_yaml
from nbvkit.limits import MAX_INT, check_input_file
from nbvkit.yamlio import read_yaml_file

ROOT = Path(__file__).resolve().parent.parent
CUBE = ROOT / "meshes" / "fixtures" / "cube.obj"
sys.path.insert(0, str(ROOT / "bench"))

from hostile_battery import (  # noqa: E402
    CUBE_F,
    CUBE_V,
    LAUGHS,
    gltf_text,
    numeric_keys,
    obj_text,
    stl_text,
)


def cli(*args, timeout=60):
    p = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=dict(os.environ, MPLBACKEND="Agg"),
    )
    return p.returncode, p.stdout, p.stderr


# ---------------------------------------------------------------------------- config keys


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e400", ".nan", ".inf", "-1e400"])
def test_every_numeric_key_refuses_non_finite_values_naming_the_key(value):
    for key, _ in numeric_keys():
        if key == "symmetry.max_descriptor_distance" and value in (".inf", "1e400"):
            assert math.isinf(getattr(load_config(overrides=[f"{key}={value}"]).symmetry,
                                      "max_descriptor_distance"))  # fmt: skip
            continue
        with pytest.raises(ValueError) as e:
            load_config(overrides=[f"{key}={value}"])
        assert repr(key) in str(e.value), (key, value, str(e.value))


def test_every_integer_key_has_a_maximum_and_refuses_1e12_naming_it():
    ints = [k for k, t in numeric_keys() if t == "int"]
    assert len(ints) >= 30
    rows = {k: rng for k, _, _, rng in bounds_table()}
    for key in ints:
        assert "<=" in rows[key] or ".." in rows[key] or rows[key].endswith("]"), (key, rows[key])
        for value in ("1e12", str(10**30)) if key != "seed" else (str(10**30),):
            with pytest.raises(ValueError, match="limit") as e:
                load_config(overrides=[f"{key}={value}"])
            assert repr(key) in str(e.value)
    # the default maximum of an integer key is the C++ int's
    with pytest.raises(ValueError, match=f"limit {MAX_INT:_}"):
        load_config(overrides=["vehicle.path_expansions=1", f"budget.max_views={MAX_INT + 1}"])


def test_integer_keys_say_integer_for_fractions_and_negatives_are_named():
    with pytest.raises(ValueError, match="'camera.width' must be an integer, got 1.5"):
        load_config(overrides=["camera.width=1.5"])
    with pytest.raises(ValueError, match="'profiling.waypoints' must be >= 1, got -1"):
        load_config(overrides=["profiling.waypoints=-1"])


def test_numpy_numbers_are_read_as_numbers_and_bools_as_none():
    # a script's numpy scalars: read by their values (an int64 was refused as no integer, a
    # float32 fraction would have been cut); a bool is no number, numpy's neither
    cfg = Config.from_dict(
        {"camera": {"width": np.int64(64)}, "map": {"resolution": np.float32(0.25)}}
    )
    assert cfg.camera.width == 64 and type(cfg.camera.width) is int and cfg.map.resolution == 0.25
    with pytest.raises(ValueError, match="'camera.width' must be an integer, got 1.5"):
        Config.from_dict({"camera": {"width": np.float32(1.5)}})
    for flag in (True, np.bool_(True)):
        with pytest.raises(ValueError, match="'map.resolution' must be a number"):
            Config.from_dict({"map": {"resolution": flag}})


def test_bounds_are_declared_on_fields_and_documented_in_default_yaml():
    text = documented_yaml()
    assert "waypoints: 4  # N, points around the structure (authors: 5) [1..1000]" in text
    assert "[0..1_000_000]" in next(ln for ln in text.splitlines() if "max_iterations:" in ln)
    # every default of every scenario lies within its bounds
    from nbvkit.scenarios import SCENARIOS

    for name in SCENARIOS:
        Config.from_dict({"scenario": name})


def test_defaults_are_unchanged_by_the_bounds():
    cfg = Config()
    assert (cfg.profiling.waypoints, cfg.profiling.margin, cfg.camera.width) == (4, 4.0, 640)
    assert cfg.evaluation.gt_density is None and cfg.observability.pose_spacing == 2.0


def test_empty_generators_with_profiling_off_is_an_error_not_profile_only():
    with pytest.raises(ValueError, match="planner.generators.*fly nothing"):
        load_config(overrides=["planner.generators=[]", "profiling.enabled=false"])
    assert load_config(overrides=["scenario=profile"]).planner.generators == ()


def test_messages_quote_hostile_values_shortly():
    huge = "x" * 10**6
    for override in ([f"scenario={huge}"], [f"camera.width={huge}"], [f"{huge}=1"]):
        with pytest.raises((ValueError, KeyError)) as e:
            load_config(overrides=override)
        assert len(str(e.value)) < 1000


# ---------------------------------------------------------------------------- files


def test_yaml_alias_bomb_is_refused_quickly_with_a_short_message(tmp_path):
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(LAUGHS)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="aliases") as e:
        Config.from_yaml(bomb)
    assert time.perf_counter() - t0 < 5 and len(str(e.value)) < 500
    # anchors and aliases of ordinary size still work
    ok = tmp_path / "ok.yaml"
    ok.write_text("camera: &c {width: 320}\nmax_iterations: 3\n")
    assert Config.from_yaml(ok).camera.width == 320


def test_config_and_sweep_files_must_be_regular_files_of_sane_size(tmp_path):
    fifo = tmp_path / "c.yaml"
    os.mkfifo(fifo)
    zero = tmp_path / "z.yaml"
    zero.symlink_to("/dev/zero")
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * (5 << 20))
    for path, needle in (
        (fifo, "FIFO"),
        (zero, "character device"),
        (tmp_path, "directory"),
        (big, "more than the 4,194,304 bytes"),
    ):
        for what in ("config file", "sweep file"):
            with pytest.raises(ValueError, match=needle) as e:
                read_yaml_file(path, what)
            assert str(path) in str(e.value) and what in str(e.value)
    with pytest.raises(FileNotFoundError):
        read_yaml_file(tmp_path / "missing.yaml")


def test_a_fifo_config_through_the_cli_exits_2_at_once(tmp_path):
    fifo = tmp_path / "c.yaml"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    rc, _, err = cli("run", "--config", fifo, "--out", tmp_path / "o", timeout=60)
    assert rc == 2 and "FIFO" in err and "Traceback" not in err, (rc, err)
    assert time.perf_counter() - t0 < 30


def test_point_cloud_and_mesh_readers_refuse_fifos_devices_and_folders(tmp_path):
    from nbvkit.cloud import read_points

    for name in ("c.npy", "c.ply", "m.obj", "m.ply"):
        fifo = tmp_path / ("fifo_" + name)
        os.mkfifo(fifo)
        dev = tmp_path / ("dev_" + name)
        dev.symlink_to("/dev/urandom")
        read = read_points if name.startswith("c") else nbvkit.load_mesh
        for path, needle in ((fifo, "FIFO"), (dev, "character device")):
            result = {}

            def call():
                try:
                    read(path)
                except Exception as e:  # noqa: BLE001 - the test inspects it
                    result["e"] = e

            t = threading.Thread(target=call, daemon=True)
            t.start()
            t.join(10)
            assert not t.is_alive(), f"reading {path} blocked"
            assert isinstance(result.get("e"), ValueError), result
            assert needle in str(result["e"]) and str(path) in str(result["e"])


def test_a_fifo_named_as_collada_names_no_run_and_does_not_block(tmp_path):
    """The run id of a spec reads a Collada file's up axis: a FIFO there neither blocks it nor
    the axis query, which refuses it naming the FIFO (the run then fails naming it)."""
    from nbvkit.experiment_specs import RunSpec

    fifo = tmp_path / "m.dae"
    os.mkfifo(fifo)
    result = {}

    def call():
        result["id"] = RunSpec("1", 0, mesh=str(fifo)).run_id
        try:
            nbvkit.file_up_axis(fifo)
        except ValueError as e:
            result["e"] = e

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(10)
    assert not t.is_alive(), "blocked on the FIFO"
    assert result["id"].startswith("m_s1_start0_") and "FIFO" in str(result["e"])


def test_the_cpp_mesh_loader_refuses_non_regular_files_too(tmp_path):
    fifo = tmp_path / "m.obj"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="FIFO"):
        nbvkit._core._load_mesh(str(fifo))
    with pytest.raises(ValueError, match="character device"):
        nbvkit._core._load_mesh("/dev/zero")


def test_check_input_file_takes_any_os_path(tmp_path):
    odd = os.path.join(os.fsencode(str(tmp_path)), b"c\xff\xfe.yaml")
    with open(odd, "wb") as f:
        f.write(b"max_iterations: 3\n")
    assert check_input_file(odd, "config file").name == os.fsdecode(b"c\xff\xfe.yaml")
    assert Config.from_yaml(os.fsdecode(odd)).max_iterations == 3


# ---------------------------------------------------------------------------- meshes


def _nan_cube(coord=float("nan")):
    v = list(CUBE_V)
    v[7] = (coord, 1.0, 1.0)
    return v


@pytest.mark.parametrize("ext", [".obj", ".stl", ".gltf"])
@pytest.mark.parametrize("coord", [float("nan"), float("inf")])
def test_non_finite_vertices_are_refused_not_merged(tmp_path, ext, coord):
    text = {".obj": obj_text, ".stl": stl_text, ".gltf": gltf_text}[ext](_nan_cube(coord), CUBE_F)
    p = tmp_path / ("m" + ext)
    p.write_text(text)
    with pytest.raises(ValueError, match="NaN or infinite") as e:
        nbvkit.load_mesh(p)
    assert str(p) in str(e.value)
    # the same file with the vertex finite loads with the cube's area
    good = tmp_path / ("good" + ext)
    good.write_text({".obj": obj_text, ".stl": stl_text, ".gltf": gltf_text}[ext](CUBE_V, CUBE_F))
    assert nbvkit.load_mesh(good).area == pytest.approx(6.0)


def test_a_mesh_without_a_triangle_of_area_is_an_error(tmp_path):
    p = tmp_path / "flat.obj"
    p.write_text(obj_text([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(0, 1, 2)]))
    with pytest.raises(ValueError, match="no area"):
        nbvkit.load_mesh(p)
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    with pytest.raises(ValueError, match=r"mesh: its 1 triangles have no area \(all degenerate"):
        nbvkit.Mesh(v, np.array([[0, 1, 2]], np.int32))
    # a scale that overflows the triangles' areas (inf - inf: NaN) was called degenerate
    with pytest.raises(ValueError, match=r"infinite area \(coordinates too large\) at mesh scale"):
        nbvkit.load_mesh(CUBE, scale=1e300)


def test_mesh_arrays_are_read_only_and_rebuilt_meshes_are_checked():
    m = nbvkit.load_mesh(CUBE)
    with pytest.raises(ValueError, match="read-only"):
        m.faces[0, 0] = 10**6
    with pytest.raises(ValueError, match="read-only"):
        m.vertices[0, 0] = np.nan
    f = np.array(m.faces)
    f[0, 0] = 10**6
    with pytest.raises(ValueError, match="out of range"):
        nbvkit.Mesh(m.vertices, f)
    v = np.array(m.vertices)
    v[0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN|finite"):
        nbvkit.Mesh(v, m.faces)


def test_arrays_reach_the_core_as_their_values_or_are_refused(tmp_path):
    """Index and kind arrays: any integer dtype (width, byte order) or whole floats are read as
    their values; a value the core's type cannot hold or a fraction is refused (numpy's cast
    wrapped 2**32 to 0 and cut 0.9 to 0). Weights in a strided view are read by their strides
    (they were read as if contiguous, past the array's end for a reversed view), and
    observable_surface keeps a copy of the points it is given."""
    from nbvkit import _core

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    for faces in ([[0, 1, 2]], np.array([[0, 1, 2]], ">i8"), np.array([[0, 1, 2]], np.uint64)):
        assert nbvkit.Mesh(v, faces).faces.tolist() == [[0, 1, 2]]
    assert nbvkit.Mesh(v, np.array([[0.0, 1.0, 2.0]])).faces.tolist() == [[0, 1, 2]]
    for faces, needle in (
        (np.array([[2**32, 1, 2]]), "mesh faces: 4294967296 does not fit int32"),
        (np.array([[2**32, 1, 2]], np.uint64), "4294967296 does not fit int32"),
        (np.array([[0.9, 1.5, 2.99]]), "mesh faces: 0.9 is not an integer"),
        (np.array([[0, 1, 2]], complex), "mesh faces must be integers.*complex128"),
        ([["a", "b", "c"]], "mesh faces must be integers"),
    ):
        with pytest.raises(ValueError, match=needle):
            nbvkit.Mesh(v, faces)

    pos, nrm, w = np.zeros((3, 3)), np.tile([1.0, 0, 0], (3, 1)), np.array([1.0, 2.0, 3.0])
    table = np.stack([w, w + 7], axis=1)
    for weight in (np.repeat(w, 2)[::2], table[:, 0], w[::-1].copy()[::-1], w.astype(">f8")):
        np.testing.assert_array_equal(_core.SurfaceTargets(pos, nrm, weight).weight, w)
    kind = np.array([1, 0, 3], np.uint8)
    np.testing.assert_array_equal(_core.SurfaceTargets(pos, nrm, w, kind).kind, [1, 0, 3])
    with pytest.raises(ValueError, match="kind: 1.7 is not an integer"):
        _core.SurfaceTargets(pos, nrm, w, np.array([1.7, 0, 0]))
    with warnings.catch_warnings():  # numpy's cast warning as an error crashed the process
        warnings.simplefilter("error")
        for kind in (np.array([2.0**63, 0, 0]), np.array([2**64 - 1, 0, 0], np.uint64)):
            with pytest.raises(ValueError, match="does not fit int64"):
                _core.SurfaceTargets(pos, nrm, w, kind)

    mesh = nbvkit.Mesh(np.array(CUBE_V, float), np.array(CUBE_F, np.int32))
    pts, fid = mesh.sample_surface(50, 0, return_faces=True)
    cfg = load_config(None, ["observability.pose_spacing=0.5"])
    r = nbvkit.observable_surface(mesh, cfg, points=pts, face_ids=fid)
    before = r.points.copy()
    pts[:] = 0
    np.testing.assert_array_equal(r.points, before)


def test_non_utf8_mesh_paths_load(tmp_path):
    raw = os.path.join(os.fsencode(str(tmp_path)), b"m\xff\xfe.obj")
    with open(raw, "wb") as f:
        f.write(obj_text(CUBE_V, CUBE_F).encode())
    for path in (raw, os.fsdecode(raw), Path(os.fsdecode(raw))):
        assert nbvkit.load_mesh(path).area == pytest.approx(6.0)
    bad = os.path.join(os.fsencode(str(tmp_path)), b"x\xff.obj")
    with open(bad, "wb") as f:
        f.write(b"not a mesh\n")
    with pytest.raises(ValueError, match="cannot read mesh|no triangles"):
        nbvkit.load_mesh(bad)


# ---------------------------------------------------------------------------- work


def _mission_error(overrides, mesh=None):
    cfg = load_config(overrides=["map.resolution=0.4", *overrides])
    t0 = time.perf_counter()
    with pytest.raises(ValueError) as e:
        nbvkit.Mission(cfg, mesh=mesh if mesh is not None else nbvkit.load_mesh(CUBE))
    assert time.perf_counter() - t0 < 10, "the check came after the work"
    return str(e.value)


@pytest.mark.parametrize(
    "override, key",
    [
        ("profiling.z_max=1e12", "profiling.z_max"),
        ("profiling.margin=1e-6", "profiling.margin"),
        ("profiling.sweep_step=1e-6", "profiling.sweep_step"),
        ("profiling.camera_step=1e-4", "profiling.camera_step"),
        ("profiling.max_segment=1e-5", "profiling.max_segment"),
        ("evaluation.gt_density=1e12", "evaluation.gt_density"),
        ("observability.pose_spacing=0.05", "observability.pose_spacing"),
    ],
)
def test_keys_that_size_work_are_checked_before_any_work(override, key):
    msg = _mission_error([override])
    assert key in msg and "limit" in msg and "would fit" in msg, msg


@pytest.mark.parametrize(
    "override, key, mesh_scale",
    [
        ("evaluation.gt_density=1e12", "evaluation.gt_density", 1),
        ("profiling.sweep_step=1e-6", "profiling.sweep_step", 1),
        ("profiling.camera_step=1e-4", "profiling.camera_step", 1),
        ("profiling.max_segment=1e-5", "profiling.max_segment", 1),
        ("observability.pose_spacing=0.05", "observability.pose_spacing", 1),
        # the reviews' cases: a fit shown rounded to nearest was refused in turn (0.25 for
        # 0.24997; 9.772e+04 for 97,719.3), on a structure 400 m across
        ("evaluation.gt_density=1e9", "evaluation.gt_density", 400),
        ("profiling.sweep_step=0.01", "profiling.sweep_step", 400),
    ],
)
def test_the_value_that_would_fit_fits(override, key, mesh_scale):
    """The value an error says would fit is accepted for its key when given back."""
    from nbvkit.work_limits import check_work
    from nbvkit.workspace import make_workspace

    mesh = nbvkit.load_mesh(CUBE, scale=mesh_scale)
    res = f"map.resolution={0.4 if mesh_scale == 1 else 1}"  # (a map that fits the structure)
    msg = _mission_error([res, override], mesh=mesh)
    fit = float(re.search(rf"{re.escape(key)} [<>]= ([0-9.e+-]+) ", msg).group(1))
    cfg = load_config(overrides=[res, f"{key}={fit}"])
    try:
        check_work(cfg, mesh, make_workspace(mesh.bounds, cfg))
    except ValueError as e:  # another key's limit may follow; this key's is met
        assert f"{key} = " not in str(e), str(e)


def test_every_limit_a_structure_exceeds_is_named_at_once():
    """A workspace too wide for both the map and the observable surface's lattice: one error
    names both, each with the value that would fit (one at a time, the user who followed the
    map's hint met the lattice's next), and the two values given back are accepted."""
    from nbvkit.work_limits import check_work
    from nbvkit.workspace import make_workspace

    wide = ["map.resolution=0.2", "workspace.margin_xy=600"]
    msg = _mission_error(wide)
    assert msg.startswith("2 limits exceeded: "), msg
    fits = {
        key: re.search(rf"{re.escape(key)} >= ([0-9.e+-]+) would fit", msg).group(1)
        for key in ("map.resolution", "observability.pose_spacing")
    }
    cfg = load_config(overrides=[*wide, *(f"{k}={v}" for k, v in fits.items())])
    mesh = nbvkit.load_mesh(CUBE)
    check_work(cfg, mesh, make_workspace(mesh.bounds, cfg))  # raises nothing


def test_a_map_too_large_names_the_keys_that_made_its_workspace():
    """Explicit workspace bounds too wide for OctoMap were blamed on workspace.margin_xy and
    margin_z, which the user never gave."""
    wide = ["workspace.bounds_min=[-1e9,-1e9,0]", "workspace.bounds_max=[1e9,1e9,10]"]
    msg = _mission_error(wide)
    assert "too large for the map" in msg and "workspace.bounds_min = [-1e+09" in msg, msg
    assert "margin_xy" not in msg, msg
    assert "workspace.margin_xy = 1e+06" in _mission_error(["workspace.margin_xy=1e6"])
    # under a flight envelope its height above the top is named too (it named margin_xy alone)
    msg = _mission_error(["workspace.margin_xy=1e6", "workspace.margin_z=null"])
    assert "margin_z = null: the camera's far stand-off above the top" in msg, msg
    # within OctoMap's range but over the map's memory at any resolution: the bounds given, not
    # the structure's scale, make the workspace
    box = ["workspace.bounds_min=[-6000,-6000,0]", "workspace.bounds_max=[6000,6000,6000]"]
    msg = _mission_error(box)
    assert "a smaller workspace" in msg and "mesh.scale" not in msg, msg


def test_given_bounds_far_from_the_origin_are_told_to_move_with_the_structure(tmp_path):
    """A structure 100 km out in bounds given around it: the error's mesh.shift alone moved the
    structure out of the bounds (then refused as holding no part of it); it says the bounds move
    by the same, and following it flies."""
    from nbvkit.world import World

    box = tmp_path / "far.obj"
    box.write_text(
        "".join(f"v {x + 1e5} {y + 1e5} {z}\n" for z in (0, 5) for y in (0, 20) for x in (0, 20))
        + "f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\n"
        + "f 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n"
    )
    lo, hi = np.array([99990.0, 99990, 0]), np.array([100030.0, 100030, 10])
    given = [f"mesh.path={box}", "map.resolution=0.4", "progress=false"]
    bounds = [f"workspace.bounds_min={lo.tolist()}", f"workspace.bounds_max={hi.tolist()}"]
    with pytest.raises(ValueError) as e:
        World(load_config(overrides=given + bounds))
    msg = str(e.value)
    shift = re.search(r"mesh.shift=\[([-0-9,]+)\]", msg).group(1)
    by = re.search(r"moved by the same \[([-0-9, ]+)\]", msg).group(1)
    by = np.array([float(x) for x in by.split(",")])
    moved = [
        f"workspace.bounds_min={(lo + by).tolist()}",
        f"workspace.bounds_max={(hi + by).tolist()}",
    ]
    world = World(load_config(overrides=given + moved + [f"mesh.shift=[{shift}]"]))
    assert np.all(np.isfinite(world.start_pose))


def test_a_structure_of_almost_no_area_names_the_ground_truth_density():
    """A cube at mesh.scale 1e-9 was refused by the evaluator's "gt_density 1000 points/m^2
    over the mesh's 6e-18 m^2 gives no ground-truth samples", naming no key: it is refused
    before any work, naming evaluation.gt_density and the density that makes a sample."""
    tiny = nbvkit.load_mesh(CUBE, scale=1e-9)
    for given, default in (([], True), (["evaluation.gt_density=5"], False)):
        msg = _mission_error(given, mesh=tiny)
        assert "evaluation.gt_density = " in msg and "makes no sample" in msg, msg
        assert ("(the default)" in msg) == default, msg


def test_every_limit_of_the_profile_flight_is_named_at_once():
    """The profile flight's checks stopped at the first: its laser rays named, its camera
    frames only once those were mended. Both are named now, with what would fit, and the
    values given back are accepted. (Its rays and legs grow with its scans: named once those
    fit.)"""
    from nbvkit.work_limits import check_work
    from nbvkit.workspace import make_workspace

    keys = [
        "profiling.sweep_step=0.0001",
        "laser.resolution_deg=0.001",
        "profiling.camera_step=0.0001",
    ]
    msg = _mission_error(keys)
    assert msg.startswith("2 limits exceeded: "), msg
    fits = {
        key: re.search(rf"{re.escape(key)} >= ([0-9.e+-]+) .*?would fit", msg).group(1)
        for key in ("laser.resolution_deg", "profiling.camera_step")
    }
    given = ["map.resolution=0.4", keys[0], *(f"{k}={v}" for k, v in fits.items())]
    cfg = load_config(overrides=given)
    mesh = nbvkit.load_mesh(CUBE)
    check_work(cfg, mesh, make_workspace(mesh.bounds, cfg))  # raises nothing
    # the error crosses from a worker process whole (pickled: rebuilt from its problems)
    cfg = load_config(overrides=["map.resolution=0.4", *keys])
    with pytest.raises(ValueError) as e:
        check_work(cfg, mesh, make_workspace(mesh.bounds, cfg))
    assert str(pickle.loads(pickle.dumps(e.value))) == str(e.value) == msg
    e.value.add_note("a worker's note")  # (a plugin frame, a part's name)
    assert pickle.loads(pickle.dumps(e.value)).__notes__ == ["a worker's note"]


def test_a_map_resolution_offered_at_the_keys_largest_fits():
    """Workspaces whose map needs just under the largest map.resolution (10 m): the value
    offered, capped at 10, was refused in turn (a 5,050 m cube); it is offered only where it
    fits."""
    import types

    from nbvkit.work_limits import check_map

    for side in np.arange(5040.0, 5056.0, 0.5):
        ws = types.SimpleNamespace(
            bounds_min=np.full(3, -side / 2), bounds_max=np.full(3, side / 2)
        )
        try:
            check_map(load_config(overrides=["map.resolution=0.2"]), ws)
            continue
        except ValueError as e:
            offered = re.search(r"map.resolution >= ([0-9.e+-]+) would fit", str(e))
        if offered:
            check_map(load_config(overrides=[f"map.resolution={offered.group(1)}"]), ws)


def _obj_mesh(tmp_path, verts, faces):
    p = tmp_path / "m.obj"
    p.write_text(obj_text(verts, faces))
    return nbvkit.load_mesh(p)


def test_a_structure_too_large_or_thin_for_the_map_is_refused_before_any_work(tmp_path):
    sliver = _obj_mesh(
        tmp_path,
        CUBE_V + [(0.5, 0.5, 0.5), (2000.0, 0.5, 0.5), (2000.0, 0.6, 0.5)],
        CUBE_F + [(8, 9, 10)],
    )
    cfg = load_config(overrides=["max_iterations=2"])
    with pytest.raises(ValueError, match="map.resolution >= .* would fit"):
        nbvkit.Mission(cfg, mesh=sliver)
    tower = _obj_mesh(tmp_path, [(2 * x, 2 * y, 2000 * z) for x, y, z in CUBE_V], CUBE_F)
    with pytest.raises(ValueError, match="would fit"):
        nbvkit.Mission(cfg, mesh=tower)


def test_limits_name_a_floating_structure_and_offer_no_resolution_past_its_range(tmp_path):
    """A structure given in altitudes (5 km up): the profile's sweeps down to the ground passed
    the scan limit, and the error blamed the sweep step alone; it now names the height and the
    mesh.shift that grounds it. A 10 km structure's map would fit at 20 m, past map.resolution's
    range (10 m): the error offered it; it now offers the workspace and the mesh's scale."""
    high = _obj_mesh(tmp_path, [(x, y, z + 5000) for x, y, z in CUBE_V], CUBE_F)
    msg = _mission_error([], mesh=high)
    assert "profiling.sweep_step" in msg and "lies 5000 m above the ground" in msg, msg
    assert "mesh.shift=[0,0,-5000]" in msg
    huge = _obj_mesh(tmp_path, [(1e4 * x, 1e4 * y, 1e4 * z) for x, y, z in CUBE_V], CUBE_F)
    msg = _mission_error(["map.resolution=10"], mesh=huge)
    assert "map.resolution >=" not in msg and "a smaller mesh.scale" in msg, msg
    # where the key's largest value fits (9.95 m needed), it is offered, not dropped
    near = _obj_mesh(tmp_path, [(5030 * x, 5030 * y, 5030 * z) for x, y, z in CUBE_V], CUBE_F)
    msg = _mission_error(["map.resolution=5", "profiling.enabled=false"], mesh=near)
    assert "map.resolution >= 10 would fit" in msg, msg
    # a value refused past a limit is shown with the digits that put it there
    with pytest.raises(ValueError, match="= 180.0001 is more than its limit 180"):
        load_config(overrides=["utility.coverage_cone_deg=180.0001"])


def test_sweep_files_are_bounded():
    from nbvkit.experiments import sweep_specs

    with pytest.raises(ValueError, match="0..5"):
        sweep_specs({"starts": 10**12})
    with pytest.raises(ValueError, match="runs"):
        sweep_specs({"starts": 5, "grid": {f"k{i}": list(range(10)) for i in range(8)}})
    for starts in ([7], [0, -1]):  # refused before any run, not each run failing alone
        with pytest.raises(ValueError, match=r"'starts' are indices 0..4 .*got \[(7|-1)\]"):
            sweep_specs({"starts": starts})
    assert [s.start for s in sweep_specs({"starts": [4, 0]})] == [4, 0]


def test_cpp_option_errors_name_the_dotted_key():
    for override, needle in (
        ("map.prob_hit=0", "config key 'map.prob_hit' must be in [0.5, 1)"),
        ("camera.hfov_deg=0", "config key 'camera.hfov_deg' must be in (0, 180)"),
        ("laser.resolution_deg=1e-9", "config key 'laser.resolution_deg'"),
    ):
        with pytest.raises(ValueError) as e:
            load_config(overrides=[override])
        assert needle in str(e.value), str(e.value)


def test_view_camera_rays_are_bounded_with_the_range_that_fits():
    with pytest.raises(ValueError, match="rays per candidate view") as e:
        load_config(overrides=["camera.max_range=1000"])
    fit = float(str(e.value).split("camera.max_range <= ")[1].split()[0])
    load_config(overrides=[f"camera.max_range={fit}"])


def test_an_empty_sweep_range_names_the_profiling_keys():
    msg = _mission_error(["profiling.z_max=0"])
    assert "'profiling.z_max'" in msg and "z_max > z_min" in msg
    # sweeps below the height the vehicle keeps above the ground (the profile flew 0.3 m up)
    msg = _mission_error(["profiling.z_min=0.3"])
    assert "'profiling.z_min' = 0.3 m lies below the navigation floor, z = 0.9 m" in msg
    assert "vehicle.min_altitude" in _mission_error(["vehicle.min_altitude=3", "profiling.z_min=2"])


def test_the_core_refuses_sizes_no_structure_has_naming_them():
    """From a review of the Python API: values a unit's mistake gives were taken silently
    (evaluate at a 1e308 m grid read 100 % coverage, a 1e308 m map of one cell, a distance of
    1e200 m came back inf, a complex query point kept its real part)."""
    from nbvkit import _core

    mesh = nbvkit.load_mesh(nbvkit.default_mesh_path())
    pts = np.asarray(mesh.vertices)[:10]
    for key, bad in (("resolutions", 1e308), ("resolutions", 1e-300), ("taus", 1e308)):
        with pytest.raises(ValueError, match=f"{key} must be within"):
            nbvkit.evaluate(mesh, pts, gt_density=50, **{key: [bad]})
    for res in (1e308, 1e-9):
        with pytest.raises(ValueError, match=r"resolution must be within \[0.0001, 100\] m"):
            _core.OccupancyMap(res, [-3, -3, -3], [3, 3, 3])
    with pytest.raises(ValueError, match="queries"):
        _core.nearest_distances([[0, 0, 0]], [[1e200, 0, 0]])
    with pytest.raises(ValueError, match="targets"):
        _core.nearest_distances([[1e200, 0, 0]], [[0, 0, 0]])
    m = _core.OccupancyMap(0.5, [-3, -3, -3], [3, 3, 3])
    with pytest.raises(ValueError, match="query points must be real numbers, got complex"):
        m.probability(np.array([[0 + 5j, 0, 0]]))
    assert m.probability(np.zeros((1, 3))) == pytest.approx([0.5])


def test_bool_arrays_are_not_read_as_numbers_by_the_core():
    # (a mask given for indices or coordinates was read as 0 and 1: a mesh of one degenerate
    # triangle from bool faces, a query at (1, 1, 1))
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match=r"mesh faces must be integers, got bools \(dtype bool\)"):
        nbvkit.Mesh(v, np.array([[False, True, True]]))
    with pytest.raises(ValueError, match="mesh vertices must be numbers, got bools"):
        nbvkit.Mesh(v.astype(bool), np.array([[0, 1, 2]]))
    m = nbvkit._core.OccupancyMap(0.5, [-3, -3, -3], [3, 3, 3])
    with pytest.raises(ValueError, match="query points must be numbers, got bools"):
        m.probability(np.ones((1, 3), bool))
    with pytest.raises(ValueError, match="option 'crop_min' must be numbers, got bools"):
        nbvkit._core.SurfaceCloudOptions(crop_min=np.array([True, False, True]))
    assert nbvkit.Mesh(v, np.array([[0, 1, 2]], np.uint8)).num_triangles == 1  # integers: read


def test_paths_of_the_wrong_type_or_with_a_nul_byte_are_named(tmp_path):
    # (a bare "expected str, bytes or os.PathLike object, not int", "embedded null byte" and a
    # FileExistsError from mkdir, none naming what was wrong)
    with pytest.raises(TypeError, match="config file path must be a str, bytes or os.PathLike"):
        Config.from_yaml(5)
    with pytest.raises(
        TypeError, match="map file path must be a str or os.PathLike of str, got int"
    ):
        nbvkit.OccupancyMap.load(5)
    with pytest.raises(ValueError, match="map file path holds a NUL byte"):
        nbvkit.OccupancyMap.load("a\0b.ot")
    with pytest.raises(ValueError, match=r"mesh file path 'a\\x00b' holds a NUL byte"):
        nbvkit.load_mesh("a\0b")
    taken = tmp_path / "file"
    taken.write_text("x")
    mesh = nbvkit.load_mesh(CUBE)
    with pytest.raises(ValueError, match="cache_dir .*file exists and is not a folder"):
        nbvkit.observable_surface(mesh, load_config(), cache_dir=taken)


@pytest.mark.parametrize("section", ["utility", "targets"])
def test_documented_ranges_of_cpp_sections_are_the_ranges_the_core_enforces(section):
    """Each range default.yaml shows for a key of a C++ options class (limits.Bound on the
    section) is the one the core's validate() enforces: both accept each end the range holds and
    both refuse a value just past each end (a documented range the core disagreed with would
    be a wrong document, or a value passed to the core unchecked)."""
    import dataclasses

    from nbvkit.config import Config

    cls = type(getattr(Config(), section))
    opts = getattr(Config(), section).options()
    checked = 0
    for f in dataclasses.fields(cls):
        b = f.metadata.get("bound")
        if b is None or f.name not in opts.fields():
            continue
        whole = isinstance(getattr(opts, f.name), int)
        step = 1 if whole else 1e-6
        cases = []
        for end, is_open, sign in ((b.lo, b.lo_open, -1), (b.hi, b.hi_open, 1)):
            if end is not None:
                cases += [(end, not is_open), (end + sign * step, False)]
        for value, ok in cases:
            value = int(value) if whole else float(value)
            key = f"{section}.{f.name}"
            try:
                opts.copy(**{f.name: value})
                core_ok = True
            except ValueError:
                core_ok = False
            try:
                load_config(overrides=[f"{key}={value!r}"])
                py_ok = True
            except ValueError:
                py_ok = False
            assert (core_ok, py_ok) == (ok, ok), (key, value, b.describe())
            checked += 1
    assert checked >= (20 if section == "utility" else 2)


def test_the_observable_lattices_would_fit_fits_a_thin_box():
    """A thin navigation box (120 x 120 x 6 m, 2e7 samples): each side's faces add a level, so
    the spacing said to fit is counted on the lattice itself (0.591 m, counted as a lattice
    about the centre, was refused in turn at 504,300 positions)."""
    from types import SimpleNamespace

    from nbvkit.work_limits import check_observability

    ws = SimpleNamespace(nav_min=np.zeros(3), nav_max=np.array([120.0, 120.0, 6.0]))
    with pytest.raises(ValueError, match="would fit") as e:
        check_observability(load_config(None, ["observability.pose_spacing=0.05"]), ws, 2e7)
    fit = re.search(r"pose_spacing >= ([0-9.e+-]+) would fit", str(e.value)).group(1)
    check_observability(load_config(None, [f"observability.pose_spacing={fit}"]), ws, 2e7)
