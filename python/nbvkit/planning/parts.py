"""What a planner is made of, and what its parts exchange.

A planner composes *generators* (propose candidate views), a *utility* (scores them, in one C++
call: nbvkit._core.evaluate_views), a *selection* (the best valid view and the path to it) and
*terminations* (when to stop). Generators and terminations are small classes registered by name
in registry.py; a new one is one file and one registry line (or, from a script,
``nbvkit.register_generator`` / ``register_termination``).

A part is built as ``Part(settings, context)``: ``settings`` is its own section of the
configuration (an instance of its ``Settings`` dataclass, the YAML section named like the part;
None for a part without one), ``context`` the few shared things every part may read
(PlanningContext).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Protocol

import numpy as np

from ..limits import add_note, shorten


@dataclass(frozen=True)
class PlanningContext:
    """What the planner's parts share besides their own sections: the camera and vehicle, the
    map's cell size, and the sections of the shared planning blocks (placement of views at
    surface targets, the utility, the planner's thresholds)."""

    camera: object  # sensors.CameraConfig
    vehicle: object  # world.VehicleConfig
    resolution: float  # m, the map's cell
    utility: object  # scoring.UtilityConfig
    targets: object  # nbvkit._core.SurfaceTargetOptions (placement.target_options)
    placement: object  # placement.PlacementConfig
    planner: object  # planner.PlannerConfig

    @classmethod
    def of(cls, config) -> "PlanningContext":
        from .placement import target_options

        return cls(
            config.camera,
            config.vehicle,
            config.map.resolution,
            config.utility,
            target_options(config.targets, config.utility),
            config.placement,
            config.planner,
        )


@dataclass
class Proposal:
    """Candidate views (K, 4) [x, y, z, yaw] (level) or (K, 5) [x, y, z, yaw, pitch] (the camera
    gimbal's pitch, radians, > 0 looks down) from one generator. An exclusive proposal
    (a tour's next view) is scored alone; the others of an iteration are scored together."""

    poses: np.ndarray
    source: str
    exclusive: bool = False
    aims: Optional[np.ndarray] = None  # (K, 3) the point each candidate is aimed at, if any

    def __getstate__(self):  # a union's members (its generators, see propose) stay behind
        return {k: v for k, v in self.__dict__.items() if k != "members"}


@dataclass
class Choice:
    """The view selected among a proposal: its index, pose, scores and the path to it."""

    index: int
    pose: np.ndarray
    utility: float
    gain: float
    path: Optional[np.ndarray]  # (P, 3) waypoints from the vehicle, or None: straight
    length_m: float


@dataclass
class Step:
    """One view of the mission: what was chosen and what it changed."""

    iteration: int
    choice: Choice
    source: str
    candidates: int
    valid: int
    entropy_before: float
    entropy_after: float
    delta_ev: float  # (E_before - E_after) / C_view, the paper's Eq. 4
    new_surface_m2: float  # m^2 of surface first seen (from any side), the leg's frames included
    distance_m: float  # total flown so far
    extra: dict = field(default_factory=dict)  # generator-specific columns (e.g. AGVS alpha)
    expected_m2: Optional[float] = None  # new surface the surface utility expected of it, m^2
    realized_m2: Optional[float] = None  # how much of that it brought (Planner.delivered)
    proposal: Optional[Proposal] = None  # the proposal it was chosen from
    makers: list = field(default_factory=list)  # the generators that proposed it

    @classmethod
    def of(cls, iteration, found, world, entropy_before, c_view, new_cells) -> "Step":
        """The step of a view just flown and integrated: found = (proposal, its generators,
        scores, choice) as Planner.next_view gave it; c_view: the paper's C_view."""
        proposal, makers, scores, choice = found
        entropy_after = world.map.total_entropy()
        return cls(
            iteration,
            choice,
            _source_of(proposal, choice.index),
            len(proposal.poses),
            int((scores["status"] == 0).sum()),
            entropy_before,
            entropy_after,
            (entropy_before - entropy_after) / c_view,
            new_cells * world.map.resolution**2,
            world.state.distance_m,
            proposal=proposal,
            makers=makers,
        )


def _source_of(proposal, index: int) -> str:
    """The source of the view `index` of `proposal`: in a union of several generators' proposals
    (parts.propose), that of the generator whose view it is."""
    for _, start, own in getattr(proposal, "members", ()):
        if start <= index < start + len(own.poses):
            return own.source
    return proposal.source


