"""Writers of the export formats, from the facts in docs/EXPORT.md (each with its source).

Every writer takes the geo-located waypoints of one sortie (GeoWaypoints) and writes one file;
COLMAP poses are nbvkit.export.colmap. Numbers are written in full (JSON) or to
1e-9 degree (about 0.1 mm) and 1 mm. The DJI WPML route's writer is nbvkit.export.wpml.
"""
from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from xml.etree import ElementTree as ET

import numpy as np

from ..flight_time import SETTLE_S, YAW_RATE_DEG_S, capture_waits, signed_deg  # noqa: F401
from ..flight_time import capture_radii as flight_capture_radii

# MAVLink common message set (mavlink/mavlink message_definitions/v1.0/common.xml)
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_NAV_DELAY = 93
MAV_CMD_CONDITION_YAW = 115
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW = 1000
MAV_CMD_IMAGE_START_CAPTURE = 2000
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
GIMBAL_MANAGER_FLAGS_PITCH_LOCK = 8  # pitch relative to the horizon
MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4 = 3, 12
MAV_TYPE_QUADROTOR = 2
QGC_ALTITUDE_MODE_RELATIVE = 1  # QGroundControl's AltMode: AltitudeModeRelative

SPEED_TYPE_GROUND = 1  # DO_CHANGE_SPEED param 1
#: the highest cruise speed the export writes (m/s): DJI WPML's globalTransitionalSpeed range is
#: [0, 15] and its route speeds may not pass the aircraft's maximum; PX4's default
#: MPC_XY_VEL_MAX is 12 m/s, ArduPilot's WPNAV_SPEED at most 20 m/s. See docs/EXPORT.md.
MAX_SPEED_M_S = 15.0
# the turn rate of CONDITION_YAW and the settle before a view's photo: nbvkit.flight_time, whose
# capture_waits gives the time model and these writers the same holds
KML_NS = "http://www.opengis.net/kml/2.2"
WPML_NS = "http://www.dji.com/wpmz/1.0.2"


@dataclass
class GeoWaypoints:
    """A sortie's waypoints with everything a format needs: lat, lon (deg), alt (m, in the
    origin's reference), rel_alt (m above the launch point), heading (deg clockwise from north,
    [0, 360)), gimbal_pitch (deg, positive up), gimbal_yaw (deg, relative to the vehicle's nose,
    positive right), action, stage, row (flight row or -1) - each (N,); the writers write the
    angles as they are (nbvkit.export's _geo rounds their numerical noise off: clean_angle);
    home: (lat, lon, alt) of the launch point; number: the 1-based number of each view/frame
    among its kind in the whole flight (0 else); seq: the 1-based number of each capture among
    all captures of the whole flight, views and frames together, in flight order (0 else);
    ell_alt (N,) and home_ell: heights above the WGS84 ellipsoid (filled for the DJI route
    only); waits: the sortie's nbvkit.flight_time.capture_waits (None: computed from the
    headings); workspace_top_rel_alt: the top of the run's workspace (the structure and the air
    round it), m above the launch point, which the DJI route's return-to-home height clears
    (nbvkit.export.wpml.rth_rel_alt; None: no top known, the highest waypoint instead); gap_m
    (N,): m from the previous waypoint (the first's: 0; None: unknown)."""

    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    rel_alt: np.ndarray
    heading: np.ndarray
    gimbal_pitch: np.ndarray
    gimbal_yaw: np.ndarray
    action: list
    stage: list
    row: list
    number: list
    home: tuple
    speed: float
    hover_s: float
    altitude_ref: str
    name: str
    seq: list = None
    ell_alt: np.ndarray = None
    home_ell: float = None
    waits: dict = None
    workspace_top_rel_alt: float = None
    gap_m: np.ndarray = None

    def __len__(self):
        return len(self.lat)

    def photos(self) -> list:
        """seq, or where not given the captures of these waypoints numbered together."""
        return self.seq or list(np.cumsum([a in ("view", "frame") for a in self.action]))


