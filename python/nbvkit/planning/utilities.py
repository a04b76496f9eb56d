"""View utilities written in Python over what each candidate's rays reach.

The C++ utilities (``UtilityOptions.name``) see every cell a ray enters, in C++. A utility can
instead be written here, in numpy, over the result of one C++ call, :func:`nbvkit.candidate_rays`:
per candidate view the DISTINCT workspace cells its camera rays reached - walked exactly as
``evaluate_views`` walks them, each ray ending at its first occupied cell (inclusive), at the
camera's depth limit or where it leaves the workspace - with each cell's occupancy probability,
log-odds, state, range and incidence, as flat numpy arrays cut per candidate by ``offsets``
(a :class:`nbvkit.CandidateRays`).

:class:`PythonUtility` wraps such a function ``fn(rays) -> gains (K,)`` (or ``(gains, cells)``)
and scores candidates as the planner's ``Scorer`` does, with the same dict. A planner flies on one
registered by name: ``nbvkit.register_utility("mine", fn)``, then ``utility.name: mine`` (its
Scorer calls :func:`score_python`).

Worked example: the paper's information gain (Eq. 3) in Python, the sum of the entropies of the
distinct cells a view's rays reach::

    import numpy as np
    from nbvkit.planning.utilities import PythonUtility, per_candidate

    def entropy_gain(rays):
        p = np.clip(rays.probability, 1e-12, 1 - 1e-12)
        h = -(p * np.log(p) + (1 - p) * np.log1p(-p))        # nats; unknown cells: ln 2
        return per_candidate(rays, h)

    utility = PythonUtility(entropy_gain)
    scores = utility.score(world, poses)  # {"utility", "gain", "cells", "occupied_seen", "status"}

It ranks views much as the "ig" utility does, but is not equal to it: the map counts a cell at a
clamping threshold as certain (zero entropy, ``clamped_entropy_zero``, the authors' rule), and
reports entropy in its ``entropy_unit``. :func:`information_gain` applies the map's own rule to
the cells' float32 log-odds and gives ig's gain (to float rounding, 1e-7 relative) and ig's
``cells`` exactly (the cells of nonzero entropy).

Cost: ``bench/bench_python_utility.py`` times it against ``evaluate_views`` on the same
candidates.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from .. import _core

CandidateRays = _core.CandidateRays

__all__ = [
    "PythonUtility",
    "score_python",
    "per_candidate",
    "candidate_of_cells",
    "information_gain",
]


def candidate_of_cells(rays) -> np.ndarray:
    """(N,) int64: the candidate each row of the per-cell arrays belongs to."""
    return np.repeat(np.arange(len(rays), dtype=np.int64), np.diff(rays.offsets))


def per_candidate(rays, values) -> np.ndarray:
    """(K,) float64 sums of per-cell `values` (N,) over each candidate's cells (0 for a candidate
    with none). ``np.add.reduceat`` would misread empty candidates; this does not."""
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (rays.num_cells,):
        raise ValueError(f"per-cell values must have shape ({rays.num_cells},), got {values.shape}")
    return np.bincount(candidate_of_cells(rays), weights=values, minlength=len(rays))


def information_gain(map_options) -> Callable:
    """The paper's information gain as a Python utility, by the map's own entropy rule
    (`map_options`: the map's OccupancyMapOptions, ``world.map.options``): a cell's binary entropy
    of its log-odds, ln 2 (1 bit) when unknown, zero at a clamping threshold where the map says so
    (``clamped_entropy_zero``), in the map's ``entropy_unit``. Returns
    ``fn(rays) -> (gain (K,), cells (K,))``, cells the count of nonzero-entropy cells: the ig
    utility's gain and cells for the same candidates."""
    lo = np.float32(math.log(map_options.clamp_min / (1.0 - map_options.clamp_min)))
    hi = np.float32(math.log(map_options.clamp_max / (1.0 - map_options.clamp_max)))
    zero_at_clamp = bool(map_options.clamped_entropy_zero)
    bits = str(map_options.entropy_unit).lower().endswith("bits")

    def fn(rays):
        lg = rays.logodds  # float32, exactly as the map holds them (OctoMap's thresholds too)
        a = np.abs(lg.astype(np.float64))
        e = np.exp(-a)
        h = np.log1p(e) + a * e / (1.0 + e)  # binary entropy of sigmoid(l), nats
        h[rays.state == -1] = math.log(2.0)
        if zero_at_clamp:
            h[(rays.state != -1) & ((lg <= lo) | (lg >= hi))] = 0.0
        if bits:
            h /= math.log(2.0)
        owner = candidate_of_cells(rays)
        gain = np.bincount(owner, weights=h, minlength=len(rays))
        cells = np.bincount(owner, weights=h != 0.0, minlength=len(rays)).astype(np.int32)
        return gain, cells

    return fn


class PythonUtility:
    """A view utility written in Python: `fn(rays)` receives the CandidateRays of all K candidates
    (one C++ call) and returns their gains, an array-like (K,), or a tuple (gains (K,),
    cells (K,)) where it also counts the cells that added to each gain (otherwise ``cells`` is
    each candidate's count of distinct cells reached).

    require_occupied / require_occupied_probability: the paper's constraint, as UtilityOptions
    has it (a view must see an occupied cell; status 4 otherwise). distance_lambda (1/m): if > 0,
    the utility is gain * exp(-distance_lambda * d), d the straight distance from the vehicle to
    the view (as ig_distance weighs it); the gain is returned unweighted. name: how its errors
    name it (None: fn's __name__). What `fn` returns is checked at each call (:meth:`gains`).

    :meth:`score` has the signature and dict of a planner's ``Scorer``; to fly a planner on `fn`,
    register it by name (``nbvkit.register_utility``; see :func:`score_python`)."""

    def __init__(
        self,
        fn: Callable,
        *,
        require_occupied: bool = True,
        require_occupied_probability: float = 0.0,
        distance_lambda: float = 0.0,
        name: str | None = None,
    ):
        if not callable(fn):
            raise TypeError(f"PythonUtility needs a callable fn(rays), got {type(fn).__name__}")
        if not (math.isfinite(distance_lambda) and distance_lambda >= 0):
            raise ValueError(f"distance_lambda must be finite and >= 0, got {distance_lambda}")
        self.name = name or getattr(fn, "__name__", "python_utility")
        self.fn = fn  # called by gains(), which checks what it returns
        self.distance_lambda = float(distance_lambda)
        # validated by the core (require_occupied_probability in [0, 1))
        self.options = _core.UtilityOptions(
            require_occupied=bool(require_occupied),
            require_occupied_probability=float(require_occupied_probability),
        )

    def __repr__(self):
        return f"PythonUtility({self.name})"

    def rays(self, world, poses):
        """The CandidateRays of candidate views `poses` (K, 4 or 5) from where the vehicle is."""
        return _core.candidate_rays(
            world.map,
            poses,
            world.state.pose,
            camera=world.view_camera,
            validity=world.validity(),
            surface=world.surface,
            utility=self.options,
        )

    def gains(self, rays):
        """(gains (K,) float64, cells (K,) or None): `fn(rays)`, its exceptions noted with the
        utility's name (parts._named); TypeError / ValueError naming it unless it returned (K,)
        gains (or a tuple (gains (K,), cells (K,))) of real numbers, finite and >= 0 for the
        valid candidates (rays.status 0; the others' are not read), cells whole numbers."""
        from .parts import PartContractError, _named

        name, k = self.name, len(rays)
        out = _named("utility", name, "its call on the candidates' rays", self.fn, rays)
        if isinstance(out, tuple) and len(out) != 2:
            raise PartContractError(
                f"utility {name!r} returned a tuple of {len(out)}; it returns gains (K,) or "
                "(gains (K,), cells (K,))"
            )
        gains, cells = out if isinstance(out, tuple) else (out, None)
        arrays = {"gains": gains} if cells is None else {"gains": gains, "cells": cells}
        for what, a in arrays.items():
            arr = None
            try:
                arr = np.asarray(a)
                ok = arr.dtype.kind in "biuf"
            except Exception:
                ok = False
            if a is None or not ok:
                seq = arr is not None and isinstance(a, (list, tuple, np.ndarray))
                kind = f" of dtype {arr.dtype}" if seq else ""
                raise PartContractError(
                    f"utility {name!r} returned {type(a).__name__}{kind} {what}, not an array "
                    f"of real numbers, one a candidate ({k},)"
                )
            if arr.shape != (k,):
                raise ValueError(
                    f"utility {name!r} returned {what} of shape {arr.shape}, not ({k},): one "
                    "a candidate"
                )
        gains = np.array(gains, dtype=np.float64)
        valid = np.asarray(rays.status) == 0
        for bad, what in ((~np.isfinite(gains), "non-finite"), (gains < 0, "negative")):
            bad &= valid
            if bad.any():
                j = int(np.flatnonzero(bad)[0])
                raise ValueError(
                    f"utility {name!r} returned a {what} gain ({gains[j]}) for valid candidate "
                    f"{j} ({int(bad.sum())} such of {k} candidates); gains are finite and >= 0 "
                    "(the planner ranks gain x a travel discount)"
                )
        if cells is not None:
            c = np.array(cells, dtype=np.float64)
            with np.errstate(invalid="ignore"):
                bad = ~(np.isfinite(c) & (c >= 0) & (c == np.round(c)) & (c < 2**31))
            if (bad & valid).any():
                j = int(np.flatnonzero(bad & valid)[0])
                raise ValueError(
                    f"utility {name!r} returned cells {c[j]} for valid candidate {j}; cells are "
                    "counts (whole numbers >= 0) of the cells that added to each gain"
                )
            cells = np.where(bad, 0, c).astype(np.int32)  # invalid candidates': not read
        return gains, cells

    def score_rays(self, rays, poses=None, current=None) -> dict:
        """The scores dict from CandidateRays already computed (`poses` and `current` only for
        the distance weight)."""
        gain, cells = self.gains(rays)
        cells = np.array(np.diff(rays.offsets) if cells is None else cells, dtype=np.int32)
        status = np.array(rays.status)
        valid = status == 0
        value = gain.copy()
        if self.distance_lambda > 0:
            d = np.linalg.norm(
                np.asarray(poses, float)[:, :3] - np.asarray(current, float)[:3], axis=1
            )
            value *= np.exp(-self.distance_lambda * d)
        return {
            "utility": np.where(valid, value, -np.inf),
            "gain": gain,
            "cells": cells,
            "occupied_seen": np.array(rays.occupied_seen),
            "status": status,
        }

    def score(self, world, poses) -> dict:
        """Scores of candidate views `poses` (K, 4 or 5) from where the vehicle is, with the keys
        of ``evaluate_views``' dict: utility (K,) float64 (gain, distance-weighted if asked;
        -inf where the view is invalid, status != 0), gain (K,) float64 (fn's), cells (K,) int32,
        occupied_seen (K,) int32, status (K,) int8 (VIEW_STATUS_NAMES)."""
        return self.score_rays(self.rays(world, poses), poses, world.state.pose)


def score_python(fn: Callable, world, poses, options=None, name: str | None = None) -> dict:
    """The scores dict of candidate views `poses` (K, 4 or 5) by a utility written in Python,
    `fn(rays) -> gains (K,)` (or ``(gains, cells)``), from where the vehicle is: the entry a
    planner's scoring calls for a utility registered from Python (``register_utility``).
    `options`: UtilityOptions (None: the defaults), of which require_occupied and
    require_occupied_probability are read (the paper's constraint, status 4); no distance
    weight (see PythonUtility for one). `name`: the name its errors give (None: fn's own
    __name__)."""
    o = options if options is not None else _core.UtilityOptions()
    return PythonUtility(
        fn,
        require_occupied=o.require_occupied,
        require_occupied_probability=o.require_occupied_probability,
        name=name,
    ).score(world, poses)
