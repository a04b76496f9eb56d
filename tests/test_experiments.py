"""Experiments: Table 2 layout, resumable sweeps, a Dask cluster on loopback, the notebook."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from conftest import TINY_RUN, execute_notebook, plugin_fixture_file
from nbvkit.experiments import RunSpec, run_specs, sweep_specs, table2, table2_markdown

ROOT = Path(__file__).resolve().parent.parent
TINY = TINY_RUN


@pytest.fixture(scope="module")
def tiny_table(tmp_path_factory):
    """A finished tiny Table 2 experiment (one start, two iterations per scenario)."""
    from nbvkit.cli import main

    out = tmp_path_factory.mktemp("table")
    assert (
        main(["table", "--starts", "1", "--workers", "2", "--set", *TINY, "--out", str(out)]) == 0
    )
    return out


def test_table_command_writes_one_report_linking_every_run(tiny_table):
    text = (tiny_table / "report.html").read_text()
    runs = pd.read_csv(tiny_table / "runs.csv")
    for rid in runs["run_id"]:
        assert f"href='runs/{rid}/report.html'" in text
        assert (tiny_table / "runs" / rid / "report.html").exists()
    assert "coverage_observable_0.05" in runs.columns
    # the observable surface was computed once for the six runs: one cache entry
    assert len(list((tiny_table / "cache").glob("observable-*.npz"))) == 1


def test_compare_command_writes_its_table_from_the_runs(tmp_path, capsys):
    # two planners from two starts: compare.md / compare.csv hold each planner's mean and spread
    # of the runs in runs.csv, observable area coverage included, and the figure is written; the
    # console says how many runs the view cap stopped, as nbvkit run says of one
    from nbvkit.cli import main

    out = tmp_path / "cmp"
    args = ["compare", "--planners", "surface,1", "--starts", "2", "--workers", "2"]
    assert main([*args, "--set", *TINY, "--out", str(out)]) == 0
    runs = pd.read_csv(out / "runs.csv")
    capped = runs[runs["termination"] == "max_iterations"]
    assert len(capped) > 0 and runs["utility_only_checks"].isna().all()
    notes = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note: ")]
    assert len(notes) == 1 and notes[0].startswith(
        f"note: {len(capped)} of 4 runs stopped by max_iterations, not because the structure"
    )
    assert all(rid in notes[0] for rid in capped["run_id"])
    t = pd.read_csv(out / "compare.csv")
    assert list(t["Planner"].astype(str)) == ["surface", "1"]
    for planner in ("surface", "1"):
        sub = runs[runs["scenario"].astype(str) == planner]
        got = t[t["Planner"].astype(str) == planner].iloc[0]
        assert len(sub) == 2 == got["runs"]
        for col, name in (
            ("area_coverage_0.05", "Area cov. @0.05 m"),
            ("area_coverage_observable_0.05", "Observable area cov. @0.05 m"),
            ("distance_m", "Distance (m)"),
        ):
            assert got[name] == pytest.approx(sub[col].mean()), (planner, name)
            assert got[name + " sd"] == pytest.approx(sub[col].std(ddof=0)), (planner, name)
        assert 0 < got["Observable area cov. @0.05 m"] <= 1
    md = (out / "compare.md").read_text()
    assert "Observable area cov. @0.05 m" in md.splitlines()[0]
    assert "standard deviation over the runs (population, ddof 0" in md  # what its ± is
    assert (out / "figures" / "coverage_vs_distance.png").stat().st_size > 0


def test_table_command_writes_the_papers_layout(tiny_table):
    md = (tiny_table / "table2.md").read_text()
    rows = [ln for ln in md.splitlines() if ln.startswith("| ") and not ln.startswith("| Scenario")]
    assert [r.split("|")[1].strip() for r in rows] == ["Profile", "1", "2", "3", "4", "5"]
    assert "standard deviation over the runs (population, ddof 0" in md  # what its ± is
    t = pd.read_csv(tiny_table / "table2.csv")
    assert list(t["Scenario"].astype(str)) == ["Profile", "1", "2", "3", "4", "5"]
    for col in (
        "Iterations",
        "Distance (m)",
        "Entropy reduction",
        "Coverage @0.05 m",
        "Coverage @0.10 m",
        "Coverage @0.50 m",
        "Wall time (s)",
        "ms/iteration",
        "Profiling",
        "Symmetry",
        "Sampling",
    ):
        assert col in t.columns, col
    runs = pd.read_csv(tiny_table / "runs.csv")
    assert len(runs) == 6 and set(runs["scenario"].astype(str)) == {
        "profile",
        "1",
        "2",
        "3",
        "4",
        "5",
    }
    # profiling scenarios fly the profile first: more distance than scenario 1's two steps
    d = dict(zip(runs["scenario"].astype(str), runs["distance_m"]))
    assert d["2"] > d["1"] and d["profile"] > 0
    for f in (
        "coverage_vs_distance.png",
        "coverage_vs_iteration.png",
        "trajectories.png",
        "final_cloud_and_map.png",
    ):
        assert (tiny_table / "figures" / f).stat().st_size > 0


def test_table2_means_and_spread():
    df = pd.DataFrame(
        [
            {
                "scenario": "1",
                "iterations": 10,
                "distance_m": 5.0,
                "entropy_reduction": 100.0,
                "coverage_0.05": 0.2,
                "coverage_0.1": 0.3,
                "coverage_0.5": 0.4,
                "area_coverage_0.05": 0.2,
                "wall_time_s": 1.0,
                "ms_per_iteration": 5.0,
            },
            {
                "scenario": "1",
                "iterations": 20,
                "distance_m": 7.0,
                "entropy_reduction": 300.0,
                "coverage_0.05": 0.4,
                "coverage_0.1": 0.5,
                "coverage_0.5": 0.6,
                "area_coverage_0.05": 0.4,
                "wall_time_s": 3.0,
                "ms_per_iteration": 7.0,
            },
        ]
    )
    t = table2(df)
    r = t.iloc[0]
    assert r["Scenario"] == "1" and r["Iterations"] == 15 and r["Iterations sd"] == 5
    assert r["Coverage @0.05 m"] == pytest.approx(0.3) and r["Distance (m)"] == 6.0
    assert "| 1 | no | no | CGVS | 15 ± 5 |" in table2_markdown(t)


def test_tables_warn_when_they_pool_configurations_and_say_when_partial(tmp_path):
    """A sweep's results.csv over two map resolutions, given to compare_table or table2, was
    averaged per scenario as if the runs were starts ("runs 2", a ± across resolutions); the
    tables of a stopped compare read as whole."""
    import warnings

    from nbvkit.experiments import compare_table, write_compare

    row = {"scenario": "5", "start": 0, "mesh": "airliner", "distance_m": 5.0, "views": 3}
    df = pd.DataFrame([{**row, "overrides": f"map.resolution={r}"} for r in (0.2, 0.4)])
    for f in (compare_table, table2):
        with pytest.warns(UserWarning, match="pools runs of different configurations.*overrides"):
            f(df)
    same = pd.DataFrame([{**row, "start": k, "overrides": "map.resolution=0.2"} for k in (0, 1)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # one configuration: no word
        assert compare_table(same).iloc[0]["runs"] == 2
    same.attrs["runs_planned"] = 4
    write_compare(tmp_path, same)
    md = (tmp_path / "compare.md").read_text()
    assert "Partial: 2 of 4 runs finished" in md

    # the profile's row has no iterations, so no time an iteration (it read 0.0 ± 0.0)
    cols = {"profile_distance_m": 80.0, "profile_entropy_reduction": 9.0, "ms_per_iteration": 0.0}
    cov = {f"profile_coverage_{r}": 0.1 for r in ("0.05", "0.1", "0.5")}
    prof = table2(pd.DataFrame([{**row, "scenario": "profile", **cols, **cov}])).iloc[0]
    assert prof["Scenario"] == "Profile" and prof["ms/iteration"] != prof["ms/iteration"]  # NaN


def test_sweep_is_resumable_and_rejects_bad_keys(tmp_path):
    sweep = {
        "scenarios": ["1"],
        "starts": [0, 1],
        "grid": {"lattice.delta_d": [1.0, 2.0]},
        "set": dict(kv.split("=") for kv in TINY),
    }
    sweep["set"] = {k: yaml.safe_load(v) for k, v in sweep["set"].items()}
    specs = sweep_specs(sweep)
    assert len(specs) == 4 and len({s.run_id for s in specs}) == 4
    rows = run_specs(specs, tmp_path, workers=1, progress=False)
    assert {r["lattice.delta_d"] for r in rows} == {1.0, 2.0}
    done = {
        s.run_id: (tmp_path / "runs" / s.run_id / "summary.json").stat().st_mtime_ns for s in specs
    }
    victim = specs[2].run_id
    import shutil

    shutil.rmtree(tmp_path / "runs" / victim)  # as if interrupted before this run finished
    (tmp_path / "runs" / f".{victim}.tmp99").mkdir()  # and a half-written temporary folder
    rows2 = run_specs(specs, tmp_path, workers=1, progress=False)
    for s in specs:
        m = (tmp_path / "runs" / s.run_id / "summary.json").stat().st_mtime_ns
        assert (m == done[s.run_id]) == (s.run_id != victim)
    assert [r["run_id"] for r in rows2] == [r["run_id"] for r in rows]
    with pytest.raises(KeyError, match="griid"):
        sweep_specs({"griid": {}})
    with pytest.raises(KeyError, match="map.nope"):
        sweep_specs({"grid": {"map.nope": [1]}})


def test_a_kept_run_of_another_configuration_or_mesh_is_flown_again(tmp_path):
    """The run id hashes the spec, not the defaults it resolves to nor the mesh file's content: a
    run kept from before a default changed (its config.yaml differs) or the mesh was edited in
    place must not stand in for the new one."""
    import shutil

    mesh = tmp_path / "airliner.obj"
    shutil.copy(ROOT / "meshes" / "airliner.obj", mesh)
    spec = RunSpec("1", 0, mesh=str(mesh), overrides=TINY)
    run = tmp_path / "runs" / spec.run_id

    def fly():
        rows = run_specs([spec], tmp_path, workers=1, progress=False)
        assert rows[0]["run_id"] == spec.run_id
        return (run / "summary.json").stat().st_mtime_ns

    kept = fly()
    assert fly() == kept  # the same configuration and mesh: reused
    config = run / "config.yaml"
    config.write_text(config.read_text().replace("prob_hit: 0.7", "prob_hit: 0.75"))
    again = fly()
    assert again != kept and "prob_hit: 0.7\n" in config.read_text()  # flown again
    with open(mesh, "a") as f:
        f.write("# edited in place\n")
    assert fly() != again  # the same path, another file: flown again


@pytest.mark.parametrize("damage", [("{", "X"), ('"scenario"', '"scenariX"')])
def test_a_kept_run_whose_summary_was_damaged_at_its_size_is_flown_again(tmp_path, damage):
    """A finished run's summary.json changed at the same size (its manifest cannot tell): every
    start of the sweep failed on it ("damaged, not JSON", KeyError 'scenario') and told the user
    to run the same command again; it is flown again instead."""
    spec = RunSpec("1", 0, overrides=TINY)
    run_specs([spec], tmp_path, workers=1, progress=False)
    summary = tmp_path / "runs" / spec.run_id / "summary.json"
    text = summary.read_text()
    summary.write_text(text.replace(*damage, 1))
    assert len(summary.read_text()) == len(text)
    rows = run_specs([spec], tmp_path, workers=1, progress=False)
    assert rows[0]["scenario"] == "1" and json.loads(summary.read_text())["scenario"] == "1"


def test_ctrl_c_keeps_a_run_that_finished_before_its_row_arrived(tmp_path, monkeypatch):
    """A worker can finish a run (its folder in place) just before Ctrl-C reaches the parent,
    which has not yet received the row: the partial table must still hold that run."""
    import nbvkit.experiments as ex

    specs = [RunSpec("1", k, overrides=TINY) for k in (0, 1)]

    def pool(specs, root, n, ncpu, rows, failures, progress):  # the first run ends, its row lost
        ex.run_one(specs[0], root)
        raise KeyboardInterrupt

    monkeypatch.setattr(ex, "_run_pool", pool)
    with pytest.raises(ex.Interrupted) as e:
        run_specs(specs, tmp_path, workers=2, progress=False)
    assert [r["run_id"] for r in e.value.rows] == [specs[0].run_id]
    assert e.value.total == 2


FAILING_PART = """
from dataclasses import dataclass

