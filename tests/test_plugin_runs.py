"""Runs of plugin parts: which plugin files (and content) produced a run, resumed only while they
are unchanged; a plugin's error shown where it was raised; parts registered from a script refused
by the sweeps' worker processes up front; the console's count of views as the summary's."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import ROOT, plugin_fixture_file
from nbvkit.experiments import RunSpec, RunsFailed, run_specs

CUBE = ROOT / "meshes" / "fixtures" / "cube.obj"
SMALL = ("map.resolution=0.4", "max_iterations=3", "progress=false", "report.enabled=false",
         "evaluation.gt_density=50", "profiling.waypoints=3", "planner.min_gain=0")  # fmt: skip

PLUGIN = """
import math

import numpy as np

import nbvkit
from nbvkit.planning.parts import Proposal

RADIUS = {radius}  # m beyond the structure's half diagonal
FAIL_AT = {fail_at}  # the call of propose that raises (0: none)


class Orbit:
    def __init__(self, settings, context):
        self.n = 0

    def propose(self, world):
        self.n += 1
        if self.n == FAIL_AT:
            np.vstack([np.zeros(3), np.zeros(4)])  # the plugin's own bug
        lo, hi = world.mesh.bounds
        c = (lo + hi) / 2
        r = np.linalg.norm(hi[:2] - lo[:2]) / 2 + RADIUS
        a = 2 * math.pi * self.n / 8
        xyz = np.clip([c[0] + r * math.cos(a), c[1] + r * math.sin(a), c[2]],
                      world.workspace.nav_min, world.workspace.nav_max)
        return Proposal(np.array([[*xyz, a + math.pi]]), "orbit")

    def feedback(self, world, proposal, step):
        pass


nbvkit.register_generator({name!r}, Orbit)
{scenario}
"""
FAIL_LINE = 20  # the line of np.vstack in PLUGIN


def _plugin(path, name="orbit", radius=2.0, fail_at=0, scenario=True):
    sc = (f"nbvkit.register_scenario({name!r}, 'an orbit', "
          f"{{'planner.generators': [{name!r}]}})") if scenario else ""  # fmt: skip
    path.write_text(PLUGIN.format(name=name, radius=radius, fail_at=fail_at, scenario=sc))
    assert path.read_text().splitlines()[FAIL_LINE - 1].strip().startswith("np.vstack")
    return path


def _nbvkit(*args):
    return subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *map(str, args)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip


def test_a_changed_plugin_file_flies_its_runs_again(tmp_path):
    """compare --plugin again after the file changed: its runs are flown anew (they were kept,
    and so the old figures); unchanged, they are kept. The summary names the files and content.
    The run of nbvkit's own scenario beside them depends on no plugin file: it stays kept."""
    plugin = _plugin(tmp_path / "evolving.py")
    out = tmp_path / "cmp"
    argv = ["compare", "--plugin", plugin, "--planners", "orbit,1", "--starts", "1", "--workers",
            "1", "--mesh", CUBE, "--out", out, "--set", *SMALL]  # fmt: skip

    def fly():
        p = _nbvkit(*argv)
        assert p.returncode == 0, p.stderr
        runs = {r.name: r for r in (out / "runs").iterdir()}
        (run,) = (r for r in runs.values() if "orbit" in r.name)
        (own,) = (r for r in runs.values() if r is not run)
        assert "plugins" not in json.loads((own / "spec.json").read_text())
        assert "plugins" not in json.loads((own / "summary.json").read_text())
        kept.append((own / "summary.json").stat().st_mtime_ns)
        return run.name, (run / "summary.json").stat().st_mtime_ns, run

    kept = []
    run_id, first, run = fly()
    import hashlib

    def recorded():
        s = json.loads((run / "summary.json").read_text())
        sha = hashlib.sha256(plugin.read_bytes()).hexdigest()
        assert s["plugins"] == [{"path": str(plugin.resolve()), "sha256": sha}]
        return s

    d0 = recorded()["distance_m"]
    assert fly()[:2] == (run_id, first)  # unchanged: resumed
    _plugin(plugin, radius=4.0)
    again = fly()
    assert again[0] == run_id and again[1] != first  # changed: flown again, in the same folder
    assert recorded()["distance_m"] != d0
    assert kept == kept[:1] * 3  # nbvkit's own scenario 1: flown once, kept since


