"""Your own planner parts (issue 35): a generator and a termination defined in this file alone,
registered by the public calls, configured from YAML under their own sections and flown by a
Mission and by `nbvkit run --plugin`. Nothing in the package is edited: that is the claim of
docs/ARCHITECTURE.md's "How to add" (one file plus one registry line) and docs/PLUGINS.md."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
import warnings
from dataclasses import dataclass, field

import numpy as np
import pytest

import nbvkit
from conftest import ROOT, box_mesh
from nbvkit.config import load_config
from nbvkit.planning import registry
from nbvkit.planning.parts import Proposal
from nbvkit.settings import positive, within

QUICK = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=50",
    "evaluation.coverage_every=0",
    "profiling.sweep_step=0.5",  # the laser's profile maps the space round the box
    "profiling.waypoints=3",
    "symmetry.mode=none",
    "report.enabled=false",
    "observability.enabled=false",
    "planner.min_gain=0",  # every view of the ring is worth flying
]


@dataclass(frozen=True)
class RingSettings:
    """Views on a horizontal ring round the structure's bounding box, aimed at its centre."""

    count: int = within(8, 1, 360)  # views on the ring
    distance: float = positive(3.0)  # m beyond the box's half diagonal


class RingGenerator:
    """Proposes the ring's views not flown yet; gives up once all are flown."""

    Settings = RingSettings

    def __init__(self, settings: RingSettings, context):
        self.s, self.ctx = settings, context
        self.flown: set[int] = set()

    def propose(self, world):
        lo, hi = world.mesh.bounds
        c, r = (lo + hi) / 2, np.linalg.norm(hi[:2] - lo[:2]) / 2 + self.s.distance
        a = 2 * math.pi * np.arange(self.s.count) / self.s.count
        keep = [k for k in range(self.s.count) if k not in self.flown]
        if not keep:
            return None
        a = a[keep]
        xyz = np.stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a), np.full_like(a, c[2])], 1)
        xyz = np.clip(xyz, world.workspace.nav_min, world.workspace.nav_max)  # where it may fly
        poses = np.column_stack([xyz, a + math.pi])  # (K, 4) level, facing the centre
        self.keep = keep
        return Proposal(poses, "ring")

    def feedback(self, world, proposal, step):
        if step is not None:
            self.flown.add(self.keep[step.choice.index])


@dataclass(frozen=True)
class DistanceCapSettings:
    max_m: float = positive(1e9)


class DistanceCap:
    Settings = DistanceCapSettings

    def __init__(self, settings, context):
        self.max_m = settings.max_m

    def check(self, world, step):
        return "distance_cap" if step.distance_m >= self.max_m else None


@pytest.fixture
def parts():
    registry.register_generator("ring", RingGenerator)
    registry.register_termination("distance_cap", DistanceCap)
    yield
    registry.GENERATORS.pop("ring")
    registry.TERMINATIONS.pop("distance_cap")


def test_a_part_from_a_script_is_configured_and_flown(parts, tmp_path, capsys):
    f = tmp_path / "mine.yaml"
    f.write_text(
        "planner: {generators: [ring], terminations: [distance_cap]}\n"
        "ring: {count: 6, distance: 2.5}\n"
        "distance_cap: {max_m: 1000}\n"
    )
    cfg = load_config(f, QUICK)
    assert cfg.ring == RingSettings(6, 2.5) and cfg.section("distance_cap").max_m == 1000
    assert cfg.to_dict()["ring"] == {"count": 6, "distance": 2.5}  # written with the run
    with pytest.raises(ValueError, match="'ring.count'"):  # the part's own bounds hold
        load_config(overrides=["ring.count=0"])
    with pytest.raises(KeyError, match="ring.nope"):
        load_config(overrides=["ring.nope=1"])
    mesh = box_mesh((-2, -2, 0), (2, 2, 3))
    m = nbvkit.Mission(cfg, mesh=mesh)
    s = m.run(tmp_path / "run")
    assert s["generators"] == ["ring"] and s["termination"] == "coverage_complete"
    assert s["terminations"] == ["distance_cap"] and s["termination_part"] is None
    assert {r.source for r in m.records} == {"ring"}
    assert len(m.records) == 6  # every view of the ring, once
    assert s["coverage"]["0.1"] > 0.1  # the ring's views saw the box
    # a part ends the mission with its own reason
    s = nbvkit.Mission(cfg.with_overrides(["distance_cap.max_m=1"]), mesh=mesh).run()
    assert s["termination"] == "distance_cap" and s["iterations"] == 1
    assert s["termination_part"] == "distance_cap"  # the part whose reason it is
    from nbvkit.commands.run import print_summary

    print_summary(s, "out")  # the parts flown, whatever the scenario's name (surface)
    assert (
        "planner: generators ring; utility surface; terminations distance_cap (distance_cap "
        "ended the run)\n" in capsys.readouterr().out
    )


def test_registering_checks_the_name(parts):
    with pytest.raises(ValueError, match="registered already"):
        registry.register_generator("ring", RingGenerator)
    with pytest.raises(ValueError, match="section of the configuration"):
        registry.register_generator("camera", RingGenerator)
    with pytest.raises(ValueError, match="'Camera' is a section .* only in case"):
        registry.register_generator("Camera", RingGenerator)
    with pytest.raises(ValueError, match="identifier"):
        registry.register_termination("two words", DistanceCap)
    with pytest.raises(ValueError, match="unknown planner generator 'rings'"):
        load_config(overrides=["planner.generators=[rings]"])
    # a termination named as a generator: the generator is named, and replace=True (which
    # replaces one's own part of the same kind only) is not offered
    with pytest.raises(ValueError, match="a generator named 'ring' is registered") as e:
        registry.register_termination("ring", DistanceCap)
    assert "replace=True" not in str(e.value)
    # a name that differs from a registered one only in case ("IG" beside the C++ "ig")
    with pytest.raises(ValueError, match="'IG' differs only in case from 'ig'"):
        registry.register_utility("IG", lambda rays: np.zeros(rays.num_candidates))
    with pytest.raises(ValueError, match="'Ring' differs only in case from 'ring'"):
        registry.register_termination("Ring", DistanceCap)
    with pytest.raises(ValueError, match="scenario 'Surface' differs only in case from 'surface'"):
        nbvkit.register_scenario("Surface", "a second surface", {})


def test_the_configuration_module_names_no_part():
    """A part's section comes from the registry: config.py names no generator or termination
    (only the renamed keys of the last release)."""
    text = (ROOT / "python" / "nbvkit" / "config.py").read_text()
    body = text.split("RENAMED = {", 1)[1].split("}", 1)[1]
    for name in (*registry.GENERATORS, *registry.TERMINATIONS):
        assert f'"{name}' not in body and f"{name}:" not in body and f".{name}" not in body, name


CUBE = ROOT / "meshes" / "fixtures" / "cube.obj"


def _run_with_plugin(plugin, out, *args) -> dict:
    """`nbvkit run --plugin plugin --mesh cube --out out ARGS` in a subprocess; its summary."""
    p = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", "run", "--plugin", str(plugin), "--mesh", str(CUBE),
         "--out", str(out), *args],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    return json.loads((out / "summary.json").read_text())


def _nbvkit(*args):
    return subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *map(str, args)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip


def _doc_example(name: str, tmp_path):
    """The python block of docs/PLUGINS.md introduced by `name`, written to tmp_path/name."""
    import re

    doc = (ROOT / "docs" / "PLUGINS.md").read_text()
    code = re.search(rf"`{re.escape(name)}`.*?```python\n(.*?)```", doc, flags=re.S).group(1)
    path = tmp_path / name
    path.write_text(code)
    return path


def test_nbvkit_run_flies_a_plugin_file(tmp_path):
    plugin = tmp_path / "my_parts.py"
    plugin.write_text(
        "import math\nimport numpy as np\nimport nbvkit\n"
        + textwrap.dedent(_source(RingSettings, RingGenerator))
        + "\nnbvkit.register_generator('ring', RingGenerator)\n"
    )
    out = tmp_path / "run"
    extra = ["planner.generators=[ring]", "ring.count=4", "max_iterations=2"]
    s = _run_with_plugin(plugin, out, "--set", *QUICK, *extra)
    assert s["generators"] == ["ring"] and s["iterations"] == 2
    assert "ring:" in (out / "config.yaml").read_text()
    bad = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", "run", "--plugin", str(tmp_path / "none.py")],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert bad.returncode == 2 and "none.py" in bad.stderr