#: The smallest factor threshold_scale gives: at a tenth of the thresholds (0.12 m^2 of new
#: surface a view, 3 cells of the 0.2 m map) a view's gain is down to the map's own noise. On a
#: 1 m cube, views planned for less only re-observed cells from new directions: 12 views and 51 m
#: for the same coverage as 3 views and 34 m.
MIN_THRESHOLD_SCALE = 0.1
#: The smallest factor of tour.rate's scale (the rate takes its square root): the rate keeps
#: shrinking with the structure below MIN_THRESHOLD_SCALE, as its tours do. At that floor a 1 m
#: structure (4 m^2 of surface) needed a 0.33 m^2 view to pay 0.16 m^2 a metre of its detour and
#: ended at 53 % of its observable surface with no view flown; unfloored, 88 % with 2 views (a
#: 1 m cube: 3 views and 41 m for the coverage the profile alone gave in 31 m).
MIN_RATE_SCALE = 1e-4


def threshold_scale(occupancy_map, reference_area: float, floor: float | None = None) -> float:
    """The factor the surface planners' thresholds take on a structure smaller than
    `reference_area` m^2 (planner.reference_area): min(1, A / reference_area), A the surface the
    map shows now (its occupied cells, predicted ones included, x the cell area), and at least
    `floor` (None: MIN_THRESHOLD_SCALE). Areas (tour.min_gain, planner.min_gain, stall.min_gain)
    are multiplied by it, rates per metre (tour.rate) by its square root at floor
    MIN_RATE_SCALE, as a structure's surface and its tour shrink with its size. A structure at
    least that large keeps them as set: its views' gains are bounded by the camera's footprint,
    not by the structure. reference_area 0: thresholds as set."""
    if reference_area <= 0:
        return 1.0
    area = occupancy_map.counts()["occupied"] * occupancy_map.resolution**2
    floor = MIN_THRESHOLD_SCALE if floor is None else floor
    return min(1.0, max(floor, area / reference_area))


def propose(generators, world):
    """(proposal, generators): an exclusive proposal of the first generator that has one, else
    the union of the others' proposals and the generators that made it; (None, []) if none."""
    merged, makers = [], []
    for g in generators:
        p = g.propose(world)
        if p is None:
            continue
        if p.exclusive:
            return p, [g]
        merged.append(p)
        makers.append(g)
    if len(merged) <= 1:
        return (merged[0] if merged else None), makers
    width = max(p.poses.shape[1] for p in merged)  # level (K, 4) beside (K, 5): pitch 0
    poses = np.vstack([np.pad(p.poses, ((0, 0), (0, width - p.poses.shape[1]))) for p in merged])
    union = Proposal(poses, "+".join(p.source for p in merged))
    starts = np.cumsum([0] + [len(p.poses) for p in merged])
    union.members = list(zip(makers, starts.tolist(), merged))  # (generator, first row, its own)
    return union, makers


def run_hooks(hooks: dict, world, step: Step) -> None:
    """Each hook(world, step) in order. One that raises (a generator's feedback) does not keep
    the later ones (the recorder's) from running: the view was flown, and is recorded, before
    the first error propagates (Ctrl-C at once)."""
    error = None
    for hook in hooks.values():
        try:
            hook(world, step)
        except Exception as e:
            error = error or e
    if error is not None:
        raise error


class Generator(Protocol):
    """Proposes candidate views; told which one (if any) was flown."""

    def propose(self, world) -> Optional[Proposal]:
        """Candidates for this iteration, or None when this generator has nothing left (an
        optional attribute `stop_reason` names the cause when it is not that the surface is
        covered)."""

    def feedback(self, world, proposal: Proposal, step: Optional[Step]) -> None:
        """After selection: `step` is the view flown (None: no candidate of `proposal` was
        valid and worth flying)."""


class Termination(Protocol):
    def check(self, world, step: Step) -> Optional[str]:
        """The reason to stop after `step`, or None."""


# ---------------------------------------------------------------- parts registered from a script


class PartContractError(TypeError):
    """A planner part (yours) returned what the planner cannot take: the wrong type (a list for
    a Proposal, True for a reason to stop, strings for gains). The message names the part."""


_RAISED_BY = "raised by the "  # the start of the note _named adds


def raised_by_a_part(e: BaseException) -> bool:
    """Whether a part registered from a script raised `e` (_named noted it)."""
    return any(str(n).startswith(_RAISED_BY) for n in getattr(e, "__notes__", ()) or ())


def _named(kind: str, name: str, call: str, fn, *args):
    """fn(*args) of the part `name` registered from a script or a plugin file. An exception of
    its own propagates as it is (a script may catch its own types; a mission that raises it after
    its views started keeps what it flew, recorder.fly_into), with a note naming the part, where
    it was registered (origins.source: the plugin file, or "a script") and the call (Python
    3.11+: printed under the traceback's last line, in ``e.__notes__``)."""
    try:
        return fn(*args)
    except Exception as e:
        from ..origins import source

        add_note(e, f"{_RAISED_BY}{kind} {name!r} (registered from {source(kind, name)}) in {call}")
        raise