def _f(x: float, nd: int) -> str:
    """x to `nd` decimals, never a negative zero ("-0.000" for -1e-7 is written "0.000")."""
    s = f"{x:.{nd}f}"
    return s[1:] if s[0] == "-" and not s.strip("-0.") else s


def bearing_text(deg: float, nd: int) -> str:
    """A bearing (degrees) written to `nd` decimals within [0, 360): rounded first, then wrapped,
    so 359.96 reads "0.0" at one decimal, not "360.0" (and 359.96 at two)."""
    v = round(float(deg) % 360.0, nd)
    return _f(v - 360.0 if v >= 360.0 else v, nd)


def signed_angle_text(deg: float, nd: int) -> str:
    """An angle (degrees) written to `nd` decimals within [-180, 180): rounded first, then
    wrapped, so 179.9996 reads "-180.000" at three decimals, not "180.000"."""
    v = round(signed_deg(float(deg)), nd)
    return _f(v - 360.0 if v >= 180.0 else v, nd)


# ---------------------------------------------------------------------- MAVLink missions
def waits(g: GeoWaypoints) -> dict:
    """The sortie's capture_waits (target -> (hold, rest, turn_s)): those the time model
    counted, or computed from the headings when g has none (without PX4's reach holds:
    px4_reach_s needs the model's climb rate)."""
    if g.waits is not None:
        return g.waits
    return capture_waits(list(g.action), [float(h) for h in g.heading], g.hover_s)


def capture_holds(g: GeoWaypoints, ardupilot: bool) -> tuple[np.ndarray, np.ndarray]:
    """(hold, rest) seconds (N,) of each waypoint in the ArduPilot file (ardupilot) or the .plan
    (PX4): hold from the arrival to the photo (NAV_WAYPOINT p1), rest after it (a NAV_DELAY);
    nbvkit.flight_time.capture_waits."""
    hold, rest, _ = waits(g)["ardupilot" if ardupilot else "px4"]
    return hold, rest


def capture_radii(g: GeoWaypoints) -> np.ndarray:
    """(N,) the .plan's p2 (m) of each waypoint: nbvkit.flight_time.capture_radii of g.gap_m."""
    return flight_capture_radii(g.action, g.gap_m)


def mavlink_items(g: GeoWaypoints, ardupilot: bool = False) -> list[dict]:
    """The mission as MAVLink items (command, frame, params p1..p7 with None for NaN): take-off,
    the cruise speed (DO_CHANGE_SPEED, again after the first waypoint's items: ArduCopter
    before 4.5 drops the first, issue #21080), a waypoint per point and return to launch. Each
    capture (view or in-flight frame): its gimbal pitch (DO_GIMBAL_MANAGER_PITCHYAW) before its
    waypoint, so that the gimbal turns on the way there; the waypoint, with the capture's heading
    as its yaw and its hold (capture_holds); then the photo (IMAGE_START_CAPTURE, the capture's
    mission-wide sequence number) and, at a view, a NAV_DELAY for the rest of the hover. A
    mission runs the commands that follow a waypoint when it is reached and its hold is over,
    so the photo is taken after the settle, at the point. ardupilot (the .waypoints file): also a
    MAV_CMD_CONDITION_YAW before every waypoint whose heading the flight plans (all but transit
    legs): ArduPilot's copter ignores NAV_WAYPOINT's yaw and resets the yaw at the start of each
    waypoint, and runs the commands between two waypoints from the start of the leg to the
    second (docs/EXPORT.md); the gimbal's rates 0, not NaN (AP_Mission refuses NaN there)."""
    hold, rest = capture_holds(g, ardupilot)
    radius = np.zeros(len(g)) if ardupilot else capture_radii(g)  # ArduPilot: its target's
    seq = g.photos()
    speed_after_first_wp = True  # ArduCopter < 4.5 drops the one after the take-off (#21080)
    items = []
    for k in range(len(g)):
        if g.action[k] == "takeoff":
            items += [_takeoff_item(g, k), _change_speed_item(g)]
            continue
        items += _waypoint_items(g, k, (hold, rest, radius), seq, ardupilot)
        if speed_after_first_wp:
            # again after the first waypoint's items: runs when it is done, after the next
            # waypoint's start, which keeps it (ArduPilot issue #21080)
            items.append(_change_speed_item(g))
            speed_after_first_wp = False
    items.append((MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_FRAME_MISSION, [0, 0, 0, 0, 0, 0, 0]))
    return [{"command": c, "frame": f, "params": p} for c, f, p in items]


