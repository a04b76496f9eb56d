"""Occupancy map (OctoMap + workspace mirror): the compiled classes and their constants.

``OccupancyMap`` is the C++ class ``nbv::OccupancyMap`` (see its docstring): the OctoMap octree
is the map of record, a mirror of the workspace box answers queries and keeps the total
entropy and cell counts incrementally; the mirror holds cells only for the bricks the sensors
reached (``OccupancyMap.grid_bricks``), so its memory follows the space observed, not the box.
``CellState`` names the values ``OccupancyMap.state`` returns; ``CellFlag`` the values of
``OccupancyMap.flag_grid``.
"""
from __future__ import annotations

import enum

from . import _core
from ._core import IntegrationStats, OccupancyMap, OccupancyMapOptions
from .limits import Bound
from .settings import cpp_section

__all__ = ["CellFlag", "CellState", "IntegrationStats", "OccupancyMap", "OccupancyMapOptions"]


MapConfig = cpp_section(
    "MapConfig",
    _core.OccupancyMapOptions,
    "The occupancy map (OctoMap) and its entropy.",
    before=[
        ("resolution", float, _core.OccupancyMap.DEFAULT_RESOLUTION, "cell edge, m (authors: 0.2)")
    ],
    bounds={"resolution": Bound(lo=0, lo_open=True)},
    choices={"entropy_unit": ("nats", "bits")},
)


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
