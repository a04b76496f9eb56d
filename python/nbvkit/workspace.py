"""Workspace, navigation bounds and the five predefined start poses of a structure."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .limits import read_only
from .settings import nonneg, triple
from .work_limits import units_hint


@dataclass(frozen=True)
class WorkspaceConfig:
    """The NBV workspace (map bounds for entropy, utility and navigation).

    Default: the structure's bounding box grown by ``margin_xy`` on each side and squared up to a
    square footprint (as the paper's 40 x 40 m), from ``min(0, bbox z min)`` (the ground) to
    ``bbox z max + margin_z``: for the shipped airliner (35.0 x 30.0 x 7.5 m) and the paper's
    margins 40.0 x 40.0 x 10.0 m. ``margin_z`` null (the ``surface_gimbal`` planner): a flight
    envelope that reaches above the top by the camera's far stand-off (max placement.standoffs x
    camera.max_range), so tops are seen from above (envelope_margin_z); the profile's sweeps and
    the starts keep to the structure's height. Explicit ``bounds_min``/``bounds_max`` override
    it.
    """

    margin_xy: float = nonneg(2.5)
    margin_z: Optional[float] = nonneg(2.5)  # m above the top; null: the camera's far stand-off
    square: bool = True  # the footprint squared up to its longer side (the paper's 40 x 40 m)
    bounds_min: Optional[tuple] = triple(None)  # (x, y, z) m; with bounds_max: the workspace
    bounds_max: Optional[tuple] = triple(None)  # (x, y, z) m; null: the margins above

    def check(self, key: str) -> None:
        if (self.bounds_min is None) != (self.bounds_max is None):
            raise ValueError(f"config keys '{key}.bounds_min' and '{key}.bounds_max' go together")

    def made_by(self, values: bool = False) -> str:
        """The keys that make the workspace (the bounds given, or the margins), with their values
        when `values`. Under a flight envelope (margin_z null) only margin_xy: the starts keep to
        the structure's height; with `values`, the envelope above the top is named too."""
        if self.bounds_min is not None:
            lo, hi = (", ".join(f"{x:g}" for x in b) for b in (self.bounds_min, self.bounds_max))
            if values:
                return f"workspace.bounds_min = [{lo}], bounds_max = [{hi}]"
            return "workspace.bounds_min, workspace.bounds_max"
        if self.margin_z is None:  # (the starts keep to the structure's height)
            if values:
                return (
                    f"workspace.margin_xy = {self.margin_xy:g} m, margin_z = null: the camera's "
                    "far stand-off above the top, placement.standoffs x camera.max_range"
                )
            return "workspace.margin_xy"
        if values:
            return f"workspace.margin_xy = {self.margin_xy:g}, margin_z = {self.margin_z:g} m"
        return "workspace.margin_xy, workspace.margin_z"


def ground_clearance(vehicle) -> float:
    """The least height above the workspace floor (the ground) the vehicle's centre keeps at its
    views: `vehicle`'s min_altitude, at least its collision radius + 0.1 m (the default)."""
    shrink = vehicle.collision_radius + 0.1
    return shrink if vehicle.min_altitude is None else max(shrink, vehicle.min_altitude)


@dataclass(frozen=True)
class Workspace:
    """The NBV workspace box (map bounds) and the navigation bounds (vehicle positions);
    sweep_top: the highest the profile's sweeps and the predefined starts go (the navigation
    top, or below it within a flight envelope: structure_nav_top)."""

    bounds_min: np.ndarray
    bounds_max: np.ndarray
    nav_min: np.ndarray
    nav_max: np.ndarray
    sweep_top: float | None = None  # None: nav_max's

    def __post_init__(self) -> None:
        """Its boxes as read-only float copies: a part that wrote into them (a plugin's
        generator) moved the workspace under the mission, whose summary then held a box
        nbvkit's own reader refuses."""
        for name in ("bounds_min", "bounds_max", "nav_min", "nav_max"):
            object.__setattr__(self, name, read_only(getattr(self, name), name))

    @property
    def structure_nav_max(self) -> np.ndarray:
        """nav_max with its z at sweep_top: the navigation box of the profile and the starts."""
        top = self.nav_max[2] if self.sweep_top is None else self.sweep_top
        return np.array([self.nav_max[0], self.nav_max[1], top])

    @property
    def center(self) -> np.ndarray:
        return (self.bounds_min + self.bounds_max) / 2

    @property
    def size(self) -> np.ndarray:
        return self.bounds_max - self.bounds_min

    def contains(self, p) -> bool:
        """Whether the position of pose `p` lies in the navigation space."""
        return bool(self.contains_each(np.asarray(p, float)[:3])[0])

    def contains_each(self, points) -> np.ndarray:
        """(K,) bool per position (K, 3): within the navigation space."""
        p = np.asarray(points, float).reshape(-1, 3)
        return np.all((p >= self.nav_min) & (p <= self.nav_max), axis=1)

    @property
    def path_floor(self) -> float:
        """The height A* paths between views keep above (their cells' tops; the waypoints to
        within half a map cell): the navigation space's floor, ground_clearance above the
        ground, as the views."""
        return float(self.nav_min[2])

    def to_dict(self) -> dict:
        return {
            k: [float(x) for x in getattr(self, k)]
            for k in ("bounds_min", "bounds_max", "nav_min", "nav_max")
        }


