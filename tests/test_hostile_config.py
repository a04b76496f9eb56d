"""Hostile configurations (audit): each case gets a clear error naming the problem, exit 2 and no
traceback from the command line, never a silent wrong answer. Each test fails if its fix is
undone. Cases that once ended the process (a plugin's SystemExit) run in a subprocess."""
from __future__ import annotations

import dataclasses
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nbvkit.cli import main
from nbvkit.config import Config, load_config
from nbvkit.experiment_specs import compare_specs, sweep_specs, table2_specs
from nbvkit.yamlio import parse_yaml, read_yaml_file

ROOT = Path(__file__).resolve().parent.parent
CUBE = ROOT / "meshes" / "fixtures" / "cube.obj"


def cli(*args, cwd=None):
    """`nbvkit ARGS` in a subprocess: (returncode, stderr)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
        env=env,
    )
    return p.returncode, p.stderr


def refused(capsys, argv, *needles) -> str:
    """main(argv) fails cleanly: exit 2 (returned, or argparse's exit), its message naming the
    problem; returns stderr."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)
    return err


# ------------------------------------------------------------ 1. map.resolution has a maximum
@pytest.mark.parametrize("value", ["1e300", "1e200", "10.5"])
def test_a_huge_map_resolution_is_refused_naming_the_key(value):
    with pytest.raises(ValueError, match=r"'map.resolution' .* more than its limit 10"):
        load_config(overrides=[f"map.resolution={value}"])


@pytest.mark.parametrize(
    "key",
    [
        "cloud.camera_voxel",
        "cloud.laser_voxel",
        "symmetry.voxel_size",
        "symmetry.icp_voxel_size",
        "symmetry.uniform_leaf",
    ],
)
def test_a_voxel_grid_cell_over_1000_m_is_refused_naming_the_key(key):
    """Cells the voxel grids refuse (over 1000 m) are refused by their key before any work: they
    once failed only where used (ICP after a plane was found), naming no key."""
    with pytest.raises(ValueError, match=rf"'{key}' = 1e\+12 is more than its limit 1000"):
        load_config(overrides=[f"{key}=1e12"])
    section, name = key.split(".")
    assert getattr(getattr(load_config(overrides=[f"{key}=1000"]), section), name) == 1000


def test_the_largest_map_resolution_loads():
    assert load_config(overrides=["map.resolution=10"]).map.resolution == 10


def test_nbvkit_run_refuses_a_huge_map_resolution(tmp_path, capsys):
    argv = ["run", "--mesh", CUBE, "--set", "map.resolution=1e300", "max_iterations=5"]
    refused(capsys, [*argv, "--out", tmp_path / "o"], "nbvkit run: error:", "map.resolution")


# ------------------------------------------------- 2. the keys each run of an experiment sets
@pytest.mark.parametrize("where", ["grid", "set"])
@pytest.mark.parametrize("key, value", [("scenario", "5"), ("start", 2)])
def test_a_sweep_may_not_set_what_each_run_sets(where, key, value):
    sweep = {"scenarios": ["surface"], "starts": [0]}
    sweep[where] = {key: [value]} if where == "grid" else {key: value}
    with pytest.raises(ValueError, match=f"sweep '{where}' sets '{key}'"):
        sweep_specs(sweep)


def test_the_sweep_file_says_to_list_scenarios_and_starts(tmp_path, capsys):
    f = tmp_path / "s.yaml"
    f.write_text(f"scenarios: [surface]\nstarts: [0]\ngrid: {{scenario: [5]}}\nout: {tmp_path}/o\n")
    refused(capsys, ["sweep", f], "nbvkit sweep: error:", "'scenario'", "'scenarios:'")
    assert not (tmp_path / "o").exists()


def test_compare_and_table_refuse_set_scenario_or_start(tmp_path, capsys):
    with pytest.raises(
        ValueError, match=r"overrides \(--set\) sets 'scenario'.*planners \(--planners"
    ):
        compare_specs(["surface"], starts=1, overrides=["scenario=1"])
    with pytest.raises(ValueError, match=r"overrides \(--set\) sets 'start'.*starts \(--starts"):
        table2_specs(starts=1, overrides=[" start =3"])
    refused(capsys, ["compare", "--set", "scenario=1", "--out", tmp_path / "c"], "'scenario'")
    refused(capsys, ["table", "--set", "start=1", "--out", tmp_path / "t"], "'start'")


def test_a_sweep_grid_of_other_keys_still_labels_its_runs():
    sweep = {"scenarios": ["surface"], "meshes": [str(CUBE)], "grid": {"max_iterations": [3, 4]}}
    specs = sweep_specs({**sweep, "set": {"progress": False}})  # the runs' own value: allowed
    assert [s.labels for s in specs] == [(("max_iterations", 3),), (("max_iterations", 4),)]


# ----------------------------------------------------------------- 3. duplicate YAML keys
@pytest.mark.parametrize(
    "text, key, line, first",
    [
        ("map:\n  resolution: 0.4\nmax_iterations: 3\nmap:\n  prob_hit: 0.7\n", "'map'", 4, 1),
        ("max_iterations: 3\nmax_iterations: 4\n", "'max_iterations'", 2, 1),
        ("scenarios: ['1']\nstarts: [0]\nscenarios: ['5']\n", "'scenarios'", 3, 1),
        ("map:\n  resolution: 0.4\n  resolution: 0.2\n", "'resolution'", 3, 2),
        ("grid: {a: [1], a: [2]}\n", "'a'", 1, 1),
        ("x:\n  - y: 1\n    'y': 2\n", "'y'", 3, 2),
        ("1: a\n1.0: b\n", "1.0", 2, 1),
    ],
)
def test_a_yaml_key_given_twice_is_refused_naming_it_and_its_lines(text, key, line, first):
    with pytest.raises(ValueError) as e:
        parse_yaml(text, "f.yaml")
    assert str(e.value) == (
        f"f.yaml:{line}: duplicate key {key} (first given on line {first}); give each key once"
    )


def test_merge_keys_and_the_same_key_in_other_mappings_are_not_duplicates():
    text = "base: &b {a: 1, c: 2}\nd:\n  <<: *b\n  a: 3\ne: {a: 4}\n"
    assert parse_yaml(text) == {"base": {"a": 1, "c": 2}, "d": {"a": 3, "c": 2}, "e": {"a": 4}}


def test_config_and_sweep_files_refuse_a_duplicate_key(tmp_path, capsys):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("map: {resolution: 0.4}\nmax_iterations: 3\nmap: {prob_hit: 0.7}\n")
    with pytest.raises(ValueError, match=f"{cfg}:3: duplicate key 'map'"):
        Config.from_yaml(cfg)
    with pytest.raises(ValueError, match="duplicate key 'map'"):
        read_yaml_file(cfg)
    refused(capsys, ["run", "--config", cfg, "--out", tmp_path / "r"], "duplicate key 'map'")
    sweep = tmp_path / "s.yaml"
    sweep.write_text("scenarios: ['1']\nscenarios: ['5']\n")
    refused(capsys, ["sweep", sweep], "s.yaml:2: duplicate key 'scenarios'")
    with pytest.raises(ValueError, match="duplicate key 'a'"):
        load_config(overrides=["map={a: 1, a: 2}"])


# --------------------------------------------------------------- 4. plugins that fail to load
@pytest.mark.parametrize(
    "source, message",
    [
        ("def f(:\n", "failed to load: SyntaxError: invalid syntax (line 1)"),
        ("x = 1\n{}['nope']\n", "failed to load: KeyError: 'nope' (line 2)"),
        ("import sys\nraise SystemExit(0)\n", "failed to load: SystemExit(0) (line 2): a plugin"),
        ("import sys\nsys.exit('bye')\n", "failed to load: SystemExit('bye') (line 2): a plugin"),
    ],
)
def test_a_plugin_that_fails_to_load_is_an_error_naming_it(tmp_path, source, message):
    plugin = tmp_path / "bad_plugin.py"
    plugin.write_text(source)
    rc, err = cli("run", "--plugin", plugin, "--mesh", CUBE, "--out", tmp_path / "o")
    assert rc == 2, err
    assert "Traceback" not in err, err
    assert f"nbvkit run: error: plugin file {plugin} {message}" in err, err
    assert not (tmp_path / "o").exists()


def test_a_sweep_files_plugin_that_fails_is_an_error_naming_it(tmp_path):
    plugin = tmp_path / "bad_plugin.py"
    plugin.write_text("raise SystemExit(0)\n")
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"plugins: [{plugin}]\nout: {tmp_path / 'o'}\n")
    rc, err = cli("sweep", sweep)
    assert rc == 2 and "Traceback" not in err, err
    assert (
        f"nbvkit sweep: error: plugin file {plugin} failed to load: SystemExit(0) (line 1)" in err
    ), err


