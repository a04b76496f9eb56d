"""Planner parts by name: one line each (the configuration's planner.generators and
planner.terminations name them; each part's section of the configuration is named like it).

From a script (or a file given to ``nbvkit run --plugin``), ``register_generator``,
``register_termination`` and ``register_utility`` add parts without editing the package; the
configuration then has their sections and accepts their names.
"""
from __future__ import annotations

from .generators.frontier import FrontierGenerator
from .generators.lattice import LatticeGenerator
from .generators.model import ModelPlan
from .generators.tour import CoverageTour
from .terminations.budget import Budget
from .terminations.entropy import EntropyChange
from .terminations.stall import SurfaceStall
from ..limits import refuse_case_twin
from ..origins import note, source
from ..settings import REGISTER_FIRST, check_defaults, check_field_types, validate

GENERATORS = {
    "lattice": LatticeGenerator,  # the paper's CGVS / AGVS lattice around the vehicle
    "frontier": FrontierGenerator,  # views aimed at the nearest surface still to observe
    "tour": CoverageTour,  # set-cover tours over the surface still to observe
    "model": ModelPlan,  # the same tours over a known model of the structure, planned up front
}

TERMINATIONS = {
    "entropy": EntropyChange,  # the paper's entropy change per viewable voxel (Eq. 4-6)
    "stall": SurfaceStall,  # the views stopped adding surface
    "budget": Budget,  # distance / views / time limits
}

#: The parts nbvkit ships (the others were registered from a script: their calls are checked and
#: their errors named, parts.PluginPart).
BUILT_IN = frozenset(GENERATORS) | frozenset(TERMINATIONS)

#: nbvkit's generators that plan their views by the surface they would newly cover
#: (nbvkit.plan_tour) and propose them one at a time: the configured utility only checks each
#: (valid, worth planner.min_gain in its units), it does not rank them (utility_only_checks).
OWN_RANKING = ("tour", "model")


def utility_only_checks(config) -> list:
    """The generators of `config` (planner.generators) whose views its utility only checks, not
    ranks (OWN_RANKING), when the utility is another than the surface coverage they plan by."""
    if config.utility.name == "surface":
        return []
    return [g for g in config.planner.generators if g in OWN_RANKING]


def part_sources(config) -> dict:
    """{"KIND NAME": where} of the parts `config` flies that are not nbvkit's own (generators,
    terminations, a utility written in Python, a registered scenario): the file that registered
    each (origins.source). A run's summary records them (`parts_from`): a run flown with parts
    that `import my_parts` registered names the file its config.yaml needs."""
    from ..scenarios import BUILT_IN as OWN_SCENARIOS
    from ..scenarios import SCENARIOS

    out = {}
    for kind, names, table in (
        ("generator", config.planner.generators, GENERATORS),
        ("termination", config.planner.terminations, TERMINATIONS),
        ("utility", [config.utility.name], UTILITIES),
    ):
        for n in names:
            if n not in BUILT_IN and n in table:
                out[f"{kind} {n}"] = source(kind, n)
    if config.scenario not in OWN_SCENARIOS and config.scenario in SCENARIOS:
        out[f"scenario {config.scenario}"] = source("scenario", config.scenario)
    return out


def checks_only_words(gens, utility: str, more: str = "") -> str:
    """The console's words for the generators `gens` (utility_only_checks) whose views
    `utility` only checked (`more`: said after the check, in the parentheses)."""
    return (
        f"the {' and '.join(gens)} generator{'s plan their' if len(gens) > 1 else ' plans its'} "
        f"views by the surface they would newly cover; utility {utility} only checked each view "
        f"(valid, worth planner.min_gain in its units{more}), it did not rank them "
        "(docs/PLUGINS.md)"
    )


def parts_words(summary: dict) -> str:
    """The planner's parts a run flew, from its summary.json (the console's and the report's
    words; its scenario's name stays the same where --set replaced them): generators, utility,
    terminations, and the termination whose reason ended it."""
    words = (
        f"generators {', '.join(summary.get('generators') or ['none'])}; utility "
        f"{summary.get('utility')}; terminations "
        f"{', '.join(summary.get('terminations') or ['none'])}"
    )
    part = summary.get("termination_part")
    return words + (f" ({part} ended the run)" if part else "")


#: Utilities written in Python (name -> function of nbvkit.CandidateRays, see
#: planning/utilities.py); the C++ core's are nbvkit._core.utility_names().
UTILITIES: dict = {}

