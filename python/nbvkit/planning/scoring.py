"""Scoring candidate views: the utility's settings (section `utility`) and the one scoring entry
of a planner, ``Scorer``: C++ calls (nbvkit._core.evaluate_views) over the candidates, in parts
of SCORE_CHUNK views, with the planner's memo, or a utility written in Python
(register_utility)."""
from __future__ import annotations

from typing import Optional

import numpy as np

from .. import _core
from ..limits import Bound
from ..settings import cpp_section


def utility_names() -> tuple:
    """The utilities a configuration may name: the C++ core's and those registered from
    Python."""
    from .registry import UTILITIES

    return tuple(_core.utility_names()) + tuple(UTILITIES)


UtilityConfig = cpp_section(
    "UtilityConfig",
    _core.UtilityOptions,
    "How candidate views are scored (paper sec. 3.4 and the peers' utilities).",
    before=[
        (
            "rays_x",
            Optional[int],
            None,
            "rays across the horizontal FOV; null: one per map cell on the far plane (47 at 0.2 m)",
        ),
        ("rays_y", Optional[int], None, "rays across the vertical FOV; null: 34 at 0.2 m"),
        (
            "saturation_hits",
            int,
            16,
            "surface: a cell is done once a camera scan from a side it had not been seen from "
            "puts this many hits in it, none in a square (a quarter of the map's cells on a side) "
            "that held none: no view is credited for it, it is no target (RESULTS.md); 0: never",
        ),
    ],
    choices={"name": utility_names},
    bounds={
        "rays_x": Bound(lo=0, lo_open=True, hi=4096),
        "rays_y": Bound(lo=0, lo_open=True, hi=4096),
        "saturation_hits": Bound(lo=0, hi=_core.SurfaceObservations.MAX_SATURATION_HITS),
        "distance_lambda": Bound(lo=0),
        "require_occupied_probability": Bound(lo=0, hi=1, hi_open=True),
        "min_visibility": Bound(lo=0, hi=1, lo_open=True, hi_open=True),
        "frontier_prior": Bound(lo=0, hi=1, hi_open=True),
        "unknown_prior": Bound(lo=0, hi=1, hi_open=True),
        "coverage_cone_deg": Bound(lo=0, hi=180),
        "density_target": Bound(lo=0, lo_open=True),
        "weight_entropy": Bound(lo=0),
        "weight_density": Bound(lo=0),
        "weight_prediction": Bound(lo=0),
        "dense_spacing": Bound(lo=0),
        "max_incidence_deg": Bound(lo=0, lo_open=True, hi=90),
        "incidence_min_patches": Bound(lo=0, hi=16),
    },
)


def _options_for(self, cls, _plain=UtilityConfig.options_for):
    """The C++ options of the section; a utility registered from Python goes to the C++ core
    (its checks, the occupied constraint, the coverage cone) under the name 'ig', which the
    core knows: built under its own name they failed its check of the name."""
    from .registry import UTILITIES

    if self.name not in UTILITIES:
        return _plain(self, cls)
    return cls(**{f: "ig" if f == "name" else getattr(self, f) for f in cls.fields()})


UtilityConfig.options_for = _options_for
UtilityConfig.options = lambda self: _options_for(self, UtilityConfig.OPTIONS)


#: candidate views scored per core call: a proposal of millions is scored in parts, so Ctrl-C
#: (or a kill) stops it within a part, not after the whole proposal. A view's walks took up to
#: 1.2 ms (50,000 views of a 0.1 m map in 60 s, SIGINT waiting for the end): 8,192 views are
#: about 10 s at that rate (65,536 were over a minute)
SCORE_CHUNK = 1 << 13
#: proposals a Scorer's memo keeps a record unused for (each part of a proposal is a call)
KEEP_CALLS = 8


class Scorer:
    """A planner's one scoring entry: the utility's scores of candidate views `poses` (K, 4 or
    5) from where the vehicle is, in one call, with one memo kept across calls (the paper's IG
    walks: the same scores, fewer walks). A utility registered from Python
    (planning.registry.register_utility) is scored over the candidates' rays instead."""

    def __init__(self, utility: UtilityConfig):
        from .registry import UTILITIES

        self.name = utility.name
        self.surface = utility.name == "surface"  # its gain: cells of new surface
        self.python = UTILITIES.get(utility.name)
        self.options = utility.options()  # for a Python utility: its occupied constraint
        self.memo = _core.ViewMemo(keep_calls=KEEP_CALLS)

    def __call__(self, world, poses) -> dict:
        """dict of (K,) arrays: utility, gain, cells, occupied_seen, status (evaluate_views)."""
        if self.python is not None:
            from .utilities import score_python

            return score_python(self.python, world, poses, self.options, name=self.name)
        kw = dict(
            camera=world.view_camera,
            utility=self.options,
            validity=world.validity(),
            surface=world.surface,
            memo=self.memo,
        )
        here = world.state.pose
        if len(poses) <= SCORE_CHUNK:
            return _core.evaluate_views(world.map, poses, here, **kw)
        poses = np.asarray(poses)
        n = -(-len(poses) // SCORE_CHUNK)
        if self.memo.keep_calls < KEEP_CALLS * n:  # records kept over KEEP_CALLS proposals
            self.memo = _core.ViewMemo(keep_calls=KEEP_CALLS * n)
        parts = [
            _core.evaluate_views(world.map, poses[i : i + SCORE_CHUNK], here, **kw)
            for i in range(0, len(poses), SCORE_CHUNK)
        ]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def delivered(self, world, choice):
        """(expected, realized) m^2 of the view just flown, in the surface utility's own terms
        (None, None for other utilities): the new surface its score counted when it was chosen,
        and how much of that the frame brought - the score's drop when the same pose is scored
        again on the map after it. What is still counted after the view was flown from there
        (unknown space the structure hides, surface beyond the camera's reach) was expected of
        it and not delivered."""
        if not self.surface:
            return None, None
        after = self(world, choice.pose[None])
        cell_m2 = world.map.resolution**2
        left = float(after["gain"][0]) if after["status"][0] == 0 else 0.0
        return choice.gain * cell_m2, max(0.0, choice.gain - left) * cell_m2
