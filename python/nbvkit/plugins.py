"""Your own planner parts from a file: ``load_plugin("my_parts.py")`` (``nbvkit run --plugin
my_parts.py``) imports it; the file registers its parts with nbvkit.register_generator,
register_termination or register_utility. The configuration then has their sections and
accepts their names, and sweeps load the same files in every worker process.
docs/PLUGINS.md has a worked example."""
from __future__ import annotations

import hashlib
import importlib.util
import sys
import threading
import traceback
from pathlib import Path

from .limits import add_note, check_input_file, shorten
from .scenarios import BUILT_IN as BUILT_IN_SCENARIOS
from .scenarios import SCENARIOS as _SCENARIOS

#: The plugin files loaded in this process, in order (the sweeps' workers load them too).
LOADED: list[str] = []
#: path -> SHA-256 of the content each file had when it was loaded (recorded with each run).
DIGESTS: dict[str, str] = {}
#: path -> the names (generator, termination, utility, scenario) each file registered as it ran;
#: a file found imported already (not run again) registered what its module holds.
REGISTERED: dict[str, set] = {}
#: the files found imported already: their REGISTERED is what their module holds, a guess
GUESSED: set[str] = set()
_LOCK = threading.RLock()


class PluginLoadError(RuntimeError):
    """A plugin file's own code failed as it was loaded, or exited (SystemExit): "plugin file
    PATH failed to load: TYPE: message (line N)". `path`: the file; the error is its
    __cause__."""

    def __init__(self, path, error: BaseException):
        self.path = str(path)
        super().__init__(f"plugin file {path} failed to load: {_load_problem(path, error)}")


def _load_problem(path, e: BaseException) -> str:
    """The "TYPE: message (line N)" of the error `e` a plugin file's code raised as it loaded:
    the line is the file's innermost frame in the traceback (or the SyntaxError's own place,
    its file named when it is another: a module the plugin imported)."""
    key = str(path)
    if isinstance(e, SyntaxError):
        text, filename, line = e.msg, e.filename, e.lineno
    else:
        text, filename, line = str(e), None, None
        for f in traceback.extract_tb(e.__traceback__):
            if f.filename == key:
                filename, line = f.filename, f.lineno
    text = text if len(text) <= 300 else text[:300] + "..."  # a hostile message may be huge
    what = type(e).__name__ + (f": {text}" if text else "")
    if isinstance(e, SystemExit):
        what = f"SystemExit({shorten(e.code)})"
    if line is not None:
        what += f" (line {line})" if filename == key else f" ({filename}, line {line})"
    return what + (": a plugin file must not exit" if isinstance(e, SystemExit) else "")


def load_plugin(path, sha256: str | None = None, wrap: bool = False) -> None:
    """Imports the Python file `path` (FileNotFoundError if missing; its own errors propagate,
    with the file named in the traceback, and what it registered before it failed is as it was:
    the file fixed loads again under the same names). A file loaded before is not run again
    unless its content changed since: then it runs anew, its parts replacing those it had
    registered (a notebook's edited file, a long-lived worker's). A file already imported as a
    module (``import my_parts``) is not run again, only noted for the sweeps' workers. Its folder
    is put on sys.path, as Python does for a script: the file imports its neighbours. It runs as
    the module of its own name when that is free (_module_name): ``import my_parts`` after it is
    the same module. A load that fails forgets the modules of yours it imported (_roll_back).
    `sha256`: the content expected (a sweep's worker, the parent's): a ValueError if it differs.
    The content run is the content hashed (read once; no cached bytecode). A file that exits
    as it loads (SystemExit) is a PluginLoadError naming it, never an exit of this process; with
    `wrap`, so is every error its code raises (the command line's message; KeyboardInterrupt
    stays an interrupt)."""
    with _LOCK:  # a Dask worker's threads may load at once
        p = check_input_file(path, "plugin file").resolve()
        key = str(p)
        if key in LOADED and sha256 is not None and DIGESTS[key] == sha256:
            return  # the content expected is the one loaded (the file may have changed since)
        source = p.read_bytes()
        digest = hashlib.sha256(source).hexdigest()
        if sha256 is not None and digest != sha256:
            raise ValueError(_changed(p, sha256, digest, "the runs were started with"))
        if key not in LOADED or DIGESTS[key] != digest:
            _run_file(p, source, digest, wrap)


