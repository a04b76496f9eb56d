"""Configuration: defaults equal the C++ defaults, YAML round trip, overrides, rejection."""
from __future__ import annotations

import math
import re
import subprocess
import sys

import pytest
import yaml

from nbvkit import _core
from nbvkit import config as cfgmod
from nbvkit.config import Config, load_config

ROOT = __import__("pathlib").Path(__file__).resolve().parent.parent


def test_python_defaults_equal_cpp_defaults():
    c = Config()
    cam, las = _core.DepthCameraOptions(), _core.LaserScannerOptions()
    for k in ("width", "height", "hfov_deg", "vfov_deg", "min_range", "max_range", "noise_k"):
        assert getattr(c.camera, k) == getattr(cam, k), k
    for k in ("fov_deg", "resolution_deg", "min_range", "max_range", "noise_sigma"):
        assert getattr(c.laser, k) == getattr(las, k), k
    import numpy as np

    np.testing.assert_allclose(
        _core.mount_transform(c.laser.mount_xyz, *c.laser.mount_rpy_deg), las.mount
    )
    np.testing.assert_allclose(
        _core.mount_transform(c.camera.mount_xyz, *c.camera.mount_rpy_deg), cam.mount
    )
    cl = _core.SurfaceCloudOptions()
    assert c.cloud.min_z is None  # no ground removal; the paper's scenarios: the core's 0.3 m
    assert load_config(overrides=["scenario=1"]).cloud.min_z == pytest.approx(cl.min_z)
    # the missions' camera voxel nests in the finest coverage cell; the paper's keeps the core's
    assert cl.voxel_size == 0.02
    assert c.cloud.camera_voxel == min(_core.EvaluationOptions().resolutions) / 2 == 0.025
    assert load_config(overrides=["scenario=3"]).cloud.camera_voxel == cl.voxel_size
    assert (
        c.map.resolution == _core.OccupancyMap.DEFAULT_RESOLUTION == _core.OccupancyMap().resolution
    )
    lo, hi = _core.OccupancyMap().bounds
    assert tuple(lo) == _core.OccupancyMap.DEFAULT_BOUNDS_MIN == (-20.0, -20.0, 0.0)
    assert tuple(hi) == _core.OccupancyMap.DEFAULT_BOUNDS_MAX == (20.0, 20.0, 10.0)
    vc = _core.ViewCameraModel.for_resolution(
        c.camera.hfov_deg, c.camera.vfov_deg, c.camera.max_range, c.map.resolution
    )
    assert (vc.rays_x, vc.rays_y) == (47, 34)


@pytest.mark.parametrize(
    "section",
    [
        cfgmod.MapConfig,
        cfgmod.UtilityConfig,
        cfgmod.VehicleConfig,
        cfgmod.TargetsConfig,
        cfgmod.ObservabilityConfig,
    ],
)
def test_sections_of_cpp_options_take_their_keys_defaults_and_docs_from_cpp(section):
    import numpy as np

    opts, mine = section.OPTIONS(), section()
    docs = section.OPTIONS.fields()
    assert section.CPP_FIELDS and set(section.CPP_FIELDS) <= set(docs)
    for k in section.CPP_FIELDS:
        np.testing.assert_equal(np.asarray(getattr(mine, k)), np.asarray(getattr(opts, k)), k)
        assert section.FIELD_DOCS[k] == docs[k]
    assert mine.options() == opts  # the section builds the very same C++ options


def test_every_bound_options_class_is_configurable_or_known_internal():
    mirrored = {
        c.__name__
        for s in (
            cfgmod.MapConfig,
            cfgmod.UtilityConfig,
            cfgmod.VehicleConfig,
            cfgmod.TargetsConfig,
            cfgmod.SymmetryConfig,
            cfgmod.ObservabilityConfig,
        )
        for c in s.OPTIONS_ALL
    }
    # set through their own config sections (sensors, clouds, symmetry) or by the mission
    # from other keys (the scoring camera from camera + map.resolution + utility.rays_*)
    elsewhere = {
        "DepthCameraOptions",
        "LaserScannerOptions",
        "SurfaceCloudOptions",
        "ViewCameraModel",
        "RaycastOptions",
        "EvaluationOptions",
    }
    bound = {n for n in dir(_core) if n.endswith("Options") or n == "ViewCameraModel"}
    assert bound - mirrored - elsewhere == set()


