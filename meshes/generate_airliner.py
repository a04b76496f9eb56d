#!/usr/bin/env python3
"""Procedural generator for a generic narrow-body airliner surface mesh.

This writes ``meshes/airliner.obj``, the reference target structure used by
nbvkit's UAV reconstruction simulations.  The aircraft is loosely modelled on
an A320-class airliner but is entirely synthetic (no external data is used).

Conventions
-----------
* units: metres
* Z is up, the fuselage axis is along X with the nose at +X,
  +Y is the aircraft's left (port) side, -Y is its right (starboard) side
* the mesh is mirror-symmetric about the plane y = 0: every part is either
  built symmetric by construction (its left half is an exact mirror of its
  right half) or is the exact mirror copy of a right-hand part
* the lowest point (bottom of the tyres) is at z = 0.03 m

Every part is written as its own ``o`` group and is a closed, consistently
outward-oriented triangle surface (each edge shared by exactly two triangles).
Parts may intersect each other (e.g. the wing roots lie inside the fuselage).

The output is deterministic: running the script again rewrites the OBJ file
byte-identically.  Only numpy and the standard library are used.

Usage::

    python3 meshes/generate_airliner.py            # writes meshes/airliner.obj
    python3 meshes/generate_airliner.py --check    # ... and prints statistics
    python3 meshes/generate_airliner.py --out /tmp/a.obj --check
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass

import numpy as np

# ---------------------------------------------------------------------------
# Main dimensions (metres)
# ---------------------------------------------------------------------------
NOSE_X = 17.5  # nose tip
TAIL_X = -17.5  # tail-cone tip
FUS_RADIUS = 1.95  # fuselage radius (diameter 3.9 m)
BELLY_Z = 1.6  # bottom of the constant section
AXIS_Z = BELLY_Z + FUS_RADIUS
NOSE_START_X = 12.5  # start of the nose cone (end of the cylinder)
TAIL_START_X = -6.5  # start of the tail cone
FIN_TOP_Z = 7.5  # top of the vertical fin
GROUND_CLEARANCE = 0.03  # lowest point of the tyres above z = 0

N_AROUND = 64  # segments around the fuselage
N_AROUND_SMALL = 48  # segments around the nacelles
N_AROUND_WHEEL = 36  # segments around the wheels
N_AROUND_STRUT = 24  # segments around struts and axles
N_CHORD = 40  # airfoil points per surface (upper / lower)

OBJ_DECIMALS = 6


# ---------------------------------------------------------------------------
# Mesh container
# ---------------------------------------------------------------------------
@dataclass
class Part:
    """A named closed triangle surface."""

    name: str
    vertices: np.ndarray  # (n, 3) float64
    faces: np.ndarray  # (m, 3) int64, 0-based, counter-clockwise seen from outside


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed enclosed volume (positive for an outward-oriented closed surface)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def make_part(name: str, vertices, faces) -> Part:
    """Build a part and orient it outwards (positive signed volume)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if signed_volume(vertices, faces) < 0.0:
        faces = faces[:, ::-1].copy()
    return Part(name, vertices, faces)


def mirror_part(part: Part, name: str) -> Part:
    """Exact mirror copy of a part about y = 0 (orientation preserved)."""
    vertices = part.vertices * np.array([1.0, -1.0, 1.0])
    return Part(name, vertices, part.faces[:, ::-1].copy())