def _run_file(p: Path, source: bytes, digest: str, wrap: bool = False) -> None:
    """load_plugin's import of `p` (`source`, its content, of SHA-256 `digest`; `wrap`: see
    load_plugin)."""
    if b"\0" in source:  # (compile's error named no file)
        raise ValueError(f"plugin file {p} holds a NUL byte: it is no Python source")
    key = str(p)
    again = key in LOADED
    if str(p.parent) not in sys.path:
        sys.path.append(str(p.parent))
    imported = [m for m in list(sys.modules.values()) if _same_file(m, p)]
    if imported and not again:
        LOADED.append(key)
        DIGESTS[key] = digest
        REGISTERED[key] = _held_by(imported[0])
        GUESSED.add(key)
        return
    name = _module_name(p)
    spec = importlib.util.spec_from_file_location(name, p)
    if spec is None or spec.loader is None:
        raise ValueError(f"plugin file {p} is not a Python module")
    module = importlib.util.module_from_spec(spec)
    modules = dict(sys.modules)
    sys.modules[name] = module
    tables = _tables()
    objects = [dict(t) for t in tables]
    state = (list(LOADED), dict(DIGESTS), dict(REGISTERED), set(GUESSED))
    mine = _own_names(key) if again else set()
    for t in tables:  # loaded again: its names are free for it
        for n in mine:
            t.pop(n, None)
    try:
        exec(compile(source, key, "exec", dont_inherit=True), module.__dict__)
    except BaseException as e:
        _roll_back(modules, name)
        for table, was in zip(tables, objects):  # what it registered or replaced before it failed
            table.clear()
            table.update(was)
        for now, was in zip((LOADED, DIGESTS, REGISTERED, GUESSED), state):
            now.clear()  # a plugin file it loaded is unloaded with it
            (now.extend if isinstance(now, list) else now.update)(was)
        if isinstance(e, PluginLoadError) or not (
            isinstance(e, SystemExit) or (wrap and isinstance(e, Exception))
        ):
            own = isinstance(e, Exception) and not isinstance(e, PluginLoadError)
            if own:  # (its own type kept)
                add_note(e, f"raised while loading the plugin file {p}")
            raise
        raise PluginLoadError(p, e) from e
    # what it registered: new names, names it took over (replace=True) from a script, and its
    # own names of the last load registered again (the same object: a part imported from a
    # module of its own is not built anew)
    registered = {
        k
        for t, was in zip(tables, objects)
        for k, v in t.items()
        if k in mine or k not in was or was[k] is not v
    }
    if key in GUESSED:  # what an imported module only held, it did not register: kept
        for t, was in zip(tables, objects):
            for n in mine:
                if n in was and n not in t:
                    t[n] = was[n]
        GUESSED.discard(key)
    if not again:
        LOADED.append(key)
    DIGESTS[key] = digest
    REGISTERED[key] = registered


def _module_name(p: Path) -> str:
    """The module name a plugin file runs as: its own (``my_parts``) when ``import my_parts``
    would find this very file (its folder is on sys.path) and no other module holds that name,
    so that importing it after loading it (or from another plugin file) gives the same module
    (its parts registered once, its types the same); else a name of its own."""
    stem = p.stem
    held = sys.modules.get(stem)
    if stem.isidentifier() and (held is None or _same_file(held, p)):
        importlib.invalidate_caches()  # a file written since the folder was last listed
        try:
            spec = importlib.util.find_spec(stem) if held is None else held.__spec__
            if spec is not None and spec.origin and Path(spec.origin).resolve() == p:
                return stem
        except (ImportError, ValueError, AttributeError, OSError):
            pass
    return "nbvkit_plugin_" + hashlib.sha1(str(p).encode()).hexdigest()[:12]