def test_load_plugin_keeps_its_error_types_but_never_exits(tmp_path):
    from nbvkit.plugins import LOADED, PluginLoadError, load_plugin

    bad = tmp_path / "raising_plugin.py"
    bad.write_text("{}['nope']\n")
    with pytest.raises(KeyError, match="nope"):
        load_plugin(bad)
    exits = tmp_path / "exiting_plugin.py"
    exits.write_text("import nbvkit\nnbvkit.register_scenario('exits_x', 'x', {})\nexit(3)\n")
    with pytest.raises(
        PluginLoadError, match=r"exiting_plugin.py failed to load: SystemExit\(3\) \(line 3\)"
    ) as e:
        load_plugin(exits)
    assert isinstance(e.value.__cause__, SystemExit)
    from nbvkit.scenarios import SCENARIOS

    assert "exits_x" not in SCENARIOS and str(exits.resolve()) not in LOADED  # rolled back


def test_an_interrupt_while_a_plugin_loads_stays_an_interrupt(tmp_path, capsys):
    from nbvkit.plugins import load_plugin

    plugin = tmp_path / "interrupted_plugin.py"
    plugin.write_text("raise KeyboardInterrupt\n")
    assert main(["run", "--plugin", str(plugin), "--out", str(tmp_path / "o")]) == 130
    assert "nbvkit run: interrupted" in capsys.readouterr().err
    with pytest.raises(KeyboardInterrupt):
        load_plugin(plugin)


