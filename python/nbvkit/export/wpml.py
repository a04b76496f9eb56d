"""The DJI WPML route writer (a .kmz of wpmz/template.kml and wpmz/waylines.wpml), from the facts
in docs/EXPORT.md; the other formats' writers are nbvkit.export.writers."""
from __future__ import annotations

import zipfile
from xml.etree import ElementTree as ET

import math

from ..flight_time import signed_deg
from .writers import (
    KML_NS,
    MAX_SPEED_M_S,
    WPML_NS,
    GeoWaypoints,
    _f,
    signed_angle_text,
    waits,
)

#: the return-to-home height's margin above the highest of the structure's workspace and the
#: flight (m)
RTH_MARGIN_M = 10.0
#: globalRTHHeight's range (m above the take-off point): WPML gives it none of its own; DJI's
#: aircraft take a return-to-home altitude of 20 to 500 m (the M30's rth_altitude property,
#: {min: 20, max: 500}, DJI Cloud API; DJI Pilot 2's setting), and may refuse or change another
RTH_MIN_M, RTH_MAX_M = 20.0, 500.0

__all__ = ["write_wpml_kmz", "LENS"]

#: takePhoto's payloadLensIndex: the visible wide camera (the M30's main camera; nbvkit
#: simulates one visible camera)
LENS = "wide"


def _el(parent, tag, text=None, ns=WPML_NS):
    e = ET.SubElement(parent, f"{{{ns}}}{tag}")
    if text is not None:
        e.text = str(text)
    return e


def rth_rel_alt(g: GeoWaypoints) -> float:
    """The return-to-home height, m above the take-off point (the launch point: the aircraft
    climbs to it before it flies home in a straight line, on a lost link or at the end): above
    the higher of the run's workspace top (g.workspace_top_rel_alt) and the highest waypoint by
    RTH_MARGIN_M, at least RTH_MIN_M; ValueError where that is above RTH_MAX_M (a return below
    the flight's top could cross the structure)."""
    top = float(max(g.rel_alt))
    if g.workspace_top_rel_alt is not None:
        top = max(float(g.workspace_top_rel_alt), top)
    if top + RTH_MARGIN_M > RTH_MAX_M:
        raise ValueError(
            f"the flight or its workspace reaches {top:.1f} m above the take-off point: a DJI "
            f"return-to-home height {RTH_MARGIN_M:g} m above it would pass DJI's {RTH_MAX_M:g} m"
        )
    return max(top + RTH_MARGIN_M, RTH_MIN_M)


def _camera_heading(g: GeoWaypoints, k: int) -> float:
    """The bearing (deg) the aircraft faces at waypoint k so that its camera, which faces forward
    on a DJI aircraft (the gimbal's yaw left at 0), looks where the run's camera looked: the
    vehicle's heading plus the camera's yaw on its mount (camera.mount_rpy_deg)."""
    return (float(g.heading[k]) + float(g.gimbal_yaw[k])) % 360.0


def _course(g: GeoWaypoints, k: int) -> float:
    """The bearing (deg) of the leg into waypoint k: the heading a followWayline leg arrives
    with."""
    import pymap3d

    e, n, _ = pymap3d.geodetic2enu(g.lat[k], g.lon[k], 0.0, g.lat[k - 1], g.lon[k - 1], 0.0)
    return math.degrees(math.atan2(e, n)) % 360.0


def _mission_config(doc, g: GeoWaypoints, drone, payload, template: bool):
    mc = _el(doc, "missionConfig")
    _el(mc, "flyToWaylineMode", "safely")
    # the last waypoint is straight above the launch point: land there (goHome would first
    # climb to the return height, out of the time model)
    _el(mc, "finishAction", "autoLand")
    _el(mc, "exitOnRCLost", "executeLostAction")
    _el(mc, "executeRCLostAction", "goBack")
    takeoff_h = float(g.rel_alt[0])
    _el(mc, "takeOffSecurityHeight", _f(min(max(takeoff_h, 1.2), 1500.0), 3))
    if template:  # "the height of the ellipsoid shall be used"
        _el(mc, "takeOffRefPoint", f"{_f(g.home[0], 9)},{_f(g.home[1], 9)},{_f(g.home_ell, 3)}")
    _el(mc, "globalTransitionalSpeed", _f(min(g.speed, MAX_SPEED_M_S), 2))
    _el(mc, "globalRTHHeight", _f(rth_rel_alt(g), 3))
    di = _el(mc, "droneInfo")
    _el(di, "droneEnumValue", drone[0])
    _el(di, "droneSubEnumValue", drone[1])
    pi = _el(mc, "payloadInfo")
    _el(pi, "payloadEnumValue", payload)
    _el(pi, "payloadPositionIndex", 0)


