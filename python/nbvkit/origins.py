"""Where a registered part or scenario came from: the file that defined it, or the file that
called register_* (a plugin file, a script, a notebook). Named when a name is registered twice:
two plugin files, or one file run a second time under another module name."""
from __future__ import annotations

import inspect
import sys
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def caller() -> tuple[str | None, str | None]:
    """(file, module name) of the innermost frame of the call stack outside the nbvkit package:
    who calls register_* now; (None, None) when there is none."""
    frame = sys._getframe(1)
    while frame is not None:
        try:
            inside = _PACKAGE in Path(frame.f_code.co_filename).resolve().parents
        except (OSError, ValueError):
            inside = False
        if not inside:
            return frame.f_code.co_filename, frame.f_globals.get("__name__")
        frame = frame.f_back
    return None, None


def defined_in(obj) -> str | None:
    """The source file of the class or function `obj`; None when it has none."""
    try:
        return inspect.getsourcefile(obj) or inspect.getfile(obj)
    except (TypeError, OSError):
        return None


def clash(first: str | None, first_module: str | None = None) -> str:
    """For a name registered twice: " (registered from FIRST; this one from FILE)", FIRST where
    the registered one came from and FILE the caller's; from the same file, as the same module
    (`first_module`, where known): the file registers the name twice, else it runs a second time
    as the module it runs as now; "" when neither file is known."""
    now, module = caller()
    if first is None and now is None:
        return ""
    try:
        same = (
            first is not None and now is not None and Path(first).resolve() == Path(now).resolve()
        )
    except (OSError, ValueError):
        same = False
    if same and first_module is not None and first_module == module:
        return f" (registered from {first}, which registers the name twice)"
    if same:
        again = f" as module {module!r}" if module else ""
        return f" (registered from {first}; this one from the same file, run a second time{again})"
    return f" (registered from {first or 'a script'}; this one from {now or 'a script'})"


#: (kind, name) -> (file, module) of the register_* call that registered each part or scenario
#: of the user's (caller: a plugin file, a module imported, a script)
REGISTERED: dict = {}


def note(kind: str, name: str) -> None:
    """Records who registers the part or scenario `name` of `kind` now (its register_* call)."""
    REGISTERED[(kind, name)] = caller()


def source(kind: str, name: str) -> str:
    """Where the part `name` of `kind` was registered, as a run's summary records it
    (parts_from): the file whose code called register_* (a plugin file, a module an import ran);
    "a script" for the program's own code (__main__: a script, `python -c`, a notebook's cell,
    with its file where it has one), which is no file to load again."""
    file, module = REGISTERED.get((kind, name), (None, None))
    if file is None or file.startswith("<"):
        return "a script"
    return f"a script ({file})" if module == "__main__" else file
