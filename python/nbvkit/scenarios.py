"""The scenarios a mission can fly: the rows of the paper's Table 2 and nbvkit's own planners.

A scenario is a preset of configuration keys, applied over the defaults and under whatever the
user sets (a config file, ``--set``): ``nbvkit run --scenario 3 --set lattice.sigma=2`` flies the
paper's Scenario 3 with a different AGVS factor. This table is the only place that lists
scenarios; the CLI, the config validation and Table 2 read it. The defaults of
``nbvkit.Config`` are the recommended planner's except where a C++ default is the paper's (the
utility, blocked legs) or the paper's workspace: those the ``surface`` preset sets.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .cloud import DEFAULT_MIN_Z, DEFAULT_VOXEL_SIZE
from .limits import refuse_case_twin
from .origins import caller, clash, note


@dataclass(frozen=True)
class Scenario:
    description: str
    settings: dict = field(default_factory=dict)  # dotted config key -> value
    table2: tuple | None = None  # (profiling, symmetry, sampling) columns of the paper's Table 2
    origin: str | None = field(default=None, compare=False)  # the file that registered it


# The paper's method (sec. 3): the CGVS/AGVS lattice scored by information gain, straight legs
# (blocked ones rejected), the entropy-per-viewable-voxel termination, in the paper's 40 x 40 x
# 10 m style workspace (the structure's box grown by 2.5 m), with Algorithm 1's profiling closed
# back to its start and a return to the start pose, the laser alone; the camera fixed level.
_PAPER = {
    "camera.gimbal_pitch_deg": (0.0, 0.0),
    "workspace.margin_xy": 2.5,
    "workspace.margin_z": 2.5,
    "planner.generators": ["lattice"],
    "planner.terminations": ["entropy"],
    "planner.min_gain": 0.0,
    "planner.travel_lambda": 0.0,
    "planner.frame_step": 0.0,
    "utility.name": "ig",
    "utility.saturation_hits": 0,
    "vehicle.blocked_path": "reject",
    "vehicle.widen_swept_volume": False,
    "vehicle.keep_off_hits": False,
    "cloud.camera_voxel": DEFAULT_VOXEL_SIZE,
    "cloud.min_z": DEFAULT_MIN_Z,  # the authors' ground removal (their world had a ground)
    "profiling.method": "circular",
    "profiling.waypoints": 5,
    "profiling.camera_step": 0.0,
    "profiling.close_circle": True,
    "profiling.arcs": "level",
    "profiling.return_to_start": True,
    "symmetry.refresh_every": 0,
    "max_iterations": 1000,
}

# nbvkit's surface planners: the surface utility (expected new surface), A* legs through known
# free space, and room round the structure for the camera's stand-off (5 m: 0.6 x its 8 m range;
# the paper's 2.5 m margin pins views against tall facades).
_SURFACE = {
    "workspace.margin_xy": 5.0,
    "utility.name": "surface",
    "utility.require_occupied": False,
    "vehicle.blocked_path": "plan",
}

SCENARIOS: dict[str, Scenario] = {
    "profile": Scenario(
        "the laser profile alone (Algorithm 1); its symmetry is reported, not used",
        {**_PAPER, "profiling.enabled": True, "symmetry.mode": "report", "planner.generators": []},
        ("yes", "no", "-"),
    ),
    "1": Scenario(
        "the paper's Scenario 1: no profiling, no symmetry, CGVS",
        {**_PAPER, "profiling.enabled": False, "symmetry.mode": "none", "lattice.method": "cgvs"},
        ("no", "no", "CGVS"),
    ),
    "2": Scenario(
        "Scenario 2: profiling, CGVS",
        {**_PAPER, "profiling.enabled": True, "symmetry.mode": "none", "lattice.method": "cgvs"},
        ("yes", "no", "CGVS"),
    ),
    "3": Scenario(
        "Scenario 3: profiling, AGVS",
        {**_PAPER, "profiling.enabled": True, "symmetry.mode": "none", "lattice.method": "agvs"},
        ("yes", "no", "AGVS"),
    ),
    "4": Scenario(
        "Scenario 4: profiling, symmetry prediction, CGVS",
        {
            **_PAPER,
            "profiling.enabled": True,
            "symmetry.mode": "predict",
            "lattice.method": "cgvs",
        },
        ("yes", "yes", "CGVS"),
    ),
    "5": Scenario(
        "Scenario 5: profiling, symmetry prediction, AGVS (the paper's full method)",
        {
            **_PAPER,
            "profiling.enabled": True,
            "symmetry.mode": "predict",
            "lattice.method": "agvs",
        },
        ("yes", "yes", "AGVS"),
    ),
    "surface": Scenario(
        "nbvkit's recommended planner: a profile round the structure's grown hull (the laser, "
        "and a camera frame every metre flown), symmetry prediction, then coverage tours of "
        "the surface still to observe (views chosen and ordered by cheapest insertion, each "
        "paying for its detour; level views of the surface, and views of the unknown space "
        "pitched down into it) until no planned view is worth its flight",
        _SURFACE,
    ),
    "surface_gimbal": Scenario(
        "the recommended planner with the camera on its gimbal (issue 33): a flight envelope "
        "reaching the camera's far stand-off above the structure, and tours that also face roofs "
        "from above and undersides from below by the gimbal's pitch",
        {**_SURFACE, "workspace.margin_z": None, "placement.gimbal": True},
    ),
    "model": Scenario(
        "plan from a known model (issue 33): the structure's mesh written into the map as seen "
        "from the navigation space, then the recommended planner's coverage tours over every "
        "surface cell, flown with the real camera; the reference for how close an online "
        "planner comes to a plan made with full knowledge",
        {
            **_SURFACE,
            "profiling.enabled": False,
            "symmetry.mode": "none",
            "planner.generators": ["model"],
            # frames every 0.5 m: with the whole surface known the frames on the legs see what
            # views left out would have (RESULTS.md)
            "planner.frame_step": 0.5,
        },
    ),
    "surface_nbv": Scenario(
        "greedy next-best-view on the surface utility: views aimed at the surface still to "
        "observe and the local lattice, the best gain * exp(-travel_lambda * path) flown each "
        "iteration, until the surface stalls",
        {
            **_SURFACE,
            "planner.generators": ["frontier", "lattice"],
            "planner.terminations": ["stall", "budget"],
        },
    ),
}

#: The scenarios of the paper's Table 2, in its row order.
TABLE2 = ("profile", "1", "2", "3", "4", "5")
#: The scenario `nbvkit run` flies unless told otherwise.
DEFAULT = "surface"


#: The scenarios nbvkit ships (those registered from a script may be replaced).
BUILT_IN = frozenset(SCENARIOS)


def register_scenario(name: str, description: str, settings: dict, *, replace=False) -> None:
    """Adds a scenario (a preset of dotted config keys, e.g. a plugin's planner:
    {"planner.generators": ["ring"]}); `nbvkit run --planner`, `nbvkit compare --planners` and
    the configuration accept its name. `replace`: `name` may be a scenario registered before
    from a script (a notebook cell run again), which this one replaces; never one of nbvkit's."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a scenario name must be a non-empty str, got {name!r}")
    if name in BUILT_IN:
        raise ValueError(
            f"scenario {name!r} is one of nbvkit's own"
            + (" and cannot be replaced" if replace else ": registered already")
            + "; choose another name"
        )
    if name in SCENARIOS and not replace:
        raise ValueError(
            f"scenario {name!r} is registered already{clash(SCENARIOS[name].origin)}; choose "
            "another name, or replace=True to replace it"
        )
    refuse_case_twin(name, SCENARIOS, "scenario")
    from collections.abc import Mapping

    if not isinstance(settings, Mapping) or not all(isinstance(k, str) for k in settings):
        raise ValueError(
            f"scenario {name!r}: settings must be a mapping of dotted config keys, got "
            f"{type(settings).__name__}"
        )
    if "scenario" in settings:  # (the user's scenario is set: the preset's was never read)
        raise ValueError(
            f"scenario {name!r} sets 'scenario': a preset names config keys, not another "
            "scenario; copy that scenario's settings (nbvkit.scenarios.SCENARIOS[...].settings)"
        )
    SCENARIOS[name] = Scenario(description, dict(settings), origin=caller()[0])
    note("scenario", name)
