"""The benchmarks (bench/) keep up with the package: every name a script imports from nbvkit, and
every attribute it reads off an nbvkit module it imported, exists. The scripts are read, not run
(most fly missions for minutes); a rename or a move in the package that left a script behind
fails here, not in the hands of the next one to measure."""
from __future__ import annotations

import ast
import importlib
import types
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"
SCRIPTS = sorted(BENCH.glob("*.py"))


def _resolve(module: str, name: str):
    """What `from module import name` gives: an attribute of the module or its submodule; None
    when neither exists."""
    mod = importlib.import_module(module)
    if hasattr(mod, name):
        return getattr(mod, name)
    try:
        return importlib.import_module(f"{module}.{name}")
    except ModuleNotFoundError:
        return None


def missing_names(source: str) -> list[str]:
    """The nbvkit names a script's source uses that do not exist, as "line N: what"."""
    tree = ast.parse(source)
    modules: dict[str, types.ModuleType] = {}  # a local name bound to an nbvkit module
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] != "nbvkit":
                    continue
                try:
                    mod = importlib.import_module(a.name)
                except ModuleNotFoundError:
                    out.append(f"line {node.lineno}: import {a.name}")
                    continue
                if a.asname:
                    modules[a.asname] = mod
                else:
                    modules["nbvkit"] = importlib.import_module("nbvkit")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] != "nbvkit":
                continue
            try:
                importlib.import_module(node.module)
            except ModuleNotFoundError:
                out.append(f"line {node.lineno}: from {node.module} import ...")
                continue
            for a in node.names:
                got = _resolve(node.module, a.name)
                if got is None:
                    out.append(f"line {node.lineno}: from {node.module} import {a.name}")
                elif isinstance(got, types.ModuleType):
                    modules[a.asname or a.name] = got
    for node in ast.walk(tree):  # attributes read (or patched) off those modules
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in modules
            and not isinstance(node.ctx, ast.Del)
        ):
            mod = modules[node.value.id]
            if _resolve(mod.__name__, node.attr) is None:
                out.append(f"line {node.lineno}: {mod.__name__}.{node.attr}")
    return out


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_a_benchmark_uses_only_names_the_package_has(script):
    assert missing_names(script.read_text()) == []


def test_the_check_finds_a_name_the_package_lost():
    """The check itself: a name a module does not hold, a missing submodule and an attribute
    patched on a module that lost it are each found, on the line that names them; names that
    moved but are still imported where a script reads them are not."""
    source = (
        "from nbvkit.flight import ReturnPaths, find_nothing\n"
        "from nbvkit import flight, flight_home\n"
        "flight_home._searches = None\n"
        "flight._searches = None\n"
        "import nbvkit.no_such_module\n"
    )
    assert missing_names(source) == [
        "line 1: from nbvkit.flight import find_nothing",
        "line 5: import nbvkit.no_such_module",
        "line 4: nbvkit.flight._searches",
    ]