def test_paper_values():
    c = Config().with_overrides(["scenario=5"])
    assert (c.lattice.delta_d, c.lattice.delta_theta, c.lattice.sigma, c.lattice.alpha_max) == (
        1.0,
        math.pi / 4,
        1.5,
        5,
    )
    assert (c.lattice.stuck_threshold, c.lattice.stuck_window) == (0.005, 3)
    assert (c.entropy.threshold, c.entropy.window) == (0.001, 5)
    assert c.vehicle.collision_radius == 0.8 and c.symmetry.prediction_probability == 0.6
    assert c.profiling.waypoints == 5 and c.profiling.close_circle and c.profiling.return_to_start
    assert c.utility.name == "ig" and c.utility.require_occupied
    assert c.planner.generators == ("lattice",) and c.planner.terminations == ("entropy",)
    assert (c.workspace.margin_xy, c.workspace.margin_z) == (2.5, 2.5)


def test_shipped_yaml_is_the_default_and_round_trips(tmp_path):
    shipped = Config.from_yaml(ROOT / "configs" / "default.yaml")
    assert shipped == Config()
    p = tmp_path / "c.yaml"
    p.write_text(Config().with_overrides(["map.resolution=0.4", "scenario=1"]).to_yaml())
    back = Config.from_yaml(p)
    assert back.map.resolution == 0.4 and back.scenario == "1"


def test_a_section_given_as_a_mapping_is_merged_into_what_is_set(tmp_path):
    """``--set mesh.scale=2 --set mesh={up: y}`` keeps the scale (it was reset to 1), also over a
    config file's section and a later with_overrides; a key given again wins; a non-mapping for a
    section is still refused."""
    c = load_config(None, ["mesh.scale=2", "mesh={up: y}"])
    assert (c.mesh.scale, c.mesh.up) == (2.0, "y")
    f = tmp_path / "c.yaml"
    f.write_text("mesh: {scale: 3, shift: [1, 2, 3]}\nprofiling: {margin: 7}\n")
    c = load_config(f, ["mesh={up: y, scale: 4}"]).with_overrides({"mesh": {"up": "z"}})
    assert (c.mesh.scale, c.mesh.up, c.mesh.shift) == (4.0, "z", (1.0, 2.0, 3.0))
    assert c.profiling.margin == 7
    with pytest.raises(ValueError, match="mesh must be a mapping"):
        load_config(None, ["mesh.scale=2", "mesh=3"])


def test_overrides_and_rejections(tmp_path):
    c = load_config(
        None,
        [
            "max_iterations=7",
            "lattice.method=cgvs",
            "workspace.bounds_min=[0,0,0]",
            "workspace.bounds_max=[10,10,5]",
            "utility.rays_x=10",
        ],
    )
    assert (
        c.max_iterations == 7
        and c.lattice.method == "cgvs"
        and c.workspace.bounds_max == (10.0, 10.0, 5.0)
    )
    with pytest.raises(KeyError, match="map.resolutionn") as e:
        c.with_overrides(["map.resolutionn=0.1"])
    # the key meant, and the section's keys (it named the typo alone)
    assert "(did you mean 'map.resolution'?); known keys here: " in e.value.args[0], e.value
    assert "prob_hit" in e.value.args[0]
    with pytest.raises(KeyError, match="nope"):
        Config.from_dict({"nope": 1})
    with pytest.raises(KeyError, match="camera.colour"):
        Config.from_dict({"camera": {"colour": 1}})
    with pytest.raises(ValueError, match="map.resolution"):
        c.with_overrides(["map.resolution=0"])
    with pytest.raises(ValueError, match="utility.name"):
        c.with_overrides(["utility.name=magic"])
    for margin in ("0", "-1"):  # a profile flown on (or inside) what it has seen
        with pytest.raises(ValueError, match="profiling.margin"):
            c.with_overrides([f"profiling.margin={margin}"])
    with pytest.raises(ValueError, match="profiling.method"):
        c.with_overrides(["profiling.method=spiral"])
    with pytest.raises(ValueError, match="profiling.arcs"):
        c.with_overrides(["profiling.arcs=spiral"])
    with pytest.raises(ValueError, match="integer"):
        c.with_overrides(["max_iterations=2.5"])
    with pytest.raises(ValueError, match="key=value"):
        c.with_overrides(["max_iterations"])
    with pytest.raises(ValueError, match="start"):
        c.with_overrides(["start=7"])
    with pytest.raises(ValueError, match="finite"):
        c.with_overrides(["map.resolution=.nan"])
    with pytest.raises(ValueError, match="go together"):
        c.with_overrides(["workspace.bounds_min=[0,0,0]", "workspace.bounds_max=null"])
    bad = tmp_path / "bad.yaml"
    bad.write_text("- a list\n")
    with pytest.raises(ValueError, match="mapping"):
        Config.from_yaml(bad)
    with pytest.raises(FileNotFoundError):
        Config.from_yaml(tmp_path / "missing.yaml")
    # a key or value wrong in a file names the file (a run folder's config.yaml among many)
    for text, what in [("sxxd: 0\n", "unknown config key 'sxxd'"), ("start: 9\n", "start")]:
        bad.write_text(text)
        with pytest.raises((KeyError, ValueError)) as e:
            Config.from_yaml(bad)
        assert re.match(f"{re.escape(str(bad))}: .*{what}", e.value.args[0]), e.value.args[0]
    yaml.safe_load(c.to_yaml())  # serialisable