#: A workspace whose longest side exceeds this many camera ranges is large: its tours take the
#: larger gains first (tour.gain_levels) and its camera cloud sums in single precision
#: (cloud.single_precision). 6 x the paper's 8 m camera is 48 m: a 35 m aircraft's workspace
#: (45 m) is not large, a 100 m plant's is.
LARGE_IN_RANGES = 6.0


def is_large(workspace, camera) -> bool:
    """Whether the workspace's longest side exceeds LARGE_IN_RANGES x camera.max_range."""
    side = float(np.max(np.asarray(workspace.bounds_max) - np.asarray(workspace.bounds_min)))
    return side > LARGE_IN_RANGES * camera.max_range


def ground_height(bounds) -> float:
    """The ground the clouds' ground removal (cloud.min_z) is measured from, and the workspace's
    floor: z = 0, the ground plane of the authors' world, unless the structure reaches below it (a
    mesh centred on its origin, a bridge's piers), in which case the ground is the structure's
    lowest point - nothing of a structure lies under the ground, and the simulated world has no
    ground plane."""
    return min(0.0, float(np.asarray(bounds, float)[0][2]))


#: m: a structure whose lowest point lies this far above the ground (z = 0), and farther than its
#: own height, is likely given in altitudes (floating_gap)
FLOATING_GAP_M = 10.0


def floating_gap(bounds) -> float:
    """How far the structure's lowest point lies above the ground (z = 0) when that gap is over
    FLOATING_GAP_M and over the structure's own height, else 0: a mesh whose z is an altitude
    (a georeferenced survey). The workspace reaches down to the ground, so the profile's sweeps,
    the map and the flight span the gap too (an 18 m building 310 m up: 3.5 km flown, against
    0.65 km on the ground)."""
    lo, hi = (float(v) for v in np.asarray(bounds, float)[:, 2])
    return lo if lo > max(FLOATING_GAP_M, hi - lo) else 0.0


def grounding_shift(bounds, shift) -> list:
    """mesh.shift (the given `shift` plus what the structure's bounds ask) that stands a floating
    structure (floating_gap) or one reaching below z = 0 on the ground; z as given otherwise."""
    lo = float(np.asarray(bounds, float)[0, 2])
    dz = -lo if (lo < 0 or floating_gap(bounds) > 0) else 0.0
    return [float(shift[0]), float(shift[1]), float(shift[2]) + dz]


def warn_floating(bounds, cfg) -> None:
    """A RuntimeWarning, with the mesh.shift that grounds it, for a floating structure
    (floating_gap) whose workspace reaches down to the ground (no explicit workspace bounds)."""
    if note := _floating(bounds, cfg):
        warnings.warn(note, RuntimeWarning, stacklevel=3)


def structure_hint(bounds, cfg) -> str:
    """What an error about the work on the structure adds of the structure itself: its size in
    another unit (work_limits.units_hint) and warn_floating's words, "; ..." each (a profile's
    sweeps or a map reaching down to the ground from a structure given in altitudes)."""
    note = _floating(bounds, cfg)
    return units_hint(bounds, cfg.mesh.scale) + (f"; {note}" if note else "")


def _floating(bounds, cfg) -> str:
    gap = floating_gap(bounds)
    if not gap or cfg.workspace.bounds_min is not None:
        return ""
    shift = grounding_shift(bounds, cfg.mesh.shift)
    shift = ",".join(np.format_float_positional(v, 3, trim="-") for v in shift)
    return (
        f"the structure's lowest point lies {gap:g} m above the ground (z = 0): the workspace, "
        f"the profile's sweeps and the flight reach down to the ground. If its z is an "
        f"altitude rather than a height above the ground, stand it on the ground with --set "
        f"mesh.shift=[{shift}]"
    )