def test_a_part_whose_code_another_plugin_file_holds_flies_again_when_that_file_changes(
    tmp_path,
):
    """One plugin file registers a class another plugin file defines (`from orbit_a import
    Orbit`, as docs/PLUGINS.md shows): editing the file that holds the code flies the run again,
    though the run's part came from the other file."""
    _plugin(tmp_path / "orbit_a.py", name="orbit_a", scenario=False)
    (tmp_path / "orbit_b.py").write_text(
        "import nbvkit\nfrom orbit_a import Orbit\n\n"
        "nbvkit.register_generator('orbit_b', Orbit)\n"
        "nbvkit.register_scenario('orbit_b', 'B', {'planner.generators': ['orbit_b']})\n"
    )
    out = tmp_path / "cmp"
    argv = ["compare", "--plugin", tmp_path / "orbit_a.py", "--plugin", tmp_path / "orbit_b.py",
            "--planners", "orbit_b", "--starts", "1", "--workers", "1", "--mesh", CUBE,
            "--out", out, "--set", *SMALL]  # fmt: skip

    def fly():
        p = _nbvkit(*argv)
        assert p.returncode == 0, p.stderr
        (run,) = (out / "runs").iterdir()
        return (run / "summary.json").stat().st_mtime_ns, json.loads(
            (run / "summary.json").read_text()
        )["distance_m"]

    first = fly()
    assert fly() == first  # unchanged: kept
    _plugin(tmp_path / "orbit_a.py", name="orbit_a", radius=4.0, scenario=False)
    again = fly()
    assert again[0] != first[0] and again[1] != first[1]  # the wider orbit, flown anew


BROKEN = """
import nbvkit


class Broken:
    def __init__(self, settings, context):
        pass

    def propose(self, world):
        if {bug!r} == "zero":
            return 1 / 0
        if {bug!r} == "key":
            return {{}}["spacing"]
        return [[0.0, -6.0, 1.0, 0.0]]  # a list, not a Proposal

    def feedback(self, world, proposal, step):
        pass


nbvkit.register_generator("broken", Broken)
"""


@pytest.mark.parametrize(
    "bug, said",
    [
        ("zero", "nbvkit run: error: ZeroDivisionError: division by zero"),
        ("key", "nbvkit run: error: KeyError: spacing"),  # (was "error: spacing")
        ("list", "nbvkit run: error: generator 'broken': propose returned list, not a"),
    ],
)
def test_a_parts_own_exception_or_wrong_return_is_one_line_not_nbvkits_traceback(
    tmp_path, bug, said
):
    """A part's own bug (any exception type) or a broken contract (a list for a Proposal): rc 2,
    the plugin's frames and one line naming it; no frame of nbvkit's own code."""
    plugin = tmp_path / "broken.py"
    plugin.write_text(BROKEN.format(bug=bug))
    p = _nbvkit("run", "--plugin", plugin, "--mesh", CUBE, "--out", tmp_path / "run", "--set",
                *SMALL, "planner.generators=[broken]")  # fmt: skip
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip().splitlines()[-1].startswith(said)
    assert "nbvkit/planning" not in p.stderr and "nbvkit/mission.py" not in p.stderr
    if bug == "zero":  # its own frame shown
        assert f'File "{plugin.resolve()}", line 11, in propose' in p.stderr


def test_a_run_without_plugins_records_none_and_keeps_its_spec(tmp_path, monkeypatch):
    """Without plugin files a run's spec.json and summary are as before (earlier run folders
    resume: their spec.json has no plugins either)."""
    monkeypatch.setattr("nbvkit.plugins.LOADED", [])  # other tests of this process loaded some
    monkeypatch.setattr("nbvkit.plugins.DIGESTS", {})
    spec = RunSpec("1", 0, overrides=(*SMALL, f"mesh.path={json.dumps(str(CUBE))}"))
    run_specs([spec], tmp_path, workers=1, progress=False)
    run = tmp_path / "runs" / spec.run_id
    assert "plugins" not in json.loads((run / "spec.json").read_text())
    assert "plugins" not in json.loads((run / "summary.json").read_text())