#: Section names a part may not take: the configuration's own (its keys and sections, and its
#: methods: config.section(name) would be one; tests/test_plugins.py checks they are all here).
RESERVED = frozenset(
    "seed scenario start start_pose max_iterations progress checkpoint_minutes mesh workspace "
    "map camera laser cloud vehicle utility targets placement planner profiling symmetry "
    "evaluation observability report sampling termination "
    "check section sections from_dict from_yaml with_overrides to_dict to_yaml".split()
)


def _check_new(name: str, kind: str, taken, replace: bool = False, table=None) -> None:
    """ValueError unless `name` is free for a `kind`, or (`replace`) names one of the user's own
    parts of that kind in `table` (never nbvkit's own, nor a part of another kind)."""
    if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
        raise ValueError(f"a {kind} name must be an identifier not starting with _, got {name!r}")
    if name.lower() in RESERVED:  # ('Camera' too: two names a reader takes for one)
        raise ValueError(
            f"{kind} name {name!r} is a section of the configuration (or one of its keys or "
            "methods), or differs from one only in case; choose another"
        )
    refuse_case_twin(name, taken, f"{kind} name")
    if name not in taken:
        return
    own = name in BUILT_IN or name in _core_utilities()
    if own and replace:
        raise ValueError(f"{kind} {name!r} is one of nbvkit's own and cannot be replaced")
    if replace and name not in table:
        other = _kind_of(name)
        raise ValueError(
            f"a {other} named {name!r} is registered, not a {kind}: replace=True replaces a "
            f"{kind} of your own; choose another name"
        )
    if not replace:
        from ..origins import clash, defined_in

        # (a generator and a termination share the configuration's sections: one name, one kind)
        held = kind if table is None or name in table or kind == "utility" else _kind_of(name)
        raise ValueError(
            f"a {held} named {name!r} is registered already"
            + (
                ""
                if own
                else clash(defined_in(taken[name]), getattr(taken[name], "__module__", None))
            )
            + (
                " (one of nbvkit's own); choose another name"
                if own
                else "; choose another name"
                + (", or replace=True to replace it" if held == kind else "")
            )
        )


def _kind_of(name: str) -> str:
    return "generator" if name in GENERATORS else "termination"


def _core_utilities() -> tuple:
    from .. import _core

    return tuple(_core.utility_names())


def _check_part(name: str, kind: str, cls, methods) -> None:
    """TypeError unless `cls` can be built as cls(settings, context) into a part with `methods`,
    and its Settings (if any) is a dataclass."""
    import dataclasses
    import inspect

    if not callable(cls):
        raise TypeError(f"{kind} {name!r} must be a class, got {type(cls).__name__}")
    if isinstance(cls, type):
        missing = [m for m in methods if not callable(getattr(cls, m, None))]
        if missing:
            raise TypeError(
                f"{kind} {name!r}: {cls.__name__} has no method "
                + " or ".join(f"{m}()" for m in missing)
            )
    try:  # built as cls(settings, context) at each mission's start: say so now
        inspect.signature(cls).bind(None, None)
    except TypeError as e:
        raise TypeError(
            f"{kind} {name!r}: {getattr(cls, '__name__', cls)!s} cannot be built as "
            f"cls(settings, context): {e}"
        ) from None
    except ValueError:
        pass  # no signature to read (a builtin): its first call says
    settings = getattr(cls, "Settings", None)
    if settings is not None and not (
        isinstance(settings, type) and dataclasses.is_dataclass(settings)
    ):
        raise TypeError(
            f"{kind} {name!r}: its Settings must be a dataclass (frozen, nbvkit.settings' "
            f"helpers for checks), got {settings!r}"
        )
    if settings is not None and not settings.__dataclass_params__.frozen:
        raise TypeError(
            f"{kind} {name!r}: its Settings must be a frozen dataclass (@dataclass(frozen=True)):"
            " the configuration a run records is the one its parts flew"
        )
    if settings is not None:  # every configuration builds its section from the defaults
        check_field_types(settings, f"{kind} {name!r}: its Settings")
        try:
            defaults = settings()
        except Exception as e:
            raise TypeError(
                f"{kind} {name!r}: its Settings() must build from the defaults alone (each field "
                f"with a default): {type(e).__name__}: {e}"
            ) from None
        try:  # (a NaN default broke every configuration after, the part named or not)
            check_defaults(defaults, name + ".")  # (its run read back otherwise, or refused)
            validate(defaults, name + ".")
        except ValueError as e:
            raise ValueError(f"{kind} {name!r}: its Settings' defaults fail their checks: {e}")


