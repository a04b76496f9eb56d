"""Regions of a large structure's workspace, covered one after another (issue 37).

With tour.region_size set (off by default: docs/RESULTS.md, "Large structures", measures it),
the coverage tour plans over one region at a time, as hierarchical coverage planners do: the
workspace box is cut into a grid of equal boxes no longer than the region size; each plan weighs,
per region, the remaining value of its patches (surface still to observe and the unknown space
within the workspace that borders known free space). A plan is made in the region the vehicle
is in, else in the first of an open tour over the regions still holding value (solve_tour from
the vehicle); a region planned in is done for this pass over the regions. When no region left
in the pass keeps a view, a new pass weighs the others again (what the flight discovered may
have given them some), and the generator ends when that keeps nothing either. A plan's tour and
selection follow a region's candidates, not the structure's."""
from __future__ import annotations

import numpy as np

from ... import _core


class Regions:
    """The region grid over a box, and which regions are done."""

    def __init__(self, lo, hi, size: float):
        self.lo = np.asarray(lo, float)
        extent = np.asarray(hi, float) - self.lo
        self.shape = np.maximum(1, np.ceil(extent / size - 1e-9)).astype(int)
        self.cell = extent / self.shape
        self.done: set[int] = set()
        self.current: int | None = None

    @classmethod
    def of(cls, workspace, size) -> "Regions | None":
        """The regions of a workspace of `size` m (None when size is None or the workspace is
        one region)."""
        if size is None:
            return None
        regions = cls(workspace.bounds_min, workspace.bounds_max, float(size))
        return regions if regions.count > 1 else None

    @property
    def count(self) -> int:
        return int(np.prod(self.shape))

    def ids(self, points) -> np.ndarray:
        """(N,) the region of each point (clipped into the grid)."""
        ijk = np.floor((np.asarray(points, float).reshape(-1, 3) - self.lo) / self.cell)
        ijk = np.clip(ijk.astype(int), 0, self.shape - 1)
        return np.ravel_multi_index(ijk.T, self.shape)

    def order(self, here, centers, weights, min_value, skip=()) -> list[int]:
        """Regions to plan in, best first: the current region while its patches (centers,
        weights) hold at least min_value, then the others holding it in the order of an open
        tour from `here` over their weighted centres; regions done or in `skip` left out."""
        region = self.ids(centers)
        value = np.bincount(region, weights, minlength=self.count)
        live = set(np.flatnonzero(value >= min_value).tolist()) - self.done - set(skip)
        if not live:
            return []
        first = [self.current] if self.current in live else []
        rest = sorted(live - set(first))
        if rest:
            mid = np.array(
                [
                    np.average(centers[region == r], axis=0, weights=weights[region == r])
                    for r in rest
                ]
            )
            order, _ = _core.solve_tour(mid, np.asarray(here, float)[:3])
            rest = [rest[k] for k in order]
        return first + rest