# ---------------------------------------------------------------------------
# Generic surface builders
# ---------------------------------------------------------------------------
def symmetric_circle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """cos/sin of n equally spaced angles, exactly mirror-symmetric.

    Returns (c, s) with c[n-k] == c[k] and s[n-k] == -s[k] bit for bit, and
    exact values at the four quadrant points (n must be a multiple of 4).
    """
    assert n % 4 == 0
    half = n // 2
    k = np.arange(half + 1)
    ang = 2.0 * np.pi * k / n
    c_half, s_half = np.cos(ang), np.sin(ang)
    c_half[0], s_half[0] = 1.0, 0.0
    c_half[n // 4], s_half[n // 4] = 0.0, 1.0
    c_half[half], s_half[half] = -1.0, 0.0
    c = np.concatenate([c_half, c_half[1:half][::-1]])
    s = np.concatenate([s_half, -s_half[1:half][::-1]])
    return c, s


def _newell_normal(points: np.ndarray) -> np.ndarray:
    """Area-weighted normal of a closed polygon (Newell's method)."""
    nxt = np.roll(points, -1, axis=0)
    return 0.5 * np.cross(points, nxt).sum(axis=0)


def _airfoil_cap(loop_idx: np.ndarray, n_chord: int) -> list[tuple[int, int, int]]:
    """Triangulate an airfoil section by chordwise strips.

    The loop is U_0..U_n followed by L_{n-1}..L_1 (U_0 = L_0 is the leading
    edge, U_n = L_n the trailing edge); each strip joins stations i and i+1 of
    the upper and lower surfaces, which is valid because the upper surface is
    above the lower one at every chord station.
    """
    n = n_chord
    upper = [int(loop_idx[i]) for i in range(n + 1)]
    lower = [upper[0]] + [int(loop_idx[2 * n - i]) for i in range(1, n)] + [upper[n]]
    tris = []
    for i in range(n):
        u0, u1, l0, l1 = upper[i], upper[i + 1], lower[i], lower[i + 1]
        if i == 0:
            tris.append((u0, u1, l1))
        elif i == n - 1:
            tris.append((u0, u1, l0))
        else:
            tris.append((u0, u1, l1))
            tris.append((u0, l1, l0))
    return tris


def loft(rings, start_cap, end_cap, n_chord: int | None = None):
    """Join a sequence of closed rings (each (m, 3), same m) into a closed surface.

    ``start_cap`` / ``end_cap`` are either a 3-vector (a pole: the ring is
    closed with a fan of triangles to that point) or the string ``"airfoil"``
    (the ring is an airfoil loop, closed by a flat strip triangulation).
    Returns (vertices, faces); the caller orients the result outwards.
    """
    rings = [np.asarray(r, dtype=np.float64) for r in rings]
    m = len(rings[0])
    n_rings = len(rings)
    verts = np.concatenate(rings, axis=0)
    faces: list[tuple[int, int, int]] = []

    # side quads: ring a = i, ring b = i + 1
    for i in range(n_rings - 1):
        a0, b0 = i * m, (i + 1) * m
        for j in range(m):
            jn = (j + 1) % m
            faces.append((a0 + j, a0 + jn, b0 + jn))
            faces.append((a0 + j, b0 + jn, b0 + j))

    extra = []

    def cap(cap_spec, ring_index: int, is_start: bool):
        base = ring_index * m
        idx = np.arange(base, base + m)
        if isinstance(cap_spec, str):
            assert cap_spec == "airfoil" and n_chord is not None
            # A start cap must traverse the loop backwards, an end cap forwards.
            want = _newell_normal(rings[ring_index]) * (-1.0 if is_start else 1.0)
            for tri in _airfoil_cap(idx, n_chord):
                p = verts[list(tri)]
                nrm = np.cross(p[1] - p[0], p[2] - p[0])
                faces.append(tri if np.dot(nrm, want) > 0.0 else (tri[0], tri[2], tri[1]))
        else:
            pole = n_rings * m + len(extra)
            extra.append(np.asarray(cap_spec, dtype=np.float64))
            for j in range(m):
                jn = (j + 1) % m
                if is_start:
                    faces.append((pole, base + jn, base + j))
                else:
                    faces.append((pole, base + j, base + jn))

    cap(start_cap, 0, True)
    cap(end_cap, n_rings - 1, False)
    if extra:
        verts = np.concatenate([verts, np.array(extra)], axis=0)
    return verts, np.array(faces, dtype=np.int64)


def revolve(profile, origin, axis, e1, e2, n_around: int):
    """Surface of revolution of a meridian profile [(s, r), ...].

    Points are ``origin + s*axis + r*(cos*e1 + sin*e2)``.  The first and last
    profile points must have r == 0 and become poles.  With e2 = +-Y and the
    origin on y = 0 the result is exactly symmetric about y = 0.
    """
    profile = np.asarray(profile, dtype=np.float64)
    assert profile[0, 1] == 0.0 and profile[-1, 1] == 0.0
    origin, axis, e1, e2 = (np.asarray(v, dtype=np.float64) for v in (origin, axis, e1, e2))
    c, s = symmetric_circle(n_around)
    circle = c[:, None] * e1[None, :] + s[:, None] * e2[None, :]
    rings = [origin + sv * axis + rv * circle for sv, rv in profile[1:-1]]
    start = origin + profile[0, 0] * axis
    end = origin + profile[-1, 0] * axis
    return loft(rings, start, end)


def cylinder(p0, p1, radius: float, e1, e2, n_around: int = N_AROUND_STRUT):
    """Closed cylinder from p0 to p1 (e1, e2: unit vectors normal to its axis)."""
    p0, p1 = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    e1, e2 = np.asarray(e1, dtype=np.float64), np.asarray(e2, dtype=np.float64)
    c, s = symmetric_circle(n_around)
    circle = radius * (c[:, None] * e1[None, :] + s[:, None] * e2[None, :])
    return loft([p0 + circle, p1 + circle], p0, p1)


# ---------------------------------------------------------------------------
# Airfoils and lifting surfaces
# ---------------------------------------------------------------------------
def naca4_loop(n: int, thickness: float, camber: float = 0.0, camber_pos: float = 0.4):
    """Closed NACA 4-digit airfoil loop in unit-chord coordinates.

    Returns (x, t) arrays of length 2n: x is the chordwise coordinate from the
    leading edge (0) to the trailing edge (1), t the thickness-direction
    coordinate.  Order: upper surface LE->TE, then lower surface TE->LE
    (LE and TE appear once).  The trailing edge is closed (sharp).
    """
    beta = np.linspace(0.0, np.pi, n + 1)
    # cosine spacing, slightly relaxed so the trailing-edge cells are not tiny
    x = 0.85 * 0.5 * (1.0 - np.cos(beta)) + 0.15 * beta / np.pi
    x[0], x[-1] = 0.0, 1.0
    yt = (
        5.0
        * thickness
        * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    )
    yt[0], yt[-1] = 0.0, 0.0
    if camber == 0.0:
        xu, zu, xl, zl = x, yt, x, -yt
    else:
        m, p = camber, camber_pos
        yc = np.where(
            x < p,
            m / p**2 * (2 * p * x - x**2),
            m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * x - x**2),
        )
        dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
        th = np.arctan(dyc)
        xu, zu = x - yt * np.sin(th), yc + yt * np.cos(th)
        xl, zl = x + yt * np.sin(th), yc - yt * np.cos(th)
    loop_x = np.concatenate([xu, xl[n - 1 : 0 : -1]])
    loop_t = np.concatenate([zu, zl[n - 1 : 0 : -1]])
    return loop_x, loop_t