def _placemark(folder, g: GeoWaypoints, k: int, index: int, template: bool, group: int, dji):
    """Waypoint k's Placemark (the point, its height, speed, heading and turn) and, at a capture,
    its action group (number `group`; dji: the sortie's waits, capture_waits' "dji"); the next
    action group's number."""
    pm = _placemark_point(folder, g, k, index, template)
    if g.action[k] not in ("view", "frame"):
        return group
    _capture_actions(pm, g, k, index, group, dji)
    return group + 1


def _placemark_point(folder, g: GeoWaypoints, k: int, index: int, template: bool):
    """The Placemark of waypoint k without actions: where, how high, how fast, its heading and
    its turn."""
    pm = ET.SubElement(folder, f"{{{KML_NS}}}Placemark")
    pt = ET.SubElement(pm, f"{{{KML_NS}}}Point")
    ET.SubElement(
        pt, f"{{{KML_NS}}}coordinates"
    ).text = f"{_f(float(g.lon[k]), 9)},{_f(float(g.lat[k]), 9)}"
    _el(pm, "index", index)
    if template:
        # both required with useGlobalHeight 0: the same point above the take-off point and
        # above the WGS84 ellipsoid
        _el(pm, "ellipsoidHeight", _f(float(g.ell_alt[k]), 3))
        _el(pm, "height", _f(float(g.rel_alt[k]), 3))
        _el(pm, "useGlobalHeight", 0)
        _el(pm, "useGlobalSpeed", 0)
        _el(pm, "useGlobalHeadingParam", 0)
        _el(pm, "useGlobalTurnParam", 0)
        _el(pm, "gimbalPitchAngle", _f(float(g.gimbal_pitch[k]), 3))
    else:
        _el(pm, "executeHeight", _f(float(g.rel_alt[k]), 3))
    _el(pm, "waypointSpeed", _f(g.speed, 2))
    hp = _el(pm, "waypointHeadingParam")
    if g.action[k] == "transit":
        _el(hp, "waypointHeadingMode", "followWayline")
    else:
        _el(hp, "waypointHeadingMode", "smoothTransition")
        _el(hp, "waypointHeadingAngle", signed_angle_text(_camera_heading(g, k), 3))
    _el(hp, "waypointHeadingPathMode", "followBadArc")
    tp = _el(pm, "waypointTurnParam")
    # no waypointTurnDampingDist: its range is (0, segment], and it is required only with
    # coordinateTurn or toPointAndPassWithContinuityCurvature and useStraightLine 1
    _el(tp, "waypointTurnMode", "toPointAndStopWithDiscontinuityCurvature")
    return pm


def _action(ag, aid: int, func: str):
    """Action number aid of the action group ag, running `func`: its actionActuatorFuncParam."""
    act = _el(ag, "action")
    _el(act, "actionId", aid)
    _el(act, "actionActuatorFunc", func)
    return _el(act, "actionActuatorFuncParam")


