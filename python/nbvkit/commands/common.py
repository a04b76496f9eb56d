"""Options shared by several subcommands."""
from __future__ import annotations

import argparse

from ..mesh import default_mesh_path, load_mesh


def add_mesh_options(p: argparse.ArgumentParser, required: bool = False) -> None:
    p.add_argument(
        "--mesh",
        metavar="PATH",
        required=required,
        help="structure mesh (OBJ, STL, DAE, glTF, ... read with assimp; PLY with nbvkit's "
        "strict reader); "
        "default: the shipped generated airliner",
    )
    p.add_argument(
        "--mesh-scale",
        metavar="S",
        type=float,
        default=1.0,
        help="multiply the mesh coordinates by S (default 1; e.g. 0.001 for millimetres)",
    )
    p.add_argument(
        "--mesh-up",
        choices=("y", "z"),
        default="z",
        help="the mesh file's up axis; y-up files are rotated to z-up (default z)",
    )


def mesh_from_args(args):
    path = args.mesh if args.mesh else default_mesh_path()
    return load_mesh(path, scale=args.mesh_scale, up=args.mesh_up)