import nbvkit


@dataclass(frozen=True)
class FailingConfig:
    fail: bool = False  # raise at the first check


class Failing:
    Settings = FailingConfig

    def __init__(self, settings, context):
        self.fail = settings.fail

    def check(self, world, step):
        if self.fail:
            raise RuntimeError("the failing part failed, as asked")
        return None


nbvkit.register_termination("failing", Failing)
"""


@pytest.fixture(scope="module")
def failing_part(tmp_path_factory):
    """A plugin file registering the termination `failing` (one file: a part registers once),
    forgotten after this module's tests."""
    folder = tmp_path_factory.mktemp("plugin")
    yield from plugin_fixture_file(
        folder, "failing_part.py", FAILING_PART, {"termination": ["failing"]}
    )


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_that_raises_fails_alone_and_the_sweep_says_which(
    tmp_path, capsys, failing_part, workers
):
    """A run's error does not stop the others: they are flown and tabled, each failed one is
    named with its error and leaves no folder, and the exit code is 1; the same command flies
    the failed ones again (which fail the same way here) and keeps the others."""
    from nbvkit.cli import main

    f = tmp_path / "sweep.yaml"
    spec = {
        "scenarios": ["1"],
        "starts": 2,
        "grid": {"failing.fail": [False, True]},
        "set": {
            **yaml.safe_load("{" + ", ".join(o.replace("=", ": ") for o in TINY) + "}"),
            "planner.terminations": ["failing", "budget"],
        },
    }
    f.write_text(yaml.safe_dump(spec))
    out = tmp_path / "out"
    argv = [
        "sweep",
        str(f),
        "--out",
        str(out),
        "--workers",
        str(workers),
        "--plugin",
        str(failing_part),
    ]
    assert main(argv) == 1
    err = capsys.readouterr().err
    rows = pd.read_csv(out / "results.csv")
    assert len(rows) == 2 and (rows["failing.fail"] == False).all()  # noqa: E712
    finished = sorted(p.name for p in (out / "runs").iterdir() if not p.name.startswith("."))
    assert finished == sorted(rows["run_id"])
    assert "2 of 4 runs failed" in err and "the failing part failed, as asked" in err
    assert "RuntimeError" in err and "2 finished" in err and "fly the failed ones again" in err
    # the command to copy keeps the options given (it dropped --workers: one per core then)
    assert f"again with the same command: nbvkit sweep {' '.join(argv[1:])} (" in err, err
    assert main(argv) == 1  # resumed: the finished runs kept, the failed ones flown again
    assert "2 of 4 runs failed" in capsys.readouterr().err
    assert sorted(pd.read_csv(out / "results.csv")["run_id"]) == finished


