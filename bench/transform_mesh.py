"""Writes a copy of a mesh turned, scaled and moved: the same structure in another pose, to check
that a planner is not tuned to one orientation, position or size.

    .venv/bin/python bench/transform_mesh.py ../shared/meshes/twinjet.obj /tmp/twinjet_posed.obj \\
        --yaw 37 --shift 23 -11 0
    .venv/bin/python bench/transform_mesh.py ../shared/meshes/twinjet.obj /tmp/twinjet_rolled.obj \\
        --roll 90 --ground

The rotation is roll (about x), then pitch (about y), then yaw (about z), in degrees, about the
origin; then the scale, then the shift (metres). --ground then moves the lowest point to z = 0.
"""
from __future__ import annotations

import argparse

import numpy as np

import nbvkit


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    def axis(a: int, deg: float) -> np.ndarray:
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        i, j = [k for k in range(3) if k != a]
        r = np.eye(3)
        r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
        return r

    return axis(2, yaw) @ axis(1, pitch) @ axis(0, roll)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh")
    ap.add_argument("out", help="the OBJ to write")
    ap.add_argument("--roll", type=float, default=0.0)
    ap.add_argument("--pitch", type=float, default=0.0)
    ap.add_argument("--yaw", type=float, default=0.0)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--shift", type=float, nargs=3, default=(0.0, 0.0, 0.0))
    ap.add_argument("--ground", action="store_true", help="lowest point to z = 0 at the end")
    ap.add_argument(
        "--up", choices=("auto", "y", "z"), default="auto", help="the input file's up axis"
    )
    args = ap.parse_args()
    mesh = nbvkit.load_mesh(args.mesh, up=args.up)
    v = np.asarray(mesh.vertices) @ rotation(args.roll, args.pitch, args.yaw).T
    v = v * args.scale + np.asarray(args.shift)
    if args.ground:
        v[:, 2] -= v[:, 2].min()
    with open(args.out, "w") as f:
        f.writelines("v %.6f %.6f %.6f\n" % tuple(p) for p in v)
        f.writelines("f %d %d %d\n" % tuple(t + 1) for t in np.asarray(mesh.faces))
    lo, hi = v.min(axis=0), v.max(axis=0)
    print(f"{args.out}: {len(v)} vertices, bounds {np.round(lo, 2)} - {np.round(hi, 2)}")


if __name__ == "__main__":
    main()
