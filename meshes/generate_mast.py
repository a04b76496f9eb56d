#!/usr/bin/env python3
"""Procedural generator for a tall lattice mast (a telecom / transmission-style tower).

This writes ``meshes/mast.obj``: a structure unlike the airliner - tall, thin and open - on which
planners are tested for stopping too early (a thin lattice fills little of any camera frustum).
Entirely synthetic; only numpy and the standard library are used.

Conventions
-----------
* units: metres; Z is up; the mast stands on z = 0, centred on the z axis
* four corner legs taper from a 4.4 m square base to a 1.6 m square at the top (24 m); each face
  carries a horizontal girt every 3 m and an X brace in every bay; a square platform with a
  guard rail sits at 18 m, a headframe of antenna panels and a lightning rod at the top
* members are closed prisms: legs are octagonal tubes (0.22 m), girts and braces square bars
  (0.10 m and 0.07 m), panels thin boxes - each part a closed, outward-oriented surface (every
  edge shared by two triangles); parts intersect where they join
* the tower is mirror-symmetric about the planes x = 0 and y = 0

The output is deterministic: running the script again rewrites the OBJ byte-identically.

Usage::

    python3 meshes/generate_mast.py            # writes meshes/mast.obj
    python3 meshes/generate_mast.py --check    # ... and prints statistics
"""
from __future__ import annotations

import argparse
import math
import os

import numpy as np

HEIGHT = 24.0  # top of the legs
BASE_HALF = 2.2  # half-width of the leg square at z = 0
TOP_HALF = 0.8  # at z = HEIGHT
BAY = 3.0  # vertical spacing of the girts
LEG_RADIUS = 0.11  # octagonal legs
GIRT_SIZE = 0.10
BRACE_SIZE = 0.07
PLATFORM_Z = 18.0
PLATFORM_HALF = 1.9  # the platform's half-width
RAIL_HEIGHT = 1.0


def half_width(z: float) -> float:
    return BASE_HALF + (TOP_HALF - BASE_HALF) * z / HEIGHT


def corner(z: float, sx: int, sy: int) -> np.ndarray:
    h = half_width(z)
    return np.array([sx * h, sy * h, z])


def _frame(axis: np.ndarray):
    a = axis / np.linalg.norm(axis)
    ref = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(a, ref)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def prism(p0, p1, radius: float, sides: int):
    """A closed prism of `sides` sides (circumradius `radius`) from p0 to p1, capped."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    e1, e2 = _frame(p1 - p0)
    ang = 2 * math.pi * (np.arange(sides) + 0.5) / sides
    ring = np.outer(np.cos(ang), e1) + np.outer(np.sin(ang), e2)
    v = np.vstack([p0 + radius * ring, p1 + radius * ring, [p0, p1]])
    f = []
    for i in range(sides):
        j = (i + 1) % sides
        f += [(i, j, sides + j), (i, sides + j, sides + i)]
        f += [(2 * sides, j, i), (2 * sides + 1, sides + i, sides + j)]
    return v, np.array(f, int)


def box(lo, hi):
    """A closed axis-aligned box."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    v = lo + c * (hi - lo)
    f = [
        (0, 2, 1),
        (1, 2, 3),
        (4, 5, 6),
        (5, 7, 6),
        (0, 1, 4),
        (1, 5, 4),
        (2, 6, 3),
        (3, 6, 7),
        (0, 4, 2),
        (2, 4, 6),
        (1, 3, 5),
        (3, 7, 5),
    ]
    return v, np.array(f, int)


def build_mast() -> list[tuple[str, np.ndarray, np.ndarray]]:
    parts = []
    signs = [(1, 1), (-1, 1), (-1, -1), (1, -1)]  # corners, counter-clockwise
    for k, (sx, sy) in enumerate(signs):
        parts.append((f"leg_{k}", *prism(corner(0, sx, sy), corner(HEIGHT, sx, sy), LEG_RADIUS, 8)))
    levels = np.arange(BAY, HEIGHT + 1e-9, BAY)
    for k in range(4):
        a, b = signs[k], signs[(k + 1) % 4]
        for i, z in enumerate(levels):
            parts.append((f"girt_{k}_{i}", *prism(corner(z, *a), corner(z, *b), GIRT_SIZE / 2, 4)))
        z0s = np.concatenate([[0.0], levels])
        for i in range(len(z0s) - 1):
            lo, hi = z0s[i], z0s[i + 1]
            parts.append(
                (f"brace_{k}_{i}_a", *prism(corner(lo, *a), corner(hi, *b), BRACE_SIZE / 2, 4))
            )
            parts.append(
                (f"brace_{k}_{i}_b", *prism(corner(lo, *b), corner(hi, *a), BRACE_SIZE / 2, 4))
            )
    # platform with a guard rail
    h = PLATFORM_HALF
    parts.append(("platform", *box((-h, -h, PLATFORM_Z - 0.08), (h, h, PLATFORM_Z))))
    rail_z = PLATFORM_Z + RAIL_HEIGHT
    rail = [(h, h), (-h, h), (-h, -h), (h, -h)]
    for k in range(4):
        (x0, y0), (x1, y1) = rail[k], rail[(k + 1) % 4]
        parts.append((f"rail_{k}", *prism((x0, y0, rail_z), (x1, y1, rail_z), 0.03, 6)))
        parts.append((f"post_{k}", *prism((x0, y0, PLATFORM_Z), (x0, y0, rail_z), 0.03, 6)))
    # headframe: antenna panels on each face, a lightning rod
    for k, (nx, ny) in enumerate([(1, 0), (0, 1), (-1, 0), (0, -1)]):
        d = TOP_HALF + 0.35
        c = np.array([nx * d, ny * d, HEIGHT - 1.6])
        ext = np.array([0.06 if nx else 0.35, 0.06 if ny else 0.35, 1.3])
        parts.append((f"panel_{k}", *box(c - ext, c + ext)))
    parts.append(("rod", *prism((0, 0, HEIGHT - 0.5), (0, 0, HEIGHT + 2.5), 0.04, 6)))
    parts.append(
        (
            "cap",
            *box(
                (-TOP_HALF - 0.12, -TOP_HALF - 0.12, HEIGHT - 0.1),
                (TOP_HALF + 0.12, TOP_HALF + 0.12, HEIGHT + 0.05),
            ),
        )
    )
    return parts


def _fmt(v: float) -> str:
    s = f"{v:.5f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def write_obj(parts, path: str) -> None:
    lines = ["# nbvkit generated lattice mast (meshes/generate_mast.py); units: metres, z up"]
    base = 1
    for name, v, f in parts:
        lines.append(f"o {name}")
        lines += [f"v {_fmt(x)} {_fmt(y)} {_fmt(z)}" for x, y, z in v]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in f]
        base += len(v)
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "mast.obj"))
    ap.add_argument("--check", action="store_true", help="print statistics")
    args = ap.parse_args()
    parts = build_mast()
    write_obj(parts, args.out)
    if args.check:
        v = np.vstack([p[1] for p in parts])
        tris = sum(len(p[2]) for p in parts)
        print(
            f"{len(parts)} parts, {tris} triangles, "
            f"bounds {v.min(0).round(2)} - {v.max(0).round(2)}"
        )


if __name__ == "__main__":
    main()