def test_sweep_on_a_local_dask_cluster(tmp_path, failing_part):
    import nbvkit
    from nbvkit.experiments import RunsFailed

    distributed = pytest.importorskip("distributed")
    nbvkit.load_plugin(failing_part)  # the workers load the parent's plugin files
    failing = ("planner.terminations=[failing, budget]", "failing.fail=true")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        specs = [RunSpec("1", k, overrides=TINY) for k in (0, 1)]
        rows = run_specs(specs, tmp_path, scheduler=cluster.scheduler_address)
        # a run that raises on the cluster fails alone, named with its error
        bad = RunSpec("1", 0, overrides=(*TINY, *failing))
        with pytest.raises(RunsFailed) as e:
            run_specs([bad, specs[1]], tmp_path, scheduler=cluster.scheduler_address)
    assert [r["start"] for r in rows] == [0, 1]
    assert all((tmp_path / "runs" / s.run_id / "summary.json").exists() for s in specs)
    assert [r["run_id"] for r in e.value.rows] == [specs[1].run_id]
    assert [run_id for run_id, _ in e.value.failures] == [bad.run_id]
    assert "the failing part failed, as asked" in e.value.failures[0][1]
    assert not (tmp_path / "runs" / bad.run_id).exists()


def test_sweep_command(tmp_path):
    from nbvkit.cli import main

    f = tmp_path / "sweep.yaml"
    f.write_text(
        yaml.safe_dump(
            {
                "scenarios": ["1"],
                "starts": 1,
                "set": {k: yaml.safe_load(v) for k, v in (kv.split("=") for kv in TINY)},
            }
        )
    )
    assert main(["sweep", str(f), "--out", str(tmp_path / "out"), "--workers", "1"]) == 0
    assert len(pd.read_csv(tmp_path / "out" / "results.csv")) == 1
    assert main(["sweep", str(tmp_path / "missing.yaml")]) == 2