#: cells of the map across the structure's largest extent below which it is mapped too coarsely
#: to plan on (warn_coarse): a 1 m structure, 5 cells of the 0.2 m map, ended at 53 % of its
#: observable surface with no view worth its flight; at 0.05 m, 100 % (2 m, 10 cells: 100 %)
COARSE_CELLS = 8
#: cells across the structure that warn_coarse's suggested resolution gives
SUGGESTED_CELLS = 20


def warn_coarse(bounds, cfg) -> None:
    """A RuntimeWarning, with a map.resolution that fits it, for a structure spanning fewer than
    COARSE_CELLS cells of the map along its largest extent; under a metre, first the mesh.scale
    of a model in another unit (work_limits.units_hint: a finer map alone met the limits of an
    8 m camera's rays and of the workspace's cells)."""
    extent = float(np.max(np.asarray(bounds[1], float) - np.asarray(bounds[0], float)))
    res = cfg.map.resolution
    if extent >= COARSE_CELLS * res:
        return
    fit = float(f"{extent / SUGGESTED_CELLS:.1g}")
    finer = f"--set map.resolution={fit:g} maps it in {extent / fit:.0f} cells"
    if unit := units_hint(bounds, cfg.mesh.scale):  # (under a metre) the unit first
        finer = f"{unit[2:]}; a finer map alone needs a camera and a workspace of its scale"
    warnings.warn(
        f"the structure spans {extent:.3g} m, {extent / res:.1f} cells of the {res:g} m map: "
        f"too coarse a map to plan views of its surface on; {finer}",
        RuntimeWarning,
        stacklevel=3,
    )


#: m above the structure's top of the paper's workspace (its 40 x 40 x 10 m box round the
#: airliner); the profile's sweeps and the predefined starts keep to it, whatever the flight
#: envelope above the top (workspace.margin_z null: envelope_margin_z).
PAPER_MARGIN_Z = 2.5


def structure_nav_top(nav_max, mesh_bounds, clearance: float) -> float:
    """Within a flight envelope (workspace.margin_z null), the highest the profile sweeps and
    the starts go: the structure's top + PAPER_MARGIN_Z less the vehicle's clearance (collision
    radius + 0.1 m), as on the paper's workspace, within the navigation space."""
    top = float(np.asarray(mesh_bounds[1], float)[2])
    return min(float(nav_max[2]), top + PAPER_MARGIN_Z - clearance)


def envelope_margin_z(cfg) -> float:
    """How far above the structure's top the workspace reaches when workspace.margin_z is null:
    the camera's far stand-off (max placement.standoffs x camera.max_range) plus the vehicle's
    collision radius and 0.1 m, so that the vehicle can fly a top's far stand-off above it."""
    far = max(cfg.placement.standoffs) * cfg.camera.max_range
    return far + cfg.vehicle.collision_radius + 0.1


def make_workspace(mesh_bounds, cfg) -> Workspace:
    """The workspace of a structure (see WorkspaceConfig); navigation bounds are the workspace
    shrunk by the collision radius (plus 0.1 m), so the vehicle's sphere stays inside the map."""
    w = cfg.workspace
    lo, hi = np.asarray(mesh_bounds[0], float), np.asarray(mesh_bounds[1], float)
    if w.bounds_min is not None:
        bmin, bmax = np.array(w.bounds_min, float), np.array(w.bounds_max, float)
        if not np.all(bmax > bmin):
            raise ValueError(
                f"workspace bounds_max {bmax.tolist()} must exceed bounds_min {bmin.tolist()}"
            )
        if np.any(bmin >= hi) or np.any(bmax <= lo):  # (a mission would see nothing)
            raise ValueError(
                f"the workspace {bmin.tolist()}..{bmax.tolist()} (workspace.bounds_min, "
                f"bounds_max) holds no part of the structure, which spans "
                f"{lo.round(3).tolist()}..{hi.round(3).tolist()} m"
            )
    else:
        c = (lo + hi) / 2
        half = (hi - lo)[:2] / 2 + w.margin_xy
        if w.square:
            half = np.full(2, half.max())
        bmin = np.array([c[0] - half[0], c[1] - half[1], ground_height(mesh_bounds)])
        margin_z = w.margin_z if w.margin_z is not None else envelope_margin_z(cfg)
        bmax = np.array([c[0] + half[0], c[1] + half[1], hi[2] + margin_z])
    shrink = cfg.vehicle.collision_radius + 0.1
    nav_min, nav_max = bmin + shrink, bmax - shrink
    nav_min[2] = bmin[2] + ground_clearance(cfg.vehicle)  # above the workspace floor
    if not np.all(nav_max > nav_min):
        raise ValueError(
            f"the workspace {(bmax - bmin).round(3).tolist()} m is too small for the vehicle's "
            f"collision radius (vehicle.collision_radius = {cfg.vehicle.collision_radius:g} m; "
            f"workspace.margin_xy = {w.margin_xy:g}, workspace.margin_z = {w.margin_z}, "
            f"vehicle.min_altitude = {cfg.vehicle.min_altitude})"
        )
    sweep_top = None
    if w.bounds_min is None and w.margin_z is None:  # a flight envelope above the structure
        sweep_top = structure_nav_top(nav_max, mesh_bounds, shrink)
    return Workspace(bmin, bmax, nav_min, nav_max, sweep_top)


