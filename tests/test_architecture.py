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