def test_notebook_executes_headless(tiny_table):
    figures = {f: f.stat().st_mtime_ns for f in (tiny_table / "figures").iterdir()}
    text = execute_notebook("table2.ipynb", {"NBVKIT_EXPERIMENT": str(tiny_table)})
    assert "6 runs" in text and "skipping the interactive 3D view" in text
    # its 3D view is the figures' run (scenario 5, first start), not the profile's ("profile"
    # sorts after "5"), and the experiment's own figures are left as they were
    runs = pd.read_csv(tiny_table / "runs.csv")
    five = runs[runs["scenario"].astype(str) == "5"].sort_values("start").iloc[0]["run_id"]
    assert five in text
    assert {f: f.stat().st_mtime_ns for f in (tiny_table / "figures").iterdir()} == figures


def test_comparison_with_the_papers_table(tmp_path):
    from nbvkit.experiments import compare_with_paper

    paper = tmp_path / "paper.csv"
    paper.write_text(
        "scenario,profiling,symmetry,sampling,iterations,distance_m,entropy_reduction,"
        "coverage_0.05,coverage_0.10,coverage_0.50\n"
        "1,no,no,CGVS,859,1039.9,289439,0.733,0.787,0.869\n"
    )
    df = pd.DataFrame(
        [
            {
                "scenario": "1",
                "iterations": 700,
                "distance_m": 900.0,
                "entropy_reduction": 8e5,
                "coverage_0.05": 0.6,
                "coverage_0.1": 0.7,
                "coverage_0.5": 0.9,
                "area_coverage_0.05": 0.6,
                "wall_time_s": 60.0,
                "ms_per_iteration": 80.0,
            }
        ]
    )
    md = compare_with_paper(table2(df), paper)
    assert "| 1 | 700 / 859 | 900.0 / 1,039.9 | 800,000 / 289,439 | 60.0 % / 73.3 % |" in md