# ----------------------------------------------------------- 5. messages name what was given
def test_a_renamed_section_that_is_no_mapping_is_named_as_written():
    with pytest.warns(DeprecationWarning):
        with pytest.raises(ValueError, match=r"section 'termination' \(now 'entropy'\).*\['a'\]"):
            load_config(overrides=["termination=[a]"])
    with pytest.warns(DeprecationWarning):
        with pytest.raises(ValueError, match=r"section 'sampling' \(now 'lattice'\)"):
            Config.from_dict({"sampling": 3})


@pytest.mark.parametrize("value", ["0", "[]", "''", "false"])
def test_a_part_section_given_an_empty_non_mapping_is_refused(value):
    with pytest.raises(ValueError, match="config section entropy must be a mapping"):
        load_config(overrides=[f"entropy={value}"])


@pytest.mark.parametrize("command", ["compare", "table", "sweep"])
@pytest.mark.parametrize("workers", ["-1", "0", "two"])
def test_workers_below_one_are_refused_naming_the_option(tmp_path, capsys, command, workers):
    first = [tmp_path / "none.yaml"] if command == "sweep" else ["--out", tmp_path / "o"]
    refused(capsys, [command, *first, "--workers", workers], "argument --workers: must be")


def test_a_sweep_files_workers_below_one_and_run_specs_negative_workers_are_refused(
    tmp_path, capsys
):
    from nbvkit.experiments import run_specs

    f = tmp_path / "s.yaml"
    f.write_text(f"workers: 0\nscenarios: ['1']\nout: {tmp_path / 'o'}\n")
    refused(capsys, ["sweep", f], "sweep 'workers' must be a count >= 1")
    with pytest.raises(ValueError, match="workers must be a count >= 0"):
        run_specs([], tmp_path / "r", workers=-1)


