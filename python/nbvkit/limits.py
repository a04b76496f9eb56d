"""Bounds on what nbvkit reads: configuration keys, arguments and files.

Two kinds of limits, both checked before any work and reported as a ValueError (or
FileNotFoundError, or a TypeError for an argument of the wrong type) naming the key or the path,
the limit, and what would fit:

- ``Bound``: the range of one configuration key, declared on its field (nbvkit.config); every
  integer key has a maximum, and no key takes NaN or an infinity unless it says so.
- ``check_input_file``: every file nbvkit reads (a config, a sweep, a point cloud, a mesh) must
  be a regular file (not a FIFO, a device, a socket or a directory) of at most a size per kind.

The work a configuration asks for on a structure is bounded by nbvkit.work_limits
(``check_work``). The limits are documented in docs/HOSTILE.md ("Inputs").
"""
from __future__ import annotations

import math
import numbers
import os
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "Bound",
    "check_input_file",
    "fmt_number",
    "is_bool",
    "is_number",
    "read_only",
    "refuse_case_twin",
    "require_bool",
    "require_config",
    "require_type",
    "shorten",
    "MAX_TEXT_FILE_BYTES",
    "MAX_DATA_FILE_BYTES",
    "MAX_YAML_NODES",
    "MAX_INT",
]

#: Largest config or sweep file read (bytes): a configuration is a few kB.
MAX_TEXT_FILE_BYTES = 4 << 20
#: Largest mesh or point-cloud file read (bytes), as the C++ mesh loader (kMaxMeshFileBytes).
MAX_DATA_FILE_BYTES = 2 << 30
#: Largest YAML document, counted as the nodes its aliases expand to (a "billion laughs" file
#: holds a few aliases that expand to 10^9 nodes).
MAX_YAML_NODES = 100_000
#: The largest value of an integer key without a maximum of its own (C++ int).
MAX_INT = 2**31 - 1


def add_note(e: BaseException, text: str) -> None:
    """Notes `text` on `e` once (printed under the traceback's last line; Python 3.11+, where
    notes exist: nothing before)."""
    if hasattr(e, "add_note") and text not in getattr(e, "__notes__", ()):
        e.add_note(text)


def shorten(value, limit: int = 120) -> str:
    """repr(value), cut to about `limit` characters (messages quote what they were given, and a
    hostile value may be gigabytes long)."""
    import reprlib

    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 100:
        return fmt_number(value)  # (repr fails past 4,300 digits)
    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    r.maxlist = r.maxtuple = r.maxdict = r.maxset = 8
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit + 10 else text[:limit] + "..."


# ---------------------------------------------------------------------------- config bounds


def require_type(value, cls, what: str, name: str) -> None:
    """TypeError "`what` must be `name`, got <its type>" unless `value` is a `cls` (a class or a
    tuple of them): an argument of the Python API, checked where it is taken rather than where
    Python first reads an attribute of it."""
    if not isinstance(value, cls):
        raise TypeError(f"{what} must be {name}, got {type(value).__name__}")


def require_config(value, what: str = "config") -> None:
    """require_type for an nbvkit.Config, by the sections every reader takes (the modules below
    nbvkit.config cannot import its class)."""
    if not all(hasattr(value, s) for s in ("mesh", "camera", "workspace", "vehicle", "map")):
        raise TypeError(
            f"{what} must be an nbvkit.Config (nbvkit.load_config()), got {type(value).__name__}"
        )


def is_bool(x) -> bool:
    """Whether x is True or False, numpy's too (a string such as "no", which is true, or 0 and 1
    are not)."""
    return isinstance(x, (bool, np.bool_))


def require_bool(value, name: str) -> bool:
    """value as a bool; TypeError naming the argument `name` unless is_bool(value)."""
    if not is_bool(value):
        raise TypeError(f"{name} must be True or False, got {shorten(value)}")
    return bool(value)


def is_number(x) -> bool:
    """Whether x is a real number: an int or a float, numpy's too; not a bool (True is no 1 in
    a file or an argument; numpy's bool is no number either), not a string."""
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def read_only(values, name: str, dtype=float) -> np.ndarray:
    """A read-only copy of `values` (named `name` in a message) as a C-ordered array of `dtype`:
    state nbvkit hands to parts (a plugin's generator, a caller's points) that they must not
    write into. A complex array is refused, not cut to its real part (NumPy keeps the real part
    with only a warning)."""
    if np.iscomplexobj(values):
        raise ValueError(f"{name} must be real numbers, got complex")
    a = np.array(values, dtype, order="C")
    a.flags.writeable = False
    return a


def refuse_case_twin(name: str, names, what: str) -> None:
    """ValueError when `name` differs only in case from one of `names` (registered parts or
    scenarios: 'IG' beside 'ig', two names a reader takes for one); `what` names it."""
    twin = next((t for t in names if t != name and t.lower() == name.lower()), None)
    if twin is not None:
        raise ValueError(
            f"{what} {name!r} differs only in case from {twin!r}, registered already; choose "
            "another name"
        )