def _yaw(g: GeoWaypoints, k: int):
    """Waypoint k's heading as a MAVLink yaw (deg), None on a transit leg (not commanded)."""
    return None if g.action[k] == "transit" else float(g.heading[k])


def _takeoff_item(g: GeoWaypoints, k: int) -> tuple:
    lat, lon, rel = float(g.lat[k]), float(g.lon[k]), float(g.rel_alt[k])
    return (
        MAV_CMD_NAV_TAKEOFF,
        MAV_FRAME_GLOBAL_RELATIVE_ALT,
        [0, 0, 0, _yaw(g, k), lat, lon, rel],
    )


def _change_speed_item(g: GeoWaypoints) -> tuple:
    """DO_CHANGE_SPEED to the cruise speed (ground speed)."""
    params = [SPEED_TYPE_GROUND, float(g.speed), -1, 0, 0, 0, 0]
    return (MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, params)


def _gimbal_item(g: GeoWaypoints, k: int, ardupilot: bool) -> tuple:
    """DO_GIMBAL_MANAGER_PITCHYAW to capture k's gimbal pitch and yaw."""
    # gimbal rates: NaN ("unset" in common.xml) for PX4; ArduPilot's AP_Mission rejects NaN
    # there on upload (sanity_check_params) and reads no rate when both angles are set
    rate = 0.0 if ardupilot else None
    pitch, yaw = float(g.gimbal_pitch[k]), float(g.gimbal_yaw[k])
    params = [pitch, yaw, rate, rate, GIMBAL_MANAGER_FLAGS_PITCH_LOCK, 0, 0]
    return (MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, MAV_FRAME_MISSION, params)


def _waypoint_items(g: GeoWaypoints, k: int, waits, seq, ardupilot: bool) -> list:
    """Waypoint k's items (not the take-off's), in mavlink_items' order: at a capture the gimbal;
    in the ArduPilot file CONDITION_YAW to a planned heading; the waypoint (waits: hold, rest,
    radius); at a capture the photo (seq: its mission-wide number) and the rest of the hover."""
    hold, rest, radius = waits
    lat, lon, rel = float(g.lat[k]), float(g.lon[k]), float(g.rel_alt[k])
    yaw = _yaw(g, k)
    capture = g.action[k] in ("view", "frame")
    items = [_gimbal_item(g, k, ardupilot)] if capture else []
    if ardupilot and yaw is not None:
        items.append(
            (MAV_CMD_CONDITION_YAW, MAV_FRAME_MISSION, [yaw, YAW_RATE_DEG_S, 0, 0, 0, 0, 0])
        )
    items.append(
        (
            MAV_CMD_NAV_WAYPOINT,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            [float(hold[k]), float(radius[k]), 0, yaw, lat, lon, rel],
        )
    )
    if capture:
        # one image: interval 0, total images 1, sequence number unique in the mission
        items.append(
            (MAV_CMD_IMAGE_START_CAPTURE, MAV_FRAME_MISSION, [0, 0, 1, int(seq[k]), 0, 0, None])
        )
        if rest[k] > 0:
            items.append(
                (MAV_CMD_NAV_DELAY, MAV_FRAME_MISSION, [float(rest[k]), -1, -1, -1, 0, 0, 0])
            )
    return items


