"""nbvkit evaluate: score a reconstructed point cloud against the structure's ground truth."""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from ..output_paths import write_text_output
from ..output_paths import check_not_input
from ..paths import check_output_file, require_complete_run
from ..run_manifest import stopped_note_of
from ..cloud import read_points
from ..mesh import default_mesh_path, file_up_axis, mesh_file_sha1
from ..evaluation import (
    DEFAULT_GT_DENSITY,
    DEFAULT_RESOLUTIONS,
    DEFAULT_TAUS,
    Evaluator,
    format_report,
)
from .common import add_mesh_options, add_set_option, mesh_from_args, path_arg


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
        "(--reference-cloud). A run's cloud (a run folder, or a file in one) is scored "
        "against the mesh the run flew (its config.yaml: path, scale, up, shift) unless --mesh "
        "or --reference-cloud names another. Prints a table; --json writes every figure.",
    )
    add_mesh_options(p)
    _add_inputs(p)
    _add_observable_options(p)
    _add_scoring_options(p)
    return p


def _add_inputs(p) -> None:
    """The ground truth besides the mesh (--reference-cloud) and the reconstruction (CLOUD)."""
    p.add_argument(
        "--reference-cloud",
        metavar="PATH",
        type=path_arg,
        help="use this ground-truth point cloud (.ply, .pcd or .npy) as is instead of "
        "sampling a mesh (as the authors evaluated); excludes --mesh, and "
        "--mesh-scale / --mesh-up / --mesh-shift / --gt-density / --seed do not apply to it",
    )
    p.add_argument(
        "cloud",
        metavar="CLOUD",
        help="the reconstruction to score: a point cloud (.ply, .pcd or .npy), a mesh "
        "(a .ply with faces, .obj, .stl, .off, .glb, .gltf, .dae: its surface is sampled at "
        "--gt-density), or a run folder (its cloud.ply; a run folder must be complete), world "
        "frame, metres, same frame as the mesh after "
        "--mesh-scale/--mesh-up/--mesh-shift",
    )


def _add_observable_options(p) -> None:
    """--observable and the configuration that defines the observable surface."""
    p.add_argument(
        "--observable",
        action="store_true",
        help="also score relative to the observable surface: the ground-truth samples that "
        "the configured camera could see from some collision-free pose of the navigation "
        "space (nbvkit.observable_surface; camera, workspace and vehicle from --config/--set). "
        "Adds coverage_observable, area_coverage_observable and observable_fraction",
    )
    p.add_argument(
        "--config",
        metavar="FILE",
        type=path_arg,
        help="mission configuration (YAML) whose camera, workspace, vehicle and observability "
        "sections define the observable surface (default: a run's own config.yaml, for a run's "
        "cloud scored against its mesh; else the default configuration)",
    )
    add_set_option(p, "override config keys for --observable (e.g. observability.pose_spacing=0.5)")
    p.add_argument(
        "--cache",
        metavar="DIR",
        type=path_arg,
        default=None,
        help="cache folder of the observable surface (default: none, computed every time)",
    )