@pytest.mark.parametrize(
    "text, needle",
    [
        ("out: 5\n", "'out' must be a folder path, got 5"),
        ("out: ''\n", "'out' must be a folder path"),
        ("scheduler: 5\n", "'scheduler' must be a Dask scheduler address, got 5"),
        ("# all commented out\n", "is empty"),
    ],
)
def test_a_sweep_files_out_and_scheduler_and_an_empty_file_are_refused_before_any_work(
    tmp_path, monkeypatch, capsys, text, needle
):
    monkeypatch.chdir(tmp_path)  # (an empty file once flew the default job into runs/s)
    f = tmp_path / "s.yaml"
    f.write_text(text)
    refused(capsys, ["sweep", f], f"sweep file {f}", needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


@pytest.mark.parametrize(
    "text, value",
    [
        ("010", 10),  # YAML 1.1: 8 (octal)
        ("0o10", 8),
        ("0x1f", 31),
        ("-007", -7),
        ("1_000", 1000),
        ("1:30", "1:30"),  # YAML 1.1: 90 (base 60)
        ("1:30.5", "1:30.5"),
        ("190:20:30", "190:20:30"),
        ("1e-4", 1e-4),
        ("-.inf", -math.inf),
        ("0b101", "0b101"),
    ],
)
def test_numbers_are_read_as_yaml_1_2_reads_them(text, value):
    """max_iterations=010 flew 8 views, checkpoint_minutes=1:30 wrote one every 90 minutes: YAML
    1.2's numbers, in config files and --set alike (a string where the key wants a number is
    then refused by name)."""
    got = parse_yaml(f"a: {text}")["a"]
    assert got == value and type(got) is type(value)


def test_a_base_60_time_for_a_number_is_refused_and_leading_zeros_are_decimal():
    assert load_config(overrides=["max_iterations=010"]).max_iterations == 10
    with pytest.raises(ValueError, match="'checkpoint_minutes' must be a number, got '1:30'"):
        load_config(overrides=["checkpoint_minutes=1:30"])


@pytest.mark.parametrize("command", ["compare", "table", "sweep", "api"])
@pytest.mark.parametrize("inside", [False, True])
def test_an_experiment_into_a_finished_runs_folder_is_refused_before_any_work(
    tmp_path, monkeypatch, capsys, command, inside
):
    """compare (or table, sweep) --out at a finished run's folder wrote its own report.html over
    the run's, whose manifest then refused it (evaluate, export): the folder, or one in it, is
    refused, naming the run, and the run's files are left as they were."""
    from nbvkit.runfolder import is_complete_run, write_manifest

    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / "report.html").write_text("<html>the run's report</html>")
    write_manifest(run)
    before = sorted(p.name for p in run.iterdir())
    out = run / "more" if inside else run
    if command == "api":
        import nbvkit

        with pytest.raises(ValueError, match="finished nbvkit run's folder"):
            nbvkit.compare(["surface"], out)
    else:
        (tmp_path / "s.yaml").write_text("scenarios: [surface]\nstarts: [0]\n")
        argv = [command, *(["s.yaml"] if command == "sweep" else []), "--out", out]
        refused(capsys, argv, "finished nbvkit run's folder", str(run))
    assert sorted(p.name for p in run.iterdir()) == before and is_complete_run(run)


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "--out", ""],
        ["run", "--config", " "],
        ["evaluate", "CLOUD", "--json", ""],
        ["evaluate", "CLOUD", "--config", "", "--observable"],
        ["evaluate", "CLOUD", "--cache", ""],
        ["evaluate", "CLOUD", "--reference-cloud", ""],
        ["sweep", "s.yaml", "--out", ""],
        ["table", "--out", ""],
        ["compare", "--out", ""],
        ["export", "RUN", "--out", ""],
        ["scan", "--out", ""],
    ],
)
def test_an_empty_path_option_is_refused_not_replaced_by_its_default(
    tmp_path, monkeypatch, capsys, argv
):
    """`run --out ""` flew into runs/..., `evaluate --json ""` wrote nothing and exited 0:
    an empty path is refused by the option's name before any work."""
    monkeypatch.chdir(tmp_path)
    option = next(a for a in argv if a.startswith("--") and a != "--observable")
    refused(capsys, argv, f"argument {option}: is empty")
    assert not list(tmp_path.iterdir())


def test_an_empty_config_file_is_refused(tmp_path, capsys):
    f = tmp_path / "c.yaml"
    f.write_text("\n# nothing here\n")
    with pytest.raises(ValueError, match=f"config file {f} is empty"):
        Config.from_yaml(f)
    refused(capsys, ["run", "--config", f, "--out", tmp_path / "r"], "is empty")
    f.write_text("{}\n")  # the defaults, said so
    assert Config.from_yaml(f) == Config()


# ------------------------------------------------------------------- 6. an empty mesh path
@pytest.mark.parametrize("value", ["''", "' '"])
def test_an_empty_mesh_path_is_refused(value):
    with pytest.raises(ValueError, match="config key 'mesh.path' is empty"):
        load_config(overrides=[f"mesh.path={value}"])


def test_the_commands_refuse_an_empty_mesh_path(tmp_path, capsys):
    refused(capsys, ["run", "--mesh", "", "--out", tmp_path / "r"], "'mesh.path' is empty")
    refused(capsys, ["run", "--set", "mesh.path=''", "--out", tmp_path / "r"], "mesh.path")
    refused(capsys, ["compare", "--mesh", "", "--out", tmp_path / "c"], "argument --mesh: is empty")
    assert load_config(overrides=["mesh.path=null"]).mesh.path is None