def start_poses(
    ws: Workspace,
    n: int = 5,
    surface=None,
    reach: float | None = None,
    clearance: float = 0.0,
    sees=None,
    collides=None,
) -> np.ndarray:
    """(n, 4) predefined starts, evenly spaced in bearing around the workspace centre at mid
    height, each facing the centre. Each lies on the ellipse inscribed in the navigation bounds
    (just inside the workspace boundary) unless the structure is out of reach from there: given
    its surface samples `surface` (M, 3) and the sensor's `reach` (m), a start whose nearest
    surface point is farther than `reach` — or, given `sees(pose) -> bool`, from which the sensor
    facing the centre does not see the structure — moves inward along its bearing until both hold
    (but not nearer than `clearance`). A start in the structure on the ellipse (one that fills
    its workspace; `collides(point) -> bool` says, in collision or inside, default: nearer than
    `clearance`) moves outward along its bearing to the bounds, then to other heights, until it is
    clear and `clearance` away (a row of NaN where no place is); one out of collision but nearer
    than `clearance` moves likewise where a place also sees the structure, else stays
    (_kept_clear). A start that sees the structure from nowhere on its bearing at the mid height
    (a navigation box reaching far above or below the structure) is placed so at the structure's
    mid height instead, where one there does. On the diagonals of a cross-shaped structure (an
    aircraft in a square workspace) the boundary is farther than the camera sees. Start 0 is on
    the -y side facing +y (the authors' (0, -20, 5), yaw 90 deg on their workspace)."""
    c = (ws.nav_min + ws.nav_max) / 2
    h = (ws.nav_max - ws.nav_min) / 2
    tree = z_mid = None
    if surface is not None and reach is not None and len(surface):
        from scipy.spatial import cKDTree

        tree = cKDTree(np.asarray(surface, float))
        z = tree.data[:, 2]
        z_mid = float(np.clip((z.min() + z.max()) / 2, ws.nav_min[2], ws.nav_max[2]))

    def clear(q):  # out of collision and `clearance` from the surface
        return tree.query(q)[0] >= clearance and not (collides is not None and collides(q))

    def place(th, z):  # ((x, y, z, yaw) or None, whether it sees the structure) on bearing th
        cz = np.array([c[0], c[1], z])
        p = np.array([c[0] + h[0] * math.cos(th), c[1] + h[1] * math.sin(th), z])
        p = np.clip(p, ws.nav_min, ws.nav_max)  # c - h can round to just outside the bounds
        if tree is None:
            return [*p, _facing(c, p)], True
        near = tree.query(p)[0] < clearance
        if collides(p) if collides else near:
            p = _clear_start(ws, cz, p, clear)
            return (None, False) if p is None else ([*p, _facing(c, p)], True)
        if near:  # out of collision, too near to fly from (airliner start 4: 1.0 m)
            p, yaw, ok = _kept_clear(ws, cz, p, tree, reach, clearance, sees, clear)
        else:
            p, yaw, ok = _inward_start(p, cz, tree, reach, clearance, sees)
        return [*p, yaw], ok

    out = np.full((n, 4), np.nan)  # NaN: nowhere clear on its bearing (World names it if flown)
    for k in range(n):
        th = -math.pi / 2 + 2 * math.pi * k / n
        pose, ok = place(th, c[2])
        if pose is not None and not ok and z_mid is not None and z_mid != c[2]:
            retry, ok = place(th, z_mid)  # (a flight envelope far above the structure)
            pose = retry if ok else pose
        if pose is not None:
            out[k] = pose
    return out


