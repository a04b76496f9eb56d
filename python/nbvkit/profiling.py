"""Profiling (paper sec. 3.2.1): a quick laser survey that seeds the map and the profile cloud.

Adaptive circular profiling, Algorithm 1: at each of N waypoints around the structure the vehicle
sweeps vertically between z_min and z_max while the laser scans (one scan every `sweep_step`
metres), facing the current centroid. The profile cloud is projected on XY; its centroid c and
bounding radius r (max XY distance from c, plus the obstacle margin d) are recomputed; the vehicle
moves radially onto the circle (c, r) at its current angle, then along the circle (straight chords
of at most `max_segment` metres) to the next angle theta + 2 pi / N, until a full turn.

theta_s is the bearing of the start position seen from the workspace centre, so the first circle
point is the one nearest the start (the paper's wording, "the angle between the global x axis and
the vector from the UAV's starting position to the centre", would put it on the far side).

The grown-hull profiler (method hull, nbvkit's) keeps Algorithm 1's loop, waypoints and bearings
but flies the profile's XY convex hull grown by d instead of the circle (c, r): the closed curve
at distance d from the hull, which lies inside that circle. Round a long or square structure it is
shorter than the circle, and it holds the camera at the stand-off d from every face, facing the
nearest point of the hull, instead of up to r - d from the faces' middles. A profile whose XY
points are collinear falls back to the circle.

The bounding-box profiler (the authors' second method) flies the four vertical faces of the
structure's observed bounding box grown by the margin, sweeping at each corner and face middle; the
box is recomputed after every sweep, as the circle is.

The flight is confined to the profiling flight volume (the workspace grown by `flight_margin` in
x and y); it is not confined to the NBV workspace (a circle around a 35 x 30 m aircraft is wider
than 40 x 40 m). The curve encloses what the laser has seen, and a part it has not seen yet
(beyond its range, or hidden behind or below other parts) can stand across it: before every
step the vehicle checks its way with range rays (an obstacle sensor: along the step, and round its
end: nearer than the collision radius, and nearer than before, is blocked) and with proximity
sensing along the step (a part within the collision radius blocks it, as one the rays pass by).
A sweep blocked on its way to its first end sweeps from there to the other, and ends where it is
blocked on that way; on a blocked move the vehicle scans with its laser where it stands, the
curve is recomputed with that scan, and the vehicle goes out along its bearing onto the new curve
and on along it (up to 3 times: at its height, then over the top of the flight volume, then along
its bottom; then the loop goes on from where it stands). `profile.blocked_steps` counts the steps
stopped.

After the survey the vehicle returns to its start pose for the camera stage
(profiling.return_to_start, the paper's scenarios) or, without returning, climbs or descends its
last sweep line to the start's height (the ends of a sweep have little known free space around
them) and flies straight into the navigation bounds if the circle left them. Where the check
blocks the way back (the climb), the vehicle first flies back along its own profile flight, which
is free, until the way is clear. profiling.close_circle = false stops after the last sweep instead
of flying Algorithm 1's final arc back to the first waypoint. All distances flown are accounted.

profiling.arcs = descending (nbvkit's) flies each arc from the end of one sweep to the other end:
from the top of sweep k down to the bottom at waypoint k + 1 (or up), the height in proportion to
the distance along the arc, so every sweep runs the same way and the camera frames of an arc cross
every height of the faces between two sweeps, where a level arc (Algorithm 1's, the paper's
scenarios) sees one band at the top or the bottom of them. The bbox profiler's legs stay level.

With profiling.camera_step > 0 (the recommended planner's 1 m; the paper's scenarios set 0) the
RGB-D camera also takes a frame every camera_step metres of the flight, facing the structure as
the vehicle does on every sweep and arc. The frames go into the map, the camera cloud and the
camera observations; they are frames in flight, not views (``profile.camera_frames`` counts them).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy.spatial import QhullError

from .mesh import fibonacci_sphere
from .profile_curves import _Circle, _GrownHull, _segments
from .settings import choice, nonneg, positive, within


@dataclass(frozen=True)
class ProfilingConfig:
    """Adaptive circular profiling (Algorithm 1), its grown-hull variant and the bounding-box
    profiler."""

    enabled: bool = True  # fly the laser profile before the camera
    # circular (Algorithm 1), hull (its loop round the grown XY hull) or bbox (the box's faces)
    method: str = choice("hull", ("circular", "hull", "bbox"))
    waypoints: int = within(4, 1, 1000)  # N, points around the structure (authors: 5)
    margin: float = positive(4.0, 1e4)  # d: margin added to the bounding radius, m (authors: 4)
    sweep_step: float = positive(0.025)  # m between laser scans: a 40 Hz scanner at 1 m/s (authors)
    camera_step: float = nonneg(1.0)  # m between profile camera frames; 0: none (paper)
    # sweep bounds; None: the navigation floor (z_min may not lie below it), and the
    # structure's top + 2.5 m less the vehicle's clearance (the paper's sweep, whatever the
    # flight envelope above the top)
    z_min: Optional[float] = None
    z_max: Optional[float] = None  # the sweeps' top, m (null: as above)
    max_segment: float = positive(7.0)  # arcs are flown as straight segments of at most this, m
    flight_margin: float = within(30.0, 0, 1e4)  # the flight volume: workspace grown by this, m
    # fly the last arc back to the first waypoint after the last sweep (Algorithm 1's loop)
    close_circle: bool = False
    return_to_start: bool = False  # fly back to the start pose before the camera stage
    # level (Algorithm 1), or descending from one sweep end to the other
    arcs: str = choice("descending", ("level", "descending"))  # level or descending


class _Blocked(Exception):
    """A profile step on which the vehicle's forward range check meets the structure."""


