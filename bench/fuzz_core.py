"""Fuzzes the C++ core's Python API (nbvkit._core) with the calls the tests make: every function
and method of _core is wrapped while the given test files run, the first calls of each are kept
(real, valid arguments), and at the end each kept call is made again with one argument replaced
by a hostile value (NaN, inf, 1e300 or 1e19 in an array or a number, -1, 2**31 or 2**62 for an
int, an array emptied, flattened, given a column more or less, Fortran-ordered or strided, a
string, None ...), each in a forked child with a time limit. A call may raise whatever it likes;
what it must not do is kill the process (a signal: segfault, abort) or run past the limit.

Usage: python bench/fuzz_core.py [--per N] [--limit S] [--json FILE] [TEST_FILES ...]
    (default: the quick test files that call the core most). Prints each call that crashed or
    ran past the limit, then a summary; exits 1 if any crashed.
This file is also the pytest plugin that does the work (loaded by name with -p)."""
from __future__ import annotations

import collections
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

DEFAULT_TESTS = [
    "test_sensors.py",
    "test_map.py",
    "test_cloud.py",
    "test_views.py",
    "test_utilities.py",
    "test_placement.py",
    "test_evaluation.py",
    "test_symmetry.py",
    "test_mesh.py",
    "test_regions.py",
    "test_legs.py",
    "test_gimbal.py",
]
SKIPPED = {"set_num_threads", "get_num_threads", "release_free_memory"}  # process-wide settings
_records: dict = collections.defaultdict(list)
_originals: dict = {}


def _wrap(name, f, per):
    def recorded(*a, **k):
        if len(_records[name]) < per:
            _records[name].append((a, dict(k)))
        return f(*a, **k)

    return recorded


def pytest_configure(config):
    from nbvkit import _core

    per = int(os.environ.get("NBV_FUZZ_PER", "2"))
    for name in dir(_core):
        value = getattr(_core, name)
        if name.startswith("_") or name in SKIPPED:
            continue
        if isinstance(value, type):  # a bound class: its methods and constructor
            for m, f in list(vars(value).items()):
                if m.startswith("__") and m not in ("__init__", "__call__", "__getitem__"):
                    continue
                if not callable(f) or isinstance(f, (property, staticmethod, classmethod)):
                    continue
                _originals[f"{name}.{m}"] = f
                try:
                    setattr(value, m, _wrap(f"{name}.{m}", f, per))
                except (AttributeError, TypeError):
                    pass
        elif callable(value):
            _originals[name] = value
            setattr(_core, name, _wrap(name, value, per))
    _rebind_imported()


def pytest_collection_finish(session):
    _rebind_imported()


def _rebind_imported():
    """Modules that imported a core function by name get the recording one."""
    from nbvkit import _core

    for module in list(sys.modules.values()):
        if module is None or module is _core:
            continue
        if not getattr(module, "__name__", "").startswith(("nbvkit", "test_", "conftest")):
            continue
        for name, f in _originals.items():
            if "." not in name and getattr(module, name, None) is f:
                setattr(module, name, getattr(_core, name))


def hostile(v):
    """(label, value) replacements for one argument value."""
    import numpy as np

    if isinstance(v, np.ndarray) and v.dtype.kind in "fiub":
        with np.errstate(all="ignore"):  # the casts of NaN and 1e300 are the point
            return _hostile_arrays(v)
    return _hostile_values(v)


def _hostile_arrays(v):
    import numpy as np

    out = []
    if v.dtype.kind == "f":
        for x in (np.nan, np.inf, 1e300, -1e300, 1e19):
            w = v.copy()
            if w.size:
                w.flat[0] = x
            out.append((f"element {x!r}", w))
        out.append(("Fortran order", np.asfortranarray(v)))
        if v.ndim >= 1 and len(v):
            out.append(("strided", np.repeat(v, 2, axis=0)[::2]))
        out.append(("as int64", v.astype(np.int64)))
    else:
        for x in (-1, 2**31 - 1, -(2**31), 2**40):
            w = v.astype(np.int64)
            if w.size:
                w.flat[0] = x
            out.append((f"element {x!r}", w))
        out.append(("NaN floats", np.full(v.shape, np.nan)))
    out.append(("empty", v[:0]))
    out.append(("flattened", v.reshape(-1)))
    if v.ndim == 2 and v.shape[1]:
        out.append(("a column more", np.hstack([v, v[:, :1]])))
        out.append(("a column less", v[:, :-1]))
    out.append(("3-d", v.reshape((1,) + v.shape)))
    return out + [("a string", "abc"), ("None", None)]