def test_shipped_yaml_is_generated_from_the_dataclasses():
    from nbvkit.config_docs import documented_yaml

    assert (ROOT / "configs" / "default.yaml").read_text() == documented_yaml()
    # the command the file's header names makes it
    cmd = [sys.executable, "-m", "nbvkit.config_docs"]
    made = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    assert made == documented_yaml()
    assert "python -m nbvkit.config_docs" in "".join(made.splitlines()[:2])


def test_core_type_stub_is_current():
    import ast

    from nbvkit._stubgen import stub

    text = (ROOT / "python" / "nbvkit" / "_core.pyi").read_text()
    assert (
        text == stub()
    ), "regenerate with: .venv/bin/python -m nbvkit._stubgen > python/nbvkit/_core.pyi"
    ast.parse(text)


def test_renamed_keys_still_load_with_a_deprecation_warning(tmp_path):
    """sampling -> lattice, termination -> entropy (sections named like their parts) and
    targets.coverage_cone_deg -> utility.coverage_cone_deg (one cone) load for one release."""
    f = tmp_path / "old.yaml"
    f.write_text("sampling: {sigma: 2.5}\ntermination: {window: 7}\n")
    with pytest.warns(DeprecationWarning, match="'sampling' is now 'lattice'"):
        c = Config.from_yaml(f)
    assert c.lattice.sigma == 2.5 and c.entropy.window == 7
    with pytest.warns(DeprecationWarning, match="now 'utility.coverage_cone_deg'"):
        c = load_config(overrides=["targets.coverage_cone_deg=60"])
    assert c.utility.coverage_cone_deg == 60.0
    assert "coverage_cone_deg" not in c.to_dict()["targets"]  # one home
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="both set"):
        Config.from_dict({"sampling": {"sigma": 2.0}, "lattice": {"sigma": 3.0}})
    # the resolved configuration is written under the current names only
    assert "sampling" not in c.to_dict() and "lattice" in c.to_dict()


def test_a_registered_scenario_setting_an_unknown_key_is_named(monkeypatch):
    """A script's scenario preset naming a key no section has: KeyError naming the scenario
    and the key when a configuration uses it (not an AttributeError from inside Config)."""
    import nbvkit
    from nbvkit.scenarios import SCENARIOS, Scenario

    for bad in ("nope.key", "planner.nope"):
        monkeypatch.setitem(SCENARIOS, "x", Scenario("a typo", {bad: 1}))
        with pytest.raises(KeyError, match=f"scenario 'x' sets '{bad}', which is not a config"):
            load_config(overrides=["scenario=x"])
    del SCENARIOS["x"]
    nbvkit.register_scenario("x", "a typo", {"nope.key": 1})  # through the public call
    with pytest.raises(KeyError, match="sets 'nope.key'"):
        load_config(overrides=["scenario=x"])
    del SCENARIOS["x"]


def test_a_config_pickles_and_copies():
    """A Config (so a Mission, a plugin part holding one) pickles: the sections generated from
    C++ options (settings.cpp_section) name the module that defines them, not nbvkit.settings."""
    import copy
    import pickle

    c = load_config(overrides=["scenario=3", "map.resolution=0.4", "lattice.sigma=2"])
    for name, section in c.sections():
        cls = type(section)
        if hasattr(cls, "OPTIONS"):
            assert pickle.loads(pickle.dumps(cls)) is cls, name
    for back in (pickle.loads(pickle.dumps(c)), copy.deepcopy(c), copy.copy(c)):
        assert back.to_dict() == c.to_dict() and back == c
    assert pickle.loads(pickle.dumps(c)).with_overrides(["start=2"]).to_dict() == (
        c.with_overrides(["start=2"]).to_dict()
    )


