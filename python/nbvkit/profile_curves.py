"""The closed curves a profiling flight flies round the structure (nbvkit.profiling): Algorithm
1's circle (c, r) and nbvkit's grown hull, the profile's XY convex hull grown by the margin; and
straight pieces of a leg."""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull


def _segments(a, b, max_len):
    """Split a-b into straight pieces of at most max_len (returns the intermediate points and b)."""
    n = max(1, int(math.ceil(np.linalg.norm(b - a) / max_len)))
    return [a + (b - a) * (i / n) for i in range(1, n + 1)]


class _Circle:
    """Algorithm 1's circle (c, r): flown facing its centre."""

    def __init__(self, c, r):
        self.c, self.r = np.asarray(c, float), float(r)

    def at(self, theta):
        return self.c + self.r * np.array([math.cos(theta), math.sin(theta)])

    def facing(self, p):
        return self.c

    def arc(self, t0, phi, max_segment):
        """Points along the circle from bearing t0 to t0 + phi (excluded, included), as chords of
        at most max_segment."""
        n = max(1, int(math.ceil(self.r * phi / max_segment)))
        return [self.at(t0 + phi * i / n) for i in range(1, n + 1)]

    def summary(self):
        return [float(self.c[0]), float(self.c[1]), self.r]


class _GrownHull:
    """The XY convex hull P of the profile grown by the margin d: the closed convex curve at
    distance d from P (straight faces at d from P's edges joined by arcs of radius d round its
    corners). Bearings are taken from the mean c of P's vertices, which lies inside P, so each
    bearing meets the curve once. Flown facing the nearest point of P, i.e. square on to the
    face beside it. Its chords of at most d / 2 keep within 0.13 d of the curve round a corner."""

    def __init__(self, xy, margin):
        v = np.asarray(xy, float)[ConvexHull(xy).vertices]  # counter-clockwise
        self.v, self.d = v, float(margin)
        self.c = v.mean(axis=0)
        self.e = np.roll(v, -1, axis=0) - v  # edge k runs from v[k] to v[k + 1]
        self.reach = float(np.linalg.norm(v - self.c, axis=1).max()) + self.d

    def _nearest(self, p):
        """The point of P's boundary nearest p, and the distance to P (0 inside)."""
        w = np.asarray(p, float) - self.v
        t = np.clip((w * self.e).sum(axis=1) / (self.e * self.e).sum(axis=1), 0.0, 1.0)
        q = self.v + t[:, None] * self.e
        k = int(np.argmin(np.linalg.norm(q - p, axis=1)))
        inside = np.all(self.e[:, 0] * w[:, 1] - self.e[:, 1] * w[:, 0] >= 0)
        return q[k], 0.0 if inside else float(np.linalg.norm(q[k] - p))

    def at(self, theta):
        u = np.array([math.cos(theta), math.sin(theta)])
        lo, hi = 0.0, self.reach  # distance to P is 0 at lo, >= d at hi, monotone in between
        for _ in range(48):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self._nearest(self.c + mid * u)[1] < self.d else (lo, mid)
        return self.c + hi * u

    def facing(self, p):
        return self._nearest(p)[0]

    def arc(self, t0, phi, max_segment):
        """Points along the curve from bearing t0 to t0 + phi (excluded, included), as chords of
        at most min(max_segment, d / 2): bearings are halved where the curve runs oblique to
        them (an elongated hull's ends)."""
        lim = min(max_segment, self.d / 2)
        out = []

        def split(a, pa, b, pb):
            if np.linalg.norm(pb - pa) <= lim or b - a < 1e-9:
                out.append(pb)
                return
            m = 0.5 * (a + b)
            pm = self.at(m)
            split(a, pa, m, pm)
            split(m, pm, b, pb)

        n = max(1, int(math.ceil(self.reach * phi / lim)))
        ts = [t0 + phi * i / n for i in range(n + 1)]
        prev = self.at(ts[0])
        for a, b in zip(ts[:-1], ts[1:]):
            pb = self.at(b)
            split(a, prev, b, pb)
            prev = pb
        return out

    def summary(self):
        """Centre and the radius of the circle of the same perimeter (P's plus 2 pi d)."""
        perimeter = float(np.linalg.norm(self.e, axis=1).sum()) + 2 * math.pi * self.d
        return [float(self.c[0]), float(self.c[1]), perimeter / (2 * math.pi)]