def _roll_back(modules: dict, name: str) -> None:
    """After a plugin file failed to load: sys.modules as it was (`modules`) for the module it
    ran as (`name`) and for the modules of your own it imported (files outside the Python
    installation and nbvkit), so that once fixed they run again and register their parts anew.
    Modules of installed packages it imported stay (some cannot be imported twice)."""
    import sysconfig

    lib = [v for k, v in sysconfig.get_paths().items() if "lib" in k]
    installed = {Path(d).resolve() for d in (*lib, sys.prefix, sys.base_prefix)}
    installed.add(Path(__file__).resolve().parent)
    for m in [m for m in sys.modules if m not in modules or sys.modules[m] is not modules[m]]:
        f = getattr(sys.modules[m], "__file__", None)
        try:
            ours = f is not None and str(f).endswith(".py")
            ours = ours and not any(d in Path(f).resolve().parents for d in installed)
        except (OSError, ValueError, TypeError):
            ours = False
        if m == name or ours:
            if m in modules:
                sys.modules[m] = modules[m]
            else:
                del sys.modules[m]


def _own_names(key: str) -> set:
    """The names the loaded file `key` registered that are neither nbvkit's nor another file's."""
    from .planning import registry

    others = set().union(*(v for k, v in REGISTERED.items() if k != key and k in LOADED))
    return REGISTERED[key] - others - set(registry.BUILT_IN) - BUILT_IN_SCENARIOS


def _changed(p: Path, was: str, now: str, what: str) -> str:
    return (
        f"plugin file {p} changed: its content's SHA-256 is {now[:12]}..., {what} {was[:12]}...;"
        f" load it again (nbvkit.load_plugin({str(p)!r}), or --plugin) and start the runs again"
    )


def run_plugins_hint(folder) -> str:
    """What reading the run folder `folder`'s config.yaml needs and this process lacks: "the run
    FOLDER was flown with the plugin file(s) A, B: give them with --plugin ..." naming the files
    its summary.json records (`plugins`) that are not loaded here; "" when none is."""
    from .runfolder import read_summary

    try:
        summary = read_summary(folder)
        paths = [str(f["path"]) for f in summary.get("plugins") or []]
        # parts registered by a module the run's process imported (recorder: parts_from)
        paths += [str(f) for f in (summary.get("parts_from") or {}).values()]
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return ""
    missing = [f for f in paths if f not in LOADED and not f.startswith("a script")]
    missing = list(dict.fromkeys(missing))
    if not missing:
        return ""
    files = ", ".join(missing)
    return (
        f"the run {folder} was flown with the plugin file{'s' if len(missing) > 1 else ''} "
        f"{files}: give {'each' if len(missing) > 1 else 'it'} with --plugin FILE "
        "(in Python: nbvkit.load_plugin(FILE)) to read its configuration"
    )


def check_unchanged() -> None:
    """ValueError naming the first plugin file loaded in this process whose content changed since
    (runs started now would fly the old parts under the new file's name, or the new ones in
    workers)."""
    for key in LOADED:
        p = Path(key)
        try:
            now = hashlib.sha256(p.read_bytes()).hexdigest()
        except OSError as e:
            raise ValueError(f"plugin file {p} can no longer be read: {e.strerror}") from None
        if now != DIGESTS[key]:
            raise ValueError(_changed(p, DIGESTS[key], now, "this process loaded"))


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


def _held_by(module) -> set:
    """The registered names whose part (class or function) the module `module` holds (defined or
    imported there): what a file imported before it was loaded registered. Its scenarios cannot
    be told from others: all that are not nbvkit's count as its (never refused wrongly)."""
    from .planning import registry

    held = {id(v) for v in vars(module).values()}
    names = {name for t in _tables()[:3] for name, obj in t.items() if id(obj) in held}
    return (names - set(registry.BUILT_IN)) | (set(_SCENARIOS) - BUILT_IN_SCENARIOS)


