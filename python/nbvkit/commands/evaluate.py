"""nbvkit evaluate: score a reconstructed point cloud against the structure's ground truth."""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from ..paths import check_output_file
from ..cloud import read_points
from ..evaluation import (
    DEFAULT_GT_DENSITY,
    DEFAULT_RESOLUTIONS,
    DEFAULT_TAUS,
    evaluate,
    format_report,
)
from .common import add_mesh_options, mesh_from_args


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "evaluate",
        help="score a reconstructed cloud against the ground-truth mesh or cloud",
        description="Score a reconstructed point cloud against ground truth: coverage (the paper's "
        "metric: ground-truth cells also holding a reconstructed point / ground-truth "
        "cells, on an origin-anchored grid) and area coverage at each resolution, "
        "precision, completeness / accuracy / F-score at each distance threshold, and "
        "the Chamfer distance. The ground truth is the mesh's surface sampled "
        "uniformly (--gt-density, --seed) or a reference point cloud "
        "(--reference-cloud). Prints a table; --json writes every figure.",
    )
    add_mesh_options(p)
    p.add_argument(
        "--reference-cloud",
        metavar="PATH",
        help="use this ground-truth point cloud (.ply, .pcd or .npy) as is instead of "
        "sampling a mesh (as the authors evaluated); excludes --mesh, and "
        "--mesh-scale / --mesh-up / --gt-density / --seed do not apply to it",
    )
    p.add_argument(
        "cloud",
        metavar="CLOUD",
        help="the reconstructed point cloud to score: .ply, .pcd or .npy (world frame, "
        "metres, same frame as the mesh after --mesh-scale/--mesh-up)",
    )
    p.add_argument(
        "--json",
        metavar="OUT",
        help="also write the results as JSON to OUT (keys: coverage, area_coverage, "
        "precision, completeness, accuracy, fscore, chamfer_m, n_points, "
        "gt_density, and more)",
    )
    p.add_argument(
        "--gt-density",
        type=float,
        default=DEFAULT_GT_DENSITY,
        metavar="D",
        help=f"ground-truth samples per m^2 of mesh surface (default {DEFAULT_GT_DENSITY:g}; "
        "coverage depends on it, area coverage does not)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="N",
        help="seed of the ground-truth surface sampling (default 0; same seed, same numbers)",
    )
    p.add_argument(
        "--resolutions",
        type=float,
        nargs="+",
        default=list(DEFAULT_RESOLUTIONS),
        metavar="R",
        help="coverage cell sizes in metres (default: "
        + " ".join(f"{r:g}" for r in DEFAULT_RESOLUTIONS)
        + ")",
    )
    p.add_argument(
        "--taus",
        type=float,
        nargs="+",
        default=list(DEFAULT_TAUS),
        metavar="T",
        help="distance thresholds in metres for completeness / accuracy / F-score "
        "(default: " + " ".join(f"{t:g}" for t in DEFAULT_TAUS) + ")",
    )
    return p


def run(args) -> int:
    if args.mesh and args.reference_cloud:
        raise ValueError("give either --mesh or --reference-cloud, not both")
    if args.json:
        check_output_file(args.json, "--json")
    cloud_path = Path(os.fspath(args.cloud)).expanduser()
    cloud = read_points(cloud_path)
    if args.reference_cloud:
        gt = read_points(args.reference_cloud)
        gt_desc = {"reference_cloud": str(Path(args.reference_cloud).expanduser())}
    else:
        gt = mesh_from_args(args)
        gt_desc = {
            "mesh": str(args.mesh) if args.mesh else "default (shipped airliner)",
            "mesh_scale": args.mesh_scale,
            "mesh_up": args.mesh_up,
        }
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    result = evaluate(
        gt,
        cloud,
        resolutions=args.resolutions,
        taus=args.taus,
        gt_density=args.gt_density,
        seed=args.seed,
    )
    print(f"cloud file: {cloud_path}")
    print(f"ground-truth file: {next(iter(gt_desc.values()))}")
    print(format_report(result))
    if args.json:
        out = dict(result)
        out["cloud_path"] = str(cloud_path)
        out.update(gt_desc)
        text = json.dumps(out, indent=2, allow_nan=False)
        Path(args.json).expanduser().write_text(text + "\n")
        print(f"results -> {args.json}")
    return 0