def _capture_actions(pm, g: GeoWaypoints, k: int, index: int, group: int, dji) -> None:
    """The action group of capture k, run on reaching it: every capture: the gimbal's pitch, the
    aircraft's heading (rotateYaw: the leg into a capture after a transit point is flown facing
    along the course, followWayline), then (a view) the settle, the photo, the rest of the hover
    (nbvkit.flight_time.capture_waits)."""
    ag = _el(pm, "actionGroup")
    _el(ag, "actionGroupId", group)
    _el(ag, "actionGroupStartIndex", index)
    _el(ag, "actionGroupEndIndex", index)
    _el(ag, "actionGroupMode", "sequence")
    _el(_el(ag, "actionTrigger"), "actionTriggerType", "reachPoint")
    hold, rest_s, _ = dji
    settle, rest = float(hold[k]), float(rest_s[k])
    p = _action(ag, 0, "gimbalRotate")
    _el(p, "gimbalHeadingYawBase", "north")
    _el(p, "gimbalRotateMode", "absoluteAngle")
    _el(p, "gimbalPitchRotateEnable", 1)
    _el(p, "gimbalPitchRotateAngle", _f(float(g.gimbal_pitch[k]), 3))
    _el(p, "gimbalRollRotateEnable", 0)
    _el(p, "gimbalRollRotateAngle", 0)
    _el(p, "gimbalYawRotateEnable", 0)
    _el(p, "gimbalYawRotateAngle", 0)
    _el(p, "gimbalRotateTimeEnable", 0)
    _el(p, "gimbalRotateTime", 0)
    _el(p, "payloadPositionIndex", 0)
    before = _camera_heading(g, k - 1) if g.action[k - 1] != "transit" else _course(g, k)
    turn = signed_deg(_camera_heading(g, k) - float(before))
    p = _action(ag, 1, "rotateYaw")
    _el(p, "aircraftHeading", signed_angle_text(_camera_heading(g, k), 3))
    _el(p, "aircraftPathMode", "clockwise" if turn >= 0 else "counterClockwise")
    aid = 2
    for step in ("settle", "photo", "rest"):
        hover = {"settle": settle, "rest": rest}.get(step)
        if hover is not None and not float(_f(hover, 3)) > 0:
            continue  # hoverTime must be > 0 as written (a rest of 0.0001 s reads 0.000)
        if step == "photo":
            p = _action(ag, aid, "takePhoto")
            _el(p, "fileSuffix", f"{g.action[k]}{int(g.number[k]):04d}")
            _el(p, "payloadPositionIndex", 0)
            _el(p, "useGlobalPayloadLensIndex", 0)
            _el(p, "payloadLensIndex", LENS)
        else:
            _el(_action(ag, aid, "hover"), "hoverTime", _f(hover, 3))
        aid += 1


def _wpml_doc(g: GeoWaypoints, drone, payload, template: bool, created_ms: int) -> bytes:
    ET.register_namespace("", KML_NS)
    ET.register_namespace("wpml", WPML_NS)
    kml = ET.Element(f"{{{KML_NS}}}kml")
    doc = ET.SubElement(kml, f"{{{KML_NS}}}Document")
    if template:
        _el(doc, "author", "nbvkit")
        _el(doc, "createTime", created_ms)
        _el(doc, "updateTime", created_ms)
    _mission_config(doc, g, drone, payload, template)
    folder = ET.SubElement(doc, f"{{{KML_NS}}}Folder")
    if template:
        _el(folder, "templateType", "waypoint")
    _el(folder, "templateId", 0)
    if template:
        cs = _el(folder, "waylineCoordinateSysParam")
        _el(cs, "coordinateMode", "WGS84")
        _el(cs, "heightMode", "relativeToStartPoint")
    else:
        _el(folder, "executeHeightMode", "relativeToStartPoint")
        _el(folder, "waylineId", 0)
    _el(folder, "autoFlightSpeed", _f(g.speed, 2))
    if template:
        _el(folder, "globalHeight", _f(float(g.rel_alt[0]), 3))
        _el(folder, "gimbalPitchMode", "usePointSetting")
        gh = _el(folder, "globalWaypointHeadingParam")
        _el(gh, "waypointHeadingMode", "followWayline")
        _el(gh, "waypointHeadingPathMode", "followBadArc")
        _el(folder, "globalWaypointTurnMode", "toPointAndStopWithDiscontinuityCurvature")
        _el(folder, "globalUseStraightLine", 0)
    group, dji = 0, waits(g)["dji"]  # once for the sortie
    for index, k in enumerate(range(len(g))):
        group = _placemark(folder, g, k, index, template, group, dji)
    if template:  # the camera's photos: the main gimbal's, its wide lens (as DJI Pilot 2 writes)
        pp = _el(folder, "payloadParam")
        _el(pp, "payloadPositionIndex", 0)
        _el(pp, "imageFormat", LENS)
    return ET.tostring(kml, encoding="UTF-8", xml_declaration=True)


def write_wpml_kmz(g: GeoWaypoints, path, drone=(67, 0), payload=52, created_ms: int = 0):
    """DJI WPML route: a zip (.kmz) of wpmz/template.kml and wpmz/waylines.wpml; heights relative
    to the take-off point. drone: (droneEnumValue, droneSubEnumValue), default M30; payload:
    payloadEnumValue (default 52, the M30's camera)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("wpmz/template.kml", _wpml_doc(g, drone, payload, True, created_ms))
        z.writestr("wpmz/waylines.wpml", _wpml_doc(g, drone, payload, False, created_ms))