def test_shipped_example_sweep_is_valid():
    spec = yaml.safe_load((ROOT / "configs" / "sweep_example.yaml").read_text())
    specs = sweep_specs(spec)
    assert len(specs) == 2 * 2 * 2 * 3


# ------------------------------------------------------------ one source of truth for the mesh


def _sha1(path) -> str:
    import hashlib

    return hashlib.sha1(Path(path).read_bytes()).hexdigest()


def test_mesh_keys_in_the_overrides_or_config_file_are_the_mesh_flown(tmp_path):
    """mesh.path / mesh.scale / mesh.up set by --set, a sweep's set or grid, or the config file
    are flown (not replaced by the spec's defaults), and the run id and the resume digest follow
    the mesh flown."""
    import shutil

    from nbvkit.experiments import _resolved

    tower = tmp_path / "tower.obj"
    shutil.copy(ROOT / "meshes" / "mast.obj", tower)
    spec = RunSpec("1", 0, overrides=(f"mesh.path={tower}", "mesh.scale=2", "mesh.up=y"))
    cfg, digest = _resolved(spec)
    assert (cfg.mesh.path, cfg.mesh.scale, cfg.mesh.up) == (str(tower), 2.0, "y")
    assert spec.flown_mesh == (str(tower), 2.0, "y")
    assert spec.run_id.startswith("tower_s1_start0_") and digest == _sha1(tower)
    airliner = RunSpec("1", 0)
    assert _resolved(airliner)[1] == _sha1(ROOT / "meshes" / "airliner.obj") != digest
    # the mesh flown decides the id: another scale, another run
    assert RunSpec("1", 0, overrides=(f"mesh.path={tower}",)).run_id != spec.run_id
    # spelled as the spec's fields, the same mesh is flown and named
    assert RunSpec("1", 0, str(tower), 2.0, "y").flown_mesh == spec.flown_mesh
    # a config file's mesh section holds too (the spec gives no mesh key)
    conf = tmp_path / "conf.yaml"
    conf.write_text(f"mesh: {{path: {tower}, scale: 3.0, up: y}}\n")
    from_file = RunSpec("1", 0, config_file=str(conf))
    assert from_file.flown_mesh == (str(tower), 3.0, "y")
    assert from_file.run_id.startswith("tower_") and _resolved(from_file)[1] == _sha1(tower)
    # ... and a key the spec gives wins over the file's (as --mesh-scale over run --config)
    assert RunSpec("1", 0, mesh_scale=0.5, config_file=str(conf)).flown_mesh[1] == 0.5
    # a sweep: set and grid over the mesh keys
    specs = sweep_specs({"set": {"mesh.path": str(tower)}, "grid": {"mesh.scale": [1, 2]}})
    assert [s.flown_mesh for s in specs] == [(str(tower), 1.0, "z"), (str(tower), 2.0, "z")]
    assert all(s.run_id.startswith("tower_") for s in specs)
    assert len({s.run_id for s in specs}) == 2


def test_an_up_axis_given_or_read_from_the_file_is_the_same_run(tmp_path):
    """mesh.up=auto on an OBJ flies it as it is, as mesh.up=z does: one run id, one recorded
    configuration (config.yaml says the axis flown), so either resumes the other's run."""
    cube = str(ROOT / "meshes" / "fixtures" / "cube.obj")
    given, auto = (RunSpec("1", 0, mesh=cube, mesh_up=u, overrides=TINY) for u in ("z", None))
    assert given.run_id == auto.run_id and auto.flown_mesh[2] == "z"
    (row,) = run_specs([given], tmp_path, workers=1, progress=False)
    run = tmp_path / "runs" / row["run_id"]
    first = (run / "summary.json").stat().st_mtime_ns
    assert yaml.safe_load((run / "config.yaml").read_text())["mesh"]["up"] == "z"
    run_specs([auto], tmp_path, workers=1, progress=False)
    assert (run / "summary.json").stat().st_mtime_ns == first  # resumed, not flown again