def register_generator(name: str, cls, *, replace: bool = False) -> None:
    """Adds a generator: `cls(settings, context)` with propose(world) and feedback(world,
    proposal, step) (parts.Generator); `cls.Settings` (optional) is the dataclass of its
    configuration section `name`. `replace`: `name` may be a generator registered before from a
    script (a notebook cell run again), which this one replaces; never one of nbvkit's own."""
    _check_new(name, "generator", {**GENERATORS, **TERMINATIONS}, replace, GENERATORS)
    _check_part(name, "generator", cls, ("propose", "feedback"))
    GENERATORS[name] = cls
    note("generator", name)


def register_termination(name: str, cls, *, replace: bool = False) -> None:
    """Adds a termination: `cls(settings, context)` with check(world, step) -> reason or None
    (parts.Termination); `cls.Settings` (optional) and `replace` as for a generator."""
    _check_new(name, "termination", {**GENERATORS, **TERMINATIONS}, replace, TERMINATIONS)
    _check_part(name, "termination", cls, ("check",))
    TERMINATIONS[name] = cls
    note("termination", name)


def register_utility(name: str, fn, *, replace: bool = False) -> None:
    """Adds a utility written in Python: `fn(rays)` -> (K,) gains of K candidate views from what
    their rays reach (nbvkit.CandidateRays), each finite and >= 0 for a valid candidate (or a
    tuple (gains, cells)); named by ``utility.name``. What it returns is checked where it is
    called, and an exception of its own noted with its name (utilities.PythonUtility).
    `replace` as for a generator (the C++ utilities are nbvkit's own)."""
    if not callable(fn):
        raise TypeError(f"utility {name!r} must be callable, got {type(fn).__name__}")
    if isinstance(fn, type):  # (it failed only in flight, built with the candidates' rays)
        raise TypeError(
            f"utility {name!r} is the class {fn.__name__}: a utility is a function of the "
            "candidates' rays (nbvkit.CandidateRays) returning their gains, registered as itself"
        )
    _check_new(
        name, "utility", {**UTILITIES, **dict.fromkeys(_core_utilities())}, replace, UTILITIES
    )
    UTILITIES[name] = fn
    note("utility", name)


def part_settings() -> dict:
    """name -> settings dataclass of every registered generator and termination that has one
    (the configuration's part sections)."""
    out = {}
    for table in (GENERATORS, TERMINATIONS):
        for name, cls in table.items():
            settings = getattr(cls, "Settings", None)
            if settings is not None:
                out[name] = settings
    return out


def get_generator(name: str, config, context=None):
    """The generator `name` built from its own section of `config` and the shared context (one
    registered from a script: in a parts.PluginPart, its calls checked and its errors named)."""
    return _build("generator", GENERATORS, name, config, context)


def _build(kind: str, table: dict, name: str, config, context):
    from .parts import PlanningContext, PluginPart, _named

    if name not in table:  # a scenario's preset is not checked as a key the user set
        check_names(*([name], []) if kind == "generator" else ([], [name]))
    cls = table[name]
    settings = config.section(name) if getattr(cls, "Settings", None) else None
    context = context or PlanningContext.of(config)
    if name in BUILT_IN:
        return cls(settings, context)
    return PluginPart(kind, name, _named(kind, name, "its construction", cls, settings, context))


def get_termination(name: str, config, context=None):
    """The termination `name` built from its own section of `config` and the shared context."""
    return _build("termination", TERMINATIONS, name, config, context)


def check_names(generators, terminations) -> None:
    """ValueError naming any unknown generator or termination, or one named twice."""
    for kind, names, known in (
        ("generator", generators, GENERATORS),
        ("termination", terminations, TERMINATIONS),
    ):
        for i, n in enumerate(names):
            if n in names[:i]:  # (two instances of one part, on one section)
                raise ValueError(f"planner {kind} {n!r} is named twice: {', '.join(names)}")
            if n not in known:
                raise ValueError(
                    f"unknown planner {kind} {n!r}; known: {', '.join(known)} (a part of your "
                    f"own: {REGISTER_FIRST})"
                )