def test_bound_options_and_a_planning_context_pickle_and_copy():
    """The C++ options of a configuration's sections (a PlanningContext holds the surface-target
    options) pickle and copy with every field."""
    import copy
    import pickle

    from nbvkit.planning.parts import PlanningContext

    ctx = PlanningContext.of(load_config(overrides=["targets.frontier_weight=0.25"]))
    for back in (pickle.loads(pickle.dumps(ctx)), copy.deepcopy(ctx), copy.copy(ctx)):
        assert back.targets == ctx.targets and back.targets.frontier_weight == 0.25
        assert back.utility == ctx.utility
    opts = load_config(overrides=["map.prob_hit=0.8"]).map.options()
    assert copy.deepcopy(opts) == opts and pickle.loads(pickle.dumps(opts)).prob_hit == 0.8


def test_every_bound_options_class_pickles_and_copies_with_its_fields():
    """Each C++ options class nbvkit binds (the camera's and the laser's too, which no section
    wraps) pickles, copies and deep-copies as its fields; a pickled value out of range is
    refused on loading, as the constructor refuses it."""
    import copy
    import pickle

    from nbvkit import _core

    classes = [
        c
        for c in vars(_core).values()
        if isinstance(c, type) and hasattr(c, "fields") and hasattr(c, "to_dict")
    ]
    assert {"DepthCameraOptions", "LaserScannerOptions", "OccupancyMapOptions"} <= {
        c.__name__ for c in classes
    }
    for cls in classes:
        o = cls()
        for back in (pickle.loads(pickle.dumps(o)), copy.deepcopy(o), copy.copy(o)):
            assert type(back) is cls and back == o and back is not o, cls.__name__
    cam = _core.DepthCameraOptions(max_range=20.0)
    assert pickle.loads(pickle.dumps(cam)).max_range == 20.0
    state = pickle.dumps(cam).replace(b"max_range", b"max_rangX")
    with pytest.raises(TypeError, match="unknown DepthCameraOptions option 'max_rangX'"):
        pickle.loads(state)


@pytest.mark.parametrize(
    "key, value, match",
    [
        # blamed the utility section
        ("map.resolution", -1, r"config key 'map.resolution' must be >= 0.0001, got -1"),
        ("map.prob_hit", 2.0, r"config key 'map.prob_hit'"),  # was accepted
        ("lattice.sigma", -5, r"config key 'lattice.sigma'"),  # was accepted
        ("map.resolution", "fine", r"config key 'map.resolution' must be a number"),
        ("max_iterations", -3, r"config key 'max_iterations'"),
    ],
)
def test_a_scenarios_preset_is_checked_naming_the_scenario_and_key(monkeypatch, key, value, match):
    from nbvkit import scenarios

    monkeypatch.setitem(scenarios.SCENARIOS, "audit_bad", scenarios.Scenario("bad", {key: value}))
    with pytest.raises(ValueError, match=f"^scenario 'audit_bad' sets {key} = .*: {match}"):
        load_config(overrides=["scenario=audit_bad"])
    # a value the user sets wins over the preset's
    default = Config().to_dict()
    for part in key.split("."):
        default = default[part]
    fix = f"{key}={3 if default is None else default}"
    assert load_config(overrides=["scenario=audit_bad", fix]).scenario == "audit_bad"


def test_a_path_object_is_taken_for_a_path_key(tmp_path):
    """load_config takes a pathlib.Path, but mesh.path refused one ("must be a string, got
    PosixPath"): a path object is its text; anything else not a string is still refused."""
    from pathlib import Path

    mesh = tmp_path / "m.obj"
    assert Config.from_dict({"mesh": {"path": mesh}}).mesh.path == str(mesh)
    assert Config().with_overrides([f"mesh.path={mesh}"]).mesh.path == str(Path(mesh))
    with pytest.raises(ValueError, match="'mesh.path' must be a string, got"):
        Config.from_dict({"mesh": {"path": [str(mesh)]}})


def test_an_override_of_an_unknown_section_names_the_sections_and_the_plugin_hint():
    """`--set rings.count=16` without the plugin that registers `ring` (or misspelt) said only
    "unknown config key 'rings'"; a key set inside a plain value said the value was unknown."""
    with pytest.raises(KeyError) as e:
        load_config(overrides=["rings.count=16"])
    said = e.value.args[0]
    assert "unknown config key 'rings'; known keys here: budget, camera" in said
    assert "--plugin FILE" in said and said.endswith("(in override 'rings.count')")
    with pytest.raises(KeyError, match=r"'camera.heigth' \(did you mean 'camera.height'\?\)"):
        load_config(overrides=["camera.heigth.x=1"])
    with pytest.raises(KeyError, match="config key 'seed' is a value, not a section"):
        load_config(overrides=["seed.x=1"])