def check_proposal(p, who: str) -> Proposal:
    """`p` (what a generator's propose returned, not None) checked for the planner: a Proposal
    whose poses are a finite (K, 4) or (K, 5) array (made float64, C-contiguous) with K >= 1 and
    pitch within +-pi/2, a str source, aims None or (K, 3). TypeError / ValueError naming the
    generator `who` otherwise."""
    if not isinstance(p, Proposal):
        raise PartContractError(
            f"generator {who!r}: propose returned {type(p).__name__}, not a "
            "nbvkit.planning.parts.Proposal or None"
        )
    poses = _numbers(p.poses, who, "poses")
    if poses.ndim != 2 or poses.shape[1] not in (4, 5):
        raise ValueError(
            f"generator {who!r}: its proposal's poses have shape {poses.shape}, not (K, 4) "
            "[x, y, z, yaw] or (K, 5) [x, y, z, yaw, pitch]"
        )
    if len(poses) == 0:
        raise ValueError(
            f"generator {who!r}: its proposal has no views (K = 0); propose returns None when "
            "the generator has none"
        )
    bad = ~np.isfinite(poses).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"generator {who!r}: its proposal's pose {k} is not finite: {poses[k].tolist()}"
        )
    if poses.shape[1] == 5 and np.any(np.abs(poses[:, 4]) > np.pi / 2):
        k = int(np.flatnonzero(np.abs(poses[:, 4]) > np.pi / 2)[0])
        raise ValueError(
            f"generator {who!r}: its proposal's pose {k} has pitch {poses[k, 4]} rad, beyond "
            "+-pi/2 (> 0 looks down)"
        )
    if not isinstance(p.source, str):
        raise PartContractError(
            f"generator {who!r}: its proposal's source must be a str, got {type(p.source).__name__}"
        )
    if not p.source or not p.source.isprintable():  # a column of iterations.csv, the report's
        raise ValueError(
            f"generator {who!r}: its proposal's source must be a name on one line (printable, "
            f"not empty), got {p.source!r}"
        )
    if p.aims is not None:
        aims = _numbers(p.aims, who, "aims")
        if aims.shape != (len(poses), 3):
            raise ValueError(
                f"generator {who!r}: its proposal's aims have shape {aims.shape}, not "
                f"({len(poses)}, 3)"
            )
        if not np.isfinite(aims).all():
            k = int(np.flatnonzero(~np.isfinite(aims).all(axis=1))[0])
            raise ValueError(f"generator {who!r}: its proposal's aim {k} is not finite: {aims[k]}")
        p.aims = aims
    p.poses = poses
    return p


