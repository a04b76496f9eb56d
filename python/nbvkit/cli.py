"""The ``nbvkit`` command line: one subcommand per module in nbvkit.commands."""
from __future__ import annotations

import argparse
import importlib
import re
import sys

from .console import own_warnings
from .interrupts import Terminated, terminate_as_interrupt
from .plugins import PluginLoadError, load_plugins

# name -> module in nbvkit.commands; each module defines register(subparsers) and run(args).
#: The commands that fly missions or read a run's configuration: they take --plugin FILE (your
#: own planner parts; a run flown with them has their sections in its config.yaml).
PLUGIN_COMMANDS = ("run", "compare", "sweep", "table", "export", "evaluate")
COMMANDS = {
    "scan": "scan",
    "evaluate": "evaluate",
    "run": "run",
    "table": "table",
    "sweep": "sweep",
    "compare": "compare",
    "export": "export",
}


class _Parser(argparse.ArgumentParser):
    """argparse, reading -5e-1 and -1.5E3 as negative numbers, not options, as it reads -5 and
    -0.5 (--mesh-shift -5e-1 0 0, --origin -3.3e1 ...). Its subcommands' parsers are of it too."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):
        if "--planner: invalid choice" in message:  # (the planners a plugin registers)
            message += "; a scenario of your own is known once its plugin is loaded: --plugin FILE"
        super().error(message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="nbvkit",
        description="Next-best-view reconstruction of large structures by a simulated UAV.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, module in COMMANDS.items():
        mod = importlib.import_module(f"nbvkit.commands.{module}")
        p = mod.register(sub)
        p.set_defaults(_run=mod.run)
        if name in PLUGIN_COMMANDS:
            p.add_argument(
                "--plugin",
                action="append",
                default=[],
                metavar="FILE",
                help="a Python file that registers your own planner parts and scenarios "
                "(nbvkit.register_generator / register_termination / register_utility / "
                "register_scenario) before "
                "the configuration is read (a run flown with it: to read its config.yaml); "
                "repeatable (docs/PLUGINS.md)",
            )
    return parser


def _plugin_files(argv) -> list:
    """The --plugin files named in argv (loaded before the parser is built, so that their
    scenarios are choices of --scenario / --planners)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--plugin", action="append", default=[])
    return pre.parse_known_args(argv)[0].plugin


def _load_plugins(prog: str, files: list) -> None:
    """Loads the --plugin `files`; a line on stderr when together they registered nothing (a
    file without its register_* call: the configuration naming its parts would only say
    "unknown"). Counted over all the files: one may load or import another's parts."""
    from .planning import registry
    from .scenarios import SCENARIOS

    def names():
        tables = (registry.GENERATORS, registry.TERMINATIONS, registry.UTILITIES, SCENARIOS)
        return [dict(t) for t in tables]

    before = names()
    load_plugins(files, wrap=True)
    if files and names() == before:
        print(
            f"{prog}: warning: the plugin files ({', '.join(map(str, files))}) registered no "
            "part or scenario: a part is known once its file calls nbvkit.register_generator, "
            "register_termination, register_utility or register_scenario (docs/PLUGINS.md)",
            file=sys.stderr,
        )


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    first = next((a for a in argv if not a.startswith("-")), None)
    prog = f"nbvkit {first}" if first in COMMANDS else "nbvkit"
    try:  # a plugin file's own errors (and its exit) are PluginLoadError, naming it
        _load_plugins(prog, _plugin_files(argv))
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except (FileNotFoundError, ValueError, OSError, PluginLoadError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with terminate_as_interrupt(), own_warnings(f"nbvkit {args.command}"):
            # a kill or a hang-up cleans up as Ctrl-C does
            return int(args._run(args) or 0)
    except KeyboardInterrupt as e:
        by = f" by {e}" if isinstance(e, Terminated) else ""
        _notes(e)
        print(f"nbvkit {args.command}: interrupted{by}", file=sys.stderr)
        return 130
    except Exception as e:
        from .planning.parts import PartContractError, raised_by_a_part

        own = raised_by_a_part(e)  # its own ZeroDivisionError, AttributeError, ...
        if not (isinstance(e, (*_CLEAN, PartContractError)) or own):
            raise  # nbvkit's own bug: its whole traceback
        msg = e.args[0] if isinstance(e, KeyError) and e.args else e
        if own and (isinstance(e, KeyError) or not isinstance(e, _CLEAN)):
            msg = f"{type(e).__name__}: {msg}"  # its type is part of the news ("foo": a key)
        _plugin_traceback(e)
        _notes(e)  # (the part that raised it; what was lost and kept: RunFolder.saving, ...)
        print(f"nbvkit {args.command}: error: {msg}", file=sys.stderr)  # the last line
        return 2


#: What main prints after a command's own lines (the except clauses above; a SystemExit's code is
#: printed by no one): a command's line about its stop points at it, or else says the stop itself.
PRINTED = (KeyboardInterrupt, Exception)
#: the errors a command reports in one line (bad input, a missing file, a failed write); also
#: a planner part's broken contract (PartContractError) and any exception a part raised
_CLEAN = (FileNotFoundError, ValueError, KeyError, RuntimeError, OSError)


def _plugin_traceback(e: BaseException) -> None:
    """For an error a plugin's part raised: the traceback's frames in the plugin files (or the
    whole traceback, for a part from another file), before its notes and the one-line error.
    nbvkit's own errors (a bad key, a missing file) print nothing here."""
    from .plugins import plugin_traceback

    lines = plugin_traceback(e)
    if lines:
        print("Traceback (the plugin's frames, most recent call last):", file=sys.stderr)
        print("".join(lines).rstrip("\n"), file=sys.stderr)


def _notes(e: BaseException) -> None:
    """An exception's notes (Python 3.11+), a line each, before the one-line error (the last)."""
    for note in getattr(e, "__notes__", ()):
        print(note, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