def _home_amsl(g: GeoWaypoints) -> tuple:
    """The launch point (lat, lon, altitude above mean sea level): MAV_FRAME_GLOBAL and the
    .plan's plannedHomePosition are AMSL, whatever the origin's reference: home's own altitude
    with an AMSL origin; with an ellipsoidal one its height less the EGM96 geoid height there
    (ValueError when the geoid is not at hand)."""
    lat, lon, alt = g.home
    return (lat, lon, float(alt) - _geoid_at_home(g, "the .plan and .waypoints home is"))


def _geoid_at_home(g: GeoWaypoints, what: str) -> float:
    """What to take from g's altitudes for heights above mean sea level: 0 with an AMSL origin,
    the EGM96 geoid height at the launch point with an ellipsoidal one (one constant: the
    altitudes' differences kept). ValueError naming `what` needs it when the geoid is not at
    hand."""
    if g.altitude_ref != "ellipsoid":
        return 0.0
    from .georef import egm96_geoid_height

    try:
        return float(egm96_geoid_height([g.home[0]], [g.home[1]])[0])
    except ValueError as e:
        raise ValueError(
            f"{what} above mean sea level; from an ellipsoidal origin that needs the EGM96 "
            f"geoid ({e})"
        ) from None


def write_qgc_plan(g: GeoWaypoints, path, firmware: int = MAV_AUTOPILOT_PX4) -> None:
    """QGroundControl .plan (JSON) for PX4 (firmwareType 12; ArduPilot: the .waypoints file):
    mission items as SimpleItems, relative altitudes, the home AMSL."""
    items = []
    for i, it in enumerate(mavlink_items(g), start=1):
        item = {
            "autoContinue": True,
            "command": it["command"],
            "doJumpId": i,
            "frame": it["frame"],
            "params": [None if v is None else float(v) for v in it["params"]],
            "type": "SimpleItem",
        }
        if it["frame"] == MAV_FRAME_GLOBAL_RELATIVE_ALT:
            item.update(
                AMSLAltAboveTerrain=None,
                Altitude=item["params"][6],
                AltitudeMode=QGC_ALTITUDE_MODE_RELATIVE,
            )
        items.append(item)
    plan = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "mission": {
            "version": 2,
            "firmwareType": firmware,
            "vehicleType": MAV_TYPE_QUADROTOR,
            "cruiseSpeed": g.speed,
            "hoverSpeed": g.speed,
            "globalPlanAltitudeMode": QGC_ALTITUDE_MODE_RELATIVE,
            "plannedHomePosition": [float(x) for x in _home_amsl(g)],
            "items": items,
        },
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
    }
    with open(path, "w") as f:
        json.dump(plan, f, indent=2, allow_nan=False)
        f.write("\n")


def write_qgc_wpl(g: GeoWaypoints, path) -> None:
    """The plain-text `QGC WPL 110` mission for ArduPilot (Mission Planner; IMAGE_START_CAPTURE
    needs ArduPilot 4.4 or later): line 0 the home (altitude above mean sea level), then the
    items, tab-separated; NaN parameters written as 0."""
    lines = ["QGC WPL 110"]
    home = [0, 1, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *_home_amsl(g), 1]
    rows = [home]
    for i, it in enumerate(mavlink_items(g, ardupilot=True), start=1):
        p = [0.0 if v is None else float(v) for v in it["params"]]
        rows.append([i, 0, it["frame"], it["command"], *p, 1])
    for r in rows:
        idx, cur, frame, cmd = r[:4]
        p = r[4:11]
        out = [str(idx), str(cur), str(frame), str(cmd)]
        out += [_f(v, 6) for v in p[:4]]
        # headings within [0, 360) as written: CONDITION_YAW's angle (p1), a waypoint's yaw (p4)
        if cmd == MAV_CMD_CONDITION_YAW:
            out[4] = bearing_text(p[0], 6)
        elif cmd in (MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_TAKEOFF) and idx > 0:
            out[7] = bearing_text(p[3], 6)
        out += [_f(p[4], 9), _f(p[5], 9), _f(p[6], 3), str(r[11])]
        lines.append("\t".join(out))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