def _source(*objs) -> str:
    import inspect

    head = "from dataclasses import dataclass\nfrom nbvkit.planning.parts import Proposal\n"
    head += "from nbvkit.settings import positive, within\n"
    return head + "\n\n".join(inspect.getsource(o) for o in objs)


def test_the_worked_example_of_docs_plugins_flies(tmp_path):
    plugin = _doc_example("my_parts.py", tmp_path)
    out = tmp_path / "ring"
    s = _run_with_plugin(plugin, out, "--planner", "ring", "--set", *QUICK, "ring.count=5",
                         "ring.distance=2")  # fmt: skip
    assert s["scenario"] == "ring" and s["generators"] == ["ring"]
    assert s["termination"] == "coverage_complete" and s["iterations"] == 5
    assert "ring:" in (out / "config.yaml").read_text()
    # the commands that read the run's config.yaml take --plugin too (they knew no 'ring' key);
    # without it the error names the plugin file the run was flown with
    export = ["export", out, "--origin", "47.3977", "8.5456", "488", "--heading", "30"]
    for cmd in (export, ["evaluate", out]):
        p = _nbvkit(*cmd)
        assert p.returncode == 2 and "unknown config key 'ring'" in p.stderr
        assert f"was flown with the plugin file {plugin.resolve()}: give it with --plugin" in (
            p.stderr
        )
        p = _nbvkit(*cmd, "--plugin", plugin)
        assert p.returncode == 0, p.stderr
    assert (out / "export").is_dir() and "Chamfer distance" in p.stdout


def test_a_run_of_parts_an_import_registered_names_their_file(tmp_path):
    """A script that registers its parts by `import my_parts` (not load_plugin) and flies them:
    the run recorded no plugin, so evaluate's error named none. Its summary's parts_from names
    where each part it flew came from; the script's own file is not offered as a plugin."""
    mod = _doc_example("my_parts.py", tmp_path)
    out = tmp_path / "run"
    script = tmp_path / "fly.py"
    script.write_text(
        "import sys, nbvkit\n"
        f"sys.path.insert(0, {str(tmp_path)!r})\n"
        "import my_parts\n"
        f"cfg = nbvkit.load_config(overrides={[*QUICK, 'scenario=ring', 'ring.count=3']!r})\n"
        f"nbvkit.Mission(cfg).run({str(out)!r})\n"
    )
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    s = json.loads((out / "summary.json").read_text())
    assert "plugins" not in s and s["parts_from"]["generator ring"] == str(mod.resolve())
    p = _nbvkit("evaluate", out)
    assert p.returncode == 2 and f"flown with the plugin file {mod.resolve()}: give" in p.stderr
    assert _nbvkit("evaluate", out, "--plugin", mod).returncode == 0


def test_parts_from_names_the_file_that_registered_a_part(tmp_path, monkeypatch):
    """A part defined in one module and registered by another is recorded with the one that
    registered it (the file --plugin must run); one registered by code of no file (`python -c`,
    exec) or by the program's own script is "a script", no file to offer."""
    from nbvkit.planning.registry import part_sources

    (tmp_path / "partlib_x.py").write_text(
        "class Quiet:\n    def __init__(self, s, c): pass\n"
        "    def propose(self, world): return None\n"
        "    def feedback(self, world, proposal, step): pass\n"
    )
    reg = tmp_path / "regmod_x.py"
    reg.write_text(
        "import nbvkit\nfrom partlib_x import Quiet\n"
        "nbvkit.register_generator('quiet_x', Quiet)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        import regmod_x  # noqa: F401

        exec(compile("import nbvkit\nnbvkit.register_utility('exec_u', len)", "<string>", "exec"))
        cfg = load_config(overrides=["planner.generators=[quiet_x]", "utility.name=exec_u"])
        assert part_sources(cfg) == {"generator quiet_x": str(reg), "utility exec_u": "a script"}
    finally:
        registry.GENERATORS.pop("quiet_x", None)
        registry.UTILITIES.pop("exec_u", None)
        for m in ("regmod_x", "partlib_x"):
            sys.modules.pop(m, None)


def test_the_tour_example_of_docs_plugins_flies_tours_that_nbvkit_plans(tmp_path):
    # views on rings round the cube, flown as the tours nbvkit.plan_tour makes of them, plan
    # after plan, until none pays for its flight
    plugin = _doc_example("my_tour.py", tmp_path)
    out = tmp_path / "orbits"
    s = _run_with_plugin(plugin, out, "--mesh-scale", "5", "--set", *QUICK[:-1],
                         "planner.generators=[orbits]", "orbits.rings=2",
                         "orbits.per_ring=12")  # fmt: skip
    assert s["generators"] == ["orbits"] and s["termination"] == "coverage_complete"
    assert 2 <= s["iterations"] <= 24  # a tour's views, not the whole rings
    assert s["area_coverage"]["0.5"] > 0.5
    flown = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3))
    assert np.ptp(flown[:, 2]) > 0  # both rings flown


def test_plan_tour_defaults_to_the_worlds_tour_and_utility_settings():
    """A part calling nbvkit.plan_tour without settings plans as the mission's own tours: the
    world's tour.* (it took the class defaults, so --set tour.rate=... never reached it)."""
    cfg = load_config(
        overrides=["map.resolution=0.4", "progress=false", "tour.rate=0.0", "tour.min_gain=0.1"]
    )
    w = nbvkit.World(cfg, mesh=box_mesh(*BOX))
    w.take_off()
    w.sense("view")
    views = np.tile(np.asarray(w.state.pose)[:4], (9, 1))
    views[:, 0] += np.linspace(-4, 4, 9)
    t = cfg.tour
    mine = nbvkit.plan_tour(w, views, cfg.utility, selection=t.selection, min_gain=0.1, rate=0.0)
    plain = nbvkit.plan_tour(w, views)
    assert list(plain.flight) == list(mine.flight) and plain.length == mine.length
    unpaid = nbvkit.plan_tour(w, views, rate=50.0)  # the rate given still wins
    assert len(unpaid.flight) < len(mine.flight)


def test_the_utility_example_of_docs_plugins_flies_the_papers_method(tmp_path):
    plugin = _doc_example("my_utility.py", tmp_path)
    s = _run_with_plugin(
        plugin, tmp_path / "u", "--scenario", "5",
        "--set", "map.resolution=0.4", "evaluation.gt_density=50", "max_iterations=3",
        "profiling.enabled=false", "symmetry.mode=none", "report.enabled=false",
        "observability.enabled=false", "utility.name=near_unknown",
    )  # fmt: skip
    assert s["utility"] == "near_unknown" and s["iterations"] >= 1
    assert s["utility_only_checks"] == []  # the lattice's views are ranked by it


def test_a_utility_the_tours_only_check_is_said_so(capsys):
    """Under the default planner the coverage tours plan by the surface they would cover and the
    utility only checks the next view: the summary said `utility: spy` as if it ranked them."""
    from nbvkit.commands.run import print_summary

    from nbvkit.planning.utilities import per_candidate

    nbvkit.register_utility("spy", lambda rays: per_candidate(rays, (rays.state == -1) * 1.0))
    try:
        cfg = load_config(overrides=QUICK + ["max_iterations=2", "utility.name=spy"])
        s = nbvkit.Mission(cfg, mesh=box_mesh(*BOX)).run()
    finally:
        registry.UTILITIES.pop("spy")
    assert s["generators"] == ["tour"] and s["utility"] == "spy"
    assert s["utility_only_checks"] == ["tour"]
    print_summary(s, "out")
    said = capsys.readouterr().out
    assert (
        "note: the tour generator plans its views by the surface they would newly cover; " in said
    )
    assert "utility spy only checked each view (valid, worth planner.min_gain" in said
    cfg = load_config(overrides=QUICK + ["max_iterations=1"])  # the surface utility: no note
    assert registry.utility_only_checks(cfg) == [] and cfg.utility.name == "surface"


# ------------------------------------------------------------------ hostile parts (issue: audit)
BOX = ((-2, -2, 0), (2, 2, 3))