def test_a_plugins_error_shows_its_frames_and_a_builtin_error_its_line(tmp_path):
    plugin = _plugin(tmp_path / "buggy.py", fail_at=3)
    out = tmp_path / "run"
    p = _nbvkit("run", "--plugin", plugin, "--planner", "orbit", "--mesh", CUBE, "--out", out,
                "--set", *SMALL)  # fmt: skip
    assert p.returncode == 2
    err = p.stderr.strip().splitlines()
    assert f'File "{plugin.resolve()}", line {FAIL_LINE}, in propose' in p.stderr
    assert "np.vstack([np.zeros(3), np.zeros(4)])" in p.stderr
    assert err[-1].startswith("nbvkit run: error: all the input array dimensions")
    s = json.loads((out / "summary.json").read_text())
    assert f"plugin file {plugin.resolve()}, line {FAIL_LINE}, in propose" in s["stopped_by"]
    # the note names the plugin file it came from (it said "a script")
    assert f"generator 'orbit' (registered from {plugin.resolve()}) in propose()" in s["stopped_by"]
    # the console counts the views as the summary does (the first, before any planning, too)
    assert s["iterations"] == 2 and s["views"] == 3
    assert "the flight stopped after 2 iterations (3 views: the first" in p.stderr
    # the part's note and where it raised are printed once, above the error line
    assert p.stderr.count(f"generator 'orbit' (registered from {plugin.resolve()})") == 1
    bad = _nbvkit("run", "--plugin", plugin, "--mesh", CUBE, "--out", tmp_path / "bad", "--set",
                  "map.nope=1")  # fmt: skip
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip().splitlines() == [bad.stderr.strip()]  # one line


@pytest.fixture
def buggy(tmp_path):
    yield from plugin_fixture_file(
        tmp_path, "buggy_part.py", "", {"generator": ["buggy_orbit"]}, load=False
    )


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failed_runs_record_names_the_plugin_file_and_line(tmp_path, buggy, workers):
    import nbvkit

    _plugin(buggy, name="buggy_orbit", fail_at=1, scenario=False)
    nbvkit.load_plugin(buggy)
    over = (*SMALL, "planner.generators=[buggy_orbit]", f"mesh.path={json.dumps(str(CUBE))}")
    specs = [RunSpec("1", k, overrides=over) for k in (0, 1)]
    with pytest.raises(RunsFailed) as e:
        run_specs(specs, tmp_path / "out", workers=workers, progress=False)
    for _, error in e.value.failures:
        assert f"plugin file {buggy.resolve()}, line {FAIL_LINE}, in propose" in error, error
    # what each flew is kept beside the runs, not in runs/ (the next start flies them again)
    for s, (run_id, error) in zip(specs, e.value.failures):
        kept = tmp_path / "out" / "failed" / s.run_id
        assert run_id == s.run_id and f"what was flown is saved in {kept}" in error, error
        summary = json.loads((kept / "summary.json").read_text())
        assert summary["termination"] == "failed" and "in propose" in summary["stopped_by"]
        assert (kept / "flight.csv").is_file() and not (
            tmp_path / "out" / "runs" / s.run_id
        ).exists()


def test_a_part_registered_from_no_file_is_refused_by_worker_processes(tmp_path):
    """Workers know only the plugin files' parts: a part or scenario registered in this process
    from no file is refused before any run (it failed in every worker, naming no plugin)."""
    from nbvkit.planning import registry
    from nbvkit.scenarios import SCENARIOS, register_scenario
    from test_plugins import RingGenerator

    registry.register_generator("script_ring", RingGenerator)
    register_scenario("script_orbit", "a ring", {"planner.generators": ["script_ring"]})
    try:
        by_scenario = [RunSpec("script_orbit", k, overrides=SMALL) for k in (0, 1)]
        by_key = [RunSpec("1", k, overrides=(*SMALL, "planner.generators=[script_ring]"))
                  for k in (0, 1)]  # fmt: skip
        for specs, what in ((by_scenario, "scenario 'script_orbit'"),
                            (by_key, "generator 'script_ring'")):  # fmt: skip
            with pytest.raises(ValueError, match=rf"the {what} .*load_plugin"):
                run_specs(specs, tmp_path, workers=2, progress=False)
        assert not (tmp_path / "runs").exists()  # refused before any run
    finally:
        registry.GENERATORS.pop("script_ring")
        SCENARIOS.pop("script_orbit")


@pytest.fixture
def evolving(tmp_path):
    yield from plugin_fixture_file(
        tmp_path, "evolving_part.py", "", {"generator": ["evolving_orbit"]}, load=False
    )