def test_a_scenario_that_sets_the_mesh_labels_its_runs_by_that_mesh(tmp_path):
    """A registered scenario's mesh keys are the mesh flown (under the spec's own): the run id and
    the tables' mesh columns follow it, not the mesh of another scenario."""
    import shutil

    from nbvkit.experiment_specs import _spec_dict
    from nbvkit.experiments import _resolved
    from nbvkit.scenarios import SCENARIOS, register_scenario

    tower = tmp_path / "tower.obj"
    shutil.copy(ROOT / "meshes" / "mast.obj", tower)
    register_scenario("on_tower", "scenario 1 on the tower", {"mesh.path": str(tower)})
    try:
        spec = RunSpec("on_tower", 0, mesh_scale=2.0)
        m = spec.config().mesh
        assert (m.path, m.scale, m.up) == (str(tower), 2.0, "auto")  # an OBJ: flown as it is
        assert spec.flown_mesh == (str(tower), 2.0, "z")
        assert spec.run_id.startswith("tower_son_tower_start0_")
        assert _spec_dict(spec)["flown_mesh"] == {"path": str(tower), "scale": 2.0, "up": "z"}
        assert _resolved(spec)[1] == _sha1(tower)
        # the spec's mesh wins over the scenario's, as --set over any preset
        assert RunSpec("on_tower", 0, "meshes/mast.obj").flown_mesh[0] == "meshes/mast.obj"
        # registered again (a plugin file fixed and loaded again) with another mesh: that one
        SCENARIOS.pop("on_tower")
        register_scenario("on_tower", "scenario 1 on the airliner", {"mesh.scale": 3.0})
        assert RunSpec("on_tower", 0).flown_mesh == (None, 3.0, "z")
        assert RunSpec("1", 0).flown_mesh == (None, 1.0, "z")
    finally:
        SCENARIOS.pop("on_tower")