def _fly(out=None, generator=None, termination=None, extra=()):
    """A 4-view mission round a box with a generator / termination of this test registered as
    'hostile' / 'hostile_stop'; its summary."""
    keys = ["max_iterations=4", *extra]
    try:
        if generator is not None:
            registry.register_generator("hostile", generator)
            keys.append("planner.generators=[hostile]")
        if termination is not None:
            registry.register_termination("hostile_stop", termination)
            keys.append("planner.terminations=[hostile_stop,budget]")
        cfg = load_config(overrides=QUICK + keys)
        m = nbvkit.Mission(cfg, mesh=box_mesh(*BOX))
        return m, m.run(out)
    finally:
        registry.GENERATORS.pop("hostile", None)
        registry.TERMINATIONS.pop("hostile_stop", None)


def _proposing(fn):
    """A ring generator whose propose returns fn(self, world, the ring's proposal)."""

    class Hostile(RingGenerator):
        calls = 0

        def propose(self, world):
            Hostile.calls += 1
            return fn(self, world, super().propose(world))

    return Hostile


def _ring_poses(p):
    return p.poses


def test_a_mission_whose_candidates_are_all_refused_says_why_nothing_was_flown(capsys):
    """Every view inside the box: no view is valid, the mission ends at 0 iterations and says
    what refuses a candidate, and how many candidates each cause refused (summary:
    refused_views), in a warning a script sees too (it ended silently, exit 0; then only the
    console said it)."""
    from nbvkit.commands.run import print_summary
    from nbvkit.planning.selection import NOTHING_FLOWN

    inside = _proposing(lambda self, world, p: Proposal(np.array([[0.0, 0.0, 1.5, 0.0]]), "ring"))
    with pytest.warns(RuntimeWarning, match="planning step: 1 within vehicle.collision_radius"):
        _, s = _fly(generator=inside)
    assert s["iterations"] == 0 and s["termination"] == "no_valid_viewpoint"
    assert s["refused_views"] == {"collision": 1}
    print_summary(s, "out")
    assert "refusals" not in capsys.readouterr().out  # (said once, by the warning)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        _, s = _fly(generator=RingGenerator)  # views round it are flown: no such warning
    assert not [w for w in said if NOTHING_FLOWN in str(w.message)]
    print_summary(s, "out")
    out = capsys.readouterr().out
    assert s["iterations"] > 0 and NOTHING_FLOWN not in out
    ended = s["termination"] in ("no_valid_viewpoint", "no_reachable_view")
    assert ("refused_views" in s) == ("refusals of candidates" in out) == ended


@pytest.mark.parametrize(
    "fn, error, match",
    [
        (lambda s, w, p: Proposal(np.zeros((0, 4)), "x"), ValueError, "has no views"),
        (lambda s, w, p: Proposal(np.zeros((0, 4)), "x", exclusive=True), ValueError, "no views"),
        (lambda s, w, p: Proposal(p.poses * np.nan, "x"), ValueError, "pose 0 is not finite"),
        (lambda s, w, p: Proposal(p.poses[:, :3], "x"), ValueError, r"shape \(8, 3\), not"),
        (lambda s, w, p: Proposal(p.poses[0], "x"), ValueError, r"shape \(4,\), not"),
        (lambda s, w, p: p.poses, TypeError, "returned ndarray, not a"),
        (lambda s, w, p: Proposal([["a"] * 4], "x"), TypeError, "are not numbers"),
        (
            lambda s, w, p: Proposal(np.column_stack([p.poses, np.full(8, 3.0)]), "x"),
            ValueError,
            "pose 0 has pitch 3.0",
        ),
        (lambda s, w, p: Proposal(p.poses, 7), TypeError, "source must be a str"),
        # a column of iterations.csv and of the report: one on two lines split its rows
        (lambda s, w, p: Proposal(p.poses, "a\nb"), ValueError, "source must be a name on one"),
        (lambda s, w, p: Proposal(p.poses, ""), ValueError, r"\(printable, not empty\), got ''"),
        (lambda s, w, p: Proposal(p.poses, "x", aims=np.zeros((2, 3))), ValueError, "aims"),
        (lambda s, w, p: 1 / 0, ZeroDivisionError, "division by zero"),
        # complex poses were cut to their real part (a NumPy warning), aims never checked
        (lambda s, w, p: Proposal(p.poses + 1j, "x"), TypeError, r"poses are not numbers \(comp"),
        # a mask flew 0 and 1 m
        (lambda s, w, p: Proposal(p.poses > 0, "x"), TypeError, r"poses are not numbers \(bool"),
        (
            lambda s, w, p: Proposal(p.poses, "x", aims=np.full((8, 3), np.nan)),
            ValueError,
            "aim 0 is not finite",
        ),
        (lambda s, w, p: Proposal(p.poses, "x", aims=[["a"] * 3] * 8), TypeError, "aims are not"),
        # beyond the gimbal's -30 deg: flown, it failed in World.fly_to naming a leg frame's pitch
        (
            lambda s, w, p: Proposal(np.column_stack([p.poses, np.full(8, -1.4)]), "x"),
            ValueError,
            r"pose 0 has pitch -80.2141 deg, outside camera.gimbal_pitch_deg \[-30, 90\]",
        ),
    ],
    ids=["empty", "empty-exclusive", "nan", "k3", "1d", "array", "strings", "pitch", "source",
         "source-lines", "source-empty", "aims", "raises", "complex", "bool", "aims-nan",
         "aims-strings", "gimbal"],
)  # fmt: skip
def test_a_hostile_generator_is_an_exception_naming_it(fn, error, match):
    with pytest.raises(error, match=match) as e:
        _fly(generator=_proposing(fn))
    if error is not ZeroDivisionError or sys.version_info >= (3, 11):
        assert "generator 'hostile'" in _said(e.value)


def _said(e: BaseException) -> str:
    """An exception's message and notes (the part a plugin's own exception came from)."""
    return "\n".join([str(e), *getattr(e, "__notes__", [])])


def test_a_generators_views_the_vehicle_cannot_take_are_masked_not_flown():
    # outside the workspace, or inside the structure's known occupied cells: invalid candidates,
    # masked like any (the mission ends no_valid_viewpoint); a list of numbers is an array
    outside = _proposing(lambda s, w, p: Proposal(p.poses + [500, 0, 0, 0], "x"))
    with pytest.warns(RuntimeWarning, match="step: 8 outside the workspace"):
        m, s = _fly(generator=outside)
    assert s["termination"] == "no_valid_viewpoint" and s["iterations"] == 0
    inside = _proposing(lambda s, w, p: Proposal([[0.0, 0.0, 1.5, 0.0]], "x"))
    with pytest.warns(RuntimeWarning, match="no planned view was flown"):
        m, s = _fly(generator=inside, extra=["vehicle.start_clear_radius=3"])
    assert s["termination"] == "no_valid_viewpoint" and s["iterations"] == 0
    listed = _proposing(lambda s, w, p: Proposal(p.poses.tolist(), "x"))
    m, s = _fly(generator=listed)
    assert s["iterations"] == 4


def test_an_exclusive_proposal_asked_again_unchanged_is_an_error_not_a_hang():
    # a tour-like generator that ignores feedback(step=None) would be asked forever
    stuck = _proposing(lambda s, w, p: Proposal([[0.0, 0.0, 1.5, 0.0]], "x", exclusive=True))
    with pytest.raises(RuntimeError, match="'hostile' proposed again the exclusive views"):
        _fly(generator=stuck, extra=["vehicle.start_clear_radius=3"])
    assert stuck.calls == 2


class _Stop:
    def __init__(self, settings, context):
        pass


@pytest.mark.parametrize(
    "reason",
    [True, False, 1, np.bool_(True), {"a": 1}, "", "  ", "stop\n| injected | row |", "x" * 201],
    ids=repr,
)
def test_a_termination_returns_a_reason_or_none(reason):
    stop = type("Stop", (_Stop,), {"check": lambda self, w, s: reason})
    with pytest.raises(TypeError, match=r"termination 'hostile_stop': check returned"):
        _fly(termination=stop)
    raising = type("Stop", (_Stop,), {"check": lambda self, w, s: {}["key"]})
    with pytest.raises(KeyError) as e:  # the part's own exception, as it raised it
        _fly(termination=raising)
    if sys.version_info >= (3, 11):
        assert f"by the termination 'hostile_stop' (registered from {__file__}) in check()" in (
            _said(e.value)
        )