def _orbit_radius():
    from nbvkit.planning import registry

    return registry.GENERATORS["evolving_orbit"].propose.__globals__["RADIUS"]


def test_a_plugin_file_changed_since_it_loaded_loads_again(evolving):
    """load_plugin of an edited file runs it anew, its parts replacing the ones it registered (a
    notebook's edit, a long-lived worker's); unchanged, it is not run again."""
    import nbvkit
    from nbvkit import plugins

    _plugin(evolving, name="evolving_orbit", radius=2.0, scenario=False)
    nbvkit.load_plugin(evolving)
    first = nbvkit.planning.registry.GENERATORS["evolving_orbit"]
    nbvkit.load_plugin(evolving)
    assert nbvkit.planning.registry.GENERATORS["evolving_orbit"] is first  # not run again
    _plugin(evolving, name="evolving_orbit", radius=4.0, scenario=False)
    nbvkit.load_plugin(evolving)
    assert _orbit_radius() == 4.0
    assert plugins.LOADED.count(str(evolving.resolve())) == 1
    assert plugins.loaded_files()[-1]["sha256"] == _sha256(evolving)
    evolving.write_text(evolving.read_text() + "\nraise RuntimeError('half edited')\n")
    with pytest.raises(RuntimeError, match="half edited"):
        nbvkit.load_plugin(evolving)  # a failed load leaves the last good one as it was
    assert _orbit_radius() == 4.0 and plugins.loaded_files()[-1]["sha256"] != _sha256(evolving)


