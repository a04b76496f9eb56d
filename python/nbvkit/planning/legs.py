"""Flying a leg to a view: camera frames taken in flight on the way (planner.frame_step: where
they are taken and which way the camera faces), and the way back out where scans closed in on
the vehicle (retreat)."""
from __future__ import annotations

import math

import numpy as np

from .. import _core
from ..vehicle import as_view


def leg_pieces(start, target, path, step: float) -> list:
    """The leg from view `start` to view `target` (x, y, z, yaw, pitch) along `path` ((P, 3)
    waypoints, first = start's position; None: straight) cut where a camera frame is taken: every
    `step` metres flown, none within step / 2 of the target. Returns [(pose, waypoints), ...]:
    the frames' poses, then the target, each with the waypoints of the piece that ends there
    (first = where the piece starts). A frame's camera turns in proportion to the distance
    flown: yaw the shorter way round, pitch linearly. step <= 0 or a leg shorter than 1.5 steps:
    the target alone, along the whole path. Poses of 4 numbers are level views."""
    start, target = as_view(start), as_view(target)
    pts = np.asarray(path if path is not None and len(path) else [start[:3], target[:3]], float)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    if step <= 0 or total < 1.5 * step:
        return [(target, pts)]
    turn = math.remainder(float(target[3] - start[3]), 2.0 * math.pi)

    def at(s):  # the point s metres along the path
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
        return pts[i] + (pts[i + 1] - pts[i]) * ((s - cum[i]) / seg[i]) if seg[i] > 0 else pts[i]

    cuts = step * np.arange(1, int(math.floor((total - 0.5 * step) / step)) + 1)
    pieces, a = [], 0.0
    for b in [*cuts, total]:
        inner = pts[(cum > a) & (cum < b)]
        piece = np.vstack([at(a)[None], inner, at(b)[None]])
        if b == total:
            pieces.append((target, piece))
        else:
            f = b / total
            yaw = math.remainder(start[3] + f * turn, 2.0 * math.pi)
            pose = np.array([*at(b), yaw, start[4] + f * (target[4] - start[4])])
            pieces.append((pose, piece))
        a = b
    return pieces


def fly_leg(world, choice, step: float, novelty: float, timers) -> tuple:
    """Flies to the chosen view, taking a camera frame every `step` metres on the way
    (leg_pieces; each in the timers' motion, sensing and mapping stages) where its preview finds
    at least the share `novelty` of its rays new (World.novelty; 0: every frame, unpreviewed);
    returns (the distance flown, the surface cells the frames saw first). Unpreviewed, each
    frame's integration takes the next frame (or the view) meanwhile (World.integrate's then:
    their sensing is timed in the mapping stage)."""
    flown, cells = 0.0, 0
    pieces = leg_pieces(world.state.pose, choice.pose, choice.path, step)
    for k, (pose, waypoints) in enumerate(pieces[:-1]):
        flown += timers.call("motion", world.fly_to, pose, "nbv", waypoints)
        if novelty > 0 and timers.call("sensing", world.novelty, pose) < novelty:
            world.state.frames_skipped += 1  # it would add (almost) nothing: not taken
            continue
        scan = timers.call("sensing", world.scan, "frame")
        then = (
            None if novelty > 0 else ("frame" if k + 2 < len(pieces) else "view", pieces[k + 1][0])
        )
        cells += timers.call("mapping", world.integrate, scan, "frame", then)
    return flown + timers.call("motion", world.fly_to, choice.pose, "nbv", pieces[-1][1]), cells


def retreat(world, radius: float) -> float:
    """Where scans have found surface round the vehicle (cells the map held free turn occupied
    once seen close up) so that neither its cell nor one beside it leaves its collision sphere
    in known free space, no path starts from where it is, and every view would be unreachable:
    it flies back along its own flight, which it has flown, to the last point whose sphere is
    free in the map as it is now. Returns the distance flown (0 where a path can start, where no
    point of the flight is free, or where the nearest free one is where it already is)."""
    here, m = world.state.pose, world.map
    around = m.cell_center(here[None, :3]) + m.resolution * _NEIGHBOURS
    if _core.spheres_are_free(m, around, radius, surface=world.hits_to_avoid).any():
        return 0.0
    back = np.array([row[1:4] for row in world.state.flight], float)[::-1]  # here to the start
    free = np.flatnonzero(_core.spheres_are_free(m, back, radius, surface=world.hits_to_avoid))
    if len(free) == 0 or free[0] == 0:  # none, or the nearest is where it is: nothing to fly
        return 0.0
    path = np.vstack([here[:3], back[: free[0] + 1]])
    path = path[np.r_[True, np.any(np.diff(path, axis=0) != 0, axis=1)]]  # each point once
    return world.fly_to(np.array([*path[-1], *here[3:]]), "nbv", path)


#: The cell offsets of a cell's 3 x 3 x 3 block.
_NEIGHBOURS = np.array(
    [(i, j, k) for k in (-1, 0, 1) for j in (-1, 0, 1) for i in (-1, 0, 1)], float
)
