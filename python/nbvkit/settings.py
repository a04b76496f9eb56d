"""Settings: how a part of nbvkit declares its configuration section.

A part (a generator, a termination, a sensor, a stage) keeps a frozen dataclass of its settings
beside its class; its YAML section is named like the part. The fields declare their own checks:
``positive`` / ``nonneg`` / ``within`` (a range, nbvkit.limits.Bound), ``choice`` (one of some
names) and ``triple`` (3 finite numbers); a section may add a ``check(self, key)`` method for
what spans several of its keys. A section that sets C++ options is generated from the bound
options class (``cpp_section``): its keys, defaults and documentation are the C++ struct's.

nbvkit.config composes the sections into a Config and loads it (YAML, dotted overrides); this
module is what the parts import, so that no part imports the configuration.
"""
from __future__ import annotations

import functools
import math
import numbers
import os
import sys
import types
import typing
from dataclasses import asdict, field, fields, is_dataclass, make_dataclass
from typing import Tuple

import numpy as np

from .limits import Bound, is_bool, is_number, shorten

#: A list of names in the configuration (YAML list of strings).
Names = Tuple[str, ...]
#: the origins of an Optional[X] annotation: typing's, and X | None's (PEP 604)
UNIONS = (typing.Union, types.UnionType)


def bounded(default, bound: Bound):
    """A dataclass field with its default and its range (nbvkit.limits.Bound), checked whenever
    a configuration is built; an integer key without a maximum gets limits.MAX_INT."""
    return field(default=default, metadata={"bound": bound})


def positive(default, hi=None):
    """A field whose value must be > 0 (and <= hi; None stays allowed where the type is
    Optional)."""
    return bounded(default, Bound(lo=0, lo_open=True, hi=hi))


def nonneg(default):
    """A field whose value must be >= 0."""
    return bounded(default, Bound(lo=0))


def within(default, lo, hi):
    """A field whose value must lie in [lo, hi]."""
    return bounded(default, Bound(lo=lo, hi=hi))


#: How a name of one's own part (registered at run time) becomes known, for messages.
REGISTER_FIRST = "register it first, e.g. nbvkit.load_plugin(FILE) or --plugin FILE"


def choice(default, options):
    """A field whose value must be one of `options` (a tuple of names, or a function returning
    them, for names that are registered at run time)."""
    return field(default=default, metadata={"choices": options})


def triple(default):
    """A field of 3 finite numbers (or None where the type is Optional)."""
    return field(default=default, metadata={"triple": True})


def _py_field(value):
    """(type, default) of a bound C++ option value in the configuration (vectors: tuples)."""
    if isinstance(value, bool):
        return bool, value
    if isinstance(value, int):
        return int, value
    if isinstance(value, float):
        return float, value
    if isinstance(value, str):
        return str, value
    arr = np.asarray(value, float)
    if arr.shape == (3,):
        return tuple, tuple(float(x) for x in arr)
    raise TypeError(f"no configuration type for a C++ option value {value!r}")


