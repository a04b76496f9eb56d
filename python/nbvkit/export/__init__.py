"""Fly the plan: a run's flight as files a ground station, a DJI aircraft or a photogrammetry tool
reads (``nbvkit export`` / ``nbvkit.export_mission``), split into one flight per battery on
request. The format facts and their sources are in docs/EXPORT.md.
"""
from __future__ import annotations

import json
import math
import numbers
import os
import secrets
import shutil
import time
from pathlib import Path

import numpy as np

from .georef import ALTITUDE_REFS, GeoFrame  # noqa: F401
from ..flight import estimate, sortie_planner
from ..flight_time import TARGETS, VIEW, FlightModel, timed_files
from ..run_report import update_flight_section
from ..limits import is_number
from ..locks import pid_alive
from ..output_paths import check_export_dir, check_output_dir
from ..runfolder import require_complete_run, stopped_note_of
from .plan import read_run
from . import cautions, colmap, items, plan, writers
from .wpml import write_wpml_kmz

GEO_NAMES = ("latitude", "longitude", "altitude")

__all__ = ["FORMATS", "export_mission", "estimate_flight", "GeoFrame", "FlightModel"]

#: format -> the files it writes per sortie (colmap: one model of the whole flight)
FORMATS = {
    "qgc": (".plan", ".waypoints"),
    "wpml": (".kmz",),
    "kml": (".kml",),
    "geojson": (".geojson",),
    "csv": (".csv",),
    "colmap": ("colmap/cameras.txt", "colmap/images.txt", "colmap/points3D.txt"),
}


def _formats(formats) -> list[str]:
    if isinstance(formats, str):
        formats = formats.split(",")
    if not isinstance(formats, (list, tuple)):
        raise ValueError(f"formats must be a list or 'qgc,kml,...', got {formats!r}")
    out = []
    for f in formats:
        f = str(f).strip().lower()
        if not f:
            continue
        if f not in FORMATS:
            raise ValueError(f"unknown export format {f!r} (known: {', '.join(FORMATS)})")
        if f not in out:
            out.append(f)
    if not out:
        raise ValueError(f"no export format given (known: {', '.join(FORMATS)})")
    return out


def _budget(flight_time_min, reserve_pct):
    """Usable seconds of one battery, or None without a budget."""
    if not (math.isfinite(reserve_pct) and 0 <= reserve_pct < 100):
        raise ValueError(f"reserve must be within [0, 100) %, got {reserve_pct}")
    if flight_time_min is None:
        return None
    if not (math.isfinite(flight_time_min) and flight_time_min > 0):
        raise ValueError(
            f"flight time must be a finite number of minutes > 0, got {flight_time_min}"
        )
    return 60.0 * flight_time_min * (1.0 - reserve_pct / 100.0)


def _number(name: str, value) -> float:
    """value as a float; ValueError naming the argument `name` unless it is a real number (a
    string or a bool is not)."""
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    return float(value)