def test_a_mesh_key_given_twice_is_refused(tmp_path, capsys):
    from nbvkit.cli import main

    with pytest.raises(ValueError, match="mesh.path is given twice"):
        RunSpec("1", 0, "a.obj", overrides=("mesh.path=b.obj",)).config()
    with pytest.raises(ValueError, match="mesh.scale is given twice"):
        RunSpec("1", 0, mesh_scale=2.0, overrides=("mesh={scale: 3}",)).config()
    with pytest.raises(ValueError, match="mesh.up is given twice"):
        sweep_specs({"meshes": [{"path": None, "up": "y"}], "grid": {"mesh.up": ["z"]}})
    out = tmp_path / "out"
    for args in (
        ["--mesh", "meshes/mast.obj", "--set", "mesh.path=meshes/airliner.obj"],
        ["--mesh-scale", "2", "--set", "mesh.scale=3"],
        ["--mesh-shift", "1", "0", "0", "--set", "mesh.shift=[2,0,0]"],
        ["--mesh-up", "y", "--set", "mesh={up: z}"],
    ):
        assert main(["compare", "--planners", "1", *args, "--out", str(out)]) == 2
        assert "given twice" in capsys.readouterr().err
        assert main(["table", *args, "--out", str(out)]) == 2
        assert "given twice" in capsys.readouterr().err
        # one run too: its option does not silently win over --set
        assert main(["run", *args, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("nbvkit run: error: mesh.") and "given twice" in err
    assert not out.exists()
    # each key once (or given only by --set) is flown
    from nbvkit.cli import build_parser
    from nbvkit.commands.run import config_from_args

    args = ["run", "--mesh", "meshes/mast.obj", "--set", "mesh.scale=2", "mesh.up=y"]
    mesh = config_from_args(build_parser().parse_args(args)).mesh
    assert (mesh.path, mesh.scale, mesh.up) == ("meshes/mast.obj", 2.0, "y")


def test_compare_flies_and_labels_the_mesh_set_by_overrides(tmp_path):
    import json
    import shutil

    from nbvkit.cli import main
    from nbvkit.experiments import row_of

    tower = tmp_path / "tower.obj"
    shutil.copy(ROOT / "meshes" / "mast.obj", tower)
    out = tmp_path / "cmp"
    args = ["compare", "--planners", "1", "--starts", "1", "--workers", "1", "--out", str(out)]
    assert main([*args, "--set", *TINY, f"mesh.path={tower}", "mesh.scale=0.5"]) == 0
    runs = pd.read_csv(out / "runs.csv")
    assert len(runs) == 1
    row = runs.iloc[0]
    assert (row["mesh"], row["mesh_scale"], row["mesh_up"]) == (str(tower), 0.5, "z")
    assert row["run_id"].startswith("tower_s1_start0_")
    run = out / "runs" / row["run_id"]
    flown = yaml.safe_load((run / "config.yaml").read_text())["mesh"]
    assert (flown["path"], flown["scale"]) == (str(tower), 0.5)
    spec = json.loads((run / "spec.json").read_text())
    assert spec["mesh_sha1"] == _sha1(tower)
    # a folder written before spec.json recorded the mesh flown: labelled from config.yaml
    del spec["flown_mesh"]
    (run / "spec.json").write_text(json.dumps(spec))
    assert (row_of(run)["mesh"], row_of(run)["mesh_scale"]) == (str(tower), 0.5)


def test_duplicates_and_empty_lists_are_refused(tmp_path, capsys):
    from nbvkit.cli import main

    assert main(["compare", "--planners", "1,surface,1", "--out", str(tmp_path / "c")]) == 2
    assert "planners (--planners) lists '1' more than once" in capsys.readouterr().err
    for sweep, needle in (
        ({"grid": {"map.resolution": [0.4, 0.2, 0.4]}}, "grid 'map.resolution' lists 0.4"),
        ({"grid": {"max_iterations": [2, 2.0]}}, "grid 'max_iterations' lists"),
        ({"scenarios": ["1", 1]}, "'scenarios' lists '1'"),
        ({"starts": [0, 1, 0]}, "'starts' lists 0"),
        ({"meshes": ["meshes/mast.obj", {"path": "meshes/mast.obj"}]}, "twice"),
        ({"grid": {"map.resolution": []}}, "grid 'map.resolution' is empty"),
        ({"grid": {"map.resolution": [0.4], "lattice.delta_d": []}}, "'lattice.delta_d' is empty"),
        ({"scenarios": []}, "'scenarios' is empty"),
        ({"starts": 0}, "'starts' is empty"),
        ({"starts": []}, "'starts' is empty"),
        ({"meshes": []}, "'meshes' is empty"),
    ):
        with pytest.raises(ValueError, match=needle):
            sweep_specs(sweep)
    f = tmp_path / "sweep.yaml"
    f.write_text(yaml.safe_dump({"grid": {"map.resolution": []}}))
    out = tmp_path / "out"
    assert main(["sweep", str(f), "--out", str(out)]) == 2
    assert "sweep grid 'map.resolution' is empty" in capsys.readouterr().err
    assert not out.exists()


def test_experiment_notes_name_the_budgets_and_the_utilities_only_checked():
    """The notes a sweep or compare prints of its finished runs: per budget, how many runs it
    stopped and which; the runs whose tour generators only checked another utility's views."""
    from nbvkit.commands.common import experiment_notes

    rows = [
        {"run_id": f"r{i}", "termination": t, "utility": u, "utility_only_checks": g}
        for i, (t, u, g) in enumerate(
            [
                ("max_iterations", "surface", ""),
                ("coverage_complete", "ig", "tour"),
                ("budget_distance", "ig", "tour access"),
                ("max_iterations", "surface", ""),
            ]
        )
    ]
    notes = experiment_notes(rows)
    assert notes[0].startswith("2 of 4 runs stopped by max_iterations, not because")
    assert "(r0, r3)" in notes[0] and "--set max_iterations=" in notes[0]
    assert (
        notes[1].startswith("1 of 4 runs stopped by budget.max_distance_m") and "(r2)" in notes[1]
    )
    assert notes[2].startswith("in 2 of 4 runs (r1, r2) the access and tour generators plan")
    assert "utility ig only checked" in notes[2] and len(notes) == 3
    assert experiment_notes(rows[1:2])[0].startswith("in 1 of 1 runs (r1) the tour generator plans")
    assert experiment_notes([{"run_id": "a", "termination": "coverage_complete"}]) == []


def test_a_workers_warnings_print_in_one_line_as_the_commands(tmp_path, capfd):
    """A warning of nbvkit's own raised in a pool worker (`compare --workers 2`: a cube floating
    20 m above the ground, workspace.warn_floating) reaches the console as the command's own
    warnings do ("nbvkit compare: warning: run RUN_ID: ..."), naming the run it came from, not
    with nbvkit's file and line."""
    from conftest import CUBE_MESH
    from nbvkit.cli import main

    args = ["compare", "--planners", "1", "--starts", "2", "--workers", "2"]
    args += ["--mesh", str(CUBE_MESH), "--mesh-shift", "0", "0", "20", "--out", str(tmp_path / "c")]
    off = ["report.enabled=false", "observability.enabled=false", "progress=false"]
    assert main([*args, "--set", *TINY, *off]) == 0
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if "lowest point lies" in ln]
    assert len(lines) == 2, err  # one a run, each in its worker
    runs = sorted(d.name for d in (tmp_path / "c" / "runs").iterdir())
    named = sorted(ln.split(": ")[2].removeprefix("run ") for ln in lines)
    assert len(runs) == 2 and named == runs, (runs, err)  # each run's own warning, named
    assert all(ln.split(": ", 3)[3].startswith("the structure's") for ln in lines), err
    assert all(ln.startswith("nbvkit compare: warning: run ") for ln in lines), err
    assert "RuntimeWarning" not in err and ".py:" not in err, err


def test_a_script_calling_compare_at_its_top_level_is_told_to_guard_it(tmp_path):
    """Python's spawned workers import the calling script again: one that calls nbvkit at its
    top level breaks the pool, which used to say only "BrokenProcessPool"; the error names the
    script and the `if __name__ == "__main__":` guard. Guarded, the same script flies."""
    import subprocess
    import sys

    cube = ROOT / "meshes" / "fixtures" / "cube.obj"
    call = (
        f"nbvkit.compare(['1', '2'], {str(tmp_path / 'cmp')!r}, mesh={str(cube)!r}, starts=1,"
        f" workers=2, overrides={TINY!r}, progress=False)"
    )
    for guarded in (False, True):
        script = tmp_path / f"mine_{guarded}.py"
        body = f"if __name__ == '__main__':\n    {call}\n" if guarded else call + "\n"
        script.write_text("import nbvkit\n" + body)
        p = subprocess.run(
            [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600
        )
        if guarded:
            assert p.returncode == 0, p.stderr[-2000:]
        else:
            last = p.stderr.strip().splitlines()[-1]
            assert p.returncode != 0 and last.startswith("nbvkit.experiments.RunsFailed"), last
            assert f"if {script.name} calls nbvkit at its top level" in last
            assert 'put the calls under `if __name__ == "__main__":`' in last


def test_the_guard_hint_is_not_given_to_the_nbvkit_command(monkeypatch):
    """The `nbvkit` command runs as a script too (its entry point): a worker that died under it
    (out of memory, a crash) is not blamed on a missing guard."""
    import sys
    import types

    from nbvkit import cli, experiments

    for entry, said in ((cli.main, False), (lambda: 0, True)):
        main = types.ModuleType("__main__")
        main.__file__, main.__spec__, main.main = "/somewhere/bin/nbvkit", None, entry
        monkeypatch.setitem(sys.modules, "__main__", main)
        assert bool(experiments._unguarded_script_hint()) is said


def test_a_run_whose_end_of_run_outputs_fail_keeps_its_flight_beside_the_runs(
    tmp_path, monkeypatch
):
    """A whole flight whose end-of-run outputs failed (the Poisson mesh out of memory) was lost
    with its runs/ folder: it is kept in failed/RUN (stopped during saving) and the error names
    it; runs/ stays without it, and once the run is flown the failed record goes."""
    import nbvkit.report
    from nbvkit.experiments import RunsFailed

    def out_of_memory(*args, **kwargs):
        raise MemoryError("the Poisson mesh ran out of memory")

    spec = RunSpec("1", 0, overrides=TINY)
    monkeypatch.setattr(nbvkit.report, "finish_run", out_of_memory)
    with pytest.raises(RunsFailed) as e:
        run_specs([spec], tmp_path, workers=1, progress=False)
    kept = tmp_path / "failed" / spec.run_id
    summary = json.loads((kept / "summary.json").read_text())
    assert summary["stopped_during"] == "saving" and "MemoryError" in summary["stopped_by"]
    assert summary["iterations"] == 2 and (kept / "cloud.ply").stat().st_size > 0
    assert f"what was flown is saved in {kept}" in e.value.failures[0][1]
    assert not (tmp_path / "runs" / spec.run_id).exists()
    monkeypatch.undo()
    run_specs([spec], tmp_path, workers=1, progress=False)
    assert (tmp_path / "runs" / spec.run_id / "manifest.json").is_file() and not kept.exists()


def test_the_table_notebook_refuses_a_folder_that_is_not_a_table(tmp_path, tiny_table):
    """Given a compare's folder it showed one planner's rows alone, dropping the others without
    a word, and wrote its figures over the compare's own figures/."""
    other = tmp_path / "cmp"
    other.mkdir()
    shutil.copy(tiny_table / "runs.csv", other / "runs.csv")  # a table's rows, no table2.csv
    with pytest.raises(Exception, match="holds no table2.csv: this notebook reads a finished"):
        execute_notebook("table2.ipynb", {"NBVKIT_EXPERIMENT": str(other)})
    assert not (other / "figures").exists()


def test_an_experiment_over_a_missing_mesh_is_refused_before_any_run(tmp_path, capsys):
    """Every run would fail on it (and the console advised flying them again): the command
    names the file and writes nothing."""
    from nbvkit.cli import main
    from nbvkit.experiments import compare_specs, run_specs

    specs = compare_specs(["surface"], str(tmp_path / "none.obj"), starts=2)
    with pytest.raises(FileNotFoundError, match="No such mesh file"):
        run_specs(specs, tmp_path / "out", workers=1, progress=False)
    args = ["--mesh", str(tmp_path / "none.obj"), "--starts", "1", "--out", str(tmp_path / "c")]
    assert main(["compare", "--planners", "surface", *args]) == 2  # (as run's: bad input)
    assert "No such mesh file" in capsys.readouterr().err
    assert not (tmp_path / "out").exists() and not (tmp_path / "c").exists()