def cpp_section(
    name: str,
    options_cls,
    doc: str,
    only=None,
    before=(),
    after=(),
    extra=(),
    bounds=None,
    choices=None,
    module=None,
):
    """A frozen config dataclass whose keys mirror a bound C++ options class: their names,
    defaults and documentation come from it (``options_cls.fields()``); `only` keeps some of them.
    `before` / `after`: Python-only keys as (name, type, default, doc). `extra`: more bound
    options classes whose every field is a key too (after the first class's; names must not
    clash). `bounds`: key -> Bound of the keys whose range is checked here (beyond the C++
    options' own checks; every integer key also gets limits.MAX_INT). `choices`: key -> the
    names it may take (see ``choice``). The class gets ``FIELD_DOCS`` (key -> documentation),
    ``OPTIONS`` (the first bound class), ``OPTIONS_ALL`` (all of them), ``options()`` (the first
    C++ options built from this section) and ``options_for(cls)`` (any of them). It lives in
    `module` (the caller's unless given), bound there to `name` (pickle finds it so)."""
    module = module or sys._getframe(1).f_globals.get("__name__", __name__)
    classes = (options_cls,) + tuple(extra)
    keys = {
        cls: [f for f in cls.fields() if cls is not options_cls or only is None or f in only]
        for cls in classes
    }
    docs, spec, bounds, choices = {}, [], dict(bounds or {}), dict(choices or {})

    def spec_field(fname, default):
        meta = {}
        if fname in bounds:
            meta["bound"] = bounds.pop(fname)
        if fname in choices:
            meta["choices"] = choices.pop(fname)
        return field(default=default, metadata=meta)

    for fname, tp, default, fdoc in before:
        spec.append((fname, tp, spec_field(fname, default)))
        docs[fname] = fdoc
    for cls in classes:
        defaults = cls()
        for fname in keys[cls]:
            if fname in docs:
                raise ValueError(f"{name}: key {fname!r} is set twice")
            tp, default = _py_field(getattr(defaults, fname))
            spec.append((fname, tp, spec_field(fname, default)))
            docs[fname] = cls.fields()[fname]
    for fname, tp, default, fdoc in after:
        spec.append((fname, tp, spec_field(fname, default)))
        docs[fname] = fdoc
    if bounds or choices:
        raise ValueError(
            f"{name}: bounds or choices of unknown keys {sorted({**bounds, **choices})}"
        )
    cpp_fields = [f for cls in classes for f in keys[cls]]

    def options_for(self, cls):
        return cls(**{f: getattr(self, f) for f in keys[cls]})

    def options(self):
        return options_for(self, options_cls)

    return make_dataclass(
        name,
        spec,
        frozen=True,
        namespace={
            "__doc__": doc,
            "FIELD_DOCS": docs,
            "OPTIONS": options_cls,
            "OPTIONS_ALL": classes,
            "options": options,
            "options_for": options_for,
            "CPP_FIELDS": tuple(cpp_fields),
            "__module__": module,
        },
    )


#: what an unknown top-level key's error adds
PLUGIN_SECTIONS = (
    " (a section of your own planner part is known once its plugin is loaded: --plugin FILE, "
    "nbvkit.load_plugin)"
)


def unknown_key(key: str, known, note: str = "") -> KeyError:
    """KeyError "unknown config key KEY (did you mean K?); known keys here: ..." for the dotted
    `key` whose last part is none of `known`, its section's keys."""
    import difflib

    last = key.rsplit(".", 1)[-1]
    near = difflib.get_close_matches(last, sorted(map(str, known)), n=1)
    meant = f" (did you mean {key[: len(key) - len(last)] + near[0]!r}?)" if near else ""
    keys = ", ".join(sorted(map(str, known))) or "none (this section has no keys)"
    return KeyError(f"unknown config key {shorten(key)}{meant}; known keys here: {keys}{note}")


def build(cls, data, prefix: str):
    """A section `cls` from a mapping of the keys to set (the rest keep their defaults), each
    value coerced to its field's type and checked; KeyError names an unknown key with its full
    dotted name, ValueError a bad value."""
    if not isinstance(data, dict):
        raise ValueError(
            f"config section {prefix.rstrip('.') or '<root>'} must be a mapping of its keys, "
            f"got {shorten(data)}"
        )
    hints = type_hints(cls)
    known = {f.name for f in fields(cls) if not f.name.startswith("_")}
    for k in data:
        if k not in known:
            raise unknown_key(prefix + str(k), known)
    values = {name: coerce(hints[name], value, prefix + name) for name, value in data.items()}
    try:
        obj = cls(**values)
    except (ValueError, TypeError) as e:  # a section's own __post_init__: named as its checks
        set_here = ", ".join(f"{prefix}{k} = {shorten(v)}" for k, v in values.items())
        extra = f" (set here: {set_here})" if set_here else ""
        raise section_error(cls, prefix.rstrip("."), e, extra) from e
    validate(obj, prefix)
    return obj


