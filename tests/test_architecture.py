"""docs/ARCHITECTURE.md names real files and real registries."""
from __future__ import annotations

import re
from pathlib import Path

import nbvkit
from nbvkit import _core
from nbvkit.planning.registry import GENERATORS, TERMINATIONS

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "ARCHITECTURE.md").read_text()


def test_every_path_the_architecture_names_exists():
    paths = set(re.findall(r"`((?:cpp|python|configs|tests|docs|meshes|bench)/[^`<>*]+)`", DOC))
    assert len(paths) > 30
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert missing == []


def test_every_registered_part_has_its_own_file():
    for kind, registry in (("generators", GENERATORS), ("terminations", TERMINATIONS)):
        for cls in registry.values():
            module = cls.__module__.split(".")
            assert module[-2] == kind, cls
            assert (ROOT / "python" / "nbvkit" / "planning" / kind / f"{module[-1]}.py").exists()
    utilities = (ROOT / "cpp" / "src" / "utilities" / "registry.hpp").read_text()
    for name in _core.utility_names():
        assert re.search(rf'X\("{name}",', utilities), name


def test_every_scenario_is_documented_by_the_cli():
    from nbvkit.cli import build_parser

    text = build_parser()._subparsers._group_actions[0].choices["run"].format_help()
    for name in nbvkit.SCENARIOS:
        assert name in text


def test_each_part_keeps_its_settings_beside_it_under_its_registry_name():
    from nbvkit.config import Config

    cfg = Config()
    for registry in (GENERATORS, TERMINATIONS):
        for name, cls in registry.items():
            assert cls.Settings.__module__ == cls.__module__, name  # in the part's own file
            assert isinstance(cfg.section(name), cls.Settings), name  # its section: its name


def test_how_to_add_a_generator_is_one_file_and_one_registry_line(tmp_path):
    """docs/ARCHITECTURE.md's "How to add": a copy of the package with one new file in
    planning/generators/ and one line added to GENERATORS configures and flies the new part;
    nothing else is edited."""
    import shutil
    import subprocess
    import sys

    pkg = tmp_path / "nbvkit"
    shutil.copytree(ROOT / "python" / "nbvkit", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (pkg / "planning" / "generators" / "hover.py").write_text(
        "from dataclasses import dataclass\n\n"
        "from ...settings import within\n"
        "from ..parts import Proposal\n\n\n"
        "@dataclass(frozen=True)\n"
        "class HoverConfig:\n"
        "    turns: int = within(3, 1, 100)  # views, turning on the spot\n\n\n"
        "class Hover:\n"
        "    Settings = HoverConfig\n\n"
        "    def __init__(self, settings, context):\n"
        "        self.left = settings.turns\n\n"
        "    def propose(self, world):\n"
        "        if self.left == 0:\n"
        "            return None\n"
        "        p = world.state.pose.copy()\n"
        "        p[3] += 1.0\n"
        "        return Proposal(p[None, :4], 'hover')\n\n"
        "    def feedback(self, world, proposal, step):\n"
        "        self.left -= step is not None\n"
    )
    reg = pkg / "planning" / "registry.py"
    text = reg.read_text()
    line = '    "tour": CoverageTour,'
    assert line in text
    reg.write_text(text.replace(line, line + '\n    "hover": __import__("nbvkit.planning.'
                                'generators.hover", fromlist=["Hover"]).Hover,'))  # fmt: skip
    script = (
        "import nbvkit\n"
        "cfg = nbvkit.load_config(overrides=['planner.generators=[hover]', 'hover.turns=2',\n"
        "    'planner.min_gain=0', 'profiling.enabled=false', 'symmetry.mode=none',\n"
        "    'map.resolution=0.4', 'evaluation.gt_density=50', 'progress=false',\n"
        "    'evaluation.coverage_every=0', 'vehicle.start_clear_radius=30',\n"
        "    'mesh.path=" + str(ROOT / "meshes" / "fixtures" / "cube.obj") + "'])\n"
        "s = nbvkit.Mission(cfg).run()\n"
        "print(s['generators'], s['iterations'], s['termination'], cfg.hover.turns)\n"
    )
    p = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PYTHONPATH": str(tmp_path), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"},
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["['hover']", "2", "coverage_complete", "2"]
