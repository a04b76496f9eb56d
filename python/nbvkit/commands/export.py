"""nbvkit export: a run's flight as missions a drone flies and camera poses (nbvkit.export)."""
from __future__ import annotations

import argparse
import sys

from .common import path_arg

#: The captures beyond the battery listed one by one on the console (export.json lists all).
SHOWN = 10
#: Each firmware's mission file, as the console names it, and the --format that writes it.
FIRMWARE_FILES = {
    "px4": (".plan (PX4)", "qgc"),
    "ardupilot": (".waypoints (ArduPilot)", "qgc"),
    "dji": (".kmz (DJI)", "wpml"),
}


def defaults() -> dict:
    """export_mission's defaults by parameter: the options' defaults, said once."""
    import inspect

    from ..export import export_mission

    return {k: v.default for k, v in inspect.signature(export_mission).parameters.items()}


def register(sub) -> argparse.ArgumentParser:
    from ..export import FORMATS

    d = defaults()
    p = sub.add_parser(
        "export",
        help="write a run's flight as QGroundControl/ArduPilot/DJI missions, KML, GeoJSON, CSV "
        "and COLMAP poses",
        description="Write what a run flew (RUN_DIR/flight.csv: the profile, the A* legs and the "
        "views) as files a ground station, a DJI aircraft or a photogrammetry tool reads. The "
        "mesh frame's origin is at --origin, +z up, +x along --heading (0: +x north, +y west; "
        "90: +x east, +y north, East-North-Up). With --flight-time "
        "the flight is split into sorties from and back to the launch point (below the start), "
        "one file per sortie per format, plus sorties.csv. Format facts and sources: "
        "docs/EXPORT.md.",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run folder of `nbvkit run`")
    p.add_argument(
        "--format",
        default=",".join(d["formats"]),
        metavar="FORMAT[,FORMAT...]",
        help=f"any of {', '.join(FORMATS)} (default {','.join(d['formats'])}; qgc: a .plan for "
        "PX4 and a QGC WPL 110 "
        ".waypoints for ArduPilot 4.4 or later, which runs IMAGE_START_CAPTURE in missions; "
        "wpml: a DJI .kmz route)",
    )
    p.add_argument(
        "--origin",
        nargs=3,
        type=float,
        required=True,
        metavar=("LAT", "LON", "ALT"),
        help="WGS84 latitude and longitude (degrees; |LAT| <= 89.9) and altitude (m, within "
        "[-500, 10000]) of the mesh frame's origin",
    )
    p.add_argument(
        "--altitude-ref",
        choices=("amsl", "ellipsoid"),
        default=d["altitude_ref"],
        help="what ALT is measured from: mean sea level or the WGS84 ellipsoid (default "
        f"{d['altitude_ref']})",
    )
    p.add_argument(
        "--heading",
        type=float,
        default=d["heading_deg"],
        metavar="DEG",
        help="bearing of the mesh's +x axis, degrees clockwise from true north, within "
        f"[-360, 360] (default {d['heading_deg']:g}; 0: +x north, +y west; 90 for a mesh in "
        "East-North-Up, +x east)",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=d["speed"],
        metavar="M_S",
        help=f"cruise speed (default {d['speed']:g}, at most 15: DJI WPML's limit, see "
        "docs/EXPORT.md)",
    )
    p.add_argument(
        "--climb-rate",
        type=float,
        default=d["climb_rate"],
        metavar="M_S",
        help=f"climb rate (default {d['climb_rate']:g}, at most 10); descents at most 1.5",
    )
    p.add_argument(
        "--hover",
        type=float,
        default=d["hover_s"],
        metavar="S",
        help="hover per view: a settle of 1 s (always, even with --hover 0), the photo, the "
        f"rest (default {d['hover_s']:g} s)",
    )
    _add_split_options(p, d)
    _add_photo_options(p, d)
    p.add_argument(
        "--out", metavar="DIR", type=path_arg, default=None, help="output folder (RUN_DIR/export)"
    )
    return p


def _add_photo_options(p, d: dict) -> None:
    """The options that name the flight's photos (the COLMAP images)."""
    p.add_argument(
        "--photo-names",
        default=None,
        metavar="PATTERN",
        help="name the COLMAP images as the aircraft's camera names its photos, numbered in "
        "flight order: a pattern with one field, e.g. 'DJI_{:04d}.JPG' (default "
        "view_0001.png ..., frame_0001.png ...)",
    )
    p.add_argument(
        "--photo-first",
        type=int,
        default=d["photo_first"],
        metavar="N",
        help="the number of the flight's first photo in --photo-names (default "
        f"{d['photo_first']})",
    )


def _add_split_options(p, d: dict) -> None:
    """The options that split the flight into sorties: a battery, a mission size."""
    p.add_argument(
        "--flight-time",
        type=float,
        default=None,
        metavar="MIN",
        help="one battery's flight time: split the flight into sorties within it",
    )
    p.add_argument(
        "--reserve",
        type=float,
        default=None,
        metavar="PCT",
        help="battery reserve kept unused, percent of --flight-time (default "
        f"{d['reserve_pct']:g})",
    )
    p.add_argument(
        "--max-items",
        type=int,
        default=None,
        metavar="N",
        help="split the flight into sorties whose MAVLink files hold at most N mission items "
        "(PX4 keeps 2000, ArduPilot on a Pixhawk 1 718)",
    )


def run(args) -> int:
    from ..export import export_mission

    if args.reserve is not None and args.flight_time is None:
        raise ValueError("--reserve is a share of --flight-time's battery: give --flight-time too")
    s = export_mission(
        args.run_dir,
        formats=args.format,
        origin=tuple(args.origin),
        heading_deg=args.heading,
        out_dir=args.out,
        speed=args.speed,
        climb_rate=args.climb_rate,
        hover_s=args.hover,
        flight_time_min=args.flight_time,
        reserve_pct=defaults()["reserve_pct"] if args.reserve is None else args.reserve,
        max_items=args.max_items,
        altitude_ref=args.altitude_ref,
        photo_names=args.photo_names,
        photo_first=args.photo_first,
    )
    m = s["mission"]
    print(
        f"mission: {m['views']} views and {m['frames']} frames in flight (photos), "
        f"{m['distance_m']:.0f} m, {m['time_min']:.1f} min "
        f"(speed {args.speed:g} m/s, climb {args.climb_rate:g} m/s, hover {args.hover:g} s)"
    )
    by = [
        f"{FIRMWARE_FILES[k][0]} {v / 60:.1f} min"
        for k, v in (m.get("time_s_by_file") or {}).items()
        if FIRMWARE_FILES[k][1] in s["formats"]
    ]
    if by:  # the files wait differently: the longest is the mission's (and a sortie's) time
        print("  time by file: " + ", ".join(by))
    if s["budget"] is not None:
        print(f"{'sortie':>6} {'views':>6} {'frames':>6} {'distance_m':>11} {'time_min':>9}")
        for r in s["sorties"]:
            print(
                f"{r['sortie']:>6} {r['views']:>6} {r['frames']:>6} {r['distance_m']:>11.1f} "
                f"{r['time_min']:>9.2f}"
            )
        for u in s["unreachable"][:SHOWN]:
            what = u["capture"] or f"{u['stage']} point"
            print(
                f"not flown: {what} at flight row {u['row']} needs "
                + (
                    f"{u['needed_s'] / 60:.2f} min out, along and back, more than one battery"
                    if u["reason"] == "flight time"
                    else f"more than --max-items {s['budget']['max_items']} mission items"
                )
            )
        if len(s["unreachable"]) > SHOWN:
            print(f"not flown: {len(s['unreachable']) - SHOWN:,} more (export.json: unreachable)")
    for w in s["warnings"]:
        print(f"nbvkit export: warning: {w}", file=sys.stderr)
    print(f"{len(s['files'])} files -> {s['out']}/")
    return 0