def test_a_part_failing_mid_mission_keeps_the_flight(tmp_path):
    """A plugin's error after views were flown: the run folder holds what was flown (summary
    termination 'failed', stopped_by its error), then the error is raised, noted with the
    part's name."""
    late = _proposing(lambda s, w, p: p if s.flown.__len__() < 2 else 1 / 0)
    with pytest.raises(ZeroDivisionError) as e:
        _fly(tmp_path / "run", generator=late)
    if sys.version_info >= (3, 11):
        assert f"by the generator 'hostile' (registered from {__file__}) in propose()" in (
            _said(e.value)
        )
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["termination"] == "failed" and s["iterations"] == 2
    assert s["stopped_by"].startswith("ZeroDivisionError: division by zero")
    if sys.version_info >= (3, 11):  # the note names the part in the summary too
        assert f"the generator 'hostile' (registered from {__file__})" in s["stopped_by"]
    rows = (tmp_path / "run" / "iterations.csv").read_text().splitlines()
    assert len(rows) == 3  # header + the two views flown
    assert (tmp_path / "run" / "cloud.ply").stat().st_size > 0


def test_a_plugin_part_reads_as_its_own_object():
    # a plain check(world, step) function registered is taken as a builder (two arguments):
    # built, it returned None, and the error said only "(NoneType) has no method check()"
    def check(world, step):
        return None

    with pytest.raises(TypeError, match=r"\(NoneType\) has no method check\(\): registered "
                       r"'hostile_stop' is called as f\(settings, context\) to build the part, "
                       r"and returned NoneType; register a class with check\(\)"):  # fmt: skip
        _fly(termination=check)
    # the planner holds a plugin's part checked; its attributes are still the part's
    m, s = _fly(generator=RingGenerator)
    g = m.planner.generators[0]
    assert g.part.__class__ is RingGenerator and len(g.flown) == 4 and g.s.count == 8
    assert "generator 'hostile'" in repr(g)


def test_registering_checks_the_part():
    with pytest.raises(TypeError, match="'x' must be a class"):
        registry.register_generator("x", 3)
    # a utility built like a generator, cls(settings, context), had failed only in flight
    with pytest.raises(TypeError, match="utility 'x' is the class G: a utility is a function"):
        registry.register_utility("x", type("G", (RingGenerator,), {}))
    with pytest.raises(TypeError, match=r"has no method feedback\(\)"):
        registry.register_generator("x", type("G", (), {"propose": lambda self, w: None}))
    with pytest.raises(TypeError, match=r"termination 'x': T has no method check\(\)"):
        registry.register_termination("x", type("T", (), {}))
    with pytest.raises(TypeError, match="Settings must be a dataclass"):
        registry.register_generator("x", type("G", (RingGenerator,), {"Settings": dict}))
    from dataclasses import dataclass

    @dataclass
    class Loose:  # not frozen: a part could change the settings its run records
        count: int = 3

    with pytest.raises(TypeError, match="Settings must be a frozen dataclass"):
        registry.register_generator("x", type("G", (RingGenerator,), {"Settings": Loose}))
    for init, words in ((lambda self, settings: None, "too many positional arguments"),
                        (lambda self, s, c, world: None, "missing a required argument: 'world'"),
                        (lambda self, *, settings, context: None,
                         "too many positional")):  # fmt: skip
        cls = type("G", (RingGenerator,), {"__init__": init})
        with pytest.raises(TypeError, match=rf"generator 'x': G cannot be built as "
                           rf"cls\(settings, context\): {words}"):  # fmt: skip
            registry.register_generator("x", cls)
    # a constructor that takes more, with defaults, or *args, is fine: registered and removed
    for init in (lambda self, s, c, extra=1: None, lambda self, *a: None):
        registry.register_termination("x_ok", type("T", (), {"__init__": init, "check": min}))
        registry.TERMINATIONS.pop("x_ok")
    with pytest.raises(ValueError, match="registered already \\(one of nbvkit's own\\)"):
        registry.register_generator("tour", RingGenerator)
    for name in ("ig", "surface"):  # (it said "a termination named 'ig'")
        with pytest.raises(
            ValueError, match=f"^a utility named '{name}' is registered already \\(one of nbvkit's"
        ):
            registry.register_utility(name, lambda rays: 0)
    assert "x" not in registry.GENERATORS and "x" not in registry.TERMINATIONS
    with pytest.raises(ValueError, match="register it first"):
        load_config(overrides=["planner.terminations=[nope]"])


def test_the_python_example_of_docs_plugins_runs(tmp_path):
    """The page's "From Python" block run as a script, as written, in a fresh Python from a
    folder holding my_parts.py: its comparison flies in worker processes (compare's default),
    which import the script again. Only the configuration is made small: a prelude above the
    block puts the cube and a coarse map in load_config, and one start each in compare."""
    import re

    _doc_example("my_parts.py", tmp_path)
    doc = (ROOT / "docs" / "PLUGINS.md").read_text()
    block = re.search(r"From Python \(a script.*?```python\n(.*?)```", doc, flags=re.S).group(1)
    small = [*QUICK, f"mesh.path={CUBE}", "mesh.scale=5", "ring.distance=2"]
    prelude = f"""
import nbvkit
from nbvkit.experiment_specs import override_strings
_small, _load, _compare = {small!r}, nbvkit.load_config, nbvkit.compare
nbvkit.load_config = lambda overrides=(): _load(overrides=[*_small, *overrides])
def _small_compare(planners, out, starts, overrides):
    over = [*_small, "max_iterations=3", *override_strings(overrides)]
    return _compare(planners, out, starts=1, overrides=over, workers=2, progress=False)
nbvkit.compare = _small_compare
def _keep():  # what the block made, for the test (the main process only)
    import pickle
    pickle.dump((summary, table), open("out.pkl", "wb"))
if __name__ == "__main__":
    import atexit
    atexit.register(_keep)
"""
    script = tmp_path / "example.py"
    script.write_text(prelude + block)
    p = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                       text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    import pickle

    s, t = pickle.loads((tmp_path / "out.pkl").read_bytes())
    # the ring's views in space the map knows free (what the laser's profile mapped) are flown,
    # the others never: as the page says
    assert s["scenario"] == "ring" and s["termination"] in (
        "coverage_complete",
        "no_valid_viewpoint",
    )
    assert 8 <= s["iterations"] <= 16
    assert "ring:" in (tmp_path / "runs" / "ring_py" / "config.yaml").read_text()
    # and the comparison: what compare.csv holds, one row per planner
    assert list(t["Planner"]) == ["ring", "surface", "5"] and (t["Views"] >= 1).all()
    assert "| ring |" in (tmp_path / "runs" / "cmp_py" / "compare.md").read_text()
    flown = [p.read_text() for p in (tmp_path / "runs" / "cmp_py" / "runs").glob("*/config.yaml")]
    assert len(flown) == 3
    assert [c for c in flown if "scenario: ring" in c and "count: 16" in c]
    # the runs that flew none of the plugin's parts hold no section of them: they read back
    # without it (evaluate and export knew no 'ring' key)
    assert [c for c in flown if "scenario: ring" not in c and "ring:" not in c]
    assert not [c for c in flown if "scenario: ring" not in c and "ring:" in c]