def _numbers(a, who: str, what: str) -> np.ndarray:
    """`a` as a C-contiguous float64 array; TypeError naming the generator `who` unless it holds
    real numbers (complex ones are refused, not cut to their real part)."""
    try:
        arr = np.asarray(a)
        if arr.dtype.kind == "c" or (arr.dtype == object and any(map(np.iscomplexobj, arr.flat))):
            raise TypeError("complex numbers")
        if arr.dtype.kind == "b":  # (a mask is not coordinates: it flew 0 and 1 m)
            raise TypeError("booleans")
        return np.ascontiguousarray(arr, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise PartContractError(
            f"generator {who!r}: its proposal's {what} are not numbers ({e})"
        ) from None


class PluginPart:
    """A generator or termination registered from a script, as the planner holds it: its calls
    checked and named (check_proposal; a termination's reason a non-empty str or None; an
    exception of its own noted with its name, _named). Any other attribute is the part's own
    (``.part``)."""

    def __init__(self, kind: str, name: str, part):
        needs = ("propose", "feedback") if kind == "generator" else ("check",)
        missing = [m for m in needs if not callable(getattr(part, m, None))]
        if missing:
            built = (  # a plain function registered: called as a builder, it returned its result
                f": registered {name!r} is called as f(settings, context) to build the part, "
                f"and returned {type(part).__name__}; register a class with "
                + " and ".join(f"{m}()" for m in needs)
                if part is None or isinstance(part, (bool, int, float, str, tuple, list, dict))
                else ""
            )
            raise TypeError(
                f"{kind} {name!r} ({type(part).__name__}) has no method "
                + " or ".join(f"{m}()" for m in missing)
                + built
            )
        self.__dict__.update(kind=kind, name=name, part=part, _rejected=None)

    def __getattr__(self, attr):
        if attr in ("kind", "name", "part", "_rejected") or attr.startswith("__"):
            raise AttributeError(attr)  # not built yet (copy, pickle): not the part's
        return getattr(self.part, attr)

    def __setattr__(self, attr, value):
        setattr(self.part, attr, value)

    def __repr__(self):
        return f"<{self.kind} {self.name!r}: {self.part!r}>"

    def propose(self, world):
        p = _named(self.kind, self.name, "propose()", self.part.propose, world)
        if p is None:
            return None
        p = check_proposal(p, self.name)
        if p.poses.shape[1] == 5:  # the gimbal's range, as the vehicle flies it (World.fly_to)
            lo, hi = world.config.camera.gimbal_pitch_deg
            deg = np.degrees(p.poses[:, 4])
            out = np.flatnonzero((deg < lo - 1e-9) | (deg > hi + 1e-9))
            if len(out):
                raise ValueError(
                    f"generator {self.name!r}: its proposal's pose {out[0]} has pitch "
                    f"{deg[out[0]]:g} deg, outside camera.gimbal_pitch_deg [{lo:g}, {hi:g}] deg"
                )
        last = self.__dict__["_rejected"]
        if last is not None and p.exclusive and np.array_equal(p.poses, last):
            raise RuntimeError(
                f"generator {self.name!r} proposed again the exclusive views it was just told "
                "none of was valid and worth flying (feedback with step None): it would be "
                "asked forever; move on from them in feedback, or return None"
            )
        return p

    @property
    def stop_reason(self):
        """The part's own stop_reason (optional): None, or why it proposes nothing, a
        non-empty str (TypeError otherwise)."""
        reason = getattr(self.part, "stop_reason", None)
        if reason is None:
            return None
        return _checked_reason(
            f"generator {self.name!r}: its stop_reason is",
            reason,
            "it is None or why it proposes nothing, "
            + REASON_WORDS.format(example="'no_reachable_view'"),
        )

    def feedback(self, world, proposal, step):
        # (proposals rejected in a row are bounded by Planner.next_view)
        proposal, step = _own(self, proposal, step)
        rejected = step is None and proposal.exclusive
        # a copy: a generator may write its next views into the same array
        self.__dict__["_rejected"] = proposal.poses.copy() if rejected else None
        _named(self.kind, self.name, "feedback()", self.part.feedback, world, proposal, step)

    def check(self, world, step):
        reason = _named(self.kind, self.name, "check()", self.part.check, world, step)
        if reason is None:
            return None
        return _checked_reason(
            f"termination {self.name!r}: check returned",
            reason,
            "it returns the reason to stop, "
            + REASON_WORDS.format(example="'distance_cap'")
            + ", or None to go on",
        )


#: The longest reason to stop a part may give (a summary field, a console line, a table's cell;
#: a 10 MB one had been kept as given).
MAX_REASON_CHARS = 200
REASON_WORDS = (
    f"a non-empty str on one line of at most {MAX_REASON_CHARS} characters (e.g. {{example}})"
)


def _checked_reason(said: str, reason, expected: str) -> str:
    """`reason` when it is a part's reason to stop: a non-empty str on one line of at most
    MAX_REASON_CHARS characters, not one nbvkit keeps for itself (_not_reserved);
    PartContractError (`said` REASON; `expected`) otherwise."""
    if not (
        isinstance(reason, str)
        and reason.strip()
        and reason.isprintable()
        and len(reason) <= MAX_REASON_CHARS
    ):
        raise PartContractError(f"{said} {shorten(reason)}; {expected}")
    _not_reserved(said, reason)
    return reason


def _not_reserved(said: str, reason: str) -> None:
    """ValueError (`said` REASON, ...) when a part's reason to stop is one nbvkit's summary keeps
    for itself: a run stopped by an error or Ctrl-C, or by a budget (`stopped_by_budget`)."""
    from .terminations.budget import BUDGET_KEYS

    if reason in ("failed", "interrupted"):
        why = "a run stopped by an error or Ctrl-C"
    elif reason in BUDGET_KEYS:
        why = f"a run stopped by its budget ({BUDGET_KEYS[reason]})"
    else:
        return
    raise ValueError(
        f"{said} {reason!r}, which nbvkit's summary keeps for {why}; name your own reason"
    )


def _own(part, proposal, step):
    """(proposal, step) as the generator `part` is told of them: where its views were scored
    with other generators' (one proposal, parts.propose), its own proposal, and the step only if
    the view flown is one of its own, with choice.index its row there (None otherwise). The step
    is the generator's copy (its choice, pose and path too): what it sets there does not change
    the mission's record of the view, but for `extra`, shared: a generator's own columns of
    iterations.csv (the lattice's alpha)."""
    from dataclasses import replace

    def told(step, index, proposal):
        c = step.choice
        path = None if c.path is None else np.array(c.path)
        choice = replace(c, index=index, pose=np.array(c.pose), path=path)
        return replace(step, choice=choice, proposal=proposal)

    for g, start, own in getattr(proposal, "members", ()):
        if g is part:
            i = -1 if step is None else step.choice.index - start
            if not 0 <= i < len(own.poses):
                return own, None
            return own, told(step, i, own)
    return proposal, None if step is None else told(step, step.choice.index, proposal)