@dataclass
class Section:
    """One spanwise station of a lifting surface."""

    span: float  # y (wings, tails) or z (fin, pylon) of the station
    x_le: float  # x of the leading edge
    offset: float  # z of the chord line (wings) or y of the chord plane (fin)
    chord: float
    thickness: float  # t/c
    twist_deg: float = 0.0  # nose-up incidence about the quarter chord (wings only)


def horizontal_section_ring(sec: Section, camber: float, n: int) -> np.ndarray:
    """Airfoil loop in the x-z plane at y = sec.span (wing, horizontal tail)."""
    xc, tc = naca4_loop(n, sec.thickness, camber)
    # relative to the quarter chord: forward is +X, aft is -X
    dx = -(xc - 0.25) * sec.chord
    dz = tc * sec.chord
    a = math.radians(sec.twist_deg)
    x = sec.x_le - 0.25 * sec.chord + dx * math.cos(a) - dz * math.sin(a)
    z = sec.offset + dx * math.sin(a) + dz * math.cos(a)
    y = np.full_like(x, sec.span)
    return np.stack([x, y, z], axis=1)


def vertical_section_ring(sec: Section, n: int) -> np.ndarray:
    """Symmetric airfoil loop in the x-y plane at z = sec.span (fin, pylons)."""
    xc, tc = naca4_loop(n, sec.thickness)
    x = sec.x_le - xc * sec.chord
    y = sec.offset + tc * sec.chord
    z = np.full_like(x, sec.span)
    return np.stack([x, y, z], axis=1)


