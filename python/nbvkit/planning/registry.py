"""Planner parts by name: one line each (the configuration's planner.generators and
planner.terminations name them)."""
from __future__ import annotations

from .generators.frontier import FrontierGenerator
from .generators.lattice import LatticeGenerator
from .generators.tour import CoverageTour
from .terminations.budget import Budget
from .terminations.entropy import EntropyChange
from .terminations.stall import SurfaceStall

GENERATORS = {
    "lattice": LatticeGenerator,  # the paper's CGVS / AGVS lattice around the vehicle
    "frontier": FrontierGenerator,  # views aimed at the nearest surface still to observe
    "tour": CoverageTour,  # set-cover tours over the surface still to observe
}

TERMINATIONS = {
    "entropy": EntropyChange,  # the paper's entropy change per viewable voxel (Eq. 4-6)
    "stall": SurfaceStall,  # the views stopped adding surface
    "budget": Budget,  # distance / views / time limits
}


def check_names(generators, terminations) -> None:
    """ValueError naming any unknown generator or termination."""
    for kind, names, known in (
        ("generator", generators, GENERATORS),
        ("termination", terminations, TERMINATIONS),
    ):
        for n in names:
            if n not in known:
                raise ValueError(f"unknown planner {kind} {n!r}; known: {', '.join(known)}")