def _hostile_values(v):
    if isinstance(v, bool):
        return [("None", None)]
    if isinstance(v, int):
        return [("-1", -1), ("2**62", 2**62), ("2**31", 2**31), ("0", 0), ("None", None)]
    if isinstance(v, float):
        return [(x, float(x)) for x in ("nan", "inf", "-inf", "-1", "0", "1e308", "1e19")]
    if isinstance(v, str):
        return [("empty", ""), ("a NUL", "\x00x"), ("None", None)]
    if isinstance(v, (list, tuple)) and v:
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            nan, big = [float("nan")] * len(v), [1e300] * len(v)
            return [("NaNs", nan), ("1e300s", big), ("shorter", list(v)[:-1]), ("empty", [])]
        if all(isinstance(x, (list, tuple)) for x in v):
            return [
                ("NaNs", [[float("nan")] * len(x) for x in v]),
                ("ragged", [list(x)[:-1] if i == 0 else list(x) for i, x in enumerate(v)]),
                ("empty", []),
            ]
    return [("None", None)]


def _in_child(f, a, k, limit):
    pid = os.fork()
    if pid == 0:
        try:
            signal.alarm(limit)
            f(*a, **k)
        except BaseException:
            pass
        os._exit(0)
    _, status = os.waitpid(pid, 0)
    if not os.WIFSIGNALED(status):
        return None
    sig = os.WTERMSIG(status)
    return "past the limit" if sig == signal.SIGALRM else signal.Signals(sig).name


def pytest_sessionfinish(session, exitstatus):
    from nbvkit import _core

    _core.set_num_threads(1)  # a forked child runs on the calling thread alone
    limit = int(os.environ.get("NBV_FUZZ_LIMIT", "30"))
    calls, found = 0, []
    for name, kept in list(_records.items()):
        f = _originals[name]
        first = 1 if "." in name else 0  # a method's own object stays
        for a, k in kept:
            slots = [(i, a[i]) for i in range(first, len(a))] + list(k.items())
            for slot, value in slots:
                for label, bad in hostile(value):
                    a2, k2 = list(a), dict(k)
                    if isinstance(slot, int):
                        a2[slot] = bad
                    else:
                        k2[slot] = bad
                    calls += 1
                    outcome = _in_child(f, a2, k2, limit)
                    if outcome:
                        where = f"argument {slot}" if isinstance(slot, int) else slot
                        found.append(dict(call=name, argument=where, value=label, outcome=outcome))
                        print(f"\n{name}: {where} = {label}: {outcome}", flush=True)
    report = dict(functions=len(_records), calls=calls, found=found)
    out = os.environ.get("NBV_FUZZ_JSON")
    if out:
        Path(out).write_text(json.dumps(report, indent=1))
    crashes = sum(x["outcome"] != "past the limit" for x in found)
    print(
        f"\nfuzz: {len(_records)} core functions called by the tests, {calls} hostile calls: "
        f"{crashes} crashed, {len(found) - crashes} ran past {limit} s",
        flush=True,
    )
    if crashes:
        session.exitstatus = 1


def main():
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "tests", nargs="*", help="test files (default: " + " ".join(DEFAULT_TESTS) + ")"
    )
    ap.add_argument("--per", type=int, default=2, help="calls kept per function (default 2)")
    ap.add_argument("--limit", type=int, default=30, help="seconds a call may take (default 30)")
    ap.add_argument("--json", help="write the findings here")
    a = ap.parse_args()
    root = Path(__file__).resolve().parent.parent
    tests = a.tests or [str(root / "tests" / t) for t in DEFAULT_TESTS]
    env = dict(os.environ, NBV_FUZZ_PER=str(a.per), NBV_FUZZ_LIMIT=str(a.limit))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root / "bench"), env.get("PYTHONPATH")]))
    if a.json:
        env["NBV_FUZZ_JSON"] = str(Path(a.json).resolve())
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "fuzz_core", "-p", "no:cacheprovider"]
    return subprocess.call(cmd + tests, env=env, cwd=root)


if __name__ == "__main__":
    sys.exit(main())