def test_an_edit_of_the_same_size_and_time_loads_again(evolving, monkeypatch):
    """The content run is the content hashed: an edit that keeps the file's size and time (which
    Python's bytecode cache takes for unchanged) is loaded as it now is."""
    import os

    import nbvkit

    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    _plugin(evolving, name="evolving_orbit", radius=2.0, scenario=False)
    nbvkit.load_plugin(evolving)
    st = evolving.stat()
    _plugin(evolving, name="evolving_orbit", radius=4.0, scenario=False)
    os.utime(evolving, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert evolving.stat().st_size == st.st_size
    nbvkit.load_plugin(evolving)
    assert _orbit_radius() == 4.0


def test_loading_again_a_file_first_imported_keeps_what_it_did_not_register(tmp_path, monkeypatch):
    """A file imported as a module, then loaded, is credited with what its module holds (a built-in
    class it imports, every scenario from elsewhere): loaded again after an edit, it takes back
    its own names only; nbvkit's parts and another file's scenario stay."""
    import importlib

    import nbvkit
    from nbvkit import plugins
    from nbvkit.planning import registry
    from nbvkit.scenarios import SCENARIOS

    monkeypatch.setattr(sys, "path", [str(tmp_path), *sys.path])
    mod = tmp_path / "imported_parts.py"
    src = (
        "import nbvkit\n"
        "from nbvkit.planning.generators.lattice import LatticeGenerator\n"
        "class Mine(LatticeGenerator):\n    N = {n}\n"
        "nbvkit.register_generator('imported_mine', Mine, replace=True)\n"
    )
    mod.write_text(src.format(n=1))
    other = tmp_path / "other_scenario.py"
    other.write_text("import nbvkit\nnbvkit.register_scenario('other_sc', 'x', {'seed': 3})\n")
    try:
        nbvkit.load_plugin(other)
        importlib.import_module("imported_parts")
        nbvkit.load_plugin(mod)
        mod.write_text(src.format(n=2))
        nbvkit.load_plugin(mod)
        assert registry.GENERATORS["imported_mine"].N == 2
        assert "lattice" in registry.GENERATORS and "other_sc" in SCENARIOS
    finally:
        registry.GENERATORS.pop("imported_mine", None)
        SCENARIOS.pop("other_sc", None)
        sys.modules.pop("imported_parts", None)
        for p in (mod, other):
            if str(p.resolve()) in plugins.LOADED:
                plugins.LOADED.remove(str(p.resolve()))


def _sha256(path):
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_runs_are_refused_while_a_loaded_plugin_file_differs_from_its_content(
    tmp_path, evolving, monkeypatch
):
    """A file edited after it was loaded: the runs would fly the old parts in this process and
    the new ones in fresh workers, each recorded under its own hash. Refused before any run, in
    every mode, naming the file; a worker handed the parent's hash refuses a file that differs."""
    import nbvkit
    from nbvkit.experiments import run_one

    _plugin(evolving, name="evolving_orbit", scenario=False)
    nbvkit.load_plugin(evolving)
    loaded = nbvkit.plugins.loaded_files()
    _plugin(evolving, name="evolving_orbit", radius=4.0, scenario=False)
    over = (*SMALL, "planner.generators=[evolving_orbit]", f"mesh.path={json.dumps(str(CUBE))}")
    spec = RunSpec("surface", 0, overrides=over)
    for workers in (1, 2):
        with pytest.raises(ValueError, match=rf"plugin file {evolving.resolve()} changed.*again"):
            run_specs([spec, spec], tmp_path, workers=workers, progress=False)
    assert not (tmp_path / "runs").exists()
    with monkeypatch.context() as m:  # a fresh worker, handed the parent's hashes
        m.setattr("nbvkit.plugins.LOADED", [])
        m.setattr("nbvkit.plugins.DIGESTS", {})
        with pytest.raises(ValueError, match="the runs were started with"):
            run_one(spec, tmp_path, plugins=loaded)
    assert _orbit_radius() == 2.0  # nothing loaded


def test_a_long_lived_dask_worker_flies_the_plugin_file_as_it_is_now(tmp_path, evolving):
    """The same Dask cluster before and after the file changed (and was loaded again here):
    its workers fly the new content and record its hash, not the version they loaded first."""
    import nbvkit

    distributed = pytest.importorskip("distributed")
    over = (*SMALL, "planner.generators=[evolving_orbit]", f"mesh.path={json.dumps(str(CUBE))}")
    specs = [RunSpec("surface", 0, overrides=over)]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        flown = []
        for radius in (2.0, 4.0):
            _plugin(evolving, name="evolving_orbit", radius=radius, scenario=False)
            nbvkit.load_plugin(evolving)
            (row,) = run_specs(specs, tmp_path, scheduler=cluster.scheduler_address)
            s = json.loads((tmp_path / "runs" / row["run_id"] / "summary.json").read_text())
            assert s["plugins"][-1] == {
                "path": str(evolving.resolve()),
                "sha256": _sha256(evolving),
            }
            flown.append(s["distance_m"])
    assert flown[0] != flown[1]  # the wider orbit flown the second time


def test_a_sweep_file_names_its_plugin_files(tmp_path):
    """A sweep file's `plugins` are loaded before its runs are made, as --plugin files are: the
    sweep of a plugin's scenario flies from the file alone, and the same command resumes it
    (the run kept). Without them the scenario is unknown; a `plugins` that is not a list of
    paths is refused by name."""
    import yaml

    plugin = _plugin(tmp_path / "sweep_parts.py", name="orbit_sw")
    sweep = {"meshes": [str(CUBE)], "scenarios": ["orbit_sw"], "starts": 1, "workers": 1,
             "set": {k: yaml.safe_load(v) for k, v in (kv.split("=") for kv in SMALL)},
             "plugins": [str(plugin)]}  # fmt: skip
    f = tmp_path / "sweep.yaml"
    f.write_text(yaml.safe_dump(sweep))
    out = tmp_path / "out"
    for _ in range(2):
        r = _nbvkit("sweep", f, "--out", out)
        assert r.returncode == 0, r.stderr
        rows = (out / "results.csv").read_text().splitlines()
        assert len(rows) == 2 and ",orbit_sw," in rows[1]
    (run,) = (out / "runs").iterdir()
    assert json.loads((run / "summary.json").read_text())["plugins"][0]["path"] == str(plugin)
    f.write_text(yaml.safe_dump({**sweep, "plugins": None}))
    r = _nbvkit("sweep", f, "--out", tmp_path / "out2")
    assert r.returncode == 2 and "orbit_sw" in r.stderr
    for bad in (str(plugin), {}, False, ""):
        f.write_text(yaml.safe_dump({**sweep, "plugins": bad}))
        r = _nbvkit("sweep", f, "--out", tmp_path / "out3")
        assert (
            r.returncode == 2 and "sweep 'plugins' must be a list of plugin file paths" in r.stderr
        )
    f.write_text(yaml.safe_dump({**sweep, "plugins": ["not_here.py"]}))
    r = _nbvkit("sweep", f, "--out", tmp_path / "out3")
    assert r.returncode == 2
    assert f"sweep file {f}: plugin file not_here.py not found" in r.stderr
    assert "paths from the folder nbvkit runs in" in r.stderr


def test_compare_from_python_flies_a_script_part_beside_the_papers_and_writes_the_tables(tmp_path):
    """nbvkit.compare: a part registered in this script flown (workers=1) beside Scenario 1 from
    the same start; it writes what nbvkit compare writes and returns the table it wrote; a
    second call reuses the finished runs; workers that cannot know the part are refused."""
    import pandas as pd

    import nbvkit
    from nbvkit.planning import registry
    from nbvkit.scenarios import SCENARIOS
    from test_plugins import RingGenerator

    nbvkit.register_generator("script_ring", RingGenerator)
    nbvkit.register_scenario("script_orbit", "a ring", {"planner.generators": ["script_ring"]})
    small = {"map.resolution": 0.4, "max_iterations": 3, "progress": False,
             "report.enabled": False, "evaluation.gt_density": 50, "profiling.waypoints": 3,
             "planner.min_gain": 0}  # fmt: skip
    try:
        out = tmp_path / "cmp"
        t = nbvkit.compare(["script_orbit", 1], out, mesh=CUBE, starts=1, overrides=small,
                           workers=1, progress=False)  # fmt: skip
        runs = pd.read_csv(out / "runs.csv")
        assert list(runs["scenario"].astype(str)) == ["script_orbit", "1"]
        assert (runs["mesh"] == str(CUBE)).all() and (runs["start"] == 0).all()
        assert list(t["Planner"]) == ["script_orbit", "1"] and list(t["runs"]) == [1, 1]
        pd.testing.assert_frame_equal(t, pd.read_csv(out / "compare.csv"), check_dtype=False)
        for _, r in runs.iterrows():  # one start: the mean is the run's own figure
            row = t[t["Planner"] == str(r["scenario"])].iloc[0]
            assert row["Distance (m)"] == pytest.approx(r["distance_m"])
            assert row["Views"] == r["views"]
            cfg = (out / "runs" / r["run_id"] / "config.yaml").read_text()
            assert "resolution: 0.4" in cfg and "max_iterations: 3" in cfg
        assert "| script_orbit |" in (out / "compare.md").read_text()
        assert (out / "report.html").exists()
        assert (out / "figures" / "coverage_vs_distance.png").stat().st_size > 0
        flown = {p: p.stat().st_mtime_ns for p in (out / "runs").glob("*/manifest.json")}
        assert len(flown) == 2
        again = nbvkit.compare(["script_orbit", "1"], out, mesh=CUBE, starts=1,
                               overrides=small, workers=1, progress=False)  # fmt: skip
        pd.testing.assert_frame_equal(again, t)
        assert {p: p.stat().st_mtime_ns for p in flown} == flown  # not flown again
        with pytest.raises(ValueError, match="script_orbit' was registered in this process"):
            nbvkit.compare(["script_orbit", "1"], tmp_path / "w2", mesh=CUBE, starts=1,
                           overrides=small, workers=2, progress=False)  # fmt: skip
    finally:
        registry.GENERATORS.pop("script_ring")
        SCENARIOS.pop("script_orbit")
    for bad, err, words in (
        (dict(planners="surface,5"), TypeError, "planners must be a list"),
        (dict(planners=5), TypeError, "planners must be a list"),
        (dict(planners=[True]), TypeError, "planners must be a list"),
        (dict(planners=[]), ValueError, "names no planner"),
        (dict(starts=0), ValueError, "starts must be 1..5"),
        (dict(starts=True), ValueError, "starts must be 1..5"),
        (dict(overrides="max_iterations=3"), TypeError, "overrides must be a list"),
        (dict(overrides={"max_iterations": object()}), TypeError, "overrides 'max_iterations'"),
        (dict(overrides={"camera.max_range": float("nan")}), TypeError, "camera.max_range"),
        (dict(overrides={"max_iteration": 3}), KeyError, "max_iteration"),
        (dict(planners=["surface", "surface"]), ValueError, "more than once"),
        (dict(planners=["nope"]), ValueError, "nope"),
    ):
        kw = {"planners": ["1"], "out": tmp_path / "bad", "starts": 1, **bad}
        with pytest.raises(err, match=words):
            nbvkit.compare(**kw, mesh=CUBE, progress=False)
        assert not (tmp_path / "bad").exists()  # refused before any work