def _enum(name: str, value) -> int:
    """A WPML enumeration value (droneEnumValue, payloadEnumValue...): a whole number >= 0."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f"{name} must be a whole number >= 0 (a WPML enum value), got {value!r}")
    return int(value)


def _checked(origin, heading_deg, speed, climb_rate, hover_s, altitude_ref, dji_drone, dji_payload):
    """export_mission's geo frame, flight model and DJI (drone, payload), each argument checked
    by name."""
    if not _pair_or_triple(origin, 3):
        raise ValueError(f"origin must be (latitude, longitude, altitude), got {origin!r}")
    latlonalt = [_number(f"origin's {n}", v) for n, v in zip(GEO_NAMES, origin)]
    frame = GeoFrame(*latlonalt, _number("heading_deg", heading_deg), altitude_ref)
    speed, climb_rate = _number("speed", speed), _number("climb_rate", climb_rate)
    _check_speed(speed, climb_rate)
    model = FlightModel(speed, climb_rate, _number("hover_s", hover_s))
    if not _pair_or_triple(dji_drone, 2):
        raise ValueError(
            f"dji_drone must be (droneEnumValue, droneSubEnumValue), got {dji_drone!r}"
        )
    drone = (_enum("dji_drone[0]", dji_drone[0]), _enum("dji_drone[1]", dji_drone[1]))
    return frame, model, (drone, _enum("dji_payload", dji_payload))


def _pair_or_triple(value, n: int) -> bool:  # a sequence of n items (a string is not)
    return not isinstance(value, (str, bytes)) and hasattr(value, "__len__") and len(value) == n


#: the fastest climb rate the export takes (m/s): above any inspection drone's ascent (DJI M30
#: and M350 6 m/s, Mavic 3 8 m/s; PX4's MPC_Z_V_AUTO_UP 3 m/s); no file commands it, so a
#: faster one only shortened the time estimate and the battery's sorties
MAX_CLIMB_M_S = 10.0


def _check_speed(v: float, climb: float) -> None:
    """ValueError for a cruise speed above writers.MAX_SPEED_M_S or a climb rate above
    MAX_CLIMB_M_S (the lower bounds are FlightModel's)."""
    if math.isfinite(v) and v > writers.MAX_SPEED_M_S:
        raise ValueError(
            f"speed {v:g} m/s is above the export's maximum of {writers.MAX_SPEED_M_S:g} m/s "
            "(DJI WPML's transitional speed range [0, 15] m/s; route speeds may not pass the "
            "aircraft's maximum: see docs/EXPORT.md)"
        )
    if math.isfinite(climb) and climb > MAX_CLIMB_M_S:
        raise ValueError(
            f"climb rate {climb:g} m/s is above the export's maximum of {MAX_CLIMB_M_S:g} m/s "
            "(faster than any inspection drone climbs: the flight times would be too short)"
        )


def _planner(run_dir, model: FlightModel, need_all_returns: bool, occ_map=None, files=TARGETS):
    """The flight of a run folder and its SortiePlanner (nbvkit.flight.sortie_planner)."""
    fl = read_run(run_dir)
    return fl, sortie_planner(fl, model, need_all_returns, occ_map, files)


def estimate_flight(run_dir, speed=5.0, climb_rate=2.0, hover_s=2.0, occ_map=None) -> dict:
    """The whole mission's estimated flight (one battery, no limit) of a run folder: time_s,
    distance_m, views, frames (see nbvkit.flight_time for the model). occ_map: the run's final
    OccupancyMap when at hand (default: read from its map.ot)."""
    return estimate(read_run(run_dir), FlightModel(speed, climb_rate, hover_s), occ_map)


def clean_angle(deg: float) -> float:
    """An angle rounded to 1e-9 degree, without a negative zero: numerical noise such as 2.8e-14
    is written as 0."""
    v = round(float(deg), 9)
    return 0.0 if v == 0 else v


def _geo(fl, sortie, frame: GeoFrame, speed, hover_s, captures, name):
    """The sortie's waypoints on the Earth, with headings and gimbal angles: bearings from the
    local north at each waypoint (exact near a pole, where the origin's north is far off),
    numerical noise rounded off (clean_angle: here only; the writers write them as they are).
    captures: colmap.capture_numbers (a waypoint's capture's number among its kind, and among
    all photos: IMAGE_START_CAPTURE's); 0 for waypoints not in it."""
    from .. import _core

    cfg = fl.config
    cam = _core.mount_transform(cfg.camera.mount_xyz, *cfg.camera.mount_rpy_deg)
    wps = sortie.waypoints
    xyz = np.array([w.xyz for w in wps], float)
    lat, lon, alt = frame.to_geodetic(xyz)
    lon = (lon + 180.0) % 360.0 - 180.0  # [-180, 180)
    heading, pitch, gyaw = [], [], []
    for k, w in enumerate(wps):
        T_body = _core.pose_to_transform([*w.xyz, w.yaw])
        T = T_body @ _core.mount_transform([0, 0, 0], 0.0, math.degrees(w.pitch), 0.0) @ cam
        h = frame.local_bearing(T_body[:3, 0], lat[k], lon[k])
        fwd = T[:3, 0]  # the camera's axis, mesh frame
        heading.append(clean_angle(h) % 360.0)  # h in [0, 360): 360 only when rounded
        # pitch above the mesh's horizontal plane (the structure's frame; the local horizon
        # departs from it by distance / Earth radius: 0.0009 degrees at 100 m)
        pitch.append(clean_angle(math.degrees(math.asin(max(-1.0, min(1.0, fwd[2]))))))
        # the camera axis's yaw from the nose, positive right, in the same plane (the local
        # horizon's bearings tilted a pitched axis: up to 1.6e-4 degrees where it is 0)
        ahead, left = float(T_body[:3, 0] @ fwd), float(T_body[:3, 1] @ fwd)
        gy = -math.degrees(math.atan2(left, ahead)) if math.hypot(ahead, left) > 1e-9 else 0.0
        gyaw.append(clean_angle(gy))
    hlat, hlon, halt = frame.to_geodetic(fl.home)
    return writers.GeoWaypoints(
        lat=lat,
        lon=lon,
        alt=alt,
        # the height above the launch point of the same point the absolute altitude places:
        # the difference of the geodetic heights (pymap3d's, which put a point of the local
        # tangent plane d^2 / 2R higher at a distance d: mesh z - home z would be 0.8 m lower at
        # 3 km, 8 m at 10 km)
        rel_alt=alt - float(halt[0]),
        heading=np.array(heading),
        gimbal_pitch=np.array(pitch),
        gimbal_yaw=np.array(gyaw),
        action=[w.action for w in wps],
        stage=[w.stage for w in wps],
        row=[w.row for w in wps],
        number=[captures[w.row][1] if w.row in captures else 0 for w in wps],
        home=(float(hlat[0]), float((hlon[0] + 180.0) % 360.0 - 180.0), float(halt[0])),
        speed=float(speed),
        hover_s=float(hover_s),
        altitude_ref=frame.altitude_ref,
        name=name,
        seq=[captures[w.row][2] if w.row in captures else 0 for w in wps],
        waits=sortie.waits or None,
        workspace_top_rel_alt=_workspace_top_rel_alt(fl),
        gap_m=np.r_[0.0, np.linalg.norm(np.diff(xyz.reshape(-1, 3), axis=0), axis=1)][: len(wps)],
    )


def _workspace_top_rel_alt(fl) -> float | None:
    """The top of the run's workspace (the structure and the air round it), m above the launch
    point, or None when the workspace has no top."""
    top = (fl.workspace or {}).get("bounds_max")
    return None if top is None else float(top[2]) - float(fl.home[2])


def export_mission(
    run_dir,
    formats=("qgc",),
    origin=None,
    heading_deg: float = 0.0,
    out_dir=None,
    speed: float = 5.0,
    climb_rate: float = 2.0,
    hover_s: float = 2.0,
    flight_time_min: float | None = None,
    reserve_pct: float = 20.0,
    altitude_ref: str = "amsl",
    dji_drone=(67, 0),
    dji_payload: int = 52,
    max_items: int | None = None,
    photo_names: str | None = None,
    photo_first: int = 1,
) -> dict:
    """Writes a run folder's flight in `formats` (FORMATS; a list or "qgc,kml,...") to `out_dir`
    (default RUN_DIR/export) and returns the export's summary (also out_dir/export.json).

    origin: (latitude, longitude, altitude) of the mesh frame's origin, degrees WGS84 and metres
    (altitude_ref "amsl" or "ellipsoid"); heading_deg: the bearing of the mesh's +x axis. speed
    (m/s), climb_rate (m/s), hover_s (s per view): the flight-time model. flight_time_min: one
    battery's flight time; with it the flight is split into sorties within flight_time_min *
    (1 - reserve_pct / 100) each, one file per sortie per format. dji_drone / dji_payload: the
    WPML droneEnumValue/droneSubEnumValue and payloadEnumValue (default: M30). max_items: the
    most mission items one MAVLink file may hold (nbvkit.export.items.MAX_MISSION_ITEMS: what
    autopilots keep); with it the flight is split into sorties whose files hold no more (within
    the battery too, with flight_time_min). photo_names: the COLMAP images' names, a pattern
    with one field for each photo's number in flight order, from photo_first ("DJI_{:04d}.JPG";
    default view_0001.png ..., frame_0001.png ...).

    Raises ValueError naming a bad value (latitude, longitude, non-finite numbers, an unknown
    format, a budget too small for any view), FileNotFoundError for a run folder without a
    flight. Files are written into a temporary folder beside out_dir and moved into place only
    when all are written: on an error nothing is left half-written.
    """
    fmts = _formats(formats)
    dji = (dji_drone, dji_payload)
    frame, model, dji = _checked(
        origin, heading_deg, speed, climb_rate, hover_s, altitude_ref, *dji
    )
    minutes = None if flight_time_min is None else _number("flight_time_min", flight_time_min)
    usable = _budget(minutes, _number("reserve_pct", reserve_pct))
    max_items = items.check_max_items(max_items)
    photos = colmap.check_photo_names(photo_names, photo_first)
    split = usable is not None or max_items is not None
    run = require_complete_run(Path(run_dir).expanduser())  # whole, not half-written
    if out_dir is not None and not os.fspath(out_dir).strip():
        raise ValueError("out_dir is empty: give a folder, or None for RUN_DIR/export")
    out = Path(out_dir).expanduser() if out_dir is not None else run / "export"
    check_output_dir(out, "output folder", whole_folder=True)  # before the work (a file, a mount)
    check_export_dir(out)  # not among a run's files (--overwrite then refused the run)

    fl, sp = _planner(run, model, split, files=timed_files(fmts))
    whole = sp.whole()
    sorties, unreachable, budget = [whole], [], None
    if split:
        fits = None if max_items is None else _fits_items(fl, frame, model, max_items)
        limits = (flight_time_min, reserve_pct, fits, max_items)
        sorties, unreachable = _split(fl, sp, usable, *limits)
        budget = {"flight_time_min": flight_time_min, "reserve_pct": reserve_pct}
        budget["usable_min"] = None if usable is None else round(usable / 60, 3)
        budget["max_items"] = max_items
    summary = _summary(run, frame, fl, model, whole, budget, sorties, unreachable, fmts)
    summary["photo_names"] = None if photos is None else list(photos)

    _write_into(out, summary, fl, sorties, frame, model, dji, split)
    paths = [np.array([fl.home, *[w.xyz for w in s.waypoints], fl.home]) for s in sorties]
    try:
        summary["report_updated"] = update_flight_section(run, summary, paths)
    except (OSError, ValueError) as e:  # the export is written; the run folder left as it was
        summary["report_updated"] = False
        summary["warnings"].append(f"{run}/report.html not updated with the flight: {e}")
    return summary


#: an export's temporary folder: TMP_PREFIX<pid>-<random>, beside its output folder
TMP_PREFIX = ".nbvkit-export-"


def _remove_stale_temporaries(parent: Path) -> None:
    """Removes the temporary folders in `parent` of exports whose process is gone (killed
    outright while writing: SIGKILL leaves no time to clean up), which a run's --overwrite
    then refused as files nbvkit did not write."""
    for d in parent.glob(f"{TMP_PREFIX}*-*"):
        pid = d.name[len(TMP_PREFIX) :].split("-", 1)[0]
        if d.is_dir() and pid.isdigit() and not pid_alive(int(pid)):  # (threads share one)
            shutil.rmtree(d, ignore_errors=True)


def _new_folder(parent: Path, prefix: str) -> Path:
    """A new empty folder in `parent` named `prefix` + a random suffix, made with the process's
    umask as any folder (tempfile.mkdtemp's is private, 0700, and moved into place as the
    export it stayed so)."""
    for _ in range(100):
        tmp = parent / f"{prefix}{secrets.token_hex(6)}"
        try:
            tmp.mkdir()
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary folder name {prefix}* in {parent}")


def _write_into(out: Path, summary: dict, fl, sorties, frame, model, dji, budget: bool) -> None:
    """Writes the export (every format, sorties.csv with a budget, export.json) into a temporary
    folder beside `out`, then moves it into place; on an error nothing is left half-written."""
    anchor = out.parent
    while not anchor.exists():
        anchor = anchor.parent
    _remove_stale_temporaries(anchor)
    tmp = _new_folder(anchor, f"{TMP_PREFIX}{os.getpid()}-")
    try:
        names = plan.sortie_names([s.number for s in sorties]) if budget else ["mission"]
        files = _write_formats(tmp, summary, fl, sorties, names, frame, model, *dji)
        if budget:
            _write_sortie_table(tmp / "sorties.csv", summary)
            files.append("sorties.csv")
        files.append("export.json")
        summary["files"] = files
        summary["mission_items"] = items.mission_items(tmp, files)
        summary["clearance"] = cautions.clearance(fl, sorties)
        summary["warnings"] = [w for w in [stopped_note_of(fl.run_dir)] if w]
        cell = float(fl.config.map.resolution)
        summary["warnings"] += cautions.clearance_warnings(summary["clearance"], cell)
        summary["warnings"] += cautions.left_out_warnings(summary["unreachable"])
        summary["warnings"] += items.item_warnings(summary["mission_items"])
        summary["out"] = str(out)
        (tmp / "export.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
        plan.move_into_place(tmp, out, files)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _fits_items(fl, frame, model, max_items: int):
    """fits(sortie) for SortiePlanner.split: its MAVLink files hold at most max_items items."""

    def fits(sortie) -> bool:
        g = _geo(fl, sortie, frame, model.speed, model.hover_s, {}, "fits")
        return items.sortie_items(g) <= max_items

    return fits


def _split(fl, sp, usable, flight_time_min, reserve_pct, fits=None, max_items=None):
    """(sorties, unreachable) of the flight within `usable` seconds (None: no limit) and fits
    each; ValueError when the budget is too short for any view."""
    sorties, unreachable = sp.split(math.inf if usable is None else usable, fits)
    n_views = int((np.asarray(fl.capture) == VIEW).sum())
    flown = sum(s.views for s in sorties)
    none = not sorties or (n_views and flown == 0)
    views_left = {u["reason"] for u in unreachable if u["capture"] == VIEW}
    if none and (usable is None or views_left == {"fits"}):
        raise ValueError(f"no view's sortie fits within {max_items} mission items a file")
    if none:
        need = min((u["needed_s"] for u in unreachable if u["capture"] == VIEW), default=None)
        raise ValueError(
            f"flight time {flight_time_min:g} min ({usable / 60:.3g} min usable after the "
            f"{reserve_pct:g}% reserve) is too short for any view"
            + (f": the nearest view needs {need / 60:.2f} min out, hover and back" if need else "")
        )
    return sorties, unreachable


def _summary(run, frame, fl, model, whole, budget, sorties, unreachable, fmts) -> dict:
    """The export's summary (export.json) before its files are listed."""
    return {
        "run": str(run),
        "origin": frame.to_dict(),
        "frames_note": (
            "mesh frame: origin at the origin, +z up, +x along heading_deg (degrees clockwise "
            "from true north; 0: +x north, +y west; 90: East-North-Up); altitudes in the "
            "origin's reference, relative altitudes above the launch point; the mesh frame is "
            "the mesh file's moved by mesh_shift (the run's mesh.shift)"
        ),
        "mesh_shift": [float(v) for v in fl.config.mesh.shift],
        "launch_point_mesh": [float(v) for v in fl.home],
        "climb_top_mesh": [float(v) for v in fl.launch],
        "model": {
            "speed_m_s": model.speed,
            "climb_rate_m_s": model.climb_rate,
            "hover_s": model.hover_s,
        },
        "mission": {
            "time_s": round(whole.time_s, 1),
            "time_min": round(whole.time_s / 60, 2),
            "distance_m": round(whole.distance_m, 3),
            "views": whole.views,
            "frames": whole.frames,
            "time_s_by_file": {k: round(v, 1) for k, v in whole.times.items()},
        },
        "budget": budget,
        "sorties": [s.to_dict() for s in sorties],
        "unreachable": unreachable,
        "formats": fmts,
        "files": [],
    }


def _write_formats(tmp: Path, summary, fl, sorties, names, frame, model, drone, payload) -> list:
    """Writes each sortie (named `names`) in each format of the export's summary into tmp;
    returns the files' names."""
    fmts, photo_names = summary["formats"], summary["photo_names"]
    # the captures the sorties fly (not those left unreachable by the budget), numbered
    captures = colmap.capture_numbers(fl.capture, {w.row for s in sorties for w in s.waypoints})
    created_ms = int(time.time() * 1000)
    files = []
    for s, name in zip(sorties, names):
        g = _geo(fl, s, frame, model.speed, model.hover_s, captures, name)
        if "qgc" in fmts:
            writers.write_qgc_plan(g, tmp / f"{name}.plan")
            writers.write_qgc_wpl(g, tmp / f"{name}.waypoints")
            files += [f"{name}.plan", f"{name}.waypoints"]
        ell_fmts = [f for f in ("wpml", "geojson") if f in fmts]
        if ell_fmts:  # heights above the WGS84 ellipsoid (DJI's ellipsoidHeight, RFC 7946)
            try:  # one geoid lookup: the waypoints' and the home's heights
                ell = frame.ellipsoid_height(np.append(g.alt, g.home[2]))
            except ValueError as e:
                raise ValueError(
                    f"the {' and '.join(ell_fmts)} "
                    + ("formats write" if len(ell_fmts) > 1 else "format writes")
                    + f" heights above the WGS84 ellipsoid: {e}"
                ) from None
            g.ell_alt, g.home_ell = ell[:-1], float(ell[-1])
        if "wpml" in fmts:
            write_wpml_kmz(g, tmp / f"{name}.kmz", drone, payload, created_ms)
            files.append(f"{name}.kmz")
        if "kml" in fmts:
            writers.write_kml(g, tmp / f"{name}.kml")
            files.append(f"{name}.kml")
        if "geojson" in fmts:
            writers.write_geojson(g, tmp / f"{name}.geojson")
            files.append(f"{name}.geojson")
        if "csv" in fmts:
            writers.write_csv(g, tmp / f"{name}.csv")
            files.append(f"{name}.csv")
    if "colmap" in fmts:
        (tmp / "colmap").mkdir()
        poses = colmap.camera_poses(fl, photo_names, set(captures))
        colmap.write_colmap(tmp / "colmap", colmap.camera_intrinsics(fl.config), poses)
        files += [f"colmap/{n}" for n in ("cameras.txt", "images.txt", "points3D.txt")]
    return files


def _write_sortie_table(path: Path, summary: dict) -> None:
    import csv

    cols = ["sortie", "views", "frames", "waypoints", "distance_m", "time_min", "time_s"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for s in summary["sorties"]:
            w.writerow([s[c] for c in cols])
