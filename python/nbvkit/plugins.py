"""Your own planner parts from a file: ``load_plugin("my_parts.py")`` (``nbvkit run --plugin
my_parts.py``) imports it; the file registers its parts with nbvkit.register_generator,
register_termination or register_utility. The configuration then has their sections and
accepts their names, and sweeps load the same files in every worker process.
docs/PLUGINS.md has a worked example."""
from __future__ import annotations

import hashlib
import importlib.util
import sys
from pathlib import Path

from .limits import check_input_file

#: The plugin files loaded in this process, in order (the sweeps' workers load them too).
LOADED: list[str] = []


def load_plugin(path) -> None:
    """Imports the Python file `path` once (FileNotFoundError if missing; its own errors
    propagate, with the file named in the traceback, and what it registered before it failed
    is forgotten: the file fixed loads again under the same names). A file already imported as
    a module (``import my_parts``) is not run again, only noted for the sweeps' workers. Its
    folder is put on sys.path, as Python does for a script: the file imports its neighbours."""
    p = check_input_file(path, "plugin file").resolve()
    if str(p) in LOADED:
        return
    if str(p.parent) not in sys.path:
        sys.path.append(str(p.parent))
    if any(_same_file(m, p) for m in list(sys.modules.values())):
        LOADED.append(str(p))
        return
    name = "nbvkit_plugin_" + hashlib.sha1(str(p).encode()).hexdigest()[:12]
    spec = importlib.util.spec_from_file_location(name, p)
    if spec is None or spec.loader is None:
        raise ValueError(f"plugin file {p} is not a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    tables = _tables()
    before = [set(t) for t in tables]
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        for table, had in zip(tables, before):  # what it registered before it failed
            for key in set(table) - had:
                del table[key]
        raise
    LOADED.append(str(p))


def _same_file(module, path) -> bool:
    """Whether `module` was imported from the file `path`."""
    f = getattr(module, "__file__", None)
    try:
        return f is not None and Path(f).resolve() == path
    except (OSError, ValueError, TypeError):
        return False


def _tables() -> tuple:
    """The tables a plugin file registers into (parts, utilities, scenarios)."""
    from .planning import registry
    from .scenarios import SCENARIOS

    return registry.GENERATORS, registry.TERMINATIONS, registry.UTILITIES, SCENARIOS


def load_plugins(paths) -> None:
    for p in paths or ():
        load_plugin(p)


def loaded() -> tuple[str, ...]:
    return tuple(LOADED)