def coerce(tp, value, key):
    origin = typing.get_origin(tp)
    if is_dataclass(tp):
        return build(tp, value if value is not None else {}, key + ".")
    if origin in UNIONS:  # Optional[X], X | None
        if value is None:
            return None
        (inner,) = [a for a in typing.get_args(tp) if a is not type(None)]  # noqa: E721
        return coerce(inner, value, key)
    if tp is bool:
        if is_bool(value):  # (numpy's read as its value)
            return bool(value)
        raise ValueError(f"config key {key!r} must be true or false, got {shorten(value)}")
    if tp is int:
        if not is_number(value) or (
            not isinstance(value, numbers.Integral)
            and not (math.isfinite(value) and value == int(value))
        ):
            raise ValueError(f"config key {key!r} must be an integer, got {shorten(value)}")
        return int(value)
    if tp is float:
        if not is_number(value):
            raise ValueError(f"config key {key!r} must be a number, got {shorten(value)}")
        try:
            return float(value)
        except OverflowError:  # an integer past 1e308
            raise ValueError(f"config key {key!r} must be finite, got {shorten(value)}") from None
    if tp is str:
        if is_number(value):
            return str(value)  # e.g. scenario: 5
        if isinstance(value, os.PathLike):  # a pathlib.Path (mesh.path), as load_config takes
            value = os.fspath(value)
        if not isinstance(value, str):
            raise ValueError(f"config key {key!r} must be a string, got {shorten(value)}")
        return value
    if tp == Names:
        if (
            isinstance(value, str)
            or not isinstance(value, (list, tuple))
            or not all(isinstance(x, str) for x in value)
        ):
            raise ValueError(f"config key {key!r} must be a list of names, got {shorten(value)}")
        return tuple(value)
    if tp is tuple:
        if (
            not isinstance(value, (list, tuple))
            or len(value) > 16
            or not all(is_number(x) for x in value)
        ):
            raise ValueError(f"config key {key!r} must be a list of numbers, got {shorten(value)}")
        try:
            items = tuple(float(x) for x in value)
        except OverflowError:
            items = (math.inf,)
        if not all(math.isfinite(x) for x in items):
            raise ValueError(f"config key {key!r} must be finite numbers, got {shorten(value)}")
        return items
    if typing.get_origin(tp) in (tuple, list):
        return _coerce_items(tp, value, key)
    return value


def _coerce_items(tp, value, key):
    """A key of type tuple[T, ...], tuple[T1, T2, ...] or list[T]: a list whose items are each
    coerced to their type (as a key of that type: f"{key}[i]"), as a tuple or a list."""
    args, origin = typing.get_args(tp), typing.get_origin(tp)
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise ValueError(f"config key {key!r} must be a list, got {shorten(value)}")
    if origin is list or (len(args) == 2 and args[1] is Ellipsis):
        kinds = [args[0]] * len(value)
    else:
        kinds = list(args)
        if len(value) != len(kinds):
            raise ValueError(
                f"config key {key!r} must be a list of {len(kinds)} items, got {shorten(value)}"
            )
    items = [coerce(t, v, f"{key}[{i}]") for i, (t, v) in enumerate(zip(kinds, value))]
    for i, (t, x) in enumerate(zip(kinds, items)):  # each a key of its type: finite, or an
        if t in (int, float):  # integer within MAX_INT (Bound's defaults)
            Bound().for_type(t).check(f"{key}[{i}]", x)
    return items if origin is list else tuple(items)


#: the item types of a tuple[...] or list[...] key that coerce checks
_ITEM_TYPES = (bool, int, float, str)


def check_field_types(cls, what: str) -> None:
    """TypeError naming `what` unless every field of the dataclass `cls` (its own, not starting
    with _) is of a type coerce checks: bool, int, float, str, tuple (of numbers), tuple[T, ...],
    tuple[T1, T2, ...] or list[T] of those scalars, Optional of any of these, or a dataclass
    of such fields (a value of another type would be taken as the YAML gave it, unchecked)."""
    try:
        hints = typing.get_type_hints(cls)
    except Exception as e:  # (a name the annotation uses is not defined where it was written)
        raise TypeError(
            f"{what}: its annotations cannot be read: {type(e).__name__}: {e}"
        ) from None
    for f in fields(cls):
        if f.name.startswith("_"):
            continue
        tp = hints[f.name]
        if typing.get_origin(tp) in UNIONS:
            args = [a for a in typing.get_args(tp) if a is not type(None)]  # noqa: E721
            tp = args[0] if len(args) == 1 else tp
        if is_dataclass(tp) and isinstance(tp, type):
            check_field_types(tp, f"{what}, field {f.name!r}")
            continue
        origin, args = typing.get_origin(tp), typing.get_args(tp)
        items = args[:1] if origin is tuple and len(args) == 2 and args[1] is Ellipsis else args
        if tp in (*_ITEM_TYPES, tuple) or (
            origin in (tuple, list) and items and all(a in _ITEM_TYPES for a in items)
        ):
            continue
        raise TypeError(
            f"{what}: field {f.name!r} is of type {tp!r}, which a configuration cannot check: "
            "use bool, int, float, str, tuple (numbers), tuple[T, ...], tuple[T1, T2] or list[T] "
            "(T one of bool, int, float, str), Optional[...] of one, or a dataclass"
        )


