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

import numpy as np

from . import _core
from ._core import IntegrationStats, OccupancyMap, OccupancyMapOptions
from .limits import Bound
from .work_limits import MAX_RESOLUTION, MissionError
from .settings import cpp_section
from .workspace import grounding_shift

__all__ = [
    "CellFlag",
    "CellState",
    "IntegrationStats",
    "OccupancyMap",
    "OccupancyMapOptions",
    "new_map",
]


MapConfig = cpp_section(
    "MapConfig",
    _core.OccupancyMapOptions,
    "The occupancy map (OctoMap) and its entropy.",
    before=[
        ("resolution", float, _core.OccupancyMap.DEFAULT_RESOLUTION, "cell edge, m (authors: 0.2)")
    ],
    bounds={"resolution": Bound(lo=1e-4, hi=MAX_RESOLUTION)},  # (the core: [1e-4, 100] m)
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


def new_map(cfg, mesh_bounds, ws) -> OccupancyMap:
    """A mission's empty map of the workspace `ws` at cfg.map; a workspace beyond OctoMap's
    range is a MissionError saying whether the structure is too large for the resolution or
    lies too far from the origin (then with the mesh.shift that brings it near)."""
    m = cfg.map
    try:
        return OccupancyMap(m.resolution, ws.bounds_min, ws.bounds_max, options=m.options())
    except ValueError as e:
        if "addressable range" not in str(e):
            raise
        if np.any(ws.bounds_max - ws.bounds_min > 32767 * m.resolution):  # OctoMap's keys
            w = cfg.workspace
            what = f"the workspace ({w.made_by(values=True)})"
            what = (  # the bounds given, or the structure and its margins, make the workspace
                f"{what} is"
                if w.bounds_min is not None
                else f"the structure (mesh.scale = {cfg.mesh.scale:g}) and {what} are"
            )
            raise MissionError(  # too large, wherever it lies
                f"{e}: {what} too large for the map at map.resolution = {m.resolution:g} m"
            ) from None
        # the centre to the origin, and a floating or sunken structure onto the ground
        c = np.round(-(np.asarray(mesh_bounds[0]) + np.asarray(mesh_bounds[1])) / 2)
        c[2] = 0.0
        old = np.asarray(cfg.mesh.shift, float)
        shift = np.round(grounding_shift(mesh_bounds, old + c))
        bounds = ""
        if cfg.workspace.bounds_min is not None:  # given bounds do not move with the structure
            by = ", ".join(f"{x:.0f}" for x in shift - old)
            bounds = f", and workspace.bounds_min / bounds_max moved by the same [{by}]"
        shift = ",".join(f"{x:.0f}" for x in shift)
        raise MissionError(
            f"{e}: the structure lies too far from the origin for the map; fly it in a frame "
            f"near the origin with mesh.shift (e.g. --set mesh.shift=[{shift}]{bounds}: its "
            "results are then in that frame)"
        ) from None
