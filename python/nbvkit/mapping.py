"""Occupancy map (OctoMap + dense workspace mirror): the compiled classes and their constants.

``OccupancyMap`` is the C++ class ``nbv::OccupancyMap`` (see its docstring): the OctoMap octree
is the map of record, a dense mirror of the workspace box answers queries and keeps the total
entropy and cell counts incrementally. ``CellState`` names the values ``OccupancyMap.state``
returns; ``CellFlag`` the values of ``OccupancyMap.flag_grid``.
"""
from __future__ import annotations

import enum

from ._core import IntegrationStats, OccupancyMap, OccupancyMapOptions

__all__ = ["CellFlag", "CellState", "IntegrationStats", "OccupancyMap", "OccupancyMapOptions"]


class CellState(enum.IntEnum):
    """Cell occupancy state, as returned (int8) by ``OccupancyMap.state``."""

    UNKNOWN = OccupancyMap.UNKNOWN  # -1: never observed (p = 0.5)
    FREE = OccupancyMap.FREE  # 0: p < occupancy_threshold
    OCCUPIED = OccupancyMap.OCCUPIED  # 1: p >= occupancy_threshold


class CellFlag(enum.IntEnum):
    """Origin of a workspace cell's value, as in ``OccupancyMap.flag_grid`` (uint8)."""

    UNKNOWN = 0  # never observed
    OBSERVED = 1  # integrated from sensor data, or loaded from a file
    PREDICTED = 2  # set by set_unknown_cells; an observation of the cell replaces it