def symmetric_wing(half_sections: list[Section], camber: float, n: int = N_CHORD):
    """A horizontal lifting surface (the tailplane) lofted tip to tip through y = 0.

    ``half_sections`` describe the right half (span = |y| increasing from the
    centre line); the left half is their exact mirror.
    """
    right = [horizontal_section_ring(s, camber, n) for s in half_sections]
    for r, s in zip(right, half_sections):
        r[:, 1] = -s.span
    left = [r * np.array([1.0, -1.0, 1.0]) for r in right]
    if half_sections[0].span == 0.0:
        left = left[1:]  # centre station is shared
    rings = right[::-1] + left
    return loft(rings, "airfoil", "airfoil", n_chord=n)


def lerp(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


# ---------------------------------------------------------------------------
# Parts
# ---------------------------------------------------------------------------
def fuselage_profile():
    """Stations (x, z_centre, radius) from the nose tip to the tail tip."""
    stations = []
    # nose cone: ellipse-like profile, centre line drooping towards the tip
    nose_len = NOSE_X - NOSE_START_X
    for k in range(27, 0, -1):
        u = math.sin(0.5 * math.pi * k / 28)  # 0 at the joint, 1 at the tip (dense near tip)
        x = NOSE_START_X + nose_len * u
        r = FUS_RADIUS * (1.0 - u**2.3) ** 0.5
        zc = AXIS_Z - 0.55 * u**2
        stations.append((x, zc, r))
    # constant section
    for k in range(0, 25):
        x = lerp(NOSE_START_X, TAIL_START_X, k / 24)
        stations.append((x, AXIS_Z, FUS_RADIUS))
    # tail cone: flat-ish top, belly sweeping up
    tail_end = TAIL_X + 0.25
    for k in range(1, 37):
        t = k / 36
        x = lerp(TAIL_START_X, tail_end, t)
        top = AXIS_Z + FUS_RADIUS - 0.55 * t**2
        smooth = t * t * (3.0 - 2.0 * t)
        bottom = BELLY_Z + (AXIS_Z + FUS_RADIUS - 0.85 - BELLY_Z) * smooth
        stations.append((x, 0.5 * (top + bottom), 0.5 * (top - bottom)))
    # rounded tail tip (APU exhaust)
    x_end, z_end, r_end = stations[-1]
    for k in range(1, 7):
        phi = 0.5 * math.pi * k / 7
        stations.append((x_end - (x_end - TAIL_X) * math.sin(phi), z_end, r_end * math.cos(phi)))
    return stations, (NOSE_X, AXIS_Z - 0.55), (TAIL_X, z_end)


def build_fuselage() -> Part:
    stations, nose, tail = fuselage_profile()
    c, s = symmetric_circle(N_AROUND)
    rings = []
    for x, zc, r in stations:
        ring = np.stack([np.full(N_AROUND, x), r * s, zc + r * c], axis=1)
        rings.append(ring)
    verts, faces = loft(rings, (nose[0], 0.0, nose[1]), (tail[0], 0.0, tail[1]))
    return make_part("fuselage", verts, faces)


WING_ROOT_Y = 1.0
WING_KINK_Y = 5.5
WING_TIP_Y = 15.0
WING_ROOT_LE_X = 3.5
WING_ROOT_TE_X = -3.0
WING_SWEEP_DEG = 30.0
WING_TIP_CHORD = 1.5
WING_DIHEDRAL_DEG = 5.0
WING_ROOT_Z = 2.35


def wing_planform(y: float) -> Section:
    """Right-wing section at span |y| (kinked trailing edge, swept leading edge)."""
    tan_sw = math.tan(math.radians(WING_SWEEP_DEG))
    ya = max(abs(y), WING_ROOT_Y)
    x_le = WING_ROOT_LE_X - (ya - WING_ROOT_Y) * tan_sw
    tip_le = WING_ROOT_LE_X - (WING_TIP_Y - WING_ROOT_Y) * tan_sw
    tip_te = tip_le - WING_TIP_CHORD
    if ya <= WING_KINK_Y:
        x_te = WING_ROOT_TE_X
    else:
        x_te = lerp(WING_ROOT_TE_X, tip_te, (ya - WING_KINK_Y) / (WING_TIP_Y - WING_KINK_Y))
    f = (ya - WING_ROOT_Y) / (WING_TIP_Y - WING_ROOT_Y)
    z = WING_ROOT_Z + (ya - WING_ROOT_Y) * math.tan(math.radians(WING_DIHEDRAL_DEG))
    return Section(
        span=abs(y),
        x_le=x_le,
        offset=z,
        chord=x_le - x_te,
        thickness=lerp(0.15, 0.11, f),
        twist_deg=lerp(2.0, -1.0, f),
    )


def build_wing_right() -> Part:
    """Right wing from its root (y = -1, inside the fuselage) to the tip."""
    ys = [WING_ROOT_Y]
    ys += [lerp(WING_ROOT_Y, WING_KINK_Y, k / 10) for k in range(1, 11)]
    ys += [lerp(WING_KINK_Y, WING_TIP_Y, k / 24) for k in range(1, 25)]
    rings = [horizontal_section_ring(wing_planform(y), 0.02, N_CHORD) for y in ys]
    for r, y in zip(rings, ys):
        r[:, 1] = -y
    verts, faces = loft(rings, "airfoil", "airfoil", n_chord=N_CHORD)
    return make_part("wing_right", verts, faces)


def build_horizontal_tail() -> Part:
    """Swept tailplane, one body through the tail cone from tip to tip."""
    root_y, tip_y = 0.0, 5.6
    root_le, root_chord, tip_chord = -12.6, 3.4, 1.25
    sweep, dihedral, z0 = 32.0, 6.0, 4.72
    secs = []
    for k in range(0, 21):
        y = lerp(root_y, tip_y, k / 20)
        f = k / 20
        secs.append(
            Section(
                span=y,
                x_le=root_le - y * math.tan(math.radians(sweep)),
                offset=z0 + y * math.tan(math.radians(dihedral)),
                chord=lerp(root_chord, tip_chord, f),
                thickness=lerp(0.12, 0.10, f),
            )
        )
    verts, faces = symmetric_wing(secs, camber=0.0)
    return make_part("horizontal_tail", verts, faces)


def build_vertical_fin() -> Part:
    """Swept vertical fin on y = 0, root buried in the tail cone, top at FIN_TOP_Z."""
    root_z, tip_z = 4.9, FIN_TOP_Z
    root_le, root_chord, tip_chord, sweep = -10.8, 5.5, 2.3, 40.0
    rings = []
    n_st = 20
    for k in range(n_st + 1):
        f = k / n_st
        z = lerp(root_z, tip_z, f)
        sec = Section(
            span=z,
            x_le=root_le - (z - root_z) * math.tan(math.radians(sweep)),
            offset=0.0,
            chord=lerp(root_chord, tip_chord, f),
            thickness=lerp(0.12, 0.10, f),
        )
        rings.append(vertical_section_ring(sec, N_CHORD))
    verts, faces = loft(rings, "airfoil", "airfoil", n_chord=N_CHORD)
    return make_part("vertical_fin", verts, faces)


ENGINE_Y = -5.7  # right engine (mirrored for the left one)
ENGINE_Z = 1.25  # nacelle axis height
ENGINE_LIP_X = 3.2  # x of the inlet lip


def nacelle_profile():
    """Meridian (s, r) of a turbofan nacelle, s = axial position from the lip (aft < 0).

    Runs from the spinner tip (inside the inlet) over the fan face, along the
    inlet wall, round the lip, along the cowl to the fan nozzle, over the core
    cowl and the exhaust plug to its tip.
    """
    prof = [(-0.30, 0.0)]
    for k in range(1, 7):  # spinner
        phi = 0.5 * math.pi * k / 6
        prof.append((-0.75 + 0.45 * math.cos(phi), 0.30 * math.sin(phi)))
    for r in (0.42, 0.54, 0.66, 0.76):  # fan face
        prof.append((-0.75, r))
    for k in range(1, 5):  # inlet wall
        f = k / 5
        prof.append((lerp(-0.75, -0.08, f), lerp(0.76, 0.80, f)))
    for k in range(0, 9):  # lip (half circle)
        psi = -0.5 * math.pi + math.pi * k / 8
        prof.append((-0.08 + 0.06 * math.cos(psi), 0.86 + 0.06 * math.sin(psi)))
    cowl = [
        (0.30, 0.955),
        (0.60, 0.98),
        (1.0, 0.995),
        (1.4, 1.0),
        (1.8, 0.99),
        (2.2, 0.965),
        (2.6, 0.92),
        (2.9, 0.86),
        (3.2, 0.78),
    ]
    for d, r in cowl:  # fan cowl
        prof.append((-d, r))
    prof += [(-3.22, 0.70), (-3.26, 0.64)]  # fan nozzle step
    core = [(3.45, 0.60), (3.65, 0.55), (3.85, 0.48), (3.95, 0.42)]
    prof += [(-d, r) for d, r in core]  # core cowl
    prof += [
        (-3.97, 0.36),
        (-4.1, 0.30),
        (-4.25, 0.22),
        (-4.4, 0.12),
        (-4.5, 0.05),
        (-4.55, 0.0),
    ]  # exhaust plug
    return prof


def build_nacelle_right() -> Part:
    verts, faces = revolve(
        nacelle_profile(),
        (ENGINE_LIP_X, ENGINE_Y, ENGINE_Z),
        axis=(1, 0, 0),
        e1=(0, 0, 1),
        e2=(0, 1, 0),
        n_around=N_AROUND_SMALL,
    )
    return make_part("nacelle_right", verts, faces)


def build_pylon_right() -> Part:
    z_bot, z_top = ENGINE_Z + 0.6, 2.75
    le_bot, te_bot = 2.8, -0.3
    le_top, te_top = 0.6, -1.6
    rings = []
    for k in range(9):
        f = k / 8
        z = lerp(z_bot, z_top, f)
        le, te = lerp(le_bot, le_top, f), lerp(te_bot, te_top, f)
        sec = Section(span=z, x_le=le, offset=ENGINE_Y, chord=le - te, thickness=0.32 / (le - te))
        rings.append(vertical_section_ring(sec, 24))
    verts, faces = loft(rings, "airfoil", "airfoil", n_chord=24)
    return make_part("pylon_right", verts, faces)


def wheel(name: str, centre, radius: float, width: float) -> Part:
    """A wheel (tyre + recessed hub) whose axle is along Y."""
    a = 0.5 * width
    b = 0.38 * radius  # tyre cross-section half height
    rc = radius - b
    hub = 0.45 * radius
    prof = [(-0.75 * a, 0.0), (-0.75 * a, 0.5 * hub), (-0.75 * a, hub), (-0.9 * a, 1.1 * hub)]
    p = 4.0  # superellipse exponent (boxy tyre with round shoulders)
    n_arc = 16
    for k in range(n_arc + 1):
        phi = math.pi - math.pi * k / n_arc
        cp, sp = math.cos(phi), math.sin(phi)
        s = a * math.copysign(abs(cp) ** (2.0 / p), cp)
        r = rc + b * abs(sp) ** (2.0 / p)
        if k == n_arc // 2:
            s, r = 0.0, radius
        prof.append((s, r))
    prof += [(0.9 * a, 1.1 * hub), (0.75 * a, hub), (0.75 * a, 0.5 * hub), (0.75 * a, 0.0)]
    verts, faces = revolve(
        prof, centre, axis=(0, 1, 0), e1=(0, 0, 1), e2=(1, 0, 0), n_around=N_AROUND_WHEEL
    )
    return make_part(name, verts, faces)


NOSE_GEAR_X = 12.6
NOSE_WHEEL_R, NOSE_WHEEL_W = 0.38, 0.20
MAIN_GEAR_X, MAIN_GEAR_Y = -1.0, -3.8  # right main gear (mirrored for the left)
MAIN_WHEEL_R, MAIN_WHEEL_W = 0.58, 0.38

Z_AXIS_DIRS = dict(e1=(1, 0, 0), e2=(0, 1, 0))  # frame for vertical struts
Y_AXIS_DIRS = dict(e1=(0, 0, 1), e2=(1, 0, 0))  # frame for axles along Y


def build_nose_gear() -> list[Part]:
    axle_z = NOSE_WHEEL_R + GROUND_CLEARANCE
    strut = cylinder((NOSE_GEAR_X, 0.0, axle_z), (NOSE_GEAR_X, 0.0, 2.3), 0.09, **Z_AXIS_DIRS)
    axle = cylinder((NOSE_GEAR_X, -0.30, axle_z), (NOSE_GEAR_X, 0.30, axle_z), 0.05, **Y_AXIS_DIRS)
    wheel_r = wheel("nose_wheel_right", (NOSE_GEAR_X, -0.22, axle_z), NOSE_WHEEL_R, NOSE_WHEEL_W)
    return [
        make_part("nose_gear_strut", *strut),
        make_part("nose_gear_axle", *axle),
        wheel_r,
        mirror_part(wheel_r, "nose_wheel_left"),
    ]


def build_main_gear_right() -> list[Part]:
    axle_z = MAIN_WHEEL_R + GROUND_CLEARANCE
    x, y = MAIN_GEAR_X, MAIN_GEAR_Y
    strut = cylinder((x, y, axle_z), (x, y, 2.55), 0.13, **Z_AXIS_DIRS)
    axle = cylinder((x, y - 0.5, axle_z), (x, y + 0.5, axle_z), 0.07, **Y_AXIS_DIRS)
    return [
        make_part("main_gear_strut_right", *strut),
        make_part("main_gear_axle_right", *axle),
        wheel("main_wheel_right_outer", (x, y - 0.37, axle_z), MAIN_WHEEL_R, MAIN_WHEEL_W),
        wheel("main_wheel_right_inner", (x, y + 0.37, axle_z), MAIN_WHEEL_R, MAIN_WHEEL_W),
    ]


def build_airliner() -> list[Part]:
    """All parts of the aircraft, in output order."""
    wing = build_wing_right()
    parts = [
        build_fuselage(),
        wing,
        mirror_part(wing, "wing_left"),
        build_horizontal_tail(),
        build_vertical_fin(),
    ]
    nacelle, pylon = build_nacelle_right(), build_pylon_right()
    parts += [
        nacelle,
        mirror_part(nacelle, "nacelle_left"),
        pylon,
        mirror_part(pylon, "pylon_left"),
    ]
    parts += build_nose_gear()
    for p in build_main_gear_right():
        parts += [p, mirror_part(p, p.name.replace("right", "left"))]
    return parts


# ---------------------------------------------------------------------------
# OBJ output / input
# ---------------------------------------------------------------------------
HEADER = """\
# airliner.obj - synthetic narrow-body airliner (A320-class proportions)
# generated by nbvkit meshes/generate_airliner.py (deterministic; do not edit by hand)
# units: metres; Z up; fuselage along X with the nose at +X; +Y = left (port) side
# mirror-symmetric about the plane y = 0; lowest point (tyres) at z = {zmin:.3f}
# {n_parts} parts (o groups), each a closed outward-oriented triangle surface
# vertices: {n_v}  triangles: {n_f}
"""


def _fmt(v: float) -> str:
    return f"{v:.{OBJ_DECIMALS}f}"


def write_obj(parts: list[Part], path: str) -> None:
    lines = []
    n_v = sum(len(p.vertices) for p in parts)
    n_f = sum(len(p.faces) for p in parts)
    zmin = min(float(p.vertices[:, 2].min()) for p in parts)
    lines.append(HEADER.format(zmin=zmin, n_parts=len(parts), n_v=n_v, n_f=n_f).rstrip("\n"))
    offset = 1
    for p in parts:
        # round first, then add 0.0 so that -0.0 is written as 0.000000
        v = np.round(p.vertices, OBJ_DECIMALS) + 0.0
        lines.append(f"o {p.name}")
        lines.extend(f"v {_fmt(a)} {_fmt(b)} {_fmt(c)}" for a, b, c in v.tolist())
        lines.extend(f"f {a} {b} {c}" for a, b, c in (p.faces + offset).tolist())
        offset += len(p.vertices)
    with open(path, "w", encoding="ascii", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")


def read_obj(path: str):
    """Read a triangle OBJ: returns (vertices, faces (0-based), {group: face slice})."""
    verts, faces, groups = [], [], {}
    current, start = None, 0
    with open(path, encoding="ascii") as fh:
        for line in fh:
            tok = line.split()
            if not tok or tok[0].startswith("#"):
                continue
            if tok[0] == "v":
                verts.append([float(t) for t in tok[1:4]])
            elif tok[0] == "f":
                if len(tok) != 4:
                    raise ValueError(f"non-triangle face: {line.strip()}")
                faces.append([int(t.split("/")[0]) - 1 for t in tok[1:4]])
            elif tok[0] in ("o", "g"):
                if current is not None:
                    groups[current] = slice(start, len(faces))
                current, start = tok[1], len(faces)
    if current is not None:
        groups[current] = slice(start, len(faces))
    else:
        groups["mesh"] = slice(0, len(faces))
    return np.array(verts, dtype=np.float64), np.array(faces, dtype=np.int64), groups


# ---------------------------------------------------------------------------
# Checks
# ---------------------------------------------------------------------------
def symmetry_error(vertices: np.ndarray, chunk: int = 512) -> float:
    """max over vertices of the distance from (x, -y, z) to the nearest vertex."""
    keys = {tuple(k) for k in np.round(vertices * 10**OBJ_DECIMALS).astype(np.int64).tolist()}
    mirrored = vertices * np.array([1.0, -1.0, 1.0])
    mkeys = np.round(mirrored * 10**OBJ_DECIMALS).astype(np.int64).tolist()
    unmatched = np.array([i for i, k in enumerate(mkeys) if tuple(k) not in keys], dtype=np.int64)
    if len(unmatched) == 0:
        return 0.0
    worst = 0.0
    for i in range(0, len(unmatched), chunk):
        q = mirrored[unmatched[i : i + chunk]]
        d2 = ((q[:, None, :] - vertices[None, :, :]) ** 2).sum(axis=2)
        worst = max(worst, float(np.sqrt(d2.min(axis=1)).max()))
    return worst


def edge_stats(faces: np.ndarray) -> tuple[bool, bool]:
    """(closed, consistently oriented) for a triangle set."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    undirected = np.sort(directed, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    closed = bool(np.all(counts == 2))
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    consistent = bool(np.all(dcounts == 1))
    return closed, consistent


def check(path: str) -> bool:
    """Print statistics of an OBJ file; returns True if all checks pass."""
    v, f, groups = read_obj(path)
    ok = True
    print(f"file:           {path}")
    print(f"triangles:      {len(f)}")
    print(f"vertices:       {len(v)}")
    finite = bool(np.isfinite(v).all())
    idx_ok = bool(f.min() >= 0 and f.max() < len(v))
    print(f"finite coords:  {finite}    indices valid: {idx_ok}")
    ok &= finite and idx_ok
    lo, hi = v.min(axis=0), v.max(axis=0)
    print("bbox min:       ({:.3f}, {:.3f}, {:.3f})".format(*lo))
    print("bbox max:       ({:.3f}, {:.3f}, {:.3f})".format(*hi))
    print("bbox size:      {:.3f} x {:.3f} x {:.3f} m".format(*(hi - lo)))
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    print(f"surface area:   {areas.sum():.3f} m^2")
    print(f"min tri area:   {areas.min():.3e} m^2  (degenerate: {int((areas <= 1e-12).sum())})")
    ok &= bool(areas.min() > 1e-12)
    sym = symmetry_error(v)
    print(f"symmetry error: {sym:.3e} m")
    ok &= sym < 1e-5
    print(f"{'part':<24}{'tris':>7}{'closed':>8}{'oriented':>10}{'volume m^3':>12}")
    for name, sl in groups.items():
        pf = f[sl]
        closed, consistent = edge_stats(pf)
        vol = signed_volume(v, pf)
        print(f"{name:<24}{len(pf):>7}{str(closed):>8}{str(consistent):>10}{vol:>12.3f}")
        ok &= closed and consistent and vol > 0.0
    print("all checks passed" if ok else "SOME CHECKS FAILED")
    return ok


def main(argv: list[str] | None = None) -> int:
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--out",
        default=os.path.join(here, "airliner.obj"),
        help="output OBJ path (default: airliner.obj next to this script)",
    )
    ap.add_argument(
        "--check", action="store_true", help="after writing, re-read the OBJ and print statistics"
    )
    args = ap.parse_args(argv)
    parts = build_airliner()
    write_obj(parts, args.out)
    n_f = sum(len(p.faces) for p in parts)
    print(f"wrote {args.out}: {len(parts)} parts, {n_f} triangles")
    if args.check:
        return 0 if check(args.out) else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
