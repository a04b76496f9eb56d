"""nbvkit run: one mission (a scenario: nbvkit's planner or a row of the paper's Table 2) from
one start, with its results."""
from __future__ import annotations

import argparse
import json
import sys

from ..config import load_config
from ..evaluation import unobservable_note
from ..interrupts import terminate_as_interrupt
from ..experiment_specs import mesh_overrides_once, with_mesh_shift
from ..mission import Mission
from ..planning.registry import checks_only_words, parts_words
from ..planning.selection import refusal_words
from ..planning.terminations.budget import budget_note
from ..recorder import fly_into, raise_stop
from ..runfolder import RunFolder
from ..scenarios import DEFAULT, SCENARIOS
from .. import symmetry
from .common import add_mesh_shift_option, add_set_option, path_arg, shift_override


#: how a quick run leaves the end-of-run outputs out
FINISH_OFF = "off: --set report.enabled=false observability.enabled=false"


def register(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "run",
        help="run one reconstruction mission and write its results folder",
        description="Fly one scenario on a structure from one of its five predefined starts, and "
        "write DIR/summary.json, iterations.csv, config.yaml (resolved), cloud.ply, map.ot, "
        "trajectory.csv, flight.csv (every point flown), mesh.ply, figures/*.png and "
        "report.html (open it in a browser), and "
        "manifest.json last: the folder appears whole once the run is complete (a failed or "
        "killed run leaves no partial folder), and a folder that already holds files is "
        "refused unless --overwrite. The mesh may be given by --mesh/--mesh-scale/--mesh-up/"
        "--mesh-shift or by --set mesh.path=... (each key once: both is refused). "
        f"Without --scenario: {DEFAULT}, the recommended planner.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="scenarios (--scenario, or --planner for nbvkit's own):\n"
        + "\n".join(f"  {k:12s} {v.description}" for k, v in SCENARIOS.items())
        + "\nexamples:\n  nbvkit run --out runs/main\n"
        "  nbvkit run --scenario 1 --start 0 --set max_iterations=50 --out runs/s1\n"
        "  nbvkit run --mesh my.obj --mesh-up y --set map.resolution=0.4",
    )
    p.add_argument(
        "--config",
        metavar="FILE",
        type=path_arg,
        help="YAML configuration (see configs/default.yaml); " "unknown keys are rejected",
    )
    p.add_argument("--mesh", metavar="PATH", help="structure mesh (default: the shipped airliner)")
    p.add_argument(
        "--mesh-scale", metavar="S", type=float, default=None, help="multiply mesh coordinates by S"
    )
    p.add_argument(
        "--mesh-up",
        choices=("auto", "y", "z"),
        default=None,
        help="the mesh file's up axis (default auto: glTF/GLB y, DAE its <up_axis>, others as they "
        "are: z)",
    )
    add_mesh_shift_option(p)
    p.add_argument(
        "--scenario",
        "--planner",
        dest="scenario",
        choices=list(SCENARIOS),
        default=None,
        help=f"what to fly: a Table 2 row (profile, 1-5) or a planner (default: {DEFAULT})",
    )
    p.add_argument(
        "--start",
        type=int,
        choices=range(5),
        default=None,
        metavar="0..4",
        help="which of the five predefined start poses around the structure (default 0)",
    )
    add_set_option(
        p,
        "override any config key, dotted for nested ones (e.g. max_iterations=50 "
        "map.resolution=0.4 utility.name=ig_distance)",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        type=path_arg,
        default=None,
        help="results folder (default runs/scenario<S>_start<K>)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the run already in --out (whole, once the new one is complete; a folder "
        "holding files nbvkit did not write is never replaced)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def config_from_args(args):
    """The resolved configuration of `nbvkit run`'s arguments; ValueError for a mesh key given
    both by its option (--mesh, --mesh-scale, --mesh-up, --mesh-shift) and by --set."""
    by = "--mesh/--mesh-scale/--mesh-up"
    mesh = mesh_overrides_once(args.set, args.mesh, args.mesh_scale, args.mesh_up, by=by)
    # after --set: a whole `mesh={...}` keeps them
    overrides = with_mesh_shift([*args.set, *mesh], shift_override(args))
    if args.scenario is not None:
        overrides.append(f"scenario={json.dumps(args.scenario)}")
    if args.start is not None:
        overrides.append(f"start={args.start}")
    if getattr(args, "no_progress", False):
        overrides.append("progress=false")
    return load_config(args.config, overrides)


def run(args) -> int:
    cfg = config_from_args(args)
    out = args.out or f"runs/scenario{cfg.scenario}_start{cfg.start}"
    # checked (writable, not in use by another run, empty or --overwrite) before any work
    inputs = (cfg.mesh.path, args.config)  # which an overwrite may not replace
    with RunFolder(out, overwrite=args.overwrite, what="--out", inputs=inputs) as folder:
        mission = Mission(cfg)
        with terminate_as_interrupt():  # a `kill` keeps the flight as Ctrl-C does
            s, stop = fly_into(mission, folder, finish=True)
    out = folder.placed  # beside a complete run --overwrite kept, for a stopped one
    if folder.placed == folder.tmp:  # which could not be put there: kept where it was written
        print(
            f"nbvkit run: the stopped run could not be put beside {folder.path}; it is kept in "
            f"{folder.tmp}: move it away before the next run on {folder.path}",
            file=sys.stderr,
        )
    print_summary(s, out, level=not (cfg.placement.gimbal or cfg.placement.explore_gimbal))
    if stop is not None and s.get("stopped_during") == "saving":
        print(
            f"nbvkit run: saving was stopped after the flight ({s['stopped_by']}); the whole "
            f"flight ({flown(s)}, {s['distance_m']:.1f} m) is saved in {out}/ without "
            "the end-of-run outputs (mesh.ply, report.html)",
            file=sys.stderr,
        )
    elif stop is not None:  # the error line (with its notes) follows: a SystemExit's does not
        from ..cli import PRINTED

        shown = isinstance(stop, PRINTED)
        why = f"by the {type(stop).__name__} below" if shown else s["stopped_by"]
        print(
            f"nbvkit run: the flight stopped after {flown(s)}, {s['distance_m']:.1f} m "
            f"({why}); what it flew is saved in {out}/",
            file=sys.stderr,
        )
    raise_stop(s, stop)
    return 0


def flown(s: dict) -> str:
    """The views a summary counts, as its keys do: `iterations` the planned views (the rows of
    iterations.csv), `views` every camera view, the first one (from where the camera stage
    starts, before any planning) included."""
    n, views = s["iterations"], s["views"]
    text = f"{n} iteration{'s' if n != 1 else ''}"
    if views == n + 1:
        text += f" ({views} views: the first, where the camera stage starts, and {n} planned)"
    elif views != n:
        text += f" ({views} camera views)"
    return text


#: below this share of the observable area at 0.05 m, a run its planner ended as complete is
#: told what it missed (missed_note): the recommended planner covers 93-98 % on most structures
COMPLETE_BELOW = 0.9


def missed_note(s: dict, level: bool) -> str | None:
    """The console's words for a coverage tour that found nothing more to fly to while a large
    share of the observable surface is missed, and, when no view could look down (`level`:
    placement.gimbal and placement.explore_gimbal off), the planner that pitches the camera (an
    open chimney: 56.6 % of the observable area with level views, 99.1 % with surface_gimbal);
    None otherwise, and None
    where the views the last plan left for their flight (budget_note) would add half of what
    was missed (a 3 m aircraft: 0.8 m2 of its 0.9 m2)."""
    cov = s.get("area_coverage_observable", {}).get("0.05")
    if s["termination"] != "coverage_complete" or cov is None or cov >= COMPLETE_BELOW:
        return None
    if "tour" not in s.get("generators", []):
        return None
    missed_m2 = (1 - cov) * s["observable_area_fraction"] * (s.get("gt_area_m2") or 0.0)
    if (s.get("tours") or [{}])[-1].get("unpaid_m2", 0.0) >= missed_m2 / 2:
        return None
    why = (
        "; its views were level, and a level camera cannot look down into an open top (a "
        "chimney, a tank, a courtyard): --planner surface_gimbal pitches the camera "
        "(docs/USAGE.md)"
    )
    return (
        f"the coverage tours found nothing more worth flying to, yet {1 - cov:.1%} of the "
        f"observable area was missed{why if level else ''}"
    )


def print_summary(s: dict, out, level: bool = False) -> None:
    """The console's account of a run: its flight, coverage (and of the observable surface,
    when the end-of-run outputs were written; missed_note, `level`: the views were level) and
    time."""
    cov = s["coverage"]
    print(
        f"scenario {s['scenario']} start {s['start']}: {s['iterations']} iterations, "
        f"{s['distance_m']:.1f} m, entropy reduction "
        f"{s['entropy_reduction']:,.0f} {s['entropy_unit']}, "
        f"termination: {s['termination']}"
    )
    print("planner: " + parts_words(s))
    if s.get("symmetry"):
        print(symmetry.summary_line(s["symmetry"]))
    note = budget_note(s)
    if note:
        print("note: " + note)
    if s.get("utility_only_checks"):
        print("note: " + checks_only_words(s["utility_only_checks"], s["utility"]))
    if (
        s.get("refused_views") and s["iterations"]
    ):  # (none flown: the mission warned, nothing_flown)
        print(
            "note: refusals of candidates in the last planning step: "
            + refusal_words(s["refused_views"])
        )
    print("coverage  " + "  ".join(f"@{k} m {v:6.1%}" for k, v in cov.items()))
    print("area cov. " + "  ".join(f"@{k} m {v:6.1%}" for k, v in s["area_coverage"].items()))
    if "coverage_observable" in s:
        print(f"of the observable surface ({s['observable_area_fraction']:.1%} of the area):")
        for name, key in (
            ("coverage", "coverage_observable"),
            ("area cov.", "area_coverage_observable"),
        ):
            print(f"  {name:<9} " + "  ".join(f"@{k} m {v:6.1%}" for k, v in s[key].items()))
        for note in (missed_note(s, level), unobservable_note(s)):
            if note:
                print("note: " + note)
    fin = (s.get("finish_s") or {}).get("total")  # end-of-run outputs: not in the wall time
    after = f" + {fin:.1f} s end-of-run outputs ({FINISH_OFF})" if (fin or 0) >= 0.05 else ""
    print(
        f"wall time {s['wall_time_s']:.1f} s{after}, {s['ms_per_iteration']:.1f} ms/iteration "
        f"-> {out}/"
    )
