"""Symmetry prediction kept current during the camera stage: the camera's hits reflected about
the detected mirror plane are predicted into the map's unknown cells every
symmetry.refresh_every views (the paper predicts once, from the profile; scenarios 4/5 keep
that). The surface utility counts a predicted cell as surface with its predicted probability, so
views that would confirm the prediction are rewarded."""
from __future__ import annotations

import numpy as np

from . import _core


class SymmetryRefresh:
    """world: the mission's World; plane: [nx, ny, nz, d] of an accepted detection; cfg: the
    config's symmetry section."""

    SUBSAMPLE = 16  # every 16th camera hit: a frame's hits are far denser than the map's cells

    def __init__(self, world, plane, cfg):
        self.world, self.plane, self.cfg = world, np.asarray(plane, float), cfg
        self.pending: list[np.ndarray] = []
        self.views = 0

    def after_view(self, step) -> int:
        """Buffers the view's hits; every refresh_every views predicts their reflections into
        unknown cells. Returns the number of cells predicted now."""
        scan = step.extra.get("scan")
        if scan is not None and len(scan.hits):
            self.pending.append(np.asarray(scan.hits[:: self.SUBSAMPLE]))
        self.views += 1
        if self.views % self.cfg.refresh_every or not self.pending:
            return 0
        points = np.vstack(self.pending)
        self.pending.clear()
        mirrored = _core.reflect_points(points, self.plane)
        return int(self.world.map.set_unknown_cells(mirrored, self.cfg.prediction_probability))