class Profiler:
    """Runs a profiling flight in a World (its laser, map, clouds and vehicle state)."""

    def __init__(self, world):
        self.m = world
        self.cfg = world.config.profiling
        ws = world.workspace
        r = world.config.vehicle.collision_radius
        self.z_min = self.cfg.z_min if self.cfg.z_min is not None else ws.nav_min[2]
        # the paper's sweep top, whatever the flight envelope above the structure: a laser
        # sweep needs no more (Workspace.sweep_top)
        self.z_max = self.cfg.z_max if self.cfg.z_max is not None else ws.structure_nav_max[2]
        if not self.z_max > self.z_min:
            raise ValueError(f"profiling sweep needs z_max > z_min, got {self.z_min}..{self.z_max}")
        fm = self.cfg.flight_margin
        self.fly_min = np.array([ws.bounds_min[0] - fm, ws.bounds_min[1] - fm, ws.nav_min[2]])
        self.fly_max = np.array([ws.bounds_max[0] + fm, ws.bounds_max[1] + fm, ws.nav_max[2]])
        self.radius = r
        self.collision_radius = world.config.vehicle.collision_radius
        self.blocked = 0  # steps the range check stopped
        self._around = fibonacci_sphere(32)
        self.camera_frames = 0
        self._since_frame = 0.0
        self.waypoints: list[list[float]] = []
        self.circles: list[list[float]] = []

    # -------------------------------------------------------------- motion and sensing
    def _clip(self, p):
        return np.minimum(np.maximum(p, self.fly_min), self.fly_max)

    def _fly(self, target):
        """fly_to in the profile stage; with profiling.camera_step > 0 the camera also takes a frame
        every camera_step metres flown (legs longer than that are split: one frame per leg)."""
        step = self.cfg.camera_step
        if step <= 0:
            self._check(self.m.state.pose[:3], target[:3])
            self.m.fly_to(target, "profile")
            return
        cur = self.m.state.pose[:3].copy()
        for q in _segments(cur, np.asarray(target[:3], float), step):
            self._check(self.m.state.pose[:3], q)
            before = self.m.state.distance_m
            self.m.fly_to(np.array([*q, target[3]]), "profile")
            self._since_frame += self.m.state.distance_m - before
            if self._since_frame >= step - 1e-9:
                self.m.sense("frame")
                self.camera_frames += 1
                self._since_frame = max(0.0, self._since_frame - step)

    def _check(self, a, b):
        """Raises _Blocked (and counts it) where the range check stops the step a -> b."""
        if self._blocked(a, b):
            self.blocked += 1
            raise _Blocked

    def clear(self, a, b) -> bool:
        """Whether the range check lets the vehicle fly a -> b (not counted as a blocked step)."""
        return not self._blocked(a, b)

    def _blocked(self, a, b) -> bool:
        """The vehicle's range check before it flies a -> b (an obstacle sensor): rays along the
        motion from its centre (to the step's end plus the collision radius) and from eight
        points of a ring of that radius about it (to the step's end), and rays in 32 directions
        about a and b (b nearer the structure than the collision radius, and nearer than a, is
        blocked); then points every quarter radius along the step, blocked where one within the
        radius of the structure follows one clear of it (a vehicle already that near may move
        away). True where one meets the structure: the profile flies round what its laser has
        seen, and a part it has not seen yet (beyond the laser's range, or behind other parts)
        can stand across the curve."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        length = float(np.linalg.norm(d))
        if length < 1e-9:
            return False
        u = d / length
        ref = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e1 = np.cross(u, ref)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        ang = np.arange(8) * (math.pi / 4)
        ring = self.collision_radius * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
        n = len(self._around)
        origins = np.vstack([a, a + ring, np.tile(b, (n, 1)), np.tile(a, (n, 1))])
        dirs = np.vstack([np.tile(u, (9, 1)), self._around, self._around])
        t, _ = self.m.scene.intersect(origins, dirs, 0.0, np.inf)
        r = self.collision_radius
        clear_b, clear_a = t[9 : 9 + n].min(), t[9 + n :].min()
        ahead = np.any(t[:9] <= np.r_[length + r, np.full(8, length)])
        # nearer than the radius only blocks a step that goes nearer still: a vehicle that got
        # close (beside a part the rays along its way passed) may always move away
        if ahead or (clear_b < r and clear_b < clear_a):
            return True
        # and its proximity sensing along the step: the rays pass beside a part thinner than
        # their spacing (a wing's edge between the ring's rays 1.5 m apart at a 2 m radius)
        n = math.ceil(length / max(r / 4, 0.01)) + 1  # (every quarter radius, 1 cm at least)
        near = self.m.scene.within(a + np.outer(np.linspace(0, 1, n), d), r)
        # a vehicle already within the radius may move away: the near points the step starts
        # with are let through, not a part it comes within the radius of after them
        first_clear = int(np.argmin(near))
        return bool(near[first_clear] == 0 and near[first_clear:].any())

    def _face(self, p, c):
        return math.atan2(c[1] - p[1], c[0] - p[0])

    def _move(self, target_xyz, yaw):
        """Fly straight to target, clipped to the flight volume, in legs of at most max_segment.
        The circle encloses every profile point plus the margin d, so legs on and onto it stay
        clear of the observed structure; `clearance()` reports the closest approach flown."""
        cur = self.m.state.pose[:3].copy()
        target = self._clip(np.asarray(target_xyz, float))
        for q in _segments(cur, target, self.cfg.max_segment):
            self._fly(np.array([*q, yaw]))

    def _sweep(self, center):
        """Vertical sweep at the current XY position between z_min and z_max, scanning with the
        laser every sweep_step metres, facing `center`. Goes to the nearer end first."""
        p = self.m.state.pose
        yaw = self._face(p, center)
        lo, hi = self.z_min, self.z_max
        first, last = (lo, hi) if abs(p[2] - lo) <= abs(p[2] - hi) else (hi, lo)
        try:
            self._fly(np.array([p[0], p[1], first, yaw]))
        except _Blocked:  # the structure below (above): the sweep starts where it stopped
            first = self.m.state.pose[2]
        try:
            n = max(1, int(math.ceil(abs(last - first) / self.cfg.sweep_step)))
            for i in range(n + 1):
                z = first + (last - first) * i / n
                if i:
                    self._fly(np.array([p[0], p[1], z, yaw]))
                self.m.sense("laser")
        except _Blocked:  # the structure above (below): the sweep ends where it stands
            self.m.sense("laser")
        self.waypoints.append([float(p[0]), float(p[1])])

    def _circle(self, fallback_center, fallback_radius):
        pts = self.m.laser_cloud.points
        if len(pts) == 0:
            return np.asarray(fallback_center[:2], float), float(fallback_radius)
        xy = pts[:, :2]
        c = xy.mean(axis=0)
        r = float(np.linalg.norm(xy - c, axis=1).max()) + self.cfg.margin
        return c, r

    def _region(self, fallback_center, fallback_radius):
        """The closed curve flown round the profile: Algorithm 1's circle (method circular) or
        the profile's XY convex hull grown by the margin (method hull), from the cloud so far."""
        if self.cfg.method == "hull" and len(self.m.laser_cloud) >= 3:
            try:
                return _GrownHull(self.m.laser_cloud.points[:, :2], self.cfg.margin)
            except QhullError:  # a profile seen edge-on (collinear in XY): the circle
                pass
        return _Circle(*self._circle(fallback_center, fallback_radius))

    def _round(self, theta_end, fallback_center, fallback_radius, tries=3):
        """After a blocked step on the way to bearing theta_end: a laser scan where the vehicle
        stands, the curve recomputed with it, then out along the bearing onto the new curve and
        along it to theta_end; again if the structure blocks that too, at the top of the flight
        volume, then at its bottom (at most `tries` attempts), over or under what stands in the
        way; then the vehicle stays where it is and the loop goes on from there. Returns the
        curve."""
        m = self.m
        for k in range(tries):
            m.sense("laser")
            region = self._region(fallback_center, fallback_radius)
            p, z = m.state.pose[:2], m.state.pose[2]
            b = math.atan2(p[1] - region.c[1], p[0] - region.c[0])
            left = (theta_end - b) % (2 * math.pi)
            if left > math.pi:  # already past it on the new curve
                left = 0.0
            try:
                if k % 3:  # over the top of the flight volume, then along its bottom
                    z = self.z_max if k % 3 == 1 else self.z_min
                    self._move([*p, z], m.state.pose[3])
                out = region.at(b)
                if np.linalg.norm(out - region.c) > np.linalg.norm(p - region.c):
                    self._move([*out, z], self._face(out, region.facing(out)))
                for q in region.arc(b, left, self.cfg.max_segment) if left > 0 else []:
                    self._move([*q, z], self._face(q, region.facing(q)))
                return region
            except _Blocked:
                continue
        return region

    def _arc_heights(self, start, arc, z):
        """The height at each point of an arc flown from `start` (XY) at height z: z throughout
        (profiling.arcs = level, Algorithm 1), or (descending) from z to the other end of the
        sweep in proportion to the distance along the arc, so that the next sweep runs the way
        this one did and the camera's frames on the way cross every height of the face between
        two sweeps instead of one band at its top or bottom."""
        if self.cfg.arcs == "level" or len(arc) == 0:
            return [z] * len(arc)
        end = self.z_min if abs(z - self.z_max) <= abs(z - self.z_min) else self.z_max
        legs = np.linalg.norm(np.diff(np.vstack([start, arc]), axis=0), axis=1)
        along = np.cumsum(legs) / max(float(legs.sum()), 1e-9)
        return list(z + (end - z) * along)

    def clearance(self) -> float:
        """Closest distance (m) from the profiling trajectory's vertices to an occupied cell."""
        occ = self.m.map.occupied_cells()
        traj = np.array([r[1:4] for r in self.m.state.trajectory if r[0] == "profile"], float)
        if len(occ) == 0 or len(traj) == 0:
            return float("inf")
        from scipy.spatial import cKDTree

        return float(cKDTree(occ).query(traj)[0].min())

    # -------------------------------------------------------------- the two methods
    def circular(self):
        m = self.m
        start = m.state.pose.copy()
        ws_c = m.workspace.center
        theta_s = math.atan2(start[1] - ws_c[1], start[0] - ws_c[0])
        theta = theta_s
        phi = 2 * math.pi / self.cfg.waypoints
        r0 = float(np.linalg.norm(start[:2] - ws_c[:2]))
        region = _Circle(ws_c[:2], r0)
        while theta - theta_s < 2 * math.pi - 1e-9:
            self._sweep(region.facing(m.state.pose[:2]))
            region = self._region(ws_c, r0)
            self.circles.append(region.summary())
            if not self.cfg.close_circle and theta + phi - theta_s >= 2 * math.pi - 1e-9:
                break  # the last sweep is done: the way back to the first waypoint adds nothing
            z = m.state.pose[2]
            try:
                on = region.at(theta)
                self._move([*on, z], self._face(on, region.facing(on)))
                arc = region.arc(theta, phi, self.cfg.max_segment)  # along the curve
                for q, zq in zip(arc, self._arc_heights(on, arc, z)):
                    self._move([*q, zq], self._face(q, region.facing(q)))
            except _Blocked:
                region = self._round(theta + phi, ws_c, r0)
            theta += phi

    def bbox(self):
        """Fly the four vertical faces of the profile's XY bounding box grown by the margin,
        sweeping at each corner and face middle; the box is recomputed after every sweep (as the
        circle is), so it grows with the profile and stays clear of what has been seen."""
        m = self.m

        def box():
            pts = m.laser_cloud.points
            if len(pts) == 0:
                return m.workspace.bounds_min[:2].copy(), m.workspace.bounds_max[:2].copy()
            return (
                pts[:, :2].min(axis=0) - self.cfg.margin,
                pts[:, :2].max(axis=0) + self.cfg.margin,
            )

        def stop(lo, hi, k):  # 8 stops round the box: corner, mid-face, corner, ... from corner 0
            corners = [
                np.array([lo[0], lo[1]]),
                np.array([hi[0], lo[1]]),
                np.array([hi[0], hi[1]]),
                np.array([lo[0], hi[1]]),
            ]
            a, b = corners[(k // 2) % 4], corners[(k // 2 + 1) % 4]
            return a if k % 2 == 0 else (a + b) / 2

        self._sweep(m.workspace.center)
        lo, hi = box()
        p = m.state.pose[:2]
        k0 = 2 * int(np.argmin([np.linalg.norm(stop(lo, hi, 2 * i) - p) for i in range(4)]))
        for k in range(k0, k0 + 8):
            c = (lo + hi) / 2
            q = stop(lo, hi, k)
            q3 = np.array([q[0], q[1], m.state.pose[2]])
            try:
                self._move(q3, self._face(q3, c))
            except _Blocked:  # sweep where it stands, and the box grows with what it sees
                pass
            self._sweep(np.array([*c, 0.0]))
            lo, hi = box()
            self.circles.append([float(c[0]), float(c[1]), float(np.linalg.norm(hi - lo) / 2)])
        c = (lo + hi) / 2
        q = stop(lo, hi, k0)
        q3 = np.array([q[0], q[1], m.state.pose[2]])
        try:
            self._move(q3, self._face(q3, c))  # close the loop
        except _Blocked:
            pass


def _retrace(world, clear) -> bool:
    """Flies the profile's own flight backwards (free: it was flown) until clear(position) holds;
    True if it does."""
    path = [np.array(r[1:6], float) for r in world.state.trajectory if r[0] == "profile"]
    for q in reversed(path):
        if clear(world.state.pose[:3]):
            return True
        world.fly_to(q, "profile")
    return clear(world.state.pose[:3])


def run_profiling(world) -> dict:
    """The profiling stage on a World; returns the profile's own summary (Table 2 "Profile"
    row): distance, entropy reduction, points, waypoints (the caller adds the coverage)."""
    t0 = time.perf_counter()
    e0 = world.map.total_entropy()
    d0 = world.state.distance_m
    start = world.state.pose.copy()
    prof = Profiler(world)
    if world.config.profiling.method == "bbox":
        prof.bbox()
    else:
        prof.circular()
    e1 = world.map.total_entropy()
    d_profile = world.state.distance_m - d0
    if world.config.profiling.return_to_start:
        try:
            prof._move(start[:3], start[3])
        except _Blocked:  # back along its own flight until the way to the start is clear
            if _retrace(world, lambda a: prof.clear(a, start[:3])):
                world.fly_to(start, "profile")
        else:
            world.fly_to(start, "profile")
    else:
        # the sweep ended at the top or bottom of the flight volume, where little around it is
        # known free: back up (or down) its own swept line to the start's height; where the
        # structure is above (below), first back along its own flight until the way is clear
        def level(a):
            return prof.clear(a, [a[0], a[1], start[2]])

        if level(world.state.pose[:3]) or _retrace(world, level):
            p = world.state.pose
            world.fly_to(np.array([p[0], p[1], start[2], p[3]]), "profile")
        world.enter_navigation_space("profile")
    return {
        "method": world.config.profiling.method,
        "distance_m": d_profile,
        "return_distance_m": world.state.distance_m - d0 - d_profile,
        "entropy_initial": e0,
        "entropy_final": e1,
        "entropy_reduction": e0 - e1,
        "points": int(len(world.laser_cloud)),
        "camera_frames": prof.camera_frames,
        "clearance_m": prof.clearance(),
        "blocked_steps": prof.blocked,
        "waypoints": prof.waypoints,
        "circles": prof.circles,
        "time_s": time.perf_counter() - t0,
    }