def _add_scoring_options(p) -> None:
    """--json and the scoring's settings: ground-truth density and seed, resolutions, taus."""
    p.add_argument(
        "--json",
        metavar="OUT",
        type=path_arg,
        help="also write the results as JSON to OUT (keys: coverage, area_coverage, "
        "precision, completeness, accuracy, fscore, chamfer_m, n_points, "
        "gt_density, and more)",
    )
    p.add_argument(
        "--gt-density",
        type=float,
        default=None,
        metavar="D",
        help="ground-truth samples per m^2 of mesh surface (default: a run's own, for a run's "
        f"cloud; else {DEFAULT_GT_DENSITY:g}; coverage depends on it, area coverage does not)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="N",
        help="seed of the ground-truth surface sampling (default: a run's own, for a run's "
        "cloud; else 0; same seed, same numbers)",
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


def run(args) -> int:
    if args.mesh and args.reference_cloud:
        raise ValueError("give either --mesh or --reference-cloud, not both")
    if args.observable and args.reference_cloud:
        raise ValueError("--observable needs the ground-truth mesh, not --reference-cloud")
    given = [f for f in ("set", "config", "cache") if getattr(args, f)]
    if given and not args.observable:
        names = " and ".join(f"--{f}" for f in given)
        raise ValueError(
            f"{names} {'define' if len(given) > 1 else 'defines'} only the observable surface: "
            "add --observable (the other figures do not read a mission configuration)"
        )
    if args.json:
        check_output_file(args.json, "--json")
    cloud_path = run_cloud(Path(os.fspath(args.cloud)).expanduser())
    _settings_of_run(args, cloud_path.parent)
    if args.json:
        _check_json_not_input(args, cloud_path)
    if not args.gt_density > 0:
        raise ValueError(f"--gt-density must be > 0, got {args.gt_density}")
    cloud, cloud_kind = read_reconstruction(cloud_path, args.gt_density, args.seed)
    if args.reference_cloud:
        gt = read_points(args.reference_cloud)
        gt_desc = {"reference_cloud": str(Path(args.reference_cloud).expanduser())}
    else:
        gt = mesh_from_args(args)
        gt_desc = {
            "mesh": str(args.mesh) if args.mesh else "default (shipped airliner)",
            "mesh_scale": args.mesh_scale,
            "mesh_up": file_up_axis(args.mesh or default_mesh_path(), args.mesh_up),
            "mesh_shift": args.mesh_shift,
        }
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if not args.reference_cloud:
        from ..work_limits import check_samples

        check_samples(gt.area, args.gt_density, "--gt-density")
    ev = Evaluator(
        gt,
        resolutions=args.resolutions,
        taus=args.taus,
        gt_density=args.gt_density,
        seed=args.seed,
    )
    obs_stats = None
    if args.observable:
        from ..config import load_config
        from ..observability import observable_surface

        overrides = list(args.set) + [f"seed={args.seed}"]
        cfg = load_config(args.config, overrides)
        obs = observable_surface(gt, cfg, evaluator=ev, cache_dir=args.cache)
        ev.set_observable(obs.observable)
        obs_stats = obs.stats
    result = ev(cloud)
    print(f"reconstruction file: {cloud_path} ({cloud_kind})")
    print(f"ground-truth file: {next(iter(gt_desc.values()))}")
    apart = _frames_apart(np.asarray(cloud), ev.gt_points, max(args.taus))
    if apart:
        print(f"nbvkit evaluate: warning: {apart}", file=sys.stderr)
    stopped = stopped_note_of(cloud_path.parent)
    if stopped:
        print(f"nbvkit evaluate: warning: {stopped}", file=sys.stderr)
    print(format_report(result))
    if args.json:
        out = dict(result)
        out["cloud_path"] = str(cloud_path)
        out["reconstruction"] = cloud_kind
        out["warnings"] = [w for w in (apart, stopped) if w]  # (the console's, for the file alone)
        if obs_stats is not None:
            out["observability"] = obs_stats
        out.update(gt_desc)
        text = json.dumps(out, indent=2, allow_nan=False)
        write_text_output(args.json, text + "\n")  # whole or not at all where it can be
        print(f"results -> {args.json}")
    return 0


def _check_json_not_input(args, cloud_path: Path) -> None:
    """ValueError when --json would overwrite an input (output_paths.check_not_input)."""
    inputs = [
        ("the reconstruction", cloud_path),
        ("the mesh", args.mesh or (None if args.reference_cloud else default_mesh_path())),
        ("the reference cloud", args.reference_cloud),
        ("the configuration", args.config),
    ]
    check_not_input(args.json, inputs, "--json")


def _recorded(summary: dict, folder: Path, key: str, default: float) -> float:
    """The run's summary.json `key` (gt_density: a number > 0; seed: a whole number >= 0), the
    default where it has none; ValueError naming the file and the key for any other value (a
    summary changed since the run)."""
    from ..limits import fmt_number, is_number

    v = summary.get(key)
    if v is None:
        return default
    ok = is_number(v) and np.isfinite(v)
    ok = ok and (v > 0 if key == "gt_density" else (v >= 0 and float(v).is_integer()))
    if not ok:
        shown = fmt_number(v) if is_number(v) else repr(v)
        raise ValueError(
            f"{folder / 'summary.json'}: its {key!r} is {shown}, not what a run records (changed "
            f"since the run?): give --{key.replace('_', '-')}, or fly the run again"
        )
    return float(v)


def _settings_of_run(args, folder: Path) -> None:
    """A run's cloud is scored as the run scored it: against the mesh it flew (its config.yaml's
    mesh: path, scale, up, shift) unless --mesh or --reference-cloud names another ground truth,
    at its ground-truth density and seed (summary.json) unless --gt-density / --seed are given.
    With --observable and no --config, the observable surface is the run's own (its config.yaml's
    camera, workspace, vehicle and observability). Anything else: the defaults. Sets args;
    ValueError for mesh options given without --mesh, a run flown on an in-memory mesh, or a mesh
    file that cannot be found from here."""
    from ..config import load_config
    from ..runfolder import looks_like_run, read_summary
    from ..mesh import IN_MEMORY_MESH

    run = looks_like_run(folder) and (folder / "config.yaml").is_file()
    summary = read_summary(folder) if run else {}
    if args.gt_density is None:
        args.gt_density = _recorded(summary, folder, "gt_density", DEFAULT_GT_DENSITY)
    if args.seed is None:
        args.seed = int(_recorded(summary, folder, "seed", 0))
    if not run or args.mesh or args.reference_cloud:
        return
    if args.mesh_scale != 1.0 or args.mesh_up != "auto" or args.mesh_shift is not None:
        raise ValueError(
            f"the run {folder} flew the mesh its config.yaml names, with its scale, up axis and "
            "shift: give --mesh too to score its cloud against another mesh"
        )
    if summary.get("mesh") == IN_MEMORY_MESH:
        raise ValueError(
            f"the run {folder} flew a mesh given in memory, which its folder does not hold: give "
            "the ground truth with --mesh or --reference-cloud"
        )
    mesh = load_config(folder / "config.yaml").mesh
    if args.observable and args.config is None:
        args.config = str(folder / "config.yaml")
    args.mesh_scale, args.mesh_up = mesh.scale, mesh.up
    args.mesh_shift = list(mesh.shift) if any(mesh.shift) else None
    path = default_mesh_path() if mesh.path is None else Path(os.fspath(mesh.path)).expanduser()
    if not path.exists():
        raise ValueError(
            f"the run {folder} flew the mesh '{path}' (its config.yaml), which is not found from "
            f"here ({Path.cwd()}): give the mesh with --mesh"
        )
    flown = summary.get("mesh_sha1")  # (runs before it was recorded: none)
    if flown is None and mesh.path is not None:
        print(
            f"nbvkit evaluate: warning: the run {folder} records no SHA-1 of its mesh "
            f"(summary.json's mesh_sha1): its cloud is scored against '{path}' as found from here, "
            "which may not be the file it flew (give it with --mesh to be sure)",
            file=sys.stderr,
        )
    elif flown is not None and mesh_file_sha1(path) != flown:
        raise ValueError(
            f"the mesh file '{path}' the run {folder} flew has changed since (its SHA-1 is not "
            "the one summary.json records): the run's cloud would be scored against another "
            "structure; give the mesh it flew with --mesh"
        )
    if mesh.path is not None:  # (the default airliner: no --mesh, at the run's scale and up)
        args.mesh = path


def run_cloud(path: Path) -> Path:
    """The file to score for CLOUD: a run folder's cloud.ply, or the file itself. A run folder,
    or a file in one, must be a complete run (nbvkit.paths.require_complete_run): the cloud of a
    run that was interrupted, failed or is still being written is refused."""
    from ..runfolder import looks_like_run

    if path.is_dir():
        return require_complete_run(path, "CLOUD") / "cloud.ply"
    if looks_like_run(path.parent):
        require_complete_run(path.parent, "CLOUD's run folder")
    return path


def _frames_apart(cloud, gt, margin: float) -> str:
    """Why the cloud and the ground truth seem to be in different frames (their bounding boxes,
    grown by `margin`, do not meet), or ''."""
    if len(cloud) == 0 or len(gt) == 0:
        return ""
    lo_c, hi_c = cloud.min(axis=0), cloud.max(axis=0)
    lo_g, hi_g = gt.min(axis=0) - margin, gt.max(axis=0) + margin
    if np.all(hi_c >= lo_g) and np.all(lo_c <= hi_g):
        return ""
    gap = np.linalg.norm(np.maximum(0, np.maximum(lo_g - hi_c, lo_c - hi_g)))
    return (
        f"the reconstruction lies {gap:.1f} m from the ground truth's bounding box: are they "
        "in the same frame? (--mesh-scale, --mesh-up and --mesh-shift apply to the mesh only)"
    )


MESH_SUFFIXES = (".obj", ".stl", ".off", ".glb", ".gltf", ".dae", ".fbx", ".3ds")


def _ply_has_faces(path: Path) -> bool:
    with open(path, "rb") as f:
        head = f.read(4096).split(b"end_header")[0].decode("ascii", "replace")
    for line in head.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[:2] == ["element", "face"]:
            return int(parts[2]) > 0
    return False


def read_reconstruction(path: Path, density: float, seed: int = 0):
    """The reconstruction's points and what it was: a point cloud as read, or a mesh (a PLY
    with faces, or another mesh format) sampled uniformly at ``density`` points per m²."""
    from ..limits import check_input_file

    path = check_input_file(path, "reconstruction file")  # not a FIFO, a device, a folder
    suffix = path.suffix.lower()
    if suffix in MESH_SUFFIXES or (suffix == ".ply" and _ply_has_faces(path)):
        from ..mesh import load_mesh

        from ..work_limits import check_samples

        mesh = load_mesh(path, up="z")  # as it is: a reconstruction is in the world frame
        check_samples(mesh.area, density, "--gt-density")
        n = max(1, round(mesh.area * density))
        return mesh.sample_surface(n, seed), f"mesh, {mesh.area:.1f} m^2 sampled at {density:g}/m^2"
    return read_points(path), "point cloud"