def script_only() -> dict:
    """{name: kind} of the parts (generator, termination, utility) and scenarios registered in
    this process but by no plugin file: the worker processes of a sweep cannot know them."""
    from .planning import registry

    known = set().union(*REGISTERED.values())
    out = {}
    for kind, table, shipped in (
        ("generator", registry.GENERATORS, registry.BUILT_IN),
        ("termination", registry.TERMINATIONS, registry.BUILT_IN),
        ("utility", registry.UTILITIES, ()),
        ("scenario", _SCENARIOS, BUILT_IN_SCENARIOS),
    ):
        for n in table:
            if n not in shipped and n not in known:
                out.setdefault(n, kind)
    return out


def loaded_files() -> list[dict]:
    """The plugin files loaded in this process: [{"path", "sha256" (of the content loaded)}]."""
    return [{"path": p, "sha256": DIGESTS[p]} for p in LOADED]


def flown_files(config) -> list[dict]:
    """The loaded plugin files (loaded_files) a run of `config` depends on: every one where it
    flies a part that is not nbvkit's own (registry.part_sources; a part's code may come from
    any of them: one plugin file imports another's), none where it flies only nbvkit's own, so
    that such a run is kept while a plugin file changes."""
    from .planning.registry import part_sources

    return loaded_files() if part_sources(config) else []


def plugin_frame(e: BaseException) -> str | None:
    """Where in a loaded plugin file `e` was raised: "plugin file PATH, line N, in FUNCTION" of
    the innermost frame of its traceback in one of them; None when none is."""
    frames = _plugin_frames(e)
    if not frames:
        return None
    f = frames[-1]
    return f"plugin file {f.filename}, line {f.lineno}, in {f.name}"


def plugin_traceback(e: BaseException) -> list[str]:
    """The traceback lines a reader needs of an error raised by a plugin's part: the frames in
    the plugin files, or the whole traceback when the part was registered from a file nbvkit did
    not load (a note names it) and no frame is in a plugin file; [] for nbvkit's own errors."""
    frames = _plugin_frames(e)
    if not frames and any("registered from a script" in str(n) for n in _notes(e)):
        frames = traceback.extract_tb(e.__traceback__)
    return traceback.format_list(frames) if frames else []


def _notes(e: BaseException) -> list:
    return list(getattr(e, "__notes__", ()) or ())


def _plugin_frames(e: BaseException) -> list:
    if not LOADED or e.__traceback__ is None:
        return []
    files = set(LOADED)
    out = []
    for f in traceback.extract_tb(e.__traceback__):
        try:
            if f.filename in files or str(Path(f.filename).resolve()) in files:
                out.append(f)
        except (OSError, ValueError):
            continue
    return out


def load_plugins(files, wrap: bool = False) -> None:
    """Loads each of `files`: paths, or loaded_files() entries ({"path", "sha256"}: the content
    expected, as the process that started the runs loaded it); `wrap`: see load_plugin."""
    for f in files or ():
        if isinstance(f, dict):
            load_plugin(f["path"], f["sha256"], wrap)
        else:
            load_plugin(f, wrap=wrap)


def error_line(e: BaseException) -> str:
    """An exception as one line for a reader: its type, and its message when it has one, its
    notes (the plugin part that raised it), and where in a plugin file it was raised (the
    innermost frame there: plugin_frame)."""
    message = " ".join(str(e).split())
    line = f"{type(e).__name__}: {message}" if message else type(e).__name__
    notes = [" ".join(str(n).split()) for n in getattr(e, "__notes__", ())]
    where = plugin_frame(e)
    if where is not None and where not in notes:
        notes.append(where)
    return "; ".join([line, *notes])