def unplaced_start(k: int, ws: Workspace, w: WorkspaceConfig) -> str:
    """Why predefined start `k` could not be placed (start_poses gave it NaN) in `ws`, the
    navigation box the starts keep to (Workspace.structure_nav_max)."""
    return (
        f"start {k}: no place on its bearing from the workspace centre is clear of the "
        f"structure inside the starts' navigation bounds {ws.nav_min.round(3).tolist()} - "
        f"{ws.nav_max.round(3).tolist()}: enlarge the workspace ({w.made_by()}), or give "
        "start_pose"
    )


def _facing(c, q) -> float:
    """The yaw (rad) from `q` towards `c`, in the horizontal plane."""
    return math.atan2(c[1] - q[1], c[0] - q[0])


def _kept_clear(ws, c, p, tree, reach: float, clearance: float, sees, clear):
    """(position, yaw, whether it sees) of a start on the ellipse out of collision but nearer
    than `clearance` to the structure: the first place on its bearing, outward then at other
    heights (_clear_start), that keeps the clearance and, facing the centre, still sees the
    structure; where none does (a pillar in a tight workspace), the place itself, as an inward
    start. There the take-off sphere, cleared to a cell short of the surface, left no
    neighbouring view free of unknown space: the paper's Scenario 1 turned on the spot (the
    airliner's start 4, 1.0 m from the tailplane)."""

    def fine(q):  # clear, and seeing the structure facing the centre
        return clear(q) and (sees is None or bool(sees(np.array([*q, _facing(c, q)]))))

    q = _clear_start(ws, c, p, fine)
    if q is None:  # nowhere on its bearing: as before, from where it is
        return _inward_start(p, c, tree, reach, clearance, sees)
    return q, _facing(c, q), True


def _inward_start(p, c, tree, reach: float, clearance: float, sees):
    """(position, yaw, whether it sees) of a start that sees the structure: from `p` inward
    towards the centre `c`, facing it, the first place within `reach` of the surface (and, given
    `sees`, seeing it). Where the centre holds no structure (structures far apart) no place on
    that bearing may be: then from `p` towards the nearest surface sample, facing it; where
    neither walk finds one, the first walk's end, not seeing."""

    def walk(p, goal):
        step = (goal - p) / max(np.linalg.norm(goal - p), 1e-9) * 0.25
        for _ in range(int(np.linalg.norm(goal - p) / 0.25)):
            yaw = _facing(goal, p)
            ok = tree.query(p)[0] <= reach and (sees is None or sees(np.array([*p, yaw])))
            if ok or tree.query(p + step)[0] < clearance:
                return p, yaw, ok
            p = p + step
        return p, _facing(goal, p), False

    q, yaw, ok = walk(p, c)
    if ok:
        return q, yaw, True
    nearest = tree.data[tree.query(p)[1]]
    goal = np.array([nearest[0], nearest[1], p[2]])
    q2, yaw2, ok2 = walk(p, goal)
    return (q2, yaw2, True) if ok2 else (q, yaw, False)


def _clear_start(ws: Workspace, c, p, clear) -> np.ndarray | None:
    """The first point where `clear(point)` holds on the bearing from `c` through `p`,
    outward from `p` to the navigation bounds, at `p`'s height and then at the other heights of
    the navigation bounds (nearest first); None where there is none."""
    d = np.array([p[0] - c[0], p[1] - c[1], 0.0])
    d /= max(np.linalg.norm(d), 1e-9)
    with np.errstate(divide="ignore", invalid="ignore"):
        lim = np.where(d > 0, (ws.nav_max - p) / d, np.where(d < 0, (ws.nav_min - p) / d, np.inf))
    outward = np.arange(0.0, max(float(np.min(lim[:2])), 0.0) + 1e-9, 0.25)
    heights = np.arange(ws.nav_min[2], ws.nav_max[2] + 1e-9, 0.25)
    for z in [p[2], *sorted(heights, key=lambda z: abs(z - p[2]))]:
        for t in outward:
            q = np.array([p[0] + t * d[0], p[1] + t * d[1], z])
            if clear(q):
                return q
    return None