def test_negative_numbers_in_exponent_form_are_values_not_options():
    """argparse took -5e-1 for an option (it knows -5 and -0.5 only): --mesh-shift -5e-1 0 0."""
    from nbvkit.cli import build_parser

    p = build_parser()
    args = p.parse_args(["run", "--mesh-shift", "-5e-1", "0", "-1E+2"])
    assert args.mesh_shift == [-0.5, 0.0, -100.0]
    args = p.parse_args(["export", "R", "--origin", "-3.3e1", "-7e1", "1e2", "--heading", "-15e1"])
    assert args.origin == [-33.0, -70.0, 100.0] and args.heading == -150.0
    with pytest.raises(SystemExit):  # an option is still an option
        p.parse_args(["run", "--mesh-shift", "-5e-1", "0", "--bogus"])


def test_a_config_built_directly_is_checked_as_one_from_a_file():
    # (Config(max_iterations=-5) flew and ended "max_iterations"; Config(map=5) and start=99
    # failed later on an AttributeError and an IndexError)
    for kwargs, needle in (
        ({"max_iterations": -5}, "config key 'max_iterations' must be >= 0, got -5"),
        ({"max_iterations": "abc"}, "config key 'max_iterations' must be an integer"),
        ({"start": 99}, "config key 'start' = 99 is more than its limit 4"),
        ({"seed": -3}, "config key 'seed' must be >= 0"),
        ({"map": 5}, "config section 'map' must be a MapConfig"),
    ):
        with pytest.raises(ValueError, match=re.escape(needle)):
            Config(**kwargs)
    with pytest.raises(ValueError, match="'max_iterations' must be >= 0, got -7"):
        dataclasses.replace(Config(), max_iterations=-7)
    assert type(Config(max_iterations=3.0).max_iterations) is int
    assert Config(progress=np.bool_(False)).progress is False


def test_config_inputs_of_the_wrong_shape_are_named():
    for data in ([1, 2], "max_iterations: 3", [("max_iterations", 3)]):
        with pytest.raises(ValueError, match="config must be a mapping of keys"):
            Config.from_dict(data)
    for overrides in ({1: 2}, {None: 2}, [("max_iterations", 3)]):
        with pytest.raises(TypeError, match="a dict of dotted keys, got"):
            Config().with_overrides(overrides)
    with pytest.raises(ValueError, match=r"'max_iterations' = ~1e5000 is more than its limit"):
        Config.from_dict({"max_iterations": 10**5000})  # (the message's str() failed)
    with pytest.raises(ValueError, match=r"^big.yaml: .*4300 digits"):
        parse_yaml("seed: " + "9" * 5000, "big.yaml")
    with pytest.raises(ValueError, match=r"'map.resolution' must be >= 0.0001"):
        Config.from_dict({"map": {"resolution": 5e-324}})  # (an OverflowError)
    loop = {"map": {}}
    loop["map"]["again"] = loop
    deep = {}
    for _ in range(100_000):
        deep = {"map": deep}
    for data in (loop, deep):  # (a RecursionError traceback)
        with pytest.raises(ValueError, match="nested too deeply, or holds itself"):
            Config.from_dict(data)


def test_an_empty_config_path_a_part_named_twice_and_a_nul_plugin_are_named(tmp_path):
    from nbvkit.plugins import load_plugin

    with pytest.raises(ValueError, match="config path is empty"):  # (the defaults were flown)
        load_config("")
    with pytest.raises(ValueError, match="planner generator 'tour' is named twice"):
        load_config(overrides=["planner.generators=[tour, tour]"])
    bad = tmp_path / "nul_plugin.py"
    bad.write_bytes(b"x = 1\0\n")
    with pytest.raises(ValueError, match=r"plugin file .*nul_plugin.py holds a NUL byte"):
        load_plugin(bad)


def test_complex_sample_points_are_refused_not_cut_to_their_real_parts():
    from nbvkit import load_mesh, observable_surface
    from nbvkit.mesh import default_mesh_path

    with pytest.raises(ValueError, match="points must be real numbers, got complex"):
        observable_surface(load_mesh(default_mesh_path()), load_config(), points=[[1j, 0, 0]])