# ---------------------------------------------------------------------- KML, GeoJSON, CSV
def write_kml(g: GeoWaypoints, path) -> None:
    """KML 2.2: the flight line (LineString) and a Point per view/frame, altitudeMode absolute:
    above mean sea level (from an ellipsoidal origin: less the EGM96 geoid height at the launch
    point)."""
    ET.register_namespace("", KML_NS)
    k = lambda tag: f"{{{KML_NS}}}{tag}"  # noqa: E731
    n = _geoid_at_home(g, "KML's absolute altitudes are")
    alt = np.asarray(g.alt, float) - n
    kml = ET.Element(k("kml"))
    doc = ET.SubElement(kml, k("Document"))
    ET.SubElement(doc, k("name")).text = g.name
    ET.SubElement(doc, k("description")).text = "nbvkit flight; altitudes above mean sea level" + (
        f" (the ellipsoidal heights less the EGM96 geoid height {n:.3f} m at the launch point)"
        if g.altitude_ref == "ellipsoid"
        else ""
    )
    line = ET.SubElement(doc, k("Placemark"))
    ET.SubElement(line, k("name")).text = "flight"
    ls = ET.SubElement(line, k("LineString"))
    ET.SubElement(ls, k("altitudeMode")).text = "absolute"
    ET.SubElement(ls, k("coordinates")).text = " ".join(
        f"{_f(float(g.lon[i]), 9)},{_f(float(g.lat[i]), 9)},{_f(float(alt[i]), 3)}"
        for i in range(len(g))
    )
    folder = ET.SubElement(doc, k("Folder"))
    ET.SubElement(folder, k("name")).text = "captures"
    for i in range(len(g)):
        if g.action[i] not in ("view", "frame"):
            continue
        pm = ET.SubElement(folder, k("Placemark"))
        ET.SubElement(pm, k("name")).text = f"{g.action[i]} {int(g.number[i])}"
        ET.SubElement(pm, k("description")).text = (
            f"heading {bearing_text(g.heading[i], 1)} deg, "
            f"gimbal pitch {_f(g.gimbal_pitch[i], 1)} deg, "
            + (f"gimbal yaw {_f(g.gimbal_yaw[i], 1)} deg, " if g.gimbal_yaw[i] else "")
            + f"{_f(g.rel_alt[i], 2)} m above the launch point"
        )
        pt = ET.SubElement(pm, k("Point"))
        ET.SubElement(pt, k("altitudeMode")).text = "absolute"
        ET.SubElement(
            pt, k("coordinates")
        ).text = f"{_f(float(g.lon[i]), 9)},{_f(float(g.lat[i]), 9)},{_f(float(alt[i]), 3)}"
    ET.ElementTree(kml).write(path, encoding="UTF-8", xml_declaration=True)


def split_antimeridian(coords: list) -> list[list]:
    """A line's positions ([lon, lat, alt], ...) cut where a leg crosses the antimeridian (its
    longitudes more than 180 degrees apart: it goes the short way round), RFC 7946 section 3.1.9:
    each part ends (or starts) on +-180 degrees at the latitude and altitude interpolated along
    the leg. One part when the line does not cross."""
    parts = [[list(coords[0])]]
    for a, b in zip(coords, coords[1:]):
        d = b[0] - a[0]
        if abs(d) > 180.0:
            edge = 180.0 if d < 0 else -180.0  # eastwards over +180 or westwards over -180
            b_lon = b[0] + (360.0 if d < 0 else -360.0)  # b on a's side of the antimeridian
            t = (edge - a[0]) / (b_lon - a[0])
            lat = a[1] + t * (b[1] - a[1])
            alt = a[2] + t * (b[2] - a[2])
            if parts[-1][-1] != [edge, lat, alt]:
                parts[-1].append([edge, lat, alt])
            parts.append([[-edge, lat, alt]])
        if parts[-1][-1] != list(b):
            parts[-1].append(list(b))
    return [p for p in parts if len(p) >= 2] or [parts[0] * 2]


