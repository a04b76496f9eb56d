"""nbvkit's own warnings on the console: one line each, as its errors are ("nbvkit run: warning:
..."), not with the file and line of nbvkit's code that raised them, in the command's process
and in the worker processes that fly its runs (`nbvkit sweep`, `compare`, `table`), each of those
naming its run. A plugin's warning (raised in its own file) prints as Python prints it."""
from __future__ import annotations

import contextlib
import sys
import warnings
from pathlib import Path

_PACKAGE = str(Path(__file__).resolve().parent)
_prog = None  # the command whose warnings print on one line now (own_warnings), or None
_run = None  # the run of an experiment being flown in this process (for_run), or None


def _one_line(prog: str, show):
    def one_line(message, category, filename, lineno, file=None, line=None):
        if not str(Path(filename).resolve()).startswith(_PACKAGE):
            return show(message, category, filename, lineno, file, line)
        run = f"run {_run}: " if _run else ""
        print(f"{prog}: warning: {run}{message}", file=sys.stderr if file is None else file)

    return one_line


@contextlib.contextmanager
def own_warnings(prog: str):
    """Within it, nbvkit's warnings print as `prog: warning: MESSAGE`."""
    global _prog
    show, before = warnings.showwarning, _prog
    warnings.showwarning, _prog = _one_line(prog, show), prog
    try:
        yield
    finally:
        warnings.showwarning, _prog = show, before


@contextlib.contextmanager
def for_run(run_id: str):
    """Within it, nbvkit's one-line warnings name the run they came from ("nbvkit sweep: warning:
    run RUN_ID: ..."): an experiment's runs, flown side by side in its workers, warn apart."""
    global _run
    before, _run = _run, run_id
    try:
        yield
    finally:
        _run = before


def current_prog():
    """The command printing one-line warnings now (own_warnings), for the workers it starts."""
    return _prog


def install(prog) -> None:
    """A worker process's warnings printed as its command's (`prog`; None: as Python prints
    them), for the rest of its life."""
    if prog:
        warnings.showwarning = _one_line(prog, warnings.showwarning)