def fmt_number(x) -> str:
    """A key's value as a message shows it: integers whole (in _-grouped thousands from 100,000;
    ~1eN past 100 bits), floats as %g where that reads back as the value, else all its digits
    (180.0001 refused past a limit of 180 showed as 180)."""
    if isinstance(x, int) and not isinstance(x, bool):
        if x.bit_length() > 100:  # (str() fails past 4,300 digits)
            return f"{'-' if x < 0 else ''}~1e{int(x.bit_length() * math.log10(2))}"
        return f"{x:,}".replace(",", "_") if abs(x) >= 100_000 else str(x)
    short = f"{x:g}"
    return short if not isinstance(x, float) or float(short) == x else repr(x)


@dataclass(frozen=True)
class Bound:
    """The range of a configuration key: ``lo <= value <= hi`` (``lo < value`` when `lo_open`);
    None: no bound on that side. NaN is always refused, an infinity unless `inf` (+inf allowed,
    e.g. "no limit"). `hi` of an integer key defaults to MAX_INT (see ``for_type``)."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    inf: bool = False
    hi_open: bool = False  # the value must be below hi

    def describe(self) -> str:
        """The range as text: "> 0", ">= 0 and <= 1000", "1..1000", "(0.5, 1)"."""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None and not self.lo_open and not self.hi_open:
            return f"{fmt_number(lo)}..{fmt_number(hi)}"
        if lo is not None and hi is not None:
            left, right = "(["[not self.lo_open], ")]"[not self.hi_open]
            return f"{left}{fmt_number(lo)}, {fmt_number(hi)}{right}"
        parts = []
        if lo is not None:
            parts.append(f"{'>' if self.lo_open else '>='} {fmt_number(lo)}")
        if hi is not None:
            parts.append(f"{'<' if self.hi_open else '<='} {fmt_number(hi)}")
        return " and ".join(parts)

    def check(self, key: str, v) -> None:
        """ValueError naming `key` unless `v` (a number or None) lies within the bound."""
        if v is None or isinstance(v, (bool, str)) or not isinstance(v, (int, float)):
            return
        if isinstance(v, float) and math.isnan(v):
            raise ValueError(f"config key {key!r} must be a finite number, got nan")
        if isinstance(v, float) and math.isinf(v) and not (self.inf and v > 0):
            raise ValueError(f"config key {key!r} must be finite, got {v!r}")
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            what = "positive" if self.lo == 0 and self.lo_open else None
            if what is None:
                what = f"{'>' if self.lo_open else '>='} {fmt_number(self.lo)}"
            raise ValueError(f"config key {key!r} must be {what}, got {fmt_number(v)}")
        if self.hi is None or (self.inf and math.isinf(v)):
            return
        if self.hi_open and v >= self.hi:
            raise ValueError(
                f"config key {key!r} must be in {self.describe()}, got {fmt_number(v)}"
            )
        if v > self.hi:
            raise ValueError(
                f"config key {key!r} = {fmt_number(v)} is more than its limit "
                f"{fmt_number(self.hi)} (range {self.describe()})"
            )

    def for_type(self, tp) -> "Bound":
        """This bound, with MAX_INT as the maximum of an integer key that has none."""
        if tp is int and self.hi is None:
            return Bound(self.lo, MAX_INT, self.lo_open, self.inf, self.hi_open)
        return self


# ---------------------------------------------------------------------------- input files


def check_input_file(path, what: str = "file", max_bytes: int = MAX_DATA_FILE_BYTES) -> Path:
    """The path (expanded, as a Path) of a regular file of at most `max_bytes` bytes.

    FileNotFoundError (with the path) when it does not exist; ValueError naming `what` and the
    path for a directory, anything that is not a regular file (a FIFO would block the reader
    forever, /dev/zero never ends), a file larger than `max_bytes`, or one that cannot be
    inspected. Any path the OS accepts is taken: str, bytes (also not UTF-8) or os.PathLike."""
    try:
        name = os.fsdecode(path)
    except TypeError:
        raise TypeError(f"{what} path must be a str, bytes or os.PathLike, got {path!r}") from None
    if "\0" in name:  # (os.stat: "embedded null byte", naming nothing)
        raise ValueError(f"{what} path {name!r} holds a NUL byte: no file has such a name")
    p = Path(name).expanduser()
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise FileNotFoundError(2, f"No such {what}", str(p)) from None
    except OSError as e:
        raise ValueError(f"cannot read {what} {p}: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{what} {p} is a directory, not a file")
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a FIFO (named pipe)"
            if stat.S_ISFIFO(st.st_mode)
            else "a character device"
            if stat.S_ISCHR(st.st_mode)
            else "a block device"
            if stat.S_ISBLK(st.st_mode)
            else "a socket"
            if stat.S_ISSOCK(st.st_mode)
            else "not a regular file"
        )
        raise ValueError(f"{what} {p} is {kind}: nbvkit reads regular files only")
    if st.st_size > max_bytes:
        raise ValueError(
            f"{what} {p} is {st.st_size:,} bytes, more than the {max_bytes:,} bytes nbvkit reads "
            f"as a {what}"
        )
    return p