def check_defaults(obj, prefix: str) -> None:
    """ValueError naming the key unless each value of the section `obj` reads back from a
    configuration file as itself (coerce): a default of the wrong type (count: int = 2.5,
    label: str = 3) flew, and its run's config.yaml was then refused or read back otherwise."""
    hints = type_hints(type(obj))
    for f in fields(obj):
        if f.name.startswith("_"):
            continue
        v, key = getattr(obj, f.name), prefix + f.name
        raw = asdict(v) if is_dataclass(v) and not isinstance(v, type) else v
        back = coerce(hints[f.name], raw, key)  # ValueError naming the key
        if back != v or (type(back) is not type(v) and not isinstance(back, float)):
            raise ValueError(
                f"config key {key!r} defaults to {shorten(v)} ({type(v).__name__}), which a "
                f"configuration file reads back as {shorten(back)} ({type(back).__name__})"
            )


@functools.lru_cache(maxsize=None)
def type_hints(cls) -> dict:
    """typing.get_type_hints(cls), once a class (every configuration reads them; read only)."""
    return typing.get_type_hints(cls)


def field_bound(cls, f) -> Bound:
    """The range of field `f` of config class `cls` (its declared Bound; an integer key without
    a maximum gets limits.MAX_INT; NaN and infinities are refused unless it says so)."""
    hint = type_hints(cls)[f.name]
    if typing.get_origin(hint) in UNIONS:  # Optional[X], X | None
        (hint,) = [a for a in typing.get_args(hint) if a is not type(None)]  # noqa: E721
    return f.metadata.get("bound", Bound()).for_type(hint)


def validate(obj, prefix: str) -> None:
    """Checks a section's values as its fields declare (range, choices, 3 numbers), its C++
    options' own checks, then its ``check(key)`` method if it has one."""
    for f in fields(obj):
        if f.name.startswith("_"):
            continue
        key = prefix + f.name
        v = getattr(obj, f.name)
        options = f.metadata.get("choices")
        if options is not None:
            # names registered at run time: a script's own part is registered before it is named
            mine = f" (one of your own: {REGISTER_FIRST})"
            late = callable(options)
            options = tuple(options() if late else options)
            if v not in options:
                raise ValueError(
                    f"config key {key!r} must be one of {', '.join(options)}"
                    f"{mine if late else ''}; got {shorten(v)}"
                )
        field_bound(type(obj), f).check(key, v)
        if f.metadata.get("triple") and v is not None:
            if len(v) != 3:
                raise ValueError(f"config key {key!r} must have 3 numbers, got {shorten(list(v))}")
            if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in v):
                raise ValueError(
                    f"config key {key!r} must be 3 finite numbers, got {shorten(list(v))}"
                )
    if hasattr(obj, "OPTIONS"):  # a section of C++ options: their own checks, named here
        try:
            for cls in obj.OPTIONS_ALL:
                obj.options_for(cls)
        except (ValueError, TypeError) as e:
            raise section_error(obj, prefix.rstrip("."), e) from None
    if hasattr(obj, "check"):
        obj.check(prefix.rstrip("."))


def section_error(section, name: str, e: Exception, extra: str = "") -> ValueError:
    """The ValueError of a section's C++ options check: "config key 'map.prob_hit' must be ..."
    when the C++ message starts with a key of the section, else "config section 'map': ..."."""
    msg = shorten(str(e), 300).strip("'\"")
    if msg.startswith(name + " "):  # "camera hfov_deg must be ..."
        msg = msg[len(name) + 1 :]
    first = msg.split(" ", 1)[0]
    if first in {f.name for f in fields(section)}:  # "prob_hit must be ...": name the key
        return ValueError(f"config key {name + '.' + first!r}{msg[len(first):]}{extra}")
    return ValueError(f"config section {name!r}: {msg}{extra}")