def test_ctrl_c_in_a_slow_utility_keeps_the_flight(tmp_path):
    """Ctrl-C while a utility of a script's runs (a slow one, say) stops the mission as anywhere
    else: what was flown is written, then KeyboardInterrupt is raised (not noted, not wrapped)."""
    from nbvkit.planning.utilities import per_candidate

    calls = []

    def slow(rays):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt  # as Ctrl-C in the middle of its work
        return per_candidate(rays, (rays.state == -1) * 1.0)

    registry.register_utility("slow", slow)
    try:
        cfg = load_config(overrides=QUICK + ["planner.generators=[lattice]", "utility.name=slow"])
        with pytest.raises(KeyboardInterrupt) as e:
            nbvkit.Mission(cfg, mesh=box_mesh(*BOX)).run(tmp_path / "run")
    finally:
        registry.UTILITIES.pop("slow")
    assert not getattr(e.value, "__notes__", None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["termination"] == "interrupted" and s["iterations"] == 2
    assert s["stopped_by"] == "KeyboardInterrupt" and s["utility"] == "slow"


def test_a_plugin_file_that_fails_registers_nothing_and_loads_again_once_fixed(tmp_path):
    """A file that registers parts and then raises leaves none of them registered: fixed, it
    loads under the same names (the names were taken: 'registered already')."""
    from nbvkit.plugins import LOADED, load_plugin
    from nbvkit.scenarios import SCENARIOS

    f = tmp_path / "half.py"
    source = (
        "import math\nimport numpy as np\nimport nbvkit\n"
        "from nbvkit.planning.utilities import per_candidate\n"
        + _source(RingSettings, RingGenerator)
        + "\nnbvkit.register_generator('half_ring', RingGenerator)\n"
        "nbvkit.register_utility('half_u', lambda rays: per_candidate(rays, rays.range))\n"
        "nbvkit.register_scenario('half', 'a half-written plugin', {})\n"
    )
    f.write_text(source + "raise RuntimeError('a bug after registering')\n")
    try:
        with pytest.raises(RuntimeError, match="a bug after registering"):
            load_plugin(f)
        assert "half_ring" not in registry.GENERATORS and "half_u" not in registry.UTILITIES
        assert "half" not in SCENARIOS and str(f.resolve()) not in LOADED
        f.write_text(source)
        load_plugin(f)
        assert "half_ring" in registry.GENERATORS and "half_u" in registry.UTILITIES
    finally:
        registry.GENERATORS.pop("half_ring", None)
        registry.UTILITIES.pop("half_u", None)
        SCENARIOS.pop("half", None)
        if str(f.resolve()) in LOADED:
            LOADED.remove(str(f.resolve()))


def test_a_plugin_file_that_fails_after_replacing_a_name_puts_the_old_part_back(tmp_path):
    """A file that replaces (replace=True) a name registered from a script and then raises
    leaves the script's part registered, not its own."""
    from nbvkit.plugins import LOADED, load_plugin

    def mine(rays):
        return rays.range

    nbvkit.register_utility("swap_u", mine)
    f = tmp_path / "swap.py"
    f.write_text(
        "import nbvkit\n"
        "nbvkit.register_utility('swap_u', lambda rays: rays.range, replace=True)\n"
        "raise RuntimeError('a bug after replacing')\n"
    )
    try:
        with pytest.raises(RuntimeError, match="a bug after replacing"):
            load_plugin(f)
        assert registry.UTILITIES["swap_u"] is mine and str(f.resolve()) not in LOADED
    finally:
        registry.UTILITIES.pop("swap_u", None)


# ------------------------------------------------------------ a researcher's mistakes (audit 2)


def test_a_part_may_not_take_a_name_the_configuration_uses():
    """A generator named 'check' or 'section' got the configuration's own method as its settings
    (config.section(name)), a name starting with _ its private fields; all are refused, and the
    reserved names cover every key and method the configuration has."""
    from nbvkit.config import Config

    for name in ("check", "section", "to_dict", "with_overrides", "_parts", "__init__"):
        with pytest.raises(ValueError, match=repr(name)):
            registry.register_generator(name, RingGenerator)
    assert {n for n in dir(Config) if not n.startswith("_")} <= registry.RESERVED


def test_settings_that_do_not_build_from_their_defaults_are_refused_when_registered():
    # a field without a default made every later load_config fail, naming no part
    @dataclass(frozen=True)
    class Required:
        count: int

    try:
        with pytest.raises(TypeError, match=r"generator 'req': its Settings\(\) must build"):
            registry.register_generator("req", type("G", (RingGenerator,), {"Settings": Required}))
        assert "req" not in registry.GENERATORS
    finally:
        registry.GENERATORS.pop("req", None)  # (registered, it broke every later test)
    load_config(overrides=["map.resolution=0.4"])


def test_settings_whose_defaults_fail_their_checks_are_refused_when_registered():
    # a NaN default registered, then every configuration failed on 'nanx.x', named or not
    @dataclass(frozen=True)
    class NotFinite:
        x: float = float("nan")

    try:
        with pytest.raises(
            ValueError, match=r"generator 'nanx': its Settings' defaults fail .*nanx.x"
        ):
            registry.register_generator(
                "nanx", type("G", (RingGenerator,), {"Settings": NotFinite})
            )
        assert "nanx" not in registry.GENERATORS
    finally:
        registry.GENERATORS.pop("nanx", None)
    load_config(overrides=["map.resolution=0.4"])


@pytest.mark.parametrize(
    "annotation, default, words",
    [
        (int, 2.5, r"'wrongx.v' must be an integer, got 2.5"),
        (str, 3, r"'wrongx.v' defaults to 3 \(int\), which a configuration file reads back as '3'"),
        (bool, 1, r"'wrongx.v' must be true or false"),
        (tuple, ("a",), r"'wrongx.v' must be a list of numbers"),
    ],
)
def test_settings_whose_defaults_would_not_read_back_are_refused(annotation, default, words):
    """count: int = 2.5 registered and flew, and its run's config.yaml was then refused by
    `nbvkit evaluate` and load_config; label: str = 3 read back as '3'."""
    import dataclasses

    Wrong = dataclasses.make_dataclass(
        "Wrong", [("v", annotation, dataclasses.field(default=default))], frozen=True
    )
    try:
        with pytest.raises(ValueError, match=words):
            registry.register_generator("wrongx", type("G", (RingGenerator,), {"Settings": Wrong}))
        assert "wrongx" not in registry.GENERATORS
    finally:
        registry.GENERATORS.pop("wrongx", None)
    Fine = dataclasses.make_dataclass(  # an int for a float reads back as its float
        "Fine", [("v", float, dataclasses.field(default=2))], frozen=True
    )
    try:
        registry.register_generator("finex", type("G", (RingGenerator,), {"Settings": Fine}))
        assert load_config(overrides=["finex.v=2.0"]).finex.v == 2.0
    finally:
        registry.GENERATORS.pop("finex", None)


def test_nbvkits_own_settings_read_back_as_themselves():
    """Every section of the default configuration passes the check a part's Settings meets."""
    import dataclasses

    from nbvkit.settings import check_defaults

    cfg = load_config()
    sections = [getattr(cfg, f.name) for f in dataclasses.fields(cfg)]
    sections = [s for s in sections if dataclasses.is_dataclass(s)]
    assert len(sections) > 10
    for section in sections:
        check_defaults(section, "")


@dataclass(frozen=True)
class _Lists:
    """A part's settings with container and PEP 604 fields (the module's own annotations are
    strings: `from __future__ import annotations`)."""

    counts: tuple[int, ...] = (1, 2)
    gains: list[float] = field(default_factory=lambda: [0.5])
    pair: tuple[int, str] = (1, "a")
    limit: float | None = None
    plain: tuple = (1.0,)


def test_container_and_optional_settings_are_checked_item_by_item():
    # tuple[int, ...] took [1.5] and "hello", list[float] anything, and `float | None` any value
    try:
        registry.register_generator("lists", type("G", (RingGenerator,), {"Settings": _Lists}))
        for over, words in (
            ("lists.counts=[1.5]", r"'lists.counts\[0\]' must be an integer"),
            ("lists.counts=hello", "'lists.counts' must be a list"),
            ("lists.gains=[true]", r"'lists.gains\[0\]' must be a number"),
            ("lists.pair=[3]", "'lists.pair' must be a list of 2 items"),
            ("lists.limit=abc", "'lists.limit' must be a number"),
            # items are keys of their type: finite, as a float key is (they took NaN and inf)
            ("lists.gains=[1, .nan]", r"'lists.gains\[1\]' must be a finite number"),
            ("lists.gains=[1e999]", r"'lists.gains\[0\]' must be finite"),
            ("lists.plain=[1, .inf]", "'lists.plain' must be finite numbers"),
            ("lists.counts=[100000000000000000000000000]", r"'lists.counts\[0\]' .* limit"),
        ):
            with pytest.raises(ValueError, match=words):
                load_config(overrides=[over])
        s = load_config(
            overrides=["lists.counts=[3, 4, 5]", "lists.gains=[1, 2]", "lists.pair=[7, 8]"]
        ).section("lists")
        assert s.counts == (3, 4, 5) and s.gains == [1.0, 2.0] and s.pair == (7, "8")
        assert all(type(x) is float for x in s.gains)
        assert load_config(overrides=["lists.limit=2"]).section("lists").limit == 2.0
    finally:
        registry.GENERATORS.pop("lists", None)


def test_settings_of_types_a_configuration_cannot_check_are_refused_when_registered():
    @dataclass(frozen=True)
    class Loose:
        table: dict = None

    @dataclass(frozen=True)
    class Unreadable:
        x: "NoSuchType" = 1  # noqa: F821

    try:
        for name, cls, words in (
            ("loose", Loose, r"generator 'loose': its Settings: field 'table' is of type"),
            ("unread", Unreadable, "generator 'unread': its Settings: its annotations cannot"),
        ):
            with pytest.raises(TypeError, match=words):
                registry.register_generator(name, type("G", (RingGenerator,), {"Settings": cls}))
            assert name not in registry.GENERATORS
    finally:
        registry.GENERATORS.pop("loose", None)
        registry.GENERATORS.pop("unread", None)


def test_an_exclusive_generator_may_write_its_views_into_the_same_array():
    """A tour-like generator that moves on in feedback but writes each next view into one
    buffer was told it 'proposed again' the views it had just moved on from."""

    class Buffered(RingGenerator):
        def __init__(self, settings, context):
            super().__init__(settings, context)
            self.buf, self.k = np.zeros((1, 4)), 0

        def propose(self, world):
            if self.k == self.s.count:
                return None
            ring = super().propose(world).poses
            ring[:2, :3] = 0.0  # the first two views inside the box: rejected
            self.buf[:] = ring[self.k]
            return Proposal(self.buf, "buffered", exclusive=True)

        def feedback(self, world, proposal, step):
            self.k += 1

    m, s = _fly(generator=Buffered, extra=["vehicle.start_clear_radius=3"])
    assert s["iterations"] == 4 and m.planner.generators[0].k == 6


def test_a_stop_reason_is_a_str_or_none():
    # True reached the planner as a 'view' (TypeError: 'bool' object is not subscriptable)
    done = type("Done", (RingGenerator,), {"propose": lambda self, w: None})
    with pytest.raises(TypeError, match="generator 'hostile': its stop_reason is True"):
        _fly(generator=type("G", (done,), {"stop_reason": True}))
    with pytest.raises(TypeError, match=r"its stop_reason is 'xxx.*at most 200 characters"):
        _fly(generator=type("G", (done,), {"stop_reason": "x" * 10**7}))  # (quoted short)
    m, s = _fly(generator=type("G", (done,), {"stop_reason": "ring_unreachable"}))
    assert s["termination"] == "ring_unreachable"


RESERVED_REASONS = ["failed", "interrupted", "budget_time", "budget_views", "max_iterations"]


@pytest.mark.parametrize("reason", RESERVED_REASONS)
def test_a_termination_may_not_claim_nbvkits_own_failure(reason):
    stop = type("Stop", (_Stop,), {"check": lambda self, w, s: reason})
    with pytest.raises(ValueError, match=f"check returned '{reason}', which nbvkit"):
        _fly(termination=stop)


@pytest.mark.parametrize("reason", RESERVED_REASONS)
def test_a_stop_reason_may_not_claim_nbvkits_own_words(tmp_path, reason):
    # "failed" from a generator's stop_reason was the summary's termination with stopped_by
    # None; "budget_time" set stopped_by_budget
    done = type("Done", (RingGenerator,), {"propose": lambda self, w: None})
    with pytest.raises(ValueError, match=f"generator 'hostile': its stop_reason is '{reason}'"):
        _fly(tmp_path / "run", generator=type("G", (done,), {"stop_reason": reason}))
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["termination"] == "failed" and not s["stopped_by_budget"]
    assert "its stop_reason is" in s["stopped_by"]


def test_a_plugin_part_copies():
    import copy

    m, s = _fly(generator=RingGenerator)
    g = copy.copy(m.planner.generators[0])  # was a RecursionError (__getattr__ before __init__)
    assert g.part is m.planner.generators[0].part and g.name == "hostile"


def test_with_other_generators_feedback_is_of_its_own_views():
    """Scored with the lattice's views, the ring's feedback had the union's step: its
    choice.index a row of the union (an IndexError, or the wrong view marked flown)."""
    told = []

    class Told(RingGenerator):
        def feedback(self, world, proposal, step):
            told.append((proposal, step))
            super().feedback(world, proposal, step)

    registry.register_generator("told", Told)
    try:
        cfg = load_config(
            overrides=QUICK + ["max_iterations=6", "planner.generators=[lattice,told]"]
        )
        m, unions = nbvkit.Mission(cfg, mesh=box_mesh(*BOX)), []
        m.planner.hooks["keep"] = lambda world, step: unions.append(step.proposal)
        s = m.run()
    finally:
        registry.GENERATORS.pop("told")
    assert s["iterations"] == 6 and len(told) == 6
    mine = [(p, st) for p, st in told if st is not None]
    assert 0 < len(mine) < 6  # the lattice's views flown too, the ring told None for them
    for proposal, step in told:
        assert proposal.source == "ring" and len(proposal.poses) <= 8
        if step is not None:
            assert step.proposal is proposal
            assert np.allclose(proposal.poses[step.choice.index], step.choice.pose[:4])
    # the union's record of whose rows are whose holds the generators: not pickled or copied
    import copy
    import pickle

    assert unions[0].source == "lattice+ring" and len(unions[0].members) == 2
    assert pickle.loads(pickle.dumps(unions[0])).source == "lattice+ring"
    # each record names the generator whose view was flown, not the union's "lattice+ring"
    sources = [r.source for r in m.records]
    assert sources.count("ring") == len(mine) and sources.count("lattice") == 6 - len(mine)
    assert not hasattr(copy.deepcopy(unions[0]), "members")


def test_a_view_whose_feedback_raised_is_recorded(tmp_path):
    late = type(
        "Late",
        (RingGenerator,),
        {"feedback": lambda self, w, p, st: self.flown.add(0) if not self.flown else 1 / 0},
    )
    with pytest.raises(ZeroDivisionError):
        _fly(tmp_path / "run", generator=late)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    rows = (tmp_path / "run" / "iterations.csv").read_text().splitlines()
    assert s["termination"] == "failed" and s["iterations"] == 2 and len(rows) == 3


@pytest.mark.parametrize("cells", [np.nan, -1.0, 0.5], ids=repr)
def test_a_utilitys_cells_are_counts(cells):
    from nbvkit.planning.utilities import per_candidate

    registry.register_utility(
        "counted", lambda r: (per_candidate(r, r.range), np.full(len(r), cells))
    )
    try:
        cfg = load_config(
            overrides=QUICK + ["planner.generators=[lattice]", "utility.name=counted"]
        )
        with pytest.raises(ValueError, match="utility 'counted' returned cells"):
            nbvkit.Mission(cfg, mesh=box_mesh(*BOX)).run()
    finally:
        registry.UTILITIES.pop("counted")


def test_a_plugin_file_imports_its_neighbours_and_loads_once_imported(tmp_path, monkeypatch):
    """A plugin that imports a module beside it failed (ModuleNotFoundError); one imported first
    (import my_parts) and then given to load_plugin, for the workers, was 'registered already'."""
    import importlib

    from nbvkit.plugins import LOADED, load_plugin

    (tmp_path / "ring_helpers.py").write_text("COUNT = 5\n")
    (tmp_path / "audit_ring.py").write_text(
        "import math\nimport numpy as np\nimport nbvkit\nfrom ring_helpers import COUNT\n"
        + _source(RingSettings, RingGenerator)
        + "\nnbvkit.register_generator('audit_ring', RingGenerator)\n"
    )
    monkeypatch.setattr(sys, "path", list(sys.path))
    files = [str(tmp_path / "audit_ring.py")]
    try:
        load_plugin(tmp_path / "audit_ring.py")
        assert "audit_ring" in registry.GENERATORS
        del registry.GENERATORS["audit_ring"], LOADED[LOADED.index(files[0])]
        sys.modules.pop("audit_ring", None)
        importlib.import_module("audit_ring")  # the folder is on sys.path now
        load_plugin(tmp_path / "audit_ring.py")
        assert LOADED[-1] == files[0]
    finally:
        registry.GENERATORS.pop("audit_ring", None)
        sys.modules.pop("audit_ring", None)
        if files[0] in LOADED:
            LOADED.remove(files[0])


def test_plan_tour_names_a_wrong_memo_or_utility():
    # a dict as memo was pybind11's page of signatures, a camera section as utility an
    # AttributeError about .options
    said, shapes = [], []

    def wrong(s, world, p):
        for kw in ({"memo": {}}, {"utility": s.ctx.camera}):
            with pytest.raises(TypeError) as e:
                nbvkit.plan_tour(world, p.poses, **kw)
            said.append(str(e.value))
        for views, got in ((p.poses[:, :3], f"({len(p.poses)}, 3)"), (p.poses[0], "(4,)")):
            with pytest.raises(ValueError) as e:  # the shape it got (it said the shape wanted)
                nbvkit.plan_tour(world, views)
            shapes.append((str(e.value).split("; ")[-1], f"got shape {got}"))

    _fly(generator=_proposing(wrong))
    assert said == [
        "plan_tour: memo is a nbvkit.CoverageMemo or None, not dict",
        "plan_tour: utility is the configuration's utility section (context.utility) or None, "
        "not CameraConfig",
    ]
    assert shapes and all(got == want for got, want in shapes), shapes


def test_a_scenario_preset_may_not_set_the_scenario():
    """{"scenario": "5", ...} registered, and the user's scenario name always won over it: the
    preset's own planner flew, silently, instead of Scenario 5's."""
    from nbvkit.scenarios import SCENARIOS

    with pytest.raises(ValueError, match="scenario 'my5' sets 'scenario': a preset names"):
        nbvkit.register_scenario("my5", "Scenario 5, tweaked", {"scenario": "5", "tour.rate": 0})
    with pytest.raises(ValueError, match="settings must be a mapping of dotted config keys"):
        nbvkit.register_scenario("my5", "a list", [("tour.rate", 0)])
    assert "my5" not in SCENARIOS


def test_a_scenario_naming_an_unknown_part_is_an_error_naming_it(tmp_path):
    # a registered scenario's preset was not checked as a key the user sets: the mission raised
    # a bare KeyError: 'nonexistent'; its sections are now checked when it is loaded
    from nbvkit.scenarios import SCENARIOS

    nbvkit.register_scenario(
        "audit_unknown",
        "names a part never registered",
        {"planner.generators": ["nonexistent"], "planner.terminations": ["nonexistent_stop"]},
    )
    try:
        with pytest.raises(
            ValueError,
            match="^scenario 'audit_unknown' sets planner.generators = .*: unknown planner "
            "generator 'nonexistent'; known: ",
        ):
            load_config(overrides=[*QUICK, "scenario=audit_unknown"])
        with pytest.raises(ValueError, match="unknown planner termination 'nonexistent_stop'"):
            load_config(overrides=[*QUICK, "scenario=audit_unknown", "planner.generators=[]"])
        # compared, it is refused before any folder or run (each run failed in turn)
        out = tmp_path / "cmp"
        with pytest.raises(ValueError, match="unknown planner generator 'nonexistent'"):
            nbvkit.compare(["audit_unknown"], out, starts=1, overrides=QUICK, progress=False)
        assert not out.exists()
        # a part gone since the configuration was loaded: named when the planner is built
        nbvkit.register_generator("audit_gone", RingGenerator)
        cfg = load_config(overrides=[*QUICK, "planner.generators=[audit_gone]"])
        del registry.GENERATORS["audit_gone"]
        with pytest.raises(ValueError, match="unknown planner generator 'audit_gone'; known: "):
            nbvkit.Mission(cfg, mesh=box_mesh(*BOX))
    finally:
        SCENARIOS.pop("audit_unknown")
        registry.GENERATORS.pop("audit_gone", None)


@dataclass(frozen=True)
class WideRingSettings:
    count: int = within(5, 1, 360)
    distance: float = positive(6.0)


class WideRing(RingGenerator):
    Settings = WideRingSettings


def test_a_part_or_scenario_registered_again_with_replace_takes_the_name(parts):
    # a notebook cell run again: "registered already" unless told to replace what the user put
    from nbvkit.scenarios import SCENARIOS

    with pytest.raises(ValueError, match="registered already.*replace=True"):
        nbvkit.register_generator("ring", WideRing)
    nbvkit.register_generator("ring", WideRing, replace=True)
    cfg = load_config(overrides=["ring.distance=7"])
    assert cfg.ring == WideRingSettings(5, 7.0)
    assert type(registry.get_generator("ring", cfg).part) is WideRing  # the planner's lookup
    nbvkit.register_termination("distance_cap", DistanceCap, replace=True)

    def near(rays):
        return np.zeros(len(rays.offsets) - 1)

    nbvkit.register_utility("audit_u", lambda rays: 0)
    nbvkit.register_scenario("audit_s", "one", {"ring.count": 3})
    try:
        with pytest.raises(ValueError, match="registered already"):
            nbvkit.register_utility("audit_u", near)
        nbvkit.register_utility("audit_u", near, replace=True)
        assert registry.UTILITIES["audit_u"] is near
        with pytest.raises(ValueError, match="registered already"):
            nbvkit.register_scenario("audit_s", "two", {"ring.count": 4})
        nbvkit.register_scenario("audit_s", "two", {"ring.count": 4}, replace=True)
        assert load_config(overrides=["scenario=audit_s"]).ring.count == 4
        # nbvkit's own are never replaced, nor a name of another kind
        for call in (
            lambda: nbvkit.register_generator("tour", WideRing, replace=True),
            lambda: nbvkit.register_termination("budget", DistanceCap, replace=True),
            lambda: nbvkit.register_utility("ig", near, replace=True),
            lambda: nbvkit.register_scenario("surface", "mine", {}, replace=True),
        ):
            with pytest.raises(ValueError, match="nbvkit's own.*cannot be replaced"):
                call()
        with pytest.raises(ValueError, match="a generator named 'ring'.*not a termination"):
            nbvkit.register_termination("ring", DistanceCap, replace=True)
        with pytest.raises(TypeError):  # the checks hold, and the name keeps its part
            nbvkit.register_generator("ring", 3, replace=True)
        assert registry.GENERATORS["ring"] is WideRing
        assert load_config(overrides=["scenario=surface"]).utility.name == "surface"
    finally:
        registry.UTILITIES.pop("audit_u", None)
        SCENARIOS.pop("audit_s", None)


@dataclass(frozen=True)
class EvenSettings:
    count: int = 4
    spread: float = 1.0

    def __post_init__(self):
        if self.count % 2:
            raise ValueError(f"count must be even, got {self.count}")
        if self.spread > self.count:
            raise ValueError("the spread may not exceed the count")


class Even(RingGenerator):
    Settings = EvenSettings


def test_a_settings_post_init_error_names_its_section_and_key():
    # a ValueError of a part's own __post_init__ named neither the section nor the key
    from nbvkit.scenarios import SCENARIOS

    nbvkit.register_generator("audit_even", Even)
    try:
        with pytest.raises(ValueError, match=r"^config key 'audit_even.count' must be even, got 3"):
            load_config(overrides=["audit_even.count=3"])
        with pytest.raises(
            ValueError, match=r"^config section 'audit_even': the spread may not exceed the count"
        ) as e:
            load_config(overrides=["audit_even.spread=9"])
        assert "audit_even.spread = 9" in str(e.value)  # what was set there
        nbvkit.register_scenario("audit_odd", "odd", {"audit_even.count": 5})
        with pytest.raises(ValueError, match="scenario 'audit_odd' sets audit_even.count = 5: "):
            load_config(overrides=["scenario=audit_odd"])
    finally:
        registry.GENERATORS.pop("audit_even", None)
        SCENARIOS.pop("audit_odd", None)


# ------------------------------------------------------------ loading and the World (audit 3)


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    """tmp_path on sys.path; on teardown the parts, scenarios, plugin files and modules the test
    loaded from it are forgotten."""
    from nbvkit import plugins
    from nbvkit.scenarios import SCENARIOS

    monkeypatch.setattr(sys, "path", [str(tmp_path), *sys.path])
    tables = [dict(t) for t in (registry.GENERATORS, registry.TERMINATIONS, registry.UTILITIES)]
    scenarios = dict(SCENARIOS)
    yield tmp_path
    for t, was in zip((registry.GENERATORS, registry.TERMINATIONS, registry.UTILITIES), tables):
        for n in set(t) - set(was):
            t.pop(n)
    for n in set(SCENARIOS) - set(scenarios):
        SCENARIOS.pop(n)
    for key in [k for k in plugins.LOADED if k.startswith(str(tmp_path.resolve()))]:
        plugins.LOADED.remove(key)
    for name in [
        n for n, m in sys.modules.items() if str(tmp_path) in str(getattr(m, "__file__", ""))
    ]:
        sys.modules.pop(name)


ONE_MODULE = """
import nbvkit


class Boom(Exception):
    pass


def booming(rays):
    raise Boom("the plugin's own error")


class Gen:
    def __init__(self, settings, context):
        pass

    def propose(self, world):
        return None

    def feedback(self, world, proposal, step):
        pass


nbvkit.register_generator("one_gen", Gen)
nbvkit.register_utility("one_u", booming)
"""


def test_a_plugin_file_loaded_and_imported_is_one_module(plugin_dir):
    """load_plugin ran the file under a made-up module name: `import one_module` then ran it
    again ('a generator named ... is registered already'), and the plugin's own exception types
    were two classes, so `except one_module.Boom` did not catch what its part raised."""
    import importlib

    (plugin_dir / "one_module.py").write_text(ONE_MODULE)
    (plugin_dir / "uses_one.py").write_text(
        "import nbvkit\nfrom one_module import Gen\nnbvkit.register_generator('uses_gen', Gen)\n"
    )
    nbvkit.load_plugin(plugin_dir / "one_module.py")
    one_module = importlib.import_module("one_module")  # not run again
    assert registry.GENERATORS["one_gen"] is one_module.Gen
    nbvkit.load_plugin(plugin_dir / "uses_one.py")  # another plugin file imports it
    assert registry.GENERATORS["uses_gen"] is one_module.Gen
    with pytest.raises(one_module.Boom, match="the plugin's own error"):
        registry.UTILITIES["one_u"](None)


def test_a_name_registered_by_two_files_is_an_error_naming_both(plugin_dir):
    a, b = plugin_dir / "first_gen.py", plugin_dir / "second_gen.py"
    for f in (a, b):
        f.write_text(ONE_MODULE)
    nbvkit.load_plugin(a)
    with pytest.raises(ValueError, match="a generator named 'one_gen' is registered already") as e:
        nbvkit.load_plugin(b)
    assert f"registered from {a}; this one from {b}" in str(e.value)
    # the same file run a second time under another module name says so
    import importlib.util

    spec = importlib.util.spec_from_file_location("other_name", a)
    with pytest.raises(ValueError, match="from the same file, run a second time as module"):
        spec.loader.exec_module(importlib.util.module_from_spec(spec))
    # a file that registers one name twice says that, not that it ran twice (it did not)
    twice = plugin_dir / "twice_gen.py"
    mine = ONE_MODULE.replace("one_gen", "twice_gen").replace("one_u", "twice_u")
    twice.write_text(mine + 'nbvkit.register_generator("twice_gen", Gen)\n')
    with pytest.raises(ValueError, match=f"registered from {twice}, which registers the name tw"):
        nbvkit.load_plugin(twice)


def test_a_failed_load_forgets_the_helper_modules_it_imported(plugin_dir):
    """A plugin that imported a helper registering a part, then failed: the helper's part was
    rolled back but its module stayed imported, so once the plugin was fixed the import found
    it and the part was silently missing."""
    (plugin_dir / "ring_helper.py").write_text(
        ONE_MODULE.replace("one_gen", "helper_gen").replace("one_u", "helper_u")
    )
    f = plugin_dir / "uses_helper.py"
    f.write_text("import ring_helper\nraise RuntimeError('a bug after the import')\n")
    with pytest.raises(RuntimeError, match="a bug after the import") as e:
        nbvkit.load_plugin(f)
    # its own type, with a note naming the file (a ModuleNotFoundError named only the module)
    assert f"raised while loading the plugin file {f}" in getattr(e.value, "__notes__", []), e
    assert "helper_gen" not in registry.GENERATORS and "ring_helper" not in sys.modules
    assert "uses_helper" not in sys.modules and "numpy" in sys.modules  # installed ones stay
    f.write_text("import ring_helper\n")
    nbvkit.load_plugin(f)
    assert "helper_gen" in registry.GENERATORS and "helper_u" in registry.UTILITIES


def test_the_world_names_a_wrong_shape_of_positions_and_an_unknown_stage():
    from nbvkit.vehicle import STAGES

    cfg = load_config(overrides=QUICK + ["max_iterations=1"])
    w = nbvkit.Mission(cfg, mesh=box_mesh(*BOX)).world
    with pytest.raises(ValueError, match=r"must be \(K, 3\) positions .* got shape \(2, 4\)"):
        w.can_hold(np.zeros((2, 4)))  # was numpy's reshape error (or 8 / 3 rows silently)
    assert w.can_hold(np.zeros(3)).shape == (1,) and w.can_hold(np.zeros((0, 3))).shape == (0,)
    for stage in (123, "views", None):
        with pytest.raises(ValueError, match=r"stage must be one of profile, nbv, got"):
            w.fly_to(w.state.pose, stage)  # 123 was written into the trajectory
    rows = len(w.state.trajectory)
    w.fly_to(w.state.pose, STAGES[1])
    assert len(w.state.trajectory) == rows + 1 and w.state.trajectory[-1][0] == "nbv"


def test_what_a_generator_sets_on_its_step_does_not_change_the_record():
    """A generator told of its view gets its own copy of the step: setting its choice's gain, its
    new surface or its distance (or writing into its pose) left iterations.csv recording those
    values; its `extra` columns are still the record's."""

    class Meddler(RingGenerator):
        def feedback(self, world, proposal, step):
            super().feedback(world, proposal, step)
            if step is not None:
                step.choice.gain, step.new_surface_m2, step.distance_m = math.nan, -5.0, 1e9
                step.choice.pose[:] = 0.0
                step.extra["meddled"] = True

    registry.register_generator("meddler", Meddler)
    try:
        cfg = load_config(overrides=QUICK + ["max_iterations=3", "planner.generators=[meddler]"])
        m = nbvkit.Mission(cfg, mesh=box_mesh(*BOX))
        s = m.run()
    finally:
        registry.GENERATORS.pop("meddler")
    assert len(m.records) == s["iterations"] == 3
    for r in m.records:
        assert math.isfinite(r.gain) and r.new_surface_m2 >= 0 and r.distance_m < 1e3
        assert max(abs(r.x), abs(r.y), abs(r.z)) > 0
    assert s["distance_m"] < 1e3


def test_a_plugin_file_edited_twice_registering_an_imported_part_loads_each_time(plugin_dir):
    """A file registering a part it imports from a module of its own registers the same object
    when edited and loaded again: it was not counted as the file's, so the third load said
    "a utility named 'near_x' is registered already"."""
    (plugin_dir / "near_lib.py").write_text(
        "import numpy as np\n\n\ndef near(rays):\n    return np.zeros(len(rays))\n"
    )
    f = plugin_dir / "near_plug.py"
    text = "import nbvkit\nfrom near_lib import near\nnbvkit.register_utility('near_x', near)\n"
    for edit in ("", "# 1\n", "# 2\n"):
        f.write_text(text + edit)
        nbvkit.load_plugin(f)
    assert registry.UTILITIES["near_x"] is sys.modules["near_lib"].near


def test_plugin_files_that_register_nothing_are_warned_of(plugin_dir, capsys):
    """`--plugin` files without a register_* call loaded without a word; the configuration
    naming their parts then said only "unknown config key"."""
    from nbvkit.cli import main

    f = plugin_dir / "helpers_only.py"
    f.write_text("class Orbits:\n    pass\n")
    with pytest.raises(SystemExit):  # (argparse: no such planner)
        main(["run", "--plugin", str(f), "--planner", "orbits"])
    err = capsys.readouterr().err
    assert f"nbvkit run: warning: the plugin files ({f}) registered no part or scenario" in err
    assert "invalid choice: 'orbits'" in err


def test_a_planner_of_a_plugin_not_loaded_is_hinted(capsys):
    from nbvkit.cli import main

    with pytest.raises(SystemExit) as e:
        main(["run", "--planner", "ring"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'ring'" in err and "once its plugin is loaded: --plugin FILE" in err