def write_geojson(g: GeoWaypoints, path) -> None:
    """GeoJSON (RFC 7946): the flight as a LineString (a MultiLineString cut at the antimeridian
    when it crosses it) and a Point per view/frame, positions [lon, lat, height] with the height
    above the WGS84 ellipsoid (RFC 7946 section 3.1.1: g.ell_alt, whatever the origin's
    reference); the altitude in the origin's reference and the height above the launch point are
    properties of each Point. ValueError when g has no ellipsoidal heights."""
    if g.ell_alt is None:
        raise ValueError(
            "GeoJSON positions are heights above the WGS84 ellipsoid (RFC 7946): the waypoints "
            "have none (GeoWaypoints.ell_alt)"
        )

    def pos(i):
        return [float(g.lon[i]), float(g.lat[i]), float(g.ell_alt[i])]

    parts = split_antimeridian([pos(i) for i in range(len(g))])
    line = (
        {"type": "LineString", "coordinates": parts[0]}
        if len(parts) == 1
        else {"type": "MultiLineString", "coordinates": parts}
    )
    height = "WGS84 ellipsoid"  # the third element of every position
    feats = [
        {
            "type": "Feature",
            "geometry": line,
            "properties": {"kind": "flight", "name": g.name, "height_reference": height},
        }
    ]
    for i in range(len(g)):
        if g.action[i] in ("view", "frame"):
            feats.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "Point", "coordinates": pos(i)},
                    "properties": {
                        "kind": g.action[i],
                        "number": int(g.number[i]),
                        "flight_row": int(g.row[i]),
                        "heading_deg": float(g.heading[i]),
                        "gimbal_pitch_deg": float(g.gimbal_pitch[i]),
                        "gimbal_yaw_deg": float(g.gimbal_yaw[i]),
                        "rel_alt_m": float(g.rel_alt[i]),
                        "height_reference": height,
                        "altitude_m": float(g.alt[i]),
                        "altitude_reference": g.altitude_ref,
                    },
                }
            )
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": feats}, f, indent=1, allow_nan=False)
        f.write("\n")


CSV_COLUMNS = (
    "seq",
    "action",
    "stage",
    "flight_row",
    "latitude_deg",
    "longitude_deg",
    "altitude_m",
    "rel_altitude_m",
    "heading_deg",
    "gimbal_pitch_deg",
    "gimbal_yaw_deg",
    "photo",
)


def write_csv(g: GeoWaypoints, path) -> None:
    """One row per waypoint: CSV_COLUMNS (altitude_m in the origin's reference; rel_altitude_m
    above the launch point; action takeoff / waypoint / view / frame / transit / home; photo:
    a capture's number among the flight's photos, IMAGE_START_CAPTURE's, empty elsewhere)."""
    seq = g.photos()
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    for i in range(len(g)):
        w.writerow(
            [
                i,
                g.action[i],
                g.stage[i],
                int(g.row[i]),
                _f(float(g.lat[i]), 9),
                _f(float(g.lon[i]), 9),
                _f(float(g.alt[i]), 3),
                _f(float(g.rel_alt[i]), 3),
                bearing_text(g.heading[i], 3),
                _f(float(g.gimbal_pitch[i]), 3),
                _f(float(g.gimbal_yaw[i]), 3),
                int(seq[i]) if g.action[i] in ("view", "frame") else "",
            ]
        )
    with open(path, "w", newline="") as f:
        f.write(buf.getvalue())
