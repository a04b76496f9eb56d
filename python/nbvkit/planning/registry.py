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

#: Utilities written in Python (name -> function of nbvkit.CandidateRays, see
#: planning/utilities.py); the C++ core's are nbvkit._core.utility_names().
UTILITIES: dict = {}

#: Section names a part may not take: the configuration's own.
RESERVED = frozenset(
    "seed scenario start start_pose max_iterations progress mesh workspace map camera laser "
    "cloud vehicle utility targets placement planner profiling symmetry evaluation "
    "observability report sampling termination".split()
)


def _check_new(name: str, kind: str, taken) -> None:
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"a {kind} name must be an identifier, got {name!r}")
    if name in RESERVED:
        raise ValueError(f"{kind} name {name!r} is a section of the configuration; choose another")
    if name in taken:
        raise ValueError(f"a {kind} named {name!r} is registered already")


def register_generator(name: str, cls) -> None:
    """Adds a generator: `cls(settings, context)` with propose(world) and feedback(world,
    proposal, step) (parts.Generator); `cls.Settings` (optional) is the dataclass of its
    configuration section `name`."""
    _check_new(name, "generator", {**GENERATORS, **TERMINATIONS})
    GENERATORS[name] = cls


def register_termination(name: str, cls) -> None:
    """Adds a termination: `cls(settings, context)` with check(world, step) -> reason or None
    (parts.Termination); `cls.Settings` (optional) as for a generator."""
    _check_new(name, "termination", {**GENERATORS, **TERMINATIONS})
    TERMINATIONS[name] = cls


def register_utility(name: str, fn) -> None:
    """Adds a utility written in Python: `fn(rays)` -> (K,) gains of K candidate views from what
    their rays reach (nbvkit.CandidateRays); named by ``utility.name``."""
    from .. import _core

    if not callable(fn):
        raise TypeError(f"utility {name!r} must be callable, got {type(fn).__name__}")
    _check_new(name, "utility", {**UTILITIES, **dict.fromkeys(_core.utility_names())})
    UTILITIES[name] = fn


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
    """The generator `name` built from its own section of `config` and the shared context."""
    from .parts import PlanningContext

    cls = GENERATORS[name]
    settings = config.section(name) if getattr(cls, "Settings", None) else None
    return cls(settings, context or PlanningContext.of(config))


def get_termination(name: str, config, context=None):
    """The termination `name` built from its own section of `config` and the shared context."""
    from .parts import PlanningContext

    cls = TERMINATIONS[name]
    settings = config.section(name) if getattr(cls, "Settings", None) else None
    return cls(settings, context or PlanningContext.of(config))


def check_names(generators, terminations) -> None:
    """ValueError naming any unknown generator or termination."""
    for kind, names, known in (
        ("generator", generators, GENERATORS),
        ("termination", terminations, TERMINATIONS),
    ):
        for n in names:
            if n not in known:
                raise ValueError(f"unknown planner {kind} {n!r}; known: {', '.join(known)}")
