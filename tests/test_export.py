"""nbvkit export: each format read back by an independent reader, the geodesy's round trip, a
COLMAP pose against the simulated camera, the battery split, and bad input."""
from __future__ import annotations

import csv
import json
import math
import os
import zipfile
from types import SimpleNamespace

import numpy as np
import pytest

import nbvkit
from conftest import ROOT
from nbvkit import _core
from nbvkit.config import Config
from nbvkit.sensors import camera_kwargs
from nbvkit.export import GeoFrame, export_mission
from nbvkit.export.plan import read_run
from nbvkit.mission import Mission

ORIGIN = (47.3977, 8.5456, 488.0)
HEADING = 30.0
FAST = [
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=100",
    "max_iterations=8",
    "evaluation.coverage_every=0",
    "vehicle.blocked_path=plan",  # legs around the structure: A* waypoints between the views
]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A short real mission on the shipped airliner (profile + 8 views) written to a folder."""
    out = tmp_path_factory.mktemp("run")
    Mission(Config().with_overrides(FAST)).run(out)
    return out


@pytest.fixture(scope="module")
def exported(run_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "ex"
    s = export_mission(
        run_dir,
        formats="qgc,wpml,kml,geojson,colmap,csv",
        origin=ORIGIN,
        heading_deg=HEADING,
        out_dir=out,
    )
    return out, s


def _frame():
    return GeoFrame(*ORIGIN, HEADING)


def _read_flight(run_dir):
    with open(run_dir / "flight.csv", newline="") as f:
        return list(csv.DictReader(f))


def _csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ------------------------------------------------------------------ what was flown
def test_flight_csv_holds_every_point_flown_and_every_trajectory_row(run_dir):
    traj = _csv(run_dir / "trajectory.csv")
    assert list(traj[0].keys()) == ["stage", "x", "y", "z", "yaw", "pitch", "distance_m"]
    flight = _read_flight(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert sum(r["capture"] == "view" for r in flight) == summary["views"]
    # every trajectory row (a leg's end) is a flight row, in order, with the same distance
    cols = ("x", "y", "z", "distance_m", "pitch")
    fx = np.array([[float(r[k]) for k in cols] for r in flight])
    j = 0
    for r in traj:
        t = np.array([float(r[k]) for k in cols])
        while not np.allclose(fx[j], t, atol=1e-9):
            j += 1
        assert j < len(fx)
    # more points than leg ends (the A* waypoints), and the distance is the polyline's length
    assert len(flight) > len(traj)
    length = np.linalg.norm(np.diff(fx[:, :3], axis=0), axis=1).sum()
    assert length == pytest.approx(summary["distance_m"], rel=1e-9)
    np.testing.assert_allclose(
        np.diff(fx[:, 3]), np.linalg.norm(np.diff(fx[:, :3], axis=0), axis=1), atol=1e-9
    )
    assert np.all(fx[:, 4] == 0.0)  # the planners fly level views (gimbal pitch 0)


# ------------------------------------------------------------------ geodesy
def test_enu_geodetic_round_trip_within_a_millimetre_over_10_km():
    rng = np.random.default_rng(0)
    for lat, lon, alt, h in [
        (47.3977, 8.5456, 488.0, 30.0),
        (-33.9, 151.2, 5.0, 250.0),
        (89.5, -179.9, 0.0, 0.0),
    ]:
        f = GeoFrame(lat, lon, alt, h)
        p = rng.uniform([-10000, -10000, -100], [10000, 10000, 500], size=(500, 3))
        back = f.to_mesh(*f.to_geodetic(p))
        assert np.abs(back - p).max() < 1e-3


def test_heading_is_the_bearing_of_mesh_x():
    import pymap3d

    for h in (0.0, 90.0, 30.0):
        f = GeoFrame(*ORIGIN, h)
        lat, lon, alt = f.to_geodetic(np.array([[100.0, 0.0, 0.0]]))
        az, el, rng = pymap3d.geodetic2aer(lat[0], lon[0], alt[0], *ORIGIN)
        assert az == pytest.approx(h % 360, abs=1e-6)
        assert rng == pytest.approx(100.0, abs=1e-6)
        assert f.bearing([0.0, 1.0, 0.0]) == pytest.approx((h - 90) % 360)


# ------------------------------------------------------------------ formats read back
def _off_segment(p, a, b):
    t = np.clip((p - a) @ (b - a) / max((b - a) @ (b - a), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t * (b - a)))


def _to_mesh(lat, lon, alt):
    return _frame().to_mesh(lat, lon, alt)


def _azimuth_along(xyz, yaw, frame=None):
    """The compass bearing (pymap3d's azimuth at the point) of the direction `yaw` (rad, mesh
    frame) at the mesh point xyz: the bearing of a point 1 m along it."""
    import pymap3d

    f = frame or _frame()
    p = np.asarray(xyz, float)
    q = p + [math.cos(yaw), math.sin(yaw), 0.0]
    la, lo, al = f.to_geodetic(np.array([p, q]))
    az, _, _ = pymap3d.geodetic2aer(la[1], lo[1], al[1], la[0], lo[0], al[0])
    return float(az) % 360.0


def test_qgc_plan_read_back_flies_the_flight(exported, run_dir):
    out, s = exported
    plan = json.loads((out / "mission.plan").read_text())
    assert plan["fileType"] == "Plan" and plan["version"] == 1
    m = plan["mission"]
    assert m["version"] == 2 and m["firmwareType"] == 12 and m["vehicleType"] == 2
    assert m["cruiseSpeed"] == 5.0
    items = m["items"]
    assert all(it["type"] == "SimpleItem" for it in items)
    assert [it["doJumpId"] for it in items] == list(range(1, len(items) + 1))
    assert items[0]["command"] == 22 and items[-1]["command"] == 20
    fl = read_run(run_dir)
    home = np.array(m["plannedHomePosition"])
    np.testing.assert_allclose(_to_mesh(*home[:, None]).ravel(), s["launch_point_mesh"], atol=0.01)
    top = np.array(s["climb_top_mesh"])
    assert top[2] == pytest.approx(fl.start[2]) and s["launch_point_mesh"][:2] == list(top[:2])
    # per capture (view or in-flight frame): its gimbal pitch (1000, horizon-locked) before its
    # waypoint, the waypoint with the capture's heading, one image (2000) right after it; a
    # view's waypoint holds the settle (1 s of the 2 s hover), its rest (93) follows the image
    rows = _csv(out / "mission.csv")
    caps = [k for k, it in enumerate(items) if it["command"] == 2000]
    n_views = sum(c == "view" for c in fl.capture)
    n_frames = sum(c == "frame" for c in fl.capture)
    assert len(caps) == n_views + n_frames
    assert sum(it["command"] == 1000 for it in items) == len(caps)
    cap_rows = [r for r in rows if r["action"] in ("view", "frame")]
    assert [r["action"] for r in cap_rows] == [c for c in fl.capture if c]
    for k, r in zip(caps, cap_rows):
        wp, g, cap = items[k - 1], items[k - 2], items[k]
        assert wp["command"] == 16 and g["command"] == 1000
        assert abs((wp["params"][3] - float(r["heading_deg"]) + 180) % 360 - 180) < 1e-3
        assert g["frame"] == 2 and g["params"][4] == 8
        assert g["params"][0] == pytest.approx(float(r["gimbal_pitch_deg"]), abs=1e-3)
        assert cap["params"][2] == 1  # one image
        # (more where PX4 would count the capture reached 0.8 m short of it: the reach hold,
        # test_qgc_plan_photos_on_vertical_legs_wait_until_the_vehicle_is_there)
        if r["action"] == "view":
            assert wp["params"][0] >= 1.0
            assert items[k + 1]["command"] == 93 and items[k + 1]["params"][0] == 1.0
        else:
            assert wp["params"][0] >= 0.0 and items[k + 1]["command"] != 93
    holds = [items[k - 1]["params"][0] for k in caps]
    assert sum(h in (0.0, 1.0) for h in holds) > len(holds) / 2
    # sequence numbers: unique and increasing over the whole mission (views and frames)
    assert [items[k]["params"][3] for k in caps] == list(range(1, len(caps) + 1))
    assert items[1]["command"] == 178 and items[1]["params"][:2] == [1.0, 5.0]  # cruise speed
    # the navigation items, back in the mesh frame, are the CSV's waypoints (same order)
    nav = [it for it in items if it["frame"] == 3]
    lat = np.array([it["params"][4] for it in nav])
    lon = np.array([it["params"][5] for it in nav])
    rel = np.array([it["params"][6] for it in nav])
    assert all(it["Altitude"] == it["params"][6] and it["AltitudeMode"] == 1 for it in nav)
    xyz = _to_mesh(lat, lon, home[2] + rel)
    rows = _csv(out / "mission.csv")
    assert len(rows) == len(nav)
    flight = np.array(fl.xyz)
    on_flight = [k for k, r in enumerate(rows) if int(r["flight_row"]) >= 0]
    idx = [int(rows[k]["flight_row"]) for k in on_flight]
    assert idx == sorted(idx) and idx[-1] == len(flight) - 1
    assert np.abs(xyz[on_flight] - flight[idx]).max() < 0.01
    # every point flown lies on the exported path (straight runs of the profile's small steps
    # are one leg), and every capture is a waypoint of its own
    assert {i for i, c in enumerate(fl.capture) if c} <= set(idx)
    for (ka, ra), (kb, rb) in zip(zip(on_flight, idx), zip(on_flight[1:], idx[1:])):
        assert kb == ka + 1
        for i in range(ra + 1, rb):
            assert _off_segment(flight[i], xyz[ka], xyz[kb]) < 0.01
    # headings: the vehicle's yaw as a compass bearing from the local north at the waypoint
    for k in on_flight:
        i = int(rows[k]["flight_row"])
        want = _azimuth_along(fl.xyz[i], fl.yaw[i])
        got = nav[k]["params"][3]
        assert abs((got - want + 180) % 360 - 180) < 1e-4
    # starts and ends above the launch point
    assert np.abs(xyz[0] - top).max() < 0.01 and np.abs(xyz[-1] - top).max() < 0.01


def test_qgc_plan_captures_are_reached_at_their_points(exported):
    # PX4 counts a waypoint reached within its p2 (NAV_ACC_RAD, 2 m by default, where p2 is 0)
    # and then runs the photo after it: each capture's waypoint has its own radius of at most
    # 0.5 m, and two consecutive captures' radii never meet (read with json and pymap3d's ENU)
    import pymap3d

    out, _ = exported
    items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
    nav = [k for k, it in enumerate(items) if it["command"] == 16]
    capture = [k + 1 < len(items) and items[k + 1]["command"] == 2000 for k in nav]
    radius = np.array([items[k]["params"][1] for k in nav])
    assert sum(capture) > 20
    assert all(0.001 < r <= 0.5 if c else r == 0 for r, c in zip(radius, capture))
    lat, lon, rel = (np.array([items[k]["params"][i] for k in nav]) for i in (4, 5, 6))
    enu = np.column_stack(pymap3d.geodetic2enu(lat, lon, rel, lat[0], lon[0], 0.0))
    gap = np.linalg.norm(np.diff(enu, axis=0), axis=1)
    both = np.array(capture[:-1]) & np.array(capture[1:])
    assert both.sum() > 10 and (gap[both] > radius[:-1][both] + radius[1:][both]).all()
    assert (gap[both] < 4.0).sum() > 5  # captures nearer than two default radii: it matters


def test_qgc_plan_photos_on_vertical_legs_wait_until_the_vehicle_is_there(exported):
    """PX4 counts a multicopter's waypoint reached within p2 horizontally and NAV_MC_ALT_RAD
    (0.8 m) vertically, then runs the photo after the hold p1: on the profile's vertical sweeps
    (frames 0.82 m apart) the photo fired 0.8 m early. Each capture whose reached point, flown
    straight from the waypoint before, is over 0.5 m from it holds at least the rest of the leg
    flown from a stop to a stop (this file's _stop_s at the model's 5 m/s and 2 m/s)."""
    import pymap3d

    out, _ = exported
    items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
    nav = [k for k, it in enumerate(items) if it["command"] in (16, 22)]
    lat, lon, rel = (np.array([items[k]["params"][i] for k in nav]) for i in (4, 5, 6))
    enu = np.column_stack(pymap3d.geodetic2enu(lat, lon, rel, lat[0], lon[0], 0.0))
    early = 0
    for j in range(1, len(nav)):
        k = nav[j]
        if not (k + 1 < len(items) and items[k + 1]["command"] == 2000):
            continue
        hold, p2 = items[k]["params"][0], items[k]["params"][1]
        leg = enu[j] - enu[j - 1]
        h, v = math.hypot(leg[0], leg[1]), abs(leg[2])
        t = np.linspace(0.0, 1.0, 20001)  # along the leg: the first point PX4 counts reached
        ok = ((1 - t) * h <= p2 + 1e-9) & ((1 - t) * v <= 0.8 + 1e-9)
        left = 1 - t[np.argmax(ok)]
        if left * math.hypot(h, v) <= 0.5 + 1e-6:
            continue
        early += 1
        need = max(_stop_s(left * h, 5.0), _stop_s(left * v, 2.0))
        assert hold >= need - 1e-3, (j, hold, need, left * math.hypot(h, v))
    assert early > 5  # the profile's sweeps: the case is there


def test_the_export_folder_is_made_as_any_folder_is(exported, tmp_path):
    """The export's folders (moved into place from a temporary one) have the mode a new folder
    gets under this process's umask, not a private temporary folder's 0700."""
    import stat

    (tmp_path / "plain").mkdir()
    want = stat.S_IMODE((tmp_path / "plain").stat().st_mode)
    out, _ = exported
    assert want != 0o700 and stat.S_IMODE(out.stat().st_mode) == want
    assert stat.S_IMODE((out / "colmap").stat().st_mode) == want
    assert not list(out.parent.glob(".nbvkit-export-*"))


def test_qgc_wpl_text_mission(exported):
    out, _ = exported
    lines = (out / "mission.waypoints").read_text().splitlines()
    assert lines[0] == "QGC WPL 110"
    rows = [ln.split("\t") for ln in lines[1:]]
    assert all(len(r) == 12 for r in rows)
    assert [int(r[0]) for r in rows] == list(range(len(rows)))
    assert rows[0][1] == "1" and rows[0][2] == "0"  # home, absolute altitude
    cmds = [int(r[3]) for r in rows]
    assert cmds[1] == 22 and cmds[-1] == 20
    caps = [r for r in _csv(out / "mission.csv") if r["action"] in ("view", "frame")]
    photos = _fly_ardupilot(rows, speed=5.0)
    assert len(photos) == len(caps) == cmds.count(2000)
    assert [p["seq"] for p in photos] == list(range(1, len(caps) + 1))  # unique, increasing
    turned = early = 0
    for p, r in zip(photos, caps):
        # taken at the capture's point, facing its heading, with its gimbal pitch commanded
        # before the arrival
        assert p["pos"][:2] == pytest.approx((float(r["latitude_deg"]), float(r["longitude_deg"])))
        assert p["heading"] is not None, f"{r['action']} {r['seq']}: heading not held"
        assert abs((p["heading"] - float(r["heading_deg"]) + 180) % 360 - 180) < 1e-3
        assert p["pitch"] == pytest.approx(float(r["gimbal_pitch_deg"]), abs=1e-3)
        assert p["pitch_t"] <= p["arrive"] + 1e-9
        turned += p["yaw_t"] > p["leg_start"] + 1e-9
        if r["action"] == "view":
            # settled (1 s after the arrival and the turn) before the photo, and the aircraft
            # stays the whole hover (2 s), the rest of it after the photo
            assert p["t"] - max(p["arrive"], p["yaw_t"]) >= 1.0 - 1e-9
            assert p["depart"] == pytest.approx(max(p["arrive"] + 2.0, p["t"]))
            early += p["t"] < p["arrive"] + 2.0 - 1e-9
    assert turned > 0  # the check saw turns
    assert early > 0  # and photos taken before the end of the hover


NAV_LAST = 95  # MAV_CMD_NAV_LAST: ArduPilot's AP_Mission::is_nav_cmd is id <= 95 (or 213)


def _fly_ardupilot(rows, speed, slew=60.0):
    """Each photo (IMAGE_START_CAPTURE) of a QGC WPL mission as ArduPilot's copter runs it, read
    from its source (libraries/AP_Mission/AP_Mission.cpp advance_current_nav_cmd /
    advance_current_do_cmd, ArduCopter/mode_auto.cpp wp_start, do_yaw, verify_yaw,
    verify_nav_wp, do_nav_delay): the do/conditional commands after a nav command start, one
    after the other, when it completes (its hold over), together with the next nav command; a
    conditional command (CONDITION_YAW) holds back the later ones until it is done; a
    NAV_WAYPOINT's start resets the yaw to the default (along the track) unless a CONDITION_YAW
    of its leg sets it again (verify_yaw); NAV_DELAY keeps position and yaw. The copter flies a
    leg in its horizontal length / speed (its quickest) and turns at CONDITION_YAW's rate (param
    2; 0: `slew`) the shortest way from the heading it has when the command starts: where a turn
    still under way was stopped (the next waypoint reached first), along the track after a
    waypoint's start without one (WP_YAW_BEHAVIOR's default: face the next waypoint), 180
    degrees away after the take-off. Returns per photo:
    t, pos (lat, lon), heading (None unless held at the target), pitch and pitch_t (the last
    gimbal command and its time), arrive, leg_start, yaw_t (when the heading was reached),
    depart, seq."""
    import pymap3d

    items = [(int(r[3]), [float(v) for v in r[4:11]]) for r in rows[1:]]  # row 0: home
    t, pos, arrive, leg_start = 0.0, None, 0.0, 0.0
    yaw = None  # (time reached, target) of the last turn
    turn = None  # (start time, start heading, target, rate): the heading at any time

    def heading_at(when):
        t0, y0, y1, rate = turn
        d = (y1 - y0 + 180) % 360 - 180
        return y0 + math.copysign(min(abs(d), rate * max(0.0, when - t0)), d)

    pitch = pitch_t = None
    photos = []
    k = 0
    while k < len(items):
        cmd, p = items[k]
        if cmd > NAV_LAST:  # the do commands after the last nav command, started at t
            j = k
            while j < len(items) and items[j][0] > NAV_LAST:
                j += 1
            t_do, held = t, False
            for c, q in items[k:j]:
                if c == 2000:
                    h = yaw[1] if yaw is not None and yaw[0] <= t_do + 1e-9 else None
                    photos.append(
                        dict(
                            t=t_do,
                            pos=pos,
                            heading=h,
                            pitch=pitch,
                            pitch_t=pitch_t,
                            arrive=arrive,
                            leg_start=leg_start,
                            yaw_t=yaw[0] if yaw else math.inf,
                            depart=None,
                            seq=int(q[3]),
                        )
                    )
                elif c == 1000:
                    pitch, pitch_t = q[0], t_do
                elif c == 115:
                    y0 = q[0] + 180.0 if turn is None else heading_at(t_do)
                    turn = (t_do, y0, q[0], q[1] or slew)
                    t_do += abs((q[0] - y0 + 180) % 360 - 180) / turn[3]  # held back till done
                    yaw, held = (t_do, q[0]), True
            k = j
            if k == len(items):
                break
            cmd, p = items[k]
        else:
            held = False
        if cmd == 22:
            pos, yaw, turn = (p[4], p[5], p[6]), None, None
        elif cmd == 16:
            if photos and photos[-1]["depart"] is None:
                photos[-1]["depart"] = t
            e, n, _ = pymap3d.geodetic2enu(p[4], p[5], 0.0, pos[0], pos[1], 0.0)
            if not held:  # wp_start: the default yaw, along the track (at once: the quickest)
                yaw = None
                if math.hypot(e, n) > 1e-6:
                    track = math.degrees(math.atan2(e, n))
                    turn = (t, track, track, slew)
            leg_start = t
            arrive = t + math.hypot(e, n) / speed
            t = arrive + int(p[0])  # the hold: whole seconds (loiter_time_max = p1)
            pos = (p[4], p[5], p[6])
        elif cmd == 93:
            t += p[0]
            if photos:
                photos[-1]["depart"] = t
        elif cmd == 20:
            if photos and photos[-1]["depart"] is None:
                photos[-1]["depart"] = t
        k += 1
    return photos


def test_wpml_kmz_read_back(exported, run_dir):
    from lxml import etree

    out, _ = exported
    with zipfile.ZipFile(out / "mission.kmz") as z:
        assert set(z.namelist()) == {"wpmz/template.kml", "wpmz/waylines.wpml"}
        docs = {n: etree.fromstring(z.read(n)) for n in z.namelist()}
    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    rows = _csv(out / "mission.csv")
    fl = read_run(run_dir)
    n_views = sum(c == "view" for c in fl.capture)
    for name, root in docs.items():
        assert root.tag == "{http://www.opengis.net/kml/2.2}kml"
        mc = root.find("k:Document/wpml:missionConfig", ns)
        # the route ends straight above the launch point and lands there (goHome would first
        # climb to the return height)
        assert mc.findtext("wpml:finishAction", namespaces=ns) == "autoLand"
        assert mc.find("wpml:droneInfo/wpml:droneEnumValue", ns) is not None
        # the template's payload parameters: both elements the spec requires in it
        pp = root.find("k:Document/k:Folder/wpml:payloadParam", ns)
        if name.endswith("template.kml"):
            assert pp.findtext("wpml:payloadPositionIndex", namespaces=ns) == "0"
            assert pp.findtext("wpml:imageFormat", namespaces=ns) == "wide"
        else:
            assert pp is None  # waylines.wpml has none
        pms = root.findall("k:Document/k:Folder/k:Placemark", ns)
        assert len(pms) == len(rows)
        assert [int(p.findtext("wpml:index", namespaces=ns)) for p in pms] == list(range(len(pms)))
        heights = [
            float(
                p.findtext(
                    "wpml:executeHeight" if name.endswith("wpml") else "wpml:height", namespaces=ns
                )
            )
            for p in pms
        ]
        np.testing.assert_allclose(heights, [float(r["rel_altitude_m"]) for r in rows], atol=1e-3)
        lonlat = [p.findtext("k:Point/k:coordinates", namespaces=ns).split(",") for p in pms]
        np.testing.assert_allclose(
            [[float(b), float(a)] for a, b in lonlat],
            [[float(r["latitude_deg"]), float(r["longitude_deg"])] for r in rows],
            atol=1e-9,
        )
        # every capture: gimbal pitch, (a view: 1 s settle,) photo (wide lens), (rest of the
        # 2 s hover); the photo's heading is the waypoint's
        n_caps = 0
        for p, r in zip(pms, rows):
            acts = p.findall("wpml:actionGroup/wpml:action", ns)
            funcs = [a.findtext("wpml:actionActuatorFunc", namespaces=ns) for a in acts]
            if r["action"] not in ("view", "frame"):
                assert funcs == []
                continue
            n_caps += 1
            want = ["gimbalRotate", "rotateYaw", "takePhoto"]
            if r["action"] == "view":
                want = ["gimbalRotate", "rotateYaw", "hover", "takePhoto", "hover"]
                hovers = [a.findtext(".//wpml:hoverTime", namespaces=ns) for a in acts]
                assert [float(h) for h in hovers if h is not None] == [1.0, 2.0 - 1.0]
            assert funcs == want
            gim = acts[0].find("wpml:actionActuatorFuncParam", ns)
            par = {e.tag.split("}")[1]: e.text for e in gim}
            assert par["gimbalPitchRotateEnable"] == "1"
            assert float(par["gimbalPitchRotateAngle"]) == pytest.approx(
                float(r["gimbal_pitch_deg"]), abs=1e-3
            )
            # the heading is turned to (rotateYaw) before the photo, whatever the leg's
            # heading mode (a leg from a transit point arrives facing along its course)
            yaw = acts[funcs.index("rotateYaw")].find("wpml:actionActuatorFuncParam", ns)
            ah = float(yaw.findtext("wpml:aircraftHeading", namespaces=ns))
            assert -180 <= ah <= 180
            assert abs((ah - float(r["heading_deg"]) + 180) % 360 - 180) < 1e-3
            assert yaw.findtext("wpml:aircraftPathMode", namespaces=ns) in (
                "clockwise",
                "counterClockwise",
            )
            photo = acts[funcs.index("takePhoto")].find("wpml:actionActuatorFuncParam", ns)
            assert photo.findtext("wpml:useGlobalPayloadLensIndex", namespaces=ns) == "0"
            assert photo.findtext("wpml:payloadLensIndex", namespaces=ns) == "wide"
            a = p.findtext("wpml:waypointHeadingParam/wpml:waypointHeadingAngle", namespaces=ns)
            assert abs((float(a) - float(r["heading_deg"]) + 180) % 360 - 180) < 1e-3
        assert n_caps == sum(bool(c) for c in fl.capture) and n_views < n_caps
        for p in pms:
            a = p.findtext("wpml:waypointHeadingParam/wpml:waypointHeadingAngle", namespaces=ns)
            assert a is None or -180 <= float(a) < 180
    # template.kml: each point's height above the WGS84 ellipsoid too (required with
    # useGlobalHeight 0), and the take-off point's: AMSL + the EGM96 geoid height, which is
    # 47.4 m at Zurich (NGA's EGM96 tables; 47.3-47.4 m around 47.4 N 8.5 E)
    tk = docs["wpmz/template.kml"]
    pms = tk.findall("k:Document/k:Folder/k:Placemark", ns)
    assert all(p.findtext("wpml:useGlobalHeight", namespaces=ns) == "0" for p in pms)
    ell = np.array([float(p.findtext("wpml:ellipsoidHeight", namespaces=ns)) for p in pms])
    n = ell - np.array([float(r["altitude_m"]) for r in rows])
    assert np.all((n > 46.8) & (n < 48.0)) and np.ptp(n) < 0.05
    plan = json.loads((out / "mission.plan").read_text())["mission"]
    ref = tk.findtext("k:Document/wpml:missionConfig/wpml:takeOffRefPoint", namespaces=ns)
    lat, lon, h = map(float, ref.split(","))
    home = plan["plannedHomePosition"]
    assert (lat, lon) == pytest.approx(home[:2], abs=1e-9)
    assert h - home[2] == pytest.approx(n.mean(), abs=0.05)
    wl = docs["wpmz/waylines.wpml"]
    assert wl.findtext("k:Document/k:Folder/wpml:executeHeightMode", namespaces=ns) == (
        "relativeToStartPoint"
    )


def test_kml_and_geojson_read_back(exported, run_dir):
    from fastkml import kml

    out, _ = exported
    fl = read_run(run_dir)
    n_caps = sum(bool(c) for c in fl.capture)
    rows = _csv(out / "mission.csv")
    k = kml.KML()
    k.from_string((out / "mission.kml").read_bytes())
    doc = list(k.features())[0]
    feats = {f.name: f for f in doc.features()}
    line = feats["flight"].geometry
    assert line.geom_type == "LineString" and len(line.coords) == len(rows)
    views = list(feats["captures"].features())
    assert all(v.geometry.geom_type == "Point" for v in views)
    assert len(views) == n_caps
    c = np.array(line.coords)
    xyz = _to_mesh(c[:, 1], c[:, 0], c[:, 2])
    ref = _to_mesh(
        *(
            np.array([[float(r[k]) for r in rows]]).ravel()
            for k in ("latitude_deg", "longitude_deg", "altitude_m")
        )
    )
    assert np.abs(xyz - ref).max() < 0.01
    gj = json.loads((out / "mission.geojson").read_text())
    assert gj["type"] == "FeatureCollection"
    ls = gj["features"][0]["geometry"]
    assert ls["type"] == "LineString" and len(ls["coordinates"]) == len(rows)
    pts = [f for f in gj["features"] if f["geometry"]["type"] == "Point"]
    assert len(pts) == n_caps
    n = _egm96(ORIGIN[0], ORIGIN[1])  # heights above the ellipsoid (RFC 7946)
    for f in pts:
        lon, lat, alt = f["geometry"]["coordinates"]
        p = _to_mesh([lat], [lon], [alt - n])[0]
        assert np.abs(p - fl.xyz[f["properties"]["flight_row"]]).max() < 0.01


def test_colmap_pose_reprojects_mesh_points_to_the_pixels_the_camera_saw(exported, run_dir):
    out, _ = exported
    cams = [
        ln.split()
        for ln in (out / "colmap/cameras.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    assert len(cams) == 1 and cams[0][1] == "PINHOLE"
    w, h = int(cams[0][2]), int(cams[0][3])
    fx, fy, cx, cy = map(float, cams[0][4:8])
    lines = [
        ln for ln in (out / "colmap/images.txt").read_text().splitlines() if not ln.startswith("#")
    ]
    images = [ln.split() for ln in lines[0::2]]
    fl = read_run(run_dir)
    caps = [i for i, c in enumerate(fl.capture) if c]
    assert len(images) == len(caps)
    from scipy.spatial.transform import Rotation

    cfg = fl.config
    mesh = nbvkit.load_mesh(nbvkit.default_mesh_path())
    cam = _core.DepthCamera(
        _core.RaycastScene(mesh),
        camera_kwargs(cfg.camera),
        noise_k=0.0,
        mount=_core.mount_transform(cfg.camera.mount_xyz, *cfg.camera.mount_rpy_deg),
    )
    assert (cam.width, cam.height) == (w, h)
    checked = 0
    for im, row in list(zip(images, caps))[:: max(1, len(caps) // 4)]:
        qw, qx, qy, qz, tx, ty, tz = map(float, im[1:8])
        R = Rotation.from_quat([qx, qy, qz, qw]).as_matrix()
        scan = cam.scan_pose([*fl.xyz[row], fl.yaw[row]])
        if len(scan.hits) == 0:
            continue
        sel = np.linspace(0, len(scan.hits) - 1, 50).astype(int)
        pc = scan.hits[sel] @ R.T + [tx, ty, tz]
        assert (pc[:, 2] > 0).all()
        uv = np.stack([fx * pc[:, 0] / pc[:, 2] + cx, fy * pc[:, 1] / pc[:, 2] + cy], axis=1)
        ray = scan.hit_rays[sel]
        seen = np.stack([ray % w + 0.5, ray // w + 0.5], axis=1)  # the pixel's centre
        assert np.abs(uv - seen).max() < 1.0
        checked += len(sel)
    assert checked >= 50


def test_colmap_images_named_as_the_camera_numbers_its_photos(run_dir, tmp_path):
    """--photo-names: the k-th COLMAP image (in images.txt's order) is the photo the mission
    files trigger k-th, named by the pattern from --photo-first: its number read back from the
    .plan's IMAGE_START_CAPTURE (param 4) and the CSV's photo."""
    from nbvkit.cli import main

    out = tmp_path / "ex"
    argv = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--out", str(out)]
    argv += ["--format", "qgc,csv,colmap", "--photo-names", "DJI_{:04d}.JPG"]
    assert main(argv + ["--photo-first", "101"]) == 0
    lines = [
        ln for ln in (out / "colmap/images.txt").read_text().splitlines() if not ln.startswith("#")
    ]
    names = [ln.split()[9] for ln in lines[0::2]]
    items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
    fired = [int(it["params"][3]) for it in items if it["command"] == 2000]
    with open(out / "mission.csv", newline="") as f:
        seqs = [int(r["photo"]) for r in csv.DictReader(f) if r["action"] in ("view", "frame")]
    assert len(names) == len(fired) == len(seqs) == sum(1 for c in read_run(run_dir).capture if c)
    assert (
        names
        == [f"DJI_{n + 100:04d}.JPG" for n in fired]
        == [f"DJI_{n + 100:04d}.JPG" for n in seqs]
    )
    assert names[0] == "DJI_0101.JPG"
    assert json.loads((out / "export.json").read_text())["photo_names"] == ["DJI_{:04d}.JPG", 101]


def test_captures_left_unreachable_take_no_photo_number_and_no_colmap_image(run_dir, tmp_path):
    """A budget that leaves captures unflown: the photos the sorties take are numbered 1, 2, ...
    with no gap (the camera numbers the photos it takes one after another), and COLMAP lists
    those photos only, each at the position of the capture that takes it (read back from the
    CSV's flight_row and flight.csv). Before, an unflown capture kept its number and its image:
    DJI_0069.JPG was given the pose of a capture never flown."""
    from nbvkit.export import _planner
    from nbvkit.export.plan import FlightModel

    _, sp = _planner(run_dir, FlightModel(), need_all_returns=True)
    views = sum(1 for c in read_run(run_dir).capture if c == "view")
    minutes = None
    for t in np.arange(0.3, 5.0, 0.1):  # a budget some views lie beyond, some within
        sorties, unreachable = sp.split(60 * t * 0.8)
        if 0 < sum(u["capture"] == "view" for u in unreachable) < views:
            minutes = float(t)
            break
    assert minutes is not None
    out = tmp_path / "ex"
    s = export_mission(
        run_dir, "qgc,csv,colmap", ORIGIN, HEADING, out, flight_time_min=minutes, reserve_pct=20
    )
    assert s["unreachable"]
    # a warning (it was a line on stdout alone, exit 0 and export.json's warnings silent)
    n = len(s["unreachable"])
    assert any(
        w.startswith(f"{n} point") and "left out of every sortie" in w for w in s["warnings"]
    )
    fired, rows = [], []
    for srt in s["sorties"]:
        plan = json.loads((out / f"sortie_{srt['sortie']:02d}.plan").read_text())["mission"]
        fired += [int(it["params"][3]) for it in plan["items"] if it["command"] == 2000]
        csv_rows = _csv(out / f"sortie_{srt['sortie']:02d}.csv")
        rows += [(int(r["photo"]), int(r["flight_row"])) for r in csv_rows if r["photo"]]
    assert fired == list(range(1, len(fired) + 1))
    assert [p for p, _ in rows] == fired
    lines = [
        ln for ln in (out / "colmap/images.txt").read_text().splitlines() if not ln.startswith("#")
    ]
    assert len(lines[0::2]) == len(fired)  # the photos taken, not every capture planned
    flight = _csv(run_dir / "flight.csv")
    for ln, (_, row) in zip(lines[0::2], rows):
        q = np.array(ln.split()[1:5], float)  # world-to-camera (qw first), t
        t = np.array(ln.split()[5:8], float)
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        at = np.array([float(flight[row][k]) for k in ("x", "y", "z")])
        assert np.abs(-R.T @ t - at).max() < 1e-6


# ------------------------------------------------------------------ one flight per battery
def test_a_budget_splits_the_flight_into_sorties_from_and_to_home(run_dir, tmp_path):
    from nbvkit.export import _planner
    from nbvkit.export.plan import FlightModel

    whole = export_mission(run_dir, "csv", ORIGIN, HEADING, tmp_path / "whole")["mission"]
    fl = read_run(run_dir)
    view_rows = [i for i, c in enumerate(fl.capture) if c == "view"]
    # the largest budget (to 0.05 min) that needs 3 sorties
    _, sp = _planner(run_dir, FlightModel(), need_all_returns=True)
    minutes = None
    for t in np.arange(math.ceil(whole["time_min"] * 20) / 20, 0.05, -0.05):
        sorties, unreachable = sp.split(60 * t * 0.8)
        if len(sorties) == 3 and not unreachable:
            minutes = float(t)
            break
    assert minutes is not None
    out = tmp_path / "whole"  # over the export without a budget: its files are replaced
    budget = export_mission(
        run_dir, "csv,qgc", ORIGIN, HEADING, out, flight_time_min=minutes, reserve_pct=20
    )
    assert len(budget["sorties"]) == 3
    assert budget["unreachable"] == []
    usable = budget["budget"]["usable_min"] * 60
    captured, seqs = [], []
    frame = _frame()
    home = None
    for srt in budget["sorties"]:
        assert srt["time_s"] <= usable + 1e-6
        rows = _csv(out / f"sortie_{srt['sortie']:02d}.csv")
        captured += [int(r["flight_row"]) for r in rows if r["action"] == "view"]
        assert rows[0]["action"] == "takeoff" and rows[-1]["action"] == "home"
        first = frame.to_mesh(
            *(
                np.array([float(rows[0][k])])
                for k in ("latitude_deg", "longitude_deg", "altitude_m")
            )
        )[0]
        last = frame.to_mesh(
            *(
                np.array([float(rows[-1][k])])
                for k in ("latitude_deg", "longitude_deg", "altitude_m")
            )
        )[0]
        top = budget["climb_top_mesh"]
        assert np.abs(first - top).max() < 0.01 and np.abs(last - top).max() < 0.01
        plan = json.loads((out / f"sortie_{srt['sortie']:02d}.plan").read_text())["mission"]
        assert plan["items"][0]["command"] == 22 and plan["items"][-1]["command"] == 20
        home = home or plan["plannedHomePosition"]
        seqs += [it["params"][3] for it in plan["items"] if it["command"] == 2000]
        assert plan["plannedHomePosition"] == home
    assert sorted(captured) == view_rows  # every view exactly once
    # the photos' sequence numbers run on over the sorties: unique and increasing
    assert len(seqs) > 0 and seqs == sorted(set(seqs))
    table = _csv(out / "sorties.csv")
    assert [int(r["sortie"]) for r in table] == [1, 2, 3]
    assert sum(int(r["views"]) for r in table) == len(view_rows)
    assert sum(s["time_s"] for s in budget["sorties"]) >= whole["time_s"] - 1e-6
    assert not (out / "mission.csv").exists()  # the previous export's files were replaced


def test_a_flight_planned_closer_than_gnss_error_is_warned_of(run_dir, tmp_path, capsys):
    """The run's stand-off (vehicle.collision_radius 0.8 m, 0.9 m above the ground) is in
    export.json and warned of on the console: a drone without RTK errs by 1-2 m. A run planned
    2 m clear is exported without the warning. export.json records the run's mesh shift (the
    frame --origin places)."""
    from nbvkit.cli import main

    args = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--out", str(tmp_path / "a")]
    assert main(args) == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "a" / "export.json").read_text())
    c = s["clearance"]
    assert _clearance_flown(run_dir) == {k: c[k] for k in _clearance_flown(run_dir)}
    assert c["collision_radius_m"] == 0.8 and c["min_altitude_m"] == 0.9
    _check_structure_distance(run_dir, c, cell=0.4)
    assert s["mesh_shift"] == [0.0, 0.0, 0.0]
    assert (
        f"nbvkit export: warning: the flight passes {c['structure_m']:g} m from the structure "
        "at its nearest (vehicle.collision_radius 0.8 m)" in err
        and "RTK" in err
    )
    far = Mission(
        Config().with_overrides([*FAST, "vehicle.collision_radius=2", "mesh.shift=[40,-25,0]"])
    )
    far.run(tmp_path / "far")
    far_ex = tmp_path / "far_ex"
    assert main(["export", str(tmp_path / "far"), *args[2:-2], "--out", str(far_ex)]) == 0
    s = json.loads((far_ex / "export.json").read_text())
    c = s["clearance"]
    assert _clearance_flown(tmp_path / "far") == {k: c[k] for k in _clearance_flown(run_dir)}
    assert c["min_altitude_m"] == 2.1 and c["collision_radius_m"] == 2.0
    # A* paths between views keep the views' height to within half a (0.4 m) cell
    assert c["ground_m"] >= 2.1 - 0.2 - 1e-9
    _check_structure_distance(tmp_path / "far", c, cell=0.4)
    assert s["mesh_shift"] == [40.0, -25.0, 0.0]
    if c["ground_m"] >= 2.0:
        assert s["warnings"] == [] and "warning" not in capsys.readouterr().err


def test_a_flight_below_its_views_height_by_more_than_half_a_cell_is_warned_of():
    from nbvkit.export.cautions import clearance_warnings

    c = {"structure_m": 3.0, "ground_m": 2.95, "min_altitude_m": 3.1, "lowest_row": 7}
    c.update(structure_measured=True, structure_point_mesh=[1, 2, 3], collision_radius_m=3.0)
    assert clearance_warnings(c, 0.4) == []  # within half a cell: as planned
    (w,) = clearance_warnings(c, 0.2)
    assert "passes 2.95 m above the ground (at flight row 7), below the 3.1 m" in w
    assert clearance_warnings({**c, "ground_m": 3.1}, 0.0) == []


def test_a_flight_nearer_the_structure_than_its_radius_by_more_than_a_cell_is_warned_of():
    """The planner keeps the collision sphere off the map's cells: the surface in a cell may lie
    up to half its diagonal nearer than the cell's centre, and no more is warned of."""
    from nbvkit.export.cautions import clearance_warnings

    c = {"structure_m": 2.7, "ground_m": 3.2, "min_altitude_m": 3.1, "lowest_row": 7}
    c.update(structure_measured=True, structure_point_mesh=[1, 2, 3], collision_radius_m=3.0)
    assert clearance_warnings(c, 0.4) == []  # 0.3 m < 0.4 * sqrt(3) / 2
    (w,) = clearance_warnings(c, 0.2)
    assert w == (
        "the flight passes 2.7 m from the structure (at [1, 2, 3] in the mesh's frame), nearer "
        "than its 3 m collision radius"
    )


def test_the_structure_distance_is_not_measured_without_the_mesh_the_run_flew(tmp_path, capsys):
    """A run whose mesh is not found from here, or has changed since (summary.json's
    mesh_sha1), is exported with the planned radius, saying it was not measured and why."""
    import shutil

    from nbvkit.cli import main

    mesh = tmp_path / "structure.obj"
    shutil.copyfile(ROOT / "meshes" / "fixtures" / "cube.obj", mesh)
    over = [*FAST, "max_iterations=2", f"mesh.path={mesh}", "mesh.scale=4"]
    Mission(Config().with_overrides(over)).run(tmp_path / "run")
    args = ["export", str(tmp_path / "run"), "--origin", *map(str, ORIGIN), "--format", "csv"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0  # the same file: measured
    c = json.loads((tmp_path / "a" / "export.json").read_text())["clearance"]
    assert c["structure_measured"] and c["structure_m"] >= 0.8 - 0.4 * 0.866
    with open(mesh, "a") as f:
        f.write("v 100 100 100\n")
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    mesh.unlink()
    assert main([*args, "--out", str(tmp_path / "c")]) == 0
    for out, why in (("b", "has changed since the run"), ("c", "is not found from here")):
        c = json.loads((tmp_path / out / "export.json").read_text())["clearance"]
        assert not c["structure_measured"] and c["structure_point_mesh"] is None
        assert c["structure_m"] == 0.8 and why in c["structure_note"]
    err = capsys.readouterr().err
    assert err.count("the flight's distance from the structure was not measured: its mesh") == 2


def yaml_config(run) -> dict:
    import yaml

    return yaml.safe_load((run / "config.yaml").read_text())


def _check_structure_distance(run, c: dict, cell: float) -> None:
    """export.json's distance from the structure, checked with open3d's distance query: at
    its point it is that point's distance from the mesh; no point of the run's own flight (a
    part of what the export flies) is nearer; and it keeps the collision radius to within half a
    map cell's diagonal."""
    o3d = pytest.importorskip("open3d")
    mesh = nbvkit.load_mesh(nbvkit.default_mesh_path())
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)),
    )
    shift = np.array(yaml_config(run)["mesh"]["shift"], float)

    def dist(p):
        return scene.compute_distance(o3d.core.Tensor((p - shift).astype(np.float32))).numpy()

    assert c["structure_measured"]
    at = np.array(c["structure_point_mesh"], float)[None]
    assert abs(float(dist(at)[0]) - c["structure_m"]) < 2e-3
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in _csv(run / "flight.csv")])
    assert float(dist(xyz).min()) >= c["structure_m"] - 2e-3
    assert c["structure_m"] >= c["collision_radius_m"] - cell * 0.866


def _clearance_flown(run) -> dict:
    """export.json's clearance from the run's own files: the least height of flight.csv's points
    above summary.json's workspace floor, and its row."""
    import yaml

    summary = json.loads((run / "summary.json").read_text())
    radius = yaml.safe_load((run / "config.yaml").read_text())["vehicle"]["collision_radius"]
    z = np.array([float(r["z"]) for r in _csv(run / "flight.csv")])
    h = z - summary["workspace"]["bounds_min"][2]
    return {
        "collision_radius_m": round(radius, 3),
        "ground_m": round(float(h.min()), 3),
        "min_altitude_m": round(radius + 0.1, 3),
        "lowest_row": int(np.argmin(h)),
    }


def test_the_console_times_only_the_files_written(run_dir, tmp_path, capsys):
    from nbvkit.cli import main

    args = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--format"]
    assert main([*args, "qgc", "--out", str(tmp_path / "q")]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "time by file" in ln)
    assert ".plan (PX4)" in line and ".waypoints" in line and ".kmz" not in line
    assert main([*args, "wpml", "--out", str(tmp_path / "w")]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "time by file" in ln)
    assert ".kmz (DJI)" in line and ".plan" not in line


def test_sortie_files_list_by_name_in_flight_order():
    from nbvkit.export.plan import sortie_names

    assert sortie_names([1, 2, 3]) == ["sortie_01", "sortie_02", "sortie_03"]
    names = sortie_names(list(range(1, 161)))  # 160 sorties: a 1-minute battery's airliner
    assert names[0] == "sortie_001" and names[-1] == "sortie_160"
    assert sorted(names) == names


def test_a_view_beyond_one_battery_is_reported_not_dropped(run_dir, tmp_path):
    from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner

    fl = read_run(run_dir)
    model = FlightModel()
    sp = SortiePlanner(fl, model, ReturnPaths(fl, model, None, []))  # retrace only: far views
    views = [i for i, c in enumerate(fl.capture) if c == "view"]
    usable = sp.sortie(1, views[0], views[0]).time_s + 1.0  # the first view's, not the last's
    sorties, unreachable = sp.split(usable)
    flown = [
        i for s in sorties for i in range(s.first_row, s.last_row + 1) if fl.capture[i] == "view"
    ]
    missed = [u["row"] for u in unreachable if u["capture"] == "view"]
    assert missed and sorted(flown + missed) == views
    assert all(s.time_s <= usable for s in sorties)


def test_each_sortie_flies_as_far_as_its_battery_allows(run_dir):
    """The split's estimate of a way back along the flight stops at each capture and turn on
    it, the sortie's own transit does not: the estimate said a row did not fit where it did, and
    a 3.7-minute flight took 11 batteries of 4 minutes, most flying one frame. Each sortie but
    the last now cannot take its next row (and stay within the battery)."""
    from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner

    fl = read_run(run_dir)
    model = FlightModel()
    sp = SortiePlanner(fl, model, ReturnPaths(fl, model, None, []))  # retrace only
    whole = sp.whole().time_s
    work = list(sp.work)
    for share in (0.46, 0.7, 0.8):  # (at 0.46 some rows are out of any sortie's reach)
        usable = share * whole
        sorties, unreachable = sp.split(usable)
        assert len(sorties) >= 2 and (share < 0.5 or not unreachable)
        for s in sorties:
            i = work.index(s.last_row)
            if i + 1 < len(work):
                more = sp.sortie(s.number, s.first_row, work[i + 1])
                assert s.time_s <= usable < more.time_s


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "kwargs, exc, words",
    [
        ({"origin": (91.0, 8.5, 400.0)}, ValueError, "latitude"),
        ({"origin": (-90.5, 8.5, 400.0)}, ValueError, "latitude"),
        ({"origin": (47.0, 180.5, 400.0)}, ValueError, "longitude"),
        ({"origin": (47.0, 8.5, float("nan"))}, ValueError, "altitude must be a finite"),
        ({"origin": (float("inf"), 8.5, 400.0)}, ValueError, "latitude must be a finite"),
        ({"heading_deg": float("nan")}, ValueError, "heading"),
        ({"climb_rate": 100.0}, ValueError, "climb rate 100 m/s is above the export's maximum"),
        # 1e20 degrees: a float cannot hold its remainder modulo 360 (it turned into 162)
        ({"heading_deg": 1e20}, ValueError, r"heading \(--heading\) must be within \[-360, 360\]"),
        ({"heading_deg": -360.5}, ValueError, r"heading \(--heading\) must be within"),
        ({"formats": "qgc,shapefile"}, ValueError, "unknown export format 'shapefile'"),
        ({"flight_time_min": 0.05}, ValueError, "too short for any view"),
        ({"flight_time_min": -1.0}, ValueError, "flight time"),
        ({"speed": 0.0}, ValueError, "speed"),
        ({"speed": 15.5}, ValueError, "above the export's maximum of 15 m/s"),
        ({"origin": (89.95, 8.5, 400.0)}, ValueError, "latitude 89.95 .* pole"),
        ({"origin": (-89.91, 8.5, 400.0)}, ValueError, "pole.*<= 89.9"),
        ({"origin": (47.0, 8.5, 1e12)}, ValueError, r"altitude must be within \[-500, 10000\]"),
        ({"origin": (47.0, 8.5, -600.0)}, ValueError, "altitude must be within"),
        # wrong types: each argument named (messages named none, or an IndexError)
        ({"origin": "abc"}, ValueError, r"origin must be \(latitude, longitude, altitude\)"),
        ({"origin": (47.0, "8.5", 400.0)}, ValueError, "origin's longitude must be a number"),
        ({"origin": None}, ValueError, "origin must be"),
        ({"heading_deg": "north"}, ValueError, "heading_deg must be a number, got 'north'"),
        ({"speed": "fast"}, ValueError, "speed must be a number"),
        ({"climb_rate": None}, ValueError, "climb_rate must be a number"),
        ({"hover_s": True}, ValueError, "hover_s must be a number"),
        ({"reserve_pct": "20"}, ValueError, "reserve_pct must be a number"),
        ({"flight_time_min": "20"}, ValueError, "flight_time_min must be a number"),
        ({"max_items": "500"}, ValueError, "max_items must be a whole number"),
        ({"formats": None}, ValueError, "formats must be a list"),
        ({"dji_drone": "x"}, ValueError, "dji_drone must be \\(droneEnumValue"),
        ({"dji_drone": 67}, ValueError, "dji_drone must be"),
        ({"dji_drone": (67, 0.5)}, ValueError, r"dji_drone\[1\] must be a whole number >= 0"),
        ({"dji_payload": -1}, ValueError, "dji_payload must be a whole number >= 0"),
        ({"dji_payload": "a<b>&"}, ValueError, "dji_payload must be a whole number"),
        ({"out_dir": ""}, ValueError, "out_dir is empty"),
        ({"photo_names": "DJI.JPG"}, ValueError, "one field for the photo's number"),
        ({"photo_names": "DJI_{}_{}.JPG"}, ValueError, "one field for the photo's number"),
        ({"photo_names": "DJI_{:s}.JPG"}, ValueError, "one field for the photo's number"),
        # '{:.1e}' gave 11 photos one name; '{:>999999999d}' built a gigabyte before its refusal
        ({"photo_names": "IMG_{:.1e}.JPG"}, ValueError, "field must write the number's digits"),
        ({"photo_names": "{:>999999999d}"}, ValueError, "at most 32 wide"),
        ({"photo_names": "{:040d}"}, ValueError, "at most 32 wide"),
        ({"photo_names": "IMG_{!r}.JPG"}, ValueError, "field must write the number's digits"),
        ({"photo_names": "DJI_{name}.JPG"}, ValueError, "one field for the photo's number"),
        ({"photo_names": "DJI_{.JPG"}, ValueError, "one field for the photo's number"),
        ({"photo_names": "x" * 260 + "{}"}, ValueError, "relative to its image folder"),
        ({"photo_names": "my photo {}.jpg"}, ValueError, "no spaces"),
        ({"photo_names": "../{}.jpg"}, ValueError, "relative to its image folder"),
        ({"photo_names": "DJI_{}.JPG", "photo_first": -1}, ValueError, "first photo's number"),
        ({"photo_names": 7}, ValueError, "photo names must be a string"),
    ],
)
def test_bad_input_names_the_problem_and_writes_nothing(run_dir, tmp_path, kwargs, exc, words):
    args = {"formats": "qgc,csv,colmap", "origin": ORIGIN, "out_dir": tmp_path / "ex", **kwargs}
    with pytest.raises(exc, match=words):
        export_mission(run_dir, **args)
    assert list(tmp_path.iterdir()) == []  # no output folder, no temporary folder


def test_an_export_into_a_run_folder_is_refused(run_dir, tmp_path):
    """An export's files among a run's (--out another run's folder, or the run's own) made
    --overwrite refuse the run as holding files nbvkit did not write."""
    before = sorted(p.name for p in run_dir.iterdir())
    with pytest.raises(ValueError, match="is a run folder: give a folder of its own"):
        export_mission(run_dir, "qgc", ORIGIN, HEADING, run_dir)
    with pytest.raises(ValueError, match=f"lies in {run_dir}, a run folder"):
        export_mission(run_dir, "qgc", ORIGIN, HEADING, run_dir / "figures" / "ex")
    assert sorted(p.name for p in run_dir.iterdir()) == before


def test_an_output_folder_that_cannot_be_made_is_named_before_the_work(run_dir, tmp_path):
    # a file on its path: "[Errno 20] Not a directory: '.../afile/.nbvkit-export-...'", a
    # temporary folder's name, once the sorties were planned
    (tmp_path / "afile").write_text("")
    out = tmp_path / "afile" / "sub"
    with pytest.raises(ValueError, match=f"output folder {out} cannot be written"):
        export_mission(run_dir, "qgc", ORIGIN, HEADING, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_a_run_folder_without_a_trajectory_is_named(run_dir, tmp_path):
    import shutil

    from nbvkit.runfolder import IncompleteRunError

    (tmp_path / "empty").mkdir()
    with pytest.raises(IncompleteRunError, match="empty is not a complete nbvkit run"):
        export_mission(tmp_path / "empty", "qgc", ORIGIN, out_dir=tmp_path / "ex")
    run = tmp_path / "run"  # a finished run that has lost its flight since
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("export"))
    (run / "flight.csv").unlink()
    (run / "trajectory.csv").unlink()
    with pytest.raises(IncompleteRunError, match="lacks flight.csv"):
        export_mission(run, "qgc", ORIGIN, out_dir=tmp_path / "ex")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "run"]


@pytest.mark.parametrize(
    "name, damage",
    [
        ("flight.csv", lambda b: b[:40] + b'"' + b"x" * (len(b) - 41)),  # an unclosed quote
        ("flight.csv", lambda b: b[:40] + b"\xff" * (len(b) - 40)),  # not text
        ("summary.json", lambda b: b"\xff" * len(b)),
        ("summary.json", lambda b: b"[" + b" " * (len(b) - 2) + b"]"),  # JSON, not an object
    ],
)
def test_a_damaged_run_file_of_the_same_size_is_named(run_dir, tmp_path, capsys, name, damage):
    """A run file damaged in place keeps its size, so the manifest passes it: export names the
    file and the damage (exit 2) rather than a csv or utf-8 traceback."""
    import shutil

    from nbvkit.cli import main

    run = tmp_path / "run"
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("export"))
    before = (run / name).read_bytes()
    (run / name).write_bytes(damage(before))
    assert len((run / name).read_bytes()) == len(before)
    argv = ["export", str(run), "--origin", *map(str, ORIGIN), "--out", str(tmp_path / "ex")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{run / name} is damaged" in err and "Traceback" not in err
    assert not (tmp_path / "ex").exists()


@pytest.mark.parametrize(
    "bounds", ["[true, -5, 0]", '"abc"', "[1, 2]", "[Infinity, 0, 0]", "[0, 0, 1000]", "null"]
)
def test_a_summary_with_bad_workspace_bounds_is_named(run_dir, tmp_path, capsys, bounds):
    """summary.json's workspace.bounds_min edited in place (the same size: the manifest passes
    it) to the wrong type, shape, a non-finite number or above bounds_max: export names the
    file and the key (exit 2), no traceback, nothing written."""
    import re
    import shutil

    from nbvkit.cli import main

    run = tmp_path / "run"
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("export"))
    text = (run / "summary.json").read_text()
    m = re.search(r'"bounds_min": (\[[^\]]*\])', text)
    assert m and len(bounds) <= len(m.group(1))
    edited = text[: m.start(1)] + bounds.ljust(len(m.group(1))) + text[m.end(1) :]
    (run / "summary.json").write_text(edited)
    argv = ["export", str(run), "--origin", *map(str, ORIGIN), "--out", str(tmp_path / "ex")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{run / 'summary.json'}" in err and "workspace.bounds_m" in err, err
    assert "Traceback" not in err and not (tmp_path / "ex").exists()


def test_cli_export_and_its_errors(run_dir, tmp_path, capsys):
    from nbvkit.cli import main

    out = tmp_path / "cli"
    rc = main(
        [
            "export",
            str(run_dir),
            "--format",
            "qgc,kml",
            "--origin",
            *map(str, ORIGIN),
            "--heading",
            "30",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    assert (out / "mission.plan").is_file() and (out / "mission.kml").is_file()
    assert "min" in capsys.readouterr().out
    rc = main(
        [
            "export",
            str(run_dir),
            "--format",
            "qgc",
            "--origin",
            "95",
            "8",
            "400",
            "--out",
            str(tmp_path / "bad"),
        ]
    )
    assert rc == 2
    assert "latitude" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_the_report_shows_the_flight_time_and_the_sorties(run_dir, tmp_path):
    from nbvkit.export import estimate_flight
    from nbvkit.report import FLIGHT_BEGIN, FLIGHT_END, flight_section

    sec = flight_section(estimate_flight(run_dir))
    assert sec.startswith(FLIGHT_BEGIN) and "estimated flight time" in sec
    report, manifest = run_dir / "report.html", run_dir / "manifest.json"
    original = report.read_bytes() if report.is_file() else None
    listed = manifest.read_bytes()  # the export lists the report it updates
    report.write_text(f"<html><body>{sec}</body></html>")
    try:
        s = export_mission(run_dir, "csv", ORIGIN, HEADING, tmp_path / "x", flight_time_min=3.0)
        assert s["report_updated"]
        text = (run_dir / "report.html").read_text()
        assert text.count(FLIGHT_BEGIN) == 1 and text.count(FLIGHT_END) == 1
        assert "sortie 1" in text and "#1f77b4" in text
    finally:  # the run folder as it was, complete, for the tests after this one
        if original is None:
            report.unlink()
        else:
            report.write_bytes(original)
        manifest.write_bytes(listed)


def test_a_blocked_climb_below_the_start_moves_the_launch_point(run_dir, monkeypatch):
    from nbvkit import flight as plan  # the flight-time model, the sorties
    from nbvkit import flight_home as home  # the launch point, the ways home

    fl = read_run(run_dir)
    occ = home.load_map(fl)
    s = fl.start
    real = home._column_clear
    # pretend the structure stands over the ground below the start (as a wing can)
    blocked = lambda f, m, x, y, top: (  # noqa: E731
        np.hypot(x - s[0], y - s[1]) > 1.0 and real(f, m, x, y, top)
    )
    monkeypatch.setattr(home, "_column_clear", blocked)
    home.find_launch(fl, occ, plan.FlightModel())
    assert np.hypot(*(fl.launch[:2] - s[:2])) > 1.0 and fl.launch[2] == s[2]
    assert np.allclose(fl.launch_path[0], fl.launch) and np.allclose(fl.launch_path[-1], s)
    assert np.allclose(fl.home, [*fl.launch[:2], fl.workspace["bounds_min"][2]])
    for a, b in zip(fl.launch_path[:-1], fl.launch_path[1:]):
        assert _core.segment_is_free(occ, a, b, fl.radius)
    sp = plan.SortiePlanner(
        fl, plan.FlightModel(), home.ReturnPaths(fl, plan.FlightModel(), occ, [])
    )
    w = sp.whole().waypoints
    assert w[0].action == "takeoff" and np.allclose(w[0].xyz, fl.launch)
    assert w[-1].action == "home" and np.allclose(w[-1].xyz, fl.launch)
    monkeypatch.setattr(home, "_column_clear", lambda *a: False)
    with pytest.raises(ValueError, match="no launch point"):
        home.find_launch(fl, occ, plan.FlightModel())


# ------------------------------------------------------------------ anywhere on the Earth
@pytest.mark.parametrize(
    "origin, heading", [((89.85, -120.0, 0.0), 250.0), ((-33.9, 151.2, 5.0), 100.0)]
)
def test_headings_are_bearings_from_the_local_north(run_dir, tmp_path, origin, heading):
    """Near a pole the meridians converge fast: 16.7 km from the north pole the north of a
    point 50 m east of the origin is 0.17 degrees off the origin's."""
    export_mission(run_dir, "csv,qgc", origin, heading, tmp_path / "ex")
    fl = read_run(run_dir)
    frame = GeoFrame(*origin, heading)
    rows = [r for r in _csv(tmp_path / "ex" / "mission.csv") if int(r["flight_row"]) >= 0]
    worst = 0.0
    for r in rows:
        i = int(r["flight_row"])
        want = _azimuth_along(fl.xyz[i], fl.yaw[i], frame)
        worst = max(worst, abs((float(r["heading_deg"]) - want + 180) % 360 - 180))
    assert worst < 5e-4 + 1e-9  # the CSV's 3 decimals
    lines = (tmp_path / "ex" / "mission.waypoints").read_text().splitlines()[1:]
    photos = _fly_ardupilot([ln.split("\t") for ln in lines], speed=5.0)
    caps = [r for r in rows if r["action"] in ("view", "frame")]
    np.testing.assert_allclose(
        [p["heading"] for p in photos], [float(r["heading_deg"]) for r in caps], atol=5e-4 + 1e-9
    )


def test_angles_are_written_without_numerical_noise(exported):
    out, _ = exported
    items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
    angles = [it["params"][k] for it in items if it["command"] == 1000 for k in (0, 1)]
    angles += [it["params"][3] for it in items if it["command"] in (16, 22)]
    angles = [v for v in angles if v is not None]
    assert angles and all(v == 0 or abs(v) >= 1e-6 for v in angles)
    assert all(math.copysign(1.0, v) > 0 for v in angles if v == 0)  # no -0.0
    # the captures look straight ahead of the nose, level: gimbal pitch and yaw exactly 0
    gimbal = [it["params"][:2] for it in items if it["command"] == 1000]
    assert gimbal and all(g == [0.0, 0.0] for g in gimbal)


def test_numbers_are_written_without_a_negative_zero(tmp_path):
    """Numerical noise below a field's last decimal (-1e-12 degrees, -1e-7 m) is written as 0,
    never as -0: in the .waypoints, CSV, KML and DJI route files."""
    import re

    from nbvkit.export import writers
    from nbvkit.export.wpml import write_wpml_kmz

    assert writers._f(-1e-7, 3) == "0.000" and writers._f(-0.0, 6) == "0.000000"
    assert writers._f(-0.4, 0) == "0" and writers._f(-0.0006, 3) == "-0.001"
    assert writers._f(-12.5, 1) == "-12.5" and writers._f(-1e-12, 9) == "0.000000000"
    tiny = np.full(4, -1e-12)
    g = writers.GeoWaypoints(
        lat=tiny,
        lon=tiny,
        alt=np.array([10.0, 10.0, -1e-7, 10.0]),
        rel_alt=np.array([10.0, 10.0, -1e-7, 10.0]),
        heading=np.array([0.0, 90.0, 359.9999999, 0.0]),
        gimbal_pitch=np.array([0.0, -1e-7, -30.0, 0.0]),
        gimbal_yaw=np.zeros(4),
        action=["takeoff", "view", "view", "home"],
        stage=["", "nbv", "nbv", ""],
        row=[-1, 1, 2, -1],
        number=[0, 1, 2, 0],
        home=(-1e-12, -1e-12, -1e-7),
        speed=5.0,
        hover_s=2.0,
        altitude_ref="ellipsoid",
        name="t",
        ell_alt=np.array([10.0, 10.0, -1e-7, 10.0]),
        home_ell=-1e-7,
    )
    writers.write_qgc_wpl(g, tmp_path / "t.waypoints")
    writers.write_csv(g, tmp_path / "t.csv")
    writers.write_kml(g, tmp_path / "t.kml")
    write_wpml_kmz(g, tmp_path / "t.kmz")
    texts = [(tmp_path / n).read_text() for n in ("t.waypoints", "t.csv", "t.kml")]
    with zipfile.ZipFile(tmp_path / "t.kmz") as z:
        texts += [z.read(n).decode() for n in z.namelist()]
    for text in texts:
        numbers = re.findall(r"(?<![\w.])-\d+(?:\.\d+)?", text)
        assert numbers and all(float(v) != 0 for v in numbers), numbers


def test_split_antimeridian_cuts_a_line_where_it_crosses():
    from nbvkit.export.writers import split_antimeridian

    west = split_antimeridian([[-179.9, 0.0, 0.0], [179.9, 1.0, 10.0]])
    assert west == [
        [[-179.9, 0.0, 0.0], [-180.0, 0.5, 5.0]],
        [[180.0, 0.5, 5.0], [179.9, 1.0, 10.0]],
    ]
    east = split_antimeridian([[179.0, 10.0, 0.0], [179.5, 10.0, 0.0], [-179.5, 12.0, 4.0]])
    assert east == [
        [[179.0, 10.0, 0.0], [179.5, 10.0, 0.0], [180.0, 11.0, 2.0]],
        [[-180.0, 11.0, 2.0], [-179.5, 12.0, 4.0]],
    ]
    assert split_antimeridian([[10.0, 0.0, 0.0], [11.0, 1.0, 0.0]]) == [
        [[10.0, 0.0, 0.0], [11.0, 1.0, 0.0]]
    ]


def test_geojson_flight_over_the_antimeridian_is_a_multilinestring(run_dir, tmp_path):
    out = tmp_path / "ex"
    export_mission(run_dir, "geojson,csv", (-16.5, 180.0, 10.0), 45.0, out)
    gj = json.loads((out / "mission.geojson").read_text())
    line = gj["features"][0]["geometry"]
    assert line["type"] == "MultiLineString" and len(line["coordinates"]) >= 2
    rows = _csv(out / "mission.csv")
    flown = []
    for part in line["coordinates"]:
        lons = [c[0] for c in part]
        assert all(-180 <= x <= 180 for x in lons)
        assert all(abs(a - b) <= 180 for a, b in zip(lons, lons[1:]))  # no part crosses
        flown += [c for c in part if abs(c[0]) != 180.0]
    for a, b in zip(line["coordinates"], line["coordinates"][1:]):
        assert abs(a[-1][0]) == 180.0 and b[0][0] == -a[-1][0]  # cut on the antimeridian
        assert a[-1][1:] == b[0][1:]
    want = [[float(r[k]) for k in ("longitude_deg", "latitude_deg", "altitude_m")] for r in rows]
    flown, want = np.array(flown), np.array(want)
    assert flown.shape == want.shape
    np.testing.assert_allclose(flown[:, :2], want[:, :2], atol=1e-8)
    # heights above the ellipsoid: the CSV's AMSL altitudes + the geoid height at the origin
    n = _egm96(-16.5, 180.0)
    np.testing.assert_allclose(flown[:, 2], want[:, 2] + n, atol=5e-4 + 1e-9)  # CSV: 3 decimals


def test_wpml_heights_from_an_ellipsoidal_origin_and_without_a_geoid(
    run_dir, tmp_path, monkeypatch
):
    import sys

    from lxml import etree

    monkeypatch.setitem(sys.modules, "pyproj", None)  # no geoid model at hand
    with pytest.raises(ValueError, match="EGM96 geoid.*--altitude-ref ellipsoid"):
        export_mission(run_dir, "wpml", ORIGIN, HEADING, tmp_path / "amsl")
    assert not (tmp_path / "amsl").exists()
    out = tmp_path / "ell"
    export_mission(run_dir, "wpml,csv", ORIGIN, HEADING, out, altitude_ref="ellipsoid")
    with zipfile.ZipFile(out / "mission.kmz") as z:
        tk = etree.fromstring(z.read("wpmz/template.kml"))
    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    ell = [float(e.text) for e in tk.iterfind(".//wpml:ellipsoidHeight", ns)]
    rows = _csv(out / "mission.csv")
    np.testing.assert_allclose(ell, [float(r["altitude_m"]) for r in rows], atol=1e-3)
    ref = tk.findtext("k:Document/wpml:missionConfig/wpml:takeOffRefPoint", namespaces=ns)
    s = json.loads((out / "export.json").read_text())
    home = GeoFrame(*ORIGIN, HEADING, "ellipsoid").to_geodetic(np.array([s["launch_point_mesh"]]))
    assert float(ref.split(",")[2]) == pytest.approx(float(home[2][0]), abs=1e-3)


def test_a_turn_at_a_capture_is_held_until_done_before_the_photo():
    """Two views 1 m apart, the second turned 150 degrees: the ArduPilot file holds the second
    until the turn (5 s at 30 deg/s) and the settle (1 s) are done."""
    from nbvkit.export import writers

    lat = np.array([47.0, 47.0, 47.000009, 47.000009])
    lon = np.array([8.0, 8.0, 8.0, 8.0])
    g = writers.GeoWaypoints(
        lat=lat,
        lon=lon,
        alt=np.full(4, 410.0),
        rel_alt=np.full(4, 10.0),
        heading=np.array([0.0, 0.0, 150.0, 150.0]),
        gimbal_pitch=np.array([0.0, -30.0, -10.0, 0.0]),
        gimbal_yaw=np.zeros(4),
        action=["takeoff", "view", "view", "home"],
        stage=["", "nbv", "nbv", ""],
        row=[-1, 1, 2, -1],
        number=[0, 1, 2, 0],
        home=(47.0, 8.0, 400.0),
        speed=5.0,
        hover_s=2.0,
        altitude_ref="amsl",
        name="t",
    )
    hold, rest = writers.capture_holds(g, ardupilot=True)
    assert list(hold) == [0.0, 7.0, 6.0, 0.0]  # 180 deg after the take-off; 150 deg
    assert list(rest) == [0.0, 0.0, 0.0, 0.0]
    # the leg's time is not taken off the turn (the copter may fly faster than --speed): 10 m
    # apart (2 s at 5 m/s), the hold is still ceil(150 / 30 + 1) = 6 s
    far = writers.GeoWaypoints(**{**g.__dict__, "lat": np.array([47.0, 47.0, 47.00009, 47.00009])})
    assert list(writers.capture_holds(far, ardupilot=True)[0]) == [0.0, 7.0, 6.0, 0.0]
    px4_hold, px4_rest = writers.capture_holds(g, ardupilot=False)
    assert list(px4_hold) == [0.0, 1.0, 1.0, 0.0] and list(px4_rest) == [0.0, 1.0, 1.0, 0.0]
    items = writers.mavlink_items(g, ardupilot=True)
    rows = [["0", "1", "0", "16"] + ["0"] * 8]
    rows += [[str(i), "0", str(it["frame"]), str(it["command"])] for i, it in enumerate(items, 1)]
    for r, it in zip(rows[1:], items):
        r += [f"{0.0 if v is None else float(v):.9f}" for v in it["params"]] + ["1"]
    photos = _fly_ardupilot(rows, speed=5.0)
    assert [p["seq"] for p in photos] == [1, 2]  # numbered without GeoWaypoints.seq too
    assert [p["heading"] for p in photos] == [0.0, 150.0]
    assert [p["pitch"] for p in photos] == [-30.0, -10.0]
    for p in photos:
        assert p["t"] - max(p["arrive"], p["yaw_t"]) >= 1.0 - 1e-9


# ------------------------------------------------------------------ what the files command
def _stop_s(d, v, a=2.5):
    """Seconds to fly d metres from a stop to a stop at most at v, accelerating and braking at a
    (2.5 m/s^2: ArduPilot's WPNAV_ACCEL): v is reached after v^2 / (2a) metres."""
    if d >= v * v / a:
        return (d - v * v / a) / v + 2 * v / a
    return 2 * math.sqrt(d / a)


def _nav_legs_s(points, speed, climb):
    """Seconds of straight legs between (lat, lon, rel_alt) points at the time model's speeds
    (vertically _vertical_s), stopping at each (a DJI route stops at every waypoint; an
    autopilot at most there), horizontal distances from pymap3d (east, north)."""
    import pymap3d

    t = 0.0
    for a, b in zip(points, points[1:]):
        e, n, _ = pymap3d.geodetic2enu(b[0], b[1], 0.0, a[0], a[1], 0.0)
        t += max(_stop_s(math.hypot(e, n), speed), _vertical_s(b[2] - a[2], climb))
    return t


def _vertical_s(dz, climb):
    """Seconds of a vertical leg dz m (up > 0) from a stop to a stop: up at the model's climb
    rate, down never faster than the autopilots' default descent speed (ArduCopter's
    WPNAV_SPEED_DN 150 cm/s, PX4's MPC_Z_V_AUTO_DN 1.5 m/s)."""
    return _stop_s(dz, climb) if dz >= 0 else _stop_s(-dz, min(climb, 1.5))


def _descent_s(h, speed_at, step=1e-3):
    """Seconds to come down h metres at speed_at(height) m/s, summed in `step` m slices."""
    z = np.arange(0.0, h, step) + step / 2
    return float(np.sum(np.minimum(step, h - z + step / 2) / np.vectorize(speed_at)(z)))


def _ardupilot_rtl_s(h, climb):
    """ArduCopter's return to launch from h m straight above home, its default parameters
    (ardupilot.org Copter parameter list): the climb of mode_rtl.cpp's compute_return_target at
    no distance from home, max(h, min(max(h, RTL_ALT 15 m), h + RTL_ABS_MIN_CLIMB 2.5 m)), at
    WPNAV_SPEED_UP 2.5 m/s; RTL_LOIT_TIME 5000 ms, then the landing at WPNAV_SPEED_DN 150 cm/s
    (LAND_SPEED_HIGH 0) above LAND_ALT_LOW 1000 cm, LAND_SPEED 50 cm/s below; never faster than
    the model's climb rate."""
    top = max(h, min(max(h, 15.0), h + 2.5))
    return (
        _stop_s(top - h, min(climb, 2.5))
        + 5.0
        + _descent_s(top, lambda z: min(climb, 1.5 if z > 10.0 else 0.5))
    )


def _px4_rtl_s(h, climb):
    """PX4's return to launch from h m above home, its defaults (RTL_LAND_DELAY 0 s): the landing
    speed MPC_Z_V_AUTO_DN 1.5 m/s above MPC_LAND_ALT1 10 m, MPC_LAND_SPEED 0.7 m/s below
    MPC_LAND_ALT2 5 m, interpolated between (FlightTaskAuto's math::gradual)."""
    return _descent_s(h, lambda z: min(climb, float(np.interp(z, [5.0, 10.0], [0.7, 1.5]))))


def _waypoints_time(path, speed=5.0, climb=2.0):
    """A .waypoints mission's seconds read back: the take-off (WPNAV_SPEED_UP 2.5 m/s at most),
    the legs between its navigation items, every hold (NAV_WAYPOINT p1, whole seconds) and
    NAV_DELAY, the return to launch (_ardupilot_rtl_s)."""
    rows = [ln.split("\t") for ln in path.read_text().splitlines()[1:]]
    items = [(int(r[3]), [float(v) for v in r[4:11]]) for r in rows[1:]]
    nav = [(p[4], p[5], p[6]) for c, p in items if c in (16, 22)]
    waits = sum(int(p[0]) for c, p in items if c == 16) + sum(p[0] for c, p in items if c == 93)
    assert int(rows[-1][3]) == 20  # NAV_RETURN_TO_LAUNCH
    up, down = _stop_s(nav[0][2], min(climb, 2.5)), _ardupilot_rtl_s(nav[-1][2], climb)
    return up + _nav_legs_s(nav, speed, climb) + waits + down


def _kmz_time(path, speed=5.0, climb=2.0):
    """A DJI route's seconds read back from waylines.wpml: the climb, the legs, every hover, and
    every rotateYaw at 30 deg/s from the farthest heading the aircraft may arrive with: the last
    rotateYaw's or a waypointHeadingAngle since (a turn over a short leg may not be done), any
    (180 degrees) after a followWayline point (the leg flown facing its course) or the
    take-off."""
    from lxml import etree

    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    with zipfile.ZipFile(path) as z:
        root = etree.fromstring(z.read("wpmz/waylines.wpml"))
    pts, t, may_face = [], 0.0, None  # the headings it may face; None: any
    for pm in root.iterfind(".//k:Placemark", ns):
        lon, lat = map(float, pm.findtext("k:Point/k:coordinates", namespaces=ns).split(","))
        pts.append((lat, lon, float(pm.findtext("wpml:executeHeight", namespaces=ns))))
        for a in pm.iterfind("wpml:actionGroup/wpml:action", ns):
            f = a.findtext("wpml:actionActuatorFunc", namespaces=ns)
            if f == "hover":
                t += float(a.findtext(".//wpml:hoverTime", namespaces=ns))
            elif f == "rotateYaw":
                h = float(a.findtext(".//wpml:aircraftHeading", namespaces=ns))
                turns = [abs((h - y + 180) % 360 - 180) for y in may_face or []]
                t += (max(turns) if may_face else 180.0) / 30.0
                may_face = [h]
        mode = pm.findtext("wpml:waypointHeadingParam/wpml:waypointHeadingMode", namespaces=ns)
        if mode == "followWayline":
            may_face = None
        elif may_face is not None:
            a = pm.findtext("wpml:waypointHeadingParam/wpml:waypointHeadingAngle", namespaces=ns)
            may_face.append(float(a))
    up, down = _vertical_s(pts[0][2], climb), _vertical_s(-pts[-1][2], climb)
    return up + _nav_legs_s(pts, speed, climb) + t + down


def _plan_time(path, speed=5.0, climb=2.0):
    items = json.loads(path.read_text())["mission"]["items"]
    nav = [tuple(it["params"][4:7]) for it in items if it["command"] in (16, 22)]
    waits = sum(it["params"][0] for it in items if it["command"] in (16, 93))
    assert items[-1]["command"] == 20  # NAV_RETURN_TO_LAUNCH
    # the take-off at MPC_TKO_SPEED (1.5 m/s) at most; the return to launch (_px4_rtl_s)
    up, down = _stop_s(nav[0][2], min(climb, 1.5)), _px4_rtl_s(nav[-1][2], climb)
    return up + _nav_legs_s(nav, speed, climb) + waits + down


def test_no_sortie_file_waits_past_the_battery(run_dir, tmp_path):
    """The reviewer's case (--flight-time 0.6 --reserve 0, 7 s more since ArduPilot's return
    climbs 2.5 m first): each sortie's .waypoints, .plan and .kmz, read back and flown at the
    model's speeds with every hold, delay, hover and turn they command, fit the 43 s; export.json
    reports each file's time (the longest is the sortie's)."""
    out = tmp_path / "b"
    s = export_mission(
        run_dir, "qgc,wpml,csv", ORIGIN, HEADING, out, flight_time_min=43 / 60, reserve_pct=0
    )
    assert len(s["sorties"]) >= 2
    turns_held = False
    for srt in s["sorties"]:
        name = f"sortie_{srt['sortie']:02d}"
        got = {
            "ardupilot": _waypoints_time(out / f"{name}.waypoints"),
            "px4": _plan_time(out / f"{name}.plan"),
            "dji": _kmz_time(out / f"{name}.kmz"),
        }
        for k, v in got.items():
            assert v <= 43.0 + 0.05, f"{name}.{k}: {v:.1f} s in a 43 s battery"
        by = srt["time_s_by_file"]
        for k, v in got.items():
            assert v <= by[k] + 0.05, (name, k, v, by[k])
        assert srt["time_s"] == max(by.values()) <= 43.0
        assert got["ardupilot"] >= got["px4"] - 1e-3
        turns_held |= got["ardupilot"] > got["px4"] + 0.5  # the turns' holds counted
    assert turns_held
    # the whole mission's waits per file in export.json too
    assert set(s["mission"]["time_s_by_file"]) == {"px4", "ardupilot", "dji"}


def test_a_dji_export_is_timed_and_split_by_its_own_file(run_dir, tmp_path):
    """A .kmz alone was timed and split by the slowest mission file, the ArduPilot one it does
    not write: its headline time was that file's and it flew more batteries than needed. Each
    sortie's .kmz, read back, fits; its time is the .kmz's."""
    both = export_mission(run_dir, "qgc,wpml", ORIGIN, HEADING, tmp_path / "a",
                          flight_time_min=43 / 60, reserve_pct=0)  # fmt: skip
    dji = export_mission(run_dir, "wpml", ORIGIN, HEADING, tmp_path / "b",
                         flight_time_min=43 / 60, reserve_pct=0)  # fmt: skip
    assert set(dji["mission"]["time_s_by_file"]) == {"dji"}
    assert dji["mission"]["time_s"] == dji["mission"]["time_s_by_file"]["dji"]
    assert dji["mission"]["time_s"] < both["mission"]["time_s"]  # ArduPilot's holds not counted
    assert len(dji["sorties"]) <= len(both["sorties"])
    for srt in dji["sorties"]:
        t = _kmz_time(tmp_path / "b" / f"sortie_{srt['sortie']:02d}.kmz")
        assert t <= srt["time_s"] + 0.05 and srt["time_s"] <= 43.0


def test_ardupilot_file_sets_the_speed_after_the_first_waypoint_and_no_nan(exported):
    """ArduCopter before 4.5 drops a DO_CHANGE_SPEED run during the take-off (issue #21080): the
    speed is set again after the first NAV_WAYPOINT. Every parameter is a number (AP_Mission's
    sanity_check_params refuses NaN), the gimbal's rates 0 (ArduPilot reads none when both
    angles are set); the .plan is PX4's (firmwareType 12) and keeps them NaN (unset)."""
    out, _ = exported
    rows = [ln.split("\t") for ln in (out / "mission.waypoints").read_text().splitlines()[1:]]
    cmds = [int(r[3]) for r in rows]
    first_wp = cmds.index(16, 1)
    assert cmds[2] == 178 and 178 in cmds[first_wp + 1 :]
    after = [float(v) for v in rows[cmds.index(178, first_wp + 1)][4:7]]
    assert after == [1.0, 5.0, -1.0]
    assert all(math.isfinite(float(v)) for r in rows for v in r[4:11])
    gimbal = [r for r in rows if r[3] == "1000"]
    assert gimbal and all(float(r[6]) == 0.0 and float(r[7]) == 0.0 for r in gimbal)
    plan = json.loads((out / "mission.plan").read_text())["mission"]
    assert plan["firmwareType"] == 12
    pg = [it for it in plan["items"] if it["command"] == 1000]
    assert pg and all(it["params"][2] is None and it["params"][3] is None for it in pg)


def test_hover_0_still_stops_and_settles_at_every_view(run_dir, tmp_path):
    from lxml import etree

    out = tmp_path / "h0"
    export_mission(run_dir, "qgc,wpml,csv", ORIGIN, HEADING, out, hover_s=0.0)
    rows = [ln.split("\t") for ln in (out / "mission.waypoints").read_text().splitlines()[1:]]
    views = [r for r in _csv(out / "mission.csv") if r["action"] == "view"]
    items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
    caps = [k for k, it in enumerate(items) if it["command"] == 2000]
    plan_holds = [items[k - 1]["params"][0] for k in caps]
    wpl = [int(r[3]) for r in rows]
    wpl_holds = [float(rows[k - 1][4]) for k in range(len(rows)) if wpl[k] == 2000]
    kinds = [r["action"] for r in _csv(out / "mission.csv") if r["action"] in ("view", "frame")]
    assert len(plan_holds) == len(kinds) == len(wpl_holds)
    for kind, ph, wh in zip(kinds, plan_holds, wpl_holds):
        if kind == "view":
            assert ph >= 1.0 and wh >= 1.0  # ArduCopter stops only when the hold is > 0
    ns = {"wpml": "http://www.dji.com/wpmz/1.0.2"}
    with zipfile.ZipFile(out / "mission.kmz") as z:
        root = etree.fromstring(z.read("wpmz/waylines.wpml"))
    settles = 0
    for ag in root.iterfind(".//wpml:actionGroup", ns):
        funcs = [a.findtext("wpml:actionActuatorFunc", namespaces=ns) for a in ag]
        funcs = [f for f in funcs if f]
        if "hover" in funcs:
            assert funcs.index("hover") < funcs.index("takePhoto")
            settles += 1
    assert settles == len(views)


def test_dji_route_values_in_their_ranges_and_rth_above_the_structure(exported, run_dir):
    from lxml import etree

    out, _ = exported
    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    ws = json.loads((run_dir / "summary.json").read_text())["workspace"]
    launch = json.loads((out / "export.json").read_text())["launch_point_mesh"]
    top = ws["bounds_max"][2] - launch[2]
    with zipfile.ZipFile(out / "mission.kmz") as z:
        for n in z.namelist():
            root = etree.fromstring(z.read(n))
            # waypointTurnDampingDist's range is (0, segment]; not needed with a stop at points
            for d in root.iterfind(".//wpml:waypointTurnDampingDist", ns):
                assert float(d.text) > 0
            rth = float(root.findtext(".//wpml:globalRTHHeight", namespaces=ns))
            heights = [float(e.text) for e in root.iterfind(".//wpml:executeHeight", ns)]
            heights += [float(e.text) for e in root.iterfind(".//k:Placemark/wpml:height", ns)]
            assert rth >= top + 5.0 and rth >= max(heights) + 5.0 and 20.0 <= rth <= 500.0


def test_dji_return_height_within_dji_range_or_refused():
    """globalRTHHeight: 10 m above the flight and its workspace, at least 20 m (a 3 m flight:
    13 m was written, below the 20 m DJI's aircraft take); a flight whose return would pass
    500 m is refused, not capped below its top."""
    from types import SimpleNamespace

    from nbvkit.export.wpml import rth_rel_alt

    low = SimpleNamespace(rel_alt=np.array([1.0, 3.0]), workspace_top_rel_alt=4.0)
    assert rth_rel_alt(low) == 20.0
    mid = SimpleNamespace(rel_alt=np.array([1.0, 43.0]), workspace_top_rel_alt=40.0)
    assert rth_rel_alt(mid) == 53.0
    high = SimpleNamespace(rel_alt=np.array([1.0, 495.0]), workspace_top_rel_alt=None)
    with pytest.raises(ValueError, match="495.0 m above the take-off point.*500 m"):
        rth_rel_alt(high)


def test_mavlink_home_is_above_mean_sea_level_from_an_ellipsoidal_origin(run_dir, tmp_path):
    """The .waypoints home row (MAV_FRAME_GLOBAL), the .plan's plannedHomePosition and the KML's
    absolute altitudes are AMSL:
    from the same place given as an ellipsoidal height (AMSL + the EGM96 geoid height, 47.3 to
    47.4 m round Zurich: NGA's EGM96 tables) they are the AMSL export's."""
    from nbvkit.export.georef import egm96_geoid_height

    n = float(egm96_geoid_height([ORIGIN[0]], [ORIGIN[1]])[0])
    assert 47.2 < n < 47.5
    from lxml import etree

    homes, kml = [], []
    for ref, alt in (("amsl", ORIGIN[2]), ("ellipsoid", ORIGIN[2] + n)):
        out = tmp_path / ref
        export_mission(run_dir, "qgc,kml", ORIGIN[:2] + (alt,), HEADING, out, altitude_ref=ref)
        home_row = (out / "mission.waypoints").read_text().splitlines()[1].split("\t")
        plan = json.loads((out / "mission.plan").read_text())["mission"]
        homes.append((float(home_row[10]), plan["plannedHomePosition"][2]))
        # KML's absolute: "altitude relative to sea level" (OGC 07-147r2), whatever the origin
        root = etree.parse(str(out / "mission.kml"))
        text = root.findtext(".//{http://www.opengis.net/kml/2.2}coordinates")
        kml.append(np.array([[float(v) for v in c.split(",")] for c in text.split()]))
    assert homes[1][0] == pytest.approx(homes[0][0], abs=0.02)
    assert homes[1][1] == pytest.approx(homes[0][1], abs=0.02)
    assert kml[0].shape == kml[1].shape and len(kml[0]) > 10
    assert np.abs(kml[1][:, 2] - kml[0][:, 2]).max() < 0.02  # not 47.3 m higher


def test_a_sortie_resuming_at_a_plain_point_after_a_transit_leg_turns_before_its_photo(
    run_dir, tmp_path
):
    """A battery split where sorties resume at a plain profile point straight after the transit
    leg out (the audit's case: the heading commanded there cannot be reached over a leg of a few
    centimetres): flown through ArduPilot's rules from the course the copter arrives with, every
    photo is taken facing its heading (and a view settled 1 s after the turn); every sortie's
    files, re-timed with the turns from the heading the vehicle may arrive with, fit the
    battery."""
    usable = 46.0
    out = tmp_path / "b"
    s = export_mission(
        run_dir, "qgc,wpml,csv", ORIGIN, HEADING, out, flight_time_min=usable / 60, reserve_pct=0
    )
    resumed = 0
    for srt in s["sorties"]:
        name = f"sortie_{srt['sortie']:02d}"
        rows = _csv(out / f"{name}.csv")
        first = next(k for k, r in enumerate(rows) if int(r["flight_row"]) >= 0)
        resumed += rows[first]["action"] == "waypoint" and rows[first - 1]["action"] == "transit"
        wpl = [ln.split("\t") for ln in (out / f"{name}.waypoints").read_text().splitlines()[1:]]
        caps = [r for r in rows if r["action"] in ("view", "frame")]
        photos = _fly_ardupilot(wpl, speed=5.0)
        assert len(photos) == len(caps)
        for p, r in zip(photos, caps):
            assert p["heading"] is not None, f"{name} row {r['flight_row']}: photo mid-turn"
            assert abs((p["heading"] - float(r["heading_deg"]) + 180) % 360 - 180) < 1e-3
            if r["action"] == "view":
                assert p["t"] - max(p["arrive"], p["yaw_t"]) >= 1.0 - 1e-9
        got = {
            "ardupilot": _waypoints_time(out / f"{name}.waypoints"),
            "px4": _plan_time(out / f"{name}.plan"),
            "dji": _kmz_time(out / f"{name}.kmz"),
        }
        for k, v in got.items():
            assert v <= usable + 0.05, f"{name}.{k}: {v:.1f} s in a {usable:g} s battery"
            assert v <= srt["time_s_by_file"][k] + 0.05, (name, k, v, srt["time_s_by_file"])
    assert resumed >= 1  # the case is there


def _scaled_run(run_dir, dst, factor):
    """A copy of the run folder with its flight and workspace stretched `factor` times
    horizontally (no map: the way back retraces the flight)."""
    import shutil

    from nbvkit.runfolder import write_manifest

    shutil.copytree(run_dir, dst)
    (dst / "map.ot").unlink()
    (dst / "manifest.json").unlink()
    rows = _read_flight(dst)
    for r in rows:
        r["x"], r["y"] = repr(float(r["x"]) * factor), repr(float(r["y"]) * factor)
    with open(dst / "flight.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    summary = json.loads((dst / "summary.json").read_text())
    for k in ("bounds_min", "bounds_max"):
        b = summary["workspace"][k]
        summary["workspace"][k] = [b[0] * factor, b[1] * factor, b[2]]
    (dst / "summary.json").write_text(json.dumps(summary))
    write_manifest(dst)
    return dst


def test_relative_and_absolute_altitudes_are_of_the_same_point_on_a_large_site(run_dir, tmp_path):
    """The flight stretched 400 times (points up to several km from the origin, where the
    Earth's curvature puts the local tangent plane metres above the ellipsoid): in every format
    the absolute altitude less the launch point's equals the relative altitude (within the
    files' rounding), and the absolute altitude is the mesh point's (pymap3d)."""
    from lxml import etree

    big = _scaled_run(run_dir, tmp_path / "big", 400.0)
    out = tmp_path / "ex"
    s = export_mission(big, "qgc,wpml,kml,geojson,csv", ORIGIN, HEADING, out)
    rows = _csv(out / "mission.csv")
    alt = np.array([float(r["altitude_m"]) for r in rows])
    rel = np.array([float(r["rel_altitude_m"]) for r in rows])
    home = json.loads((out / "mission.plan").read_text())["mission"]["plannedHomePosition"][2]
    # the absolute altitudes are the mesh points' (pymap3d's local tangent plane)
    flight = np.array([[float(r[k]) for k in "xyz"] for r in _read_flight(big)])
    on = [k for k, r in enumerate(rows) if int(r["flight_row"]) >= 0]
    xyz = _to_mesh(
        *(
            np.array([float(rows[k][c]) for k in on])
            for c in ("latitude_deg", "longitude_deg", "altitude_m")
        )
    )
    assert np.abs(xyz - flight[[int(rows[k]["flight_row"]) for k in on]]).max() < 0.01
    launch = np.array(s["launch_point_mesh"])
    lift = np.array(
        [alt[k] - home - (flight[int(rows[k]["flight_row"]), 2] - launch[2]) for k in on]
    )
    assert np.abs(lift).max() > 1.0  # metres of curvature: the case is there
    # CSV
    assert np.abs(alt - home - rel).max() <= 1.5e-3
    # .plan (PX4) and .waypoints (ArduPilot): frame 3, relative to home (their home: AMSL)
    nav = [
        it
        for it in json.loads((out / "mission.plan").read_text())["mission"]["items"]
        if it["frame"] == 3
    ]
    np.testing.assert_allclose([home + it["params"][6] for it in nav], alt, atol=1.5e-3)
    wpl = [ln.split("\t") for ln in (out / "mission.waypoints").read_text().splitlines()[1:]]
    wp_home = float(wpl[0][10])
    wp_nav = [float(r[10]) for r in wpl[1:] if r[2] == "3"]
    np.testing.assert_allclose(wp_home + np.array(wp_nav), alt, atol=2e-3)
    # DJI: ellipsoidHeight - the take-off point's ellipsoidal height = height (both files)
    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    with zipfile.ZipFile(out / "mission.kmz") as z:
        tk = etree.fromstring(z.read("wpmz/template.kml"))
        wl = etree.fromstring(z.read("wpmz/waylines.wpml"))
    ref = tk.findtext("k:Document/wpml:missionConfig/wpml:takeOffRefPoint", namespaces=ns)
    h0 = float(ref.split(",")[2])
    ell = np.array([float(e.text) for e in tk.iterfind(".//k:Placemark/wpml:ellipsoidHeight", ns)])
    hgt = np.array([float(e.text) for e in tk.iterfind(".//k:Placemark/wpml:height", ns)])
    exe = np.array([float(e.text) for e in wl.iterfind(".//k:Placemark/wpml:executeHeight", ns)])
    assert np.abs(ell - h0 - hgt).max() <= 1.5e-3 and np.abs(exe - hgt).max() <= 1e-9
    np.testing.assert_allclose(hgt, rel, atol=1e-9)
    # GeoJSON (heights above the ellipsoid) less the take-off point's: rel_alt_m
    gj = json.loads((out / "mission.geojson").read_text())
    for f in gj["features"][1:]:
        z = f["geometry"]["coordinates"][2]
        assert abs(z - h0 - f["properties"]["rel_alt_m"]) <= 1e-3
    # KML: absolute (the CSV's) and, per capture, the height above the launch point
    km = etree.fromstring((out / "mission.kml").read_bytes())
    for pm in km.iterfind(".//k:Folder/k:Placemark", ns):
        a = float(pm.findtext("k:Point/k:coordinates", namespaces=ns).split(",")[2])
        r = float(pm.findtext("k:description", namespaces=ns).split(", ")[-1].split(" m ")[0])
        assert abs(a - home - r) <= 6e-3


def test_dji_hover_times_are_above_0_as_written(run_dir, tmp_path):
    """--hover 1.0001: the rest of the hover after the 1 s settle is 0.0001 s, 0.000 at the
    file's millisecond: DJI's hoverTime must be > 0, so no such hover is written; nor is a
    MAVLink NAV_DELAY of 0.0001 s (every format waits to the millisecond alike), while 7.25 s
    writes a rest of 6.25 s in each."""
    from lxml import etree

    ns = {"wpml": "http://www.dji.com/wpmz/1.0.2"}
    for hover, rest in ((1.0001, None), (7.25, 6.25)):
        out = tmp_path / f"h{hover}"
        export_mission(run_dir, "wpml,qgc", ORIGIN, HEADING, out, hover_s=hover)
        with zipfile.ZipFile(out / "mission.kmz") as z:
            for n in z.namelist():
                root = etree.fromstring(z.read(n))
                times = [e.text for e in root.iterfind(".//wpml:hoverTime", ns)]
                assert times and all(float(t) > 0 for t in times), sorted(set(times))
        items = json.loads((out / "mission.plan").read_text())["mission"]["items"]
        delays = {it["params"][0] for it in items if it["command"] == 93}
        with open(out / "mission.waypoints") as f:
            rows = [line.split("\t") for line in f.read().splitlines()[1:]]
        assert delays == ({rest} if rest else set())
        ap = [float(r[4]) for r in rows if r[3] == "93"]  # after holds of whole seconds
        assert all(0 < x <= hover - 1 and round(x, 3) == x for x in ap) and bool(ap) == bool(rest)


def _egm96(lat, lon):
    """The EGM96 geoid height (m) through pyproj: EGM96 height 0 as a WGS84 ellipsoidal one."""
    import pyproj

    t = pyproj.Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True)
    return t.transform(lon, lat, 0.0)[2]


def test_geojson_heights_are_above_the_ellipsoid_from_an_amsl_origin(
    run_dir, tmp_path, monkeypatch
):
    """RFC 7946 section 3.1.1: a position's third element is the height above the WGS84
    ellipsoid. From the default AMSL origin the GeoJSON heights are the CSV's AMSL altitudes plus
    the EGM96 geoid height at the origin (47.3 to 47.4 m at Zurich), the AMSL one a property;
    from an ellipsoidal origin the origin's heights; without a geoid an AMSL origin is refused."""
    import sys

    n = _egm96(ORIGIN[0], ORIGIN[1])
    assert 47.2 < n < 47.5
    for ref, origin, geoid in (
        ("amsl", ORIGIN, n),
        ("ellipsoid", ORIGIN[:2] + (ORIGIN[2] + n,), 0),
    ):
        out = tmp_path / ref
        export_mission(run_dir, "geojson,csv", origin, HEADING, out, altitude_ref=ref)
        rows = _csv(out / "mission.csv")
        gj = json.loads((out / "mission.geojson").read_text())
        z = [c[2] for c in gj["features"][0]["geometry"]["coordinates"]]
        np.testing.assert_allclose(z, [float(r["altitude_m"]) + geoid for r in rows], atol=1e-3)
        caps = [r for r in rows if r["action"] in ("view", "frame")]
        for f, r in zip(gj["features"][1:], caps):
            assert f["properties"]["height_reference"] == "WGS84 ellipsoid"
            assert f["properties"]["altitude_reference"] == ref
            assert f["properties"]["altitude_m"] == pytest.approx(float(r["altitude_m"]), abs=1e-3)
            assert f["geometry"]["coordinates"][2] == pytest.approx(
                float(r["altitude_m"]) + geoid, abs=1e-3
            )
    monkeypatch.setitem(sys.modules, "pyproj", None)  # no geoid model at hand
    with pytest.raises(
        ValueError, match="geojson format writes heights above the WGS84 ellipsoid.*EGM96"
    ):
        export_mission(run_dir, "geojson", ORIGIN, HEADING, tmp_path / "none")
    assert not (tmp_path / "none").exists()


def test_headings_are_written_within_their_ranges_after_rounding(tmp_path):
    """359.96 degrees reads 0.0 at one decimal (not 360.0), 359.96 at two; WPML's signed angles
    stay within [-180, 180); a KML description says so too."""
    from lxml import etree

    from nbvkit.export import writers

    assert writers.bearing_text(359.96, 1) == "0.0"
    assert writers.bearing_text(359.96, 2) == "359.96"
    assert writers.bearing_text(359.9999996, 6) == "0.000000"
    assert writers.bearing_text(-0.04, 1) == "0.0"
    assert writers.signed_angle_text(179.9996, 3) == "-180.000"
    assert writers.signed_angle_text(-179.9996, 3) == "-180.000"
    g = writers.GeoWaypoints(
        lat=np.array([47.0, 47.00001]),
        lon=np.array([8.0, 8.0]),
        alt=np.array([410.0, 410.0]),
        rel_alt=np.array([10.0, 10.0]),
        heading=np.array([359.96, 359.96]),
        gimbal_pitch=np.zeros(2),
        gimbal_yaw=np.zeros(2),
        action=["takeoff", "view"],
        stage=["", "nbv"],
        row=[-1, 1],
        number=[0, 1],
        home=(47.0, 8.0, 400.0),
        speed=5.0,
        hover_s=2.0,
        altitude_ref="amsl",
        name="t",
    )
    writers.write_kml(g, tmp_path / "t.kml")
    root = etree.parse(str(tmp_path / "t.kml")).getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    desc = root.findtext(".//k:Folder/k:Placemark/k:description", namespaces=ns)
    assert desc.startswith("heading 0.0 deg,"), desc


@pytest.mark.parametrize("heading", [-360.0, 360.0, 359.96])
def test_headings_of_a_full_turn_are_accepted(heading):
    b = GeoFrame(*ORIGIN, heading).bearing([1.0, 0.0, 0.0])
    assert abs((b - heading + 180.0) % 360.0 - 180.0) < 1e-9


def test_an_export_again_into_a_relative_folder_removes_the_previous_files(
    run_dir, tmp_path, monkeypatch
):
    """A relative --out (as USAGE shows): the sorties of the previous export (a tighter budget,
    more sorties) are removed, not left beside the new mission."""
    monkeypatch.chdir(tmp_path)
    whole = export_mission(run_dir, "csv", ORIGIN, HEADING, tmp_path / "w")["mission"]
    split = export_mission(
        run_dir, "csv,qgc", ORIGIN, HEADING, "again", flight_time_min=whole["time_min"] / 1.5
    )
    assert len(split["sorties"]) >= 2 and (tmp_path / "again" / "sortie_02.plan").exists()
    export_mission(run_dir, "csv", ORIGIN, HEADING, "again")
    left = sorted(p.name for p in (tmp_path / "again").iterdir())
    assert left == ["export.json", "mission.csv"], left


def test_an_export_removes_only_the_files_an_export_writes(run_dir, tmp_path):
    """The previous export's list (export.json's files) is trusted only for the names an export
    writes: a list naming the user's own files (a forged or foreign export.json) removed them.
    A colmap/ folder emptied by an export without colmap is removed too (it was left)."""
    out = tmp_path / "mine"
    export_mission(run_dir, "csv,colmap", ORIGIN, HEADING, out)
    (out / "notes.txt").write_text("precious")
    (out / "sub").mkdir()
    (out / "sub" / "data.csv").write_text("precious")
    s = json.loads((out / "export.json").read_text())
    s["files"] += ["notes.txt", "sub/data.csv", "../outside.txt"]
    (out / "export.json").write_text(json.dumps(s))
    (tmp_path / "outside.txt").write_text("precious")
    export_mission(run_dir, "qgc", ORIGIN, HEADING, out)
    assert (out / "notes.txt").read_text() == (out / "sub" / "data.csv").read_text() == "precious"
    assert (tmp_path / "outside.txt").exists()
    assert not (out / "mission.csv").exists() and not (out / "colmap").exists()
    assert (out / "mission.plan").exists()


def test_an_export_keeps_files_behind_a_link_and_reads_no_list_from_a_foreign_json(
    run_dir, tmp_path
):
    """A listed name reached through a link out of the folder (colmap/ a link to the user's
    folder) was removed there, then the export failed; an export.json that is not an object
    with a list of files (a list, "files": 5) made the export fail after its files were made."""
    out, mine = tmp_path / "ex", tmp_path / "mine"
    export_mission(run_dir, "csv,colmap", ORIGIN, HEADING, out)
    mine.mkdir()
    (mine / "images.txt").write_text("precious")
    for f in (out / "colmap").iterdir():
        f.unlink()
    (out / "colmap").rmdir()
    (out / "colmap").symlink_to(mine, target_is_directory=True)
    export_mission(run_dir, "csv", ORIGIN, HEADING, out)
    assert (mine / "images.txt").read_text() == "precious" and (out / "colmap").is_symlink()
    # an export.json no export wrote (not an object listing its files and itself, names only):
    # the user's, refused before anything is touched, not replaced
    for foreign in ("[1, 2]", '{"files": 5}', '{"files": ["mission.csv", 7, "export.json"]}'):
        (out / "export.json").write_text(foreign)
        with pytest.raises(FileExistsError, match="holds export.json, which no earlier export"):
            export_mission(run_dir, "qgc", ORIGIN, HEADING, out)
        assert (out / "export.json").read_text() == foreign
        assert not (out / "mission.plan").exists() and (out / "mission.csv").exists()


def test_an_export_stopped_while_it_moved_its_files_in_is_replaced_by_the_next(run_dir, tmp_path):
    """An export stopped half-way through moving its files in leaves new names beside the old
    export.json (sortie_01.plan beside a list of mission.plan): the next export replaces them,
    as an export's, not as a user's."""
    out = tmp_path / "ex"
    export_mission(run_dir, "qgc", ORIGIN, HEADING, out)
    (out / "sortie_01.plan").write_text("half an export")
    s = export_mission(run_dir, "qgc", ORIGIN, HEADING, out, flight_time_min=3.0)
    assert "sortie_01.plan" in s["files"]
    assert json.loads((out / "sortie_01.plan").read_text())["fileType"] == "Plan"


def test_the_structure_distance_of_a_far_off_line_is_measured_at_a_wider_spacing(run_dir):
    """A row 3e8 m away (a same-size edit of flight.csv passes the manifest) asked for 15e9
    points 2 cm apart (224 GiB): lines longer than MAX_SAMPLES points allow are measured at a
    spacing as much wider."""
    from nbvkit.export import cautions

    fl = read_run(run_dir)
    line = np.array([[0.0, -20.0, 5.0], [3e8, -20.0, 5.0]])
    near = float(
        _core.RaycastScene(nbvkit.load_mesh(nbvkit.default_mesh_path())).distances(line[:1])[0]
    )
    c = cautions.structure_distance(fl, [line])
    assert c["structure_measured"] and c["structure_m"] <= round(near, 3)
    assert len(cautions._along(line, 3e8 / cautions.MAX_SAMPLES)) == cautions.MAX_SAMPLES


def test_dji_headings_turn_the_camera_of_a_yawed_mount_where_the_run_looked(tmp_path):
    """A camera yawed 45 deg on its mount: the DJI aircraft, whose camera faces forward, faces
    where the run's camera looked (waypointHeadingAngle and aircraftHeading), from the run's
    poses and mount alone (bearing = HEADING - the direction's angle from mesh +x)."""
    from lxml import etree

    run = tmp_path / "run"
    over = [*FAST, "max_iterations=3", "camera.mount_rpy_deg=[0,10,45]"]
    Mission(Config().with_overrides(over)).run(run)
    export_mission(run, "wpml,csv,geojson", ORIGIN, HEADING, tmp_path / "ex")
    with zipfile.ZipFile(tmp_path / "ex" / "mission.kmz") as z:
        root = etree.fromstring(z.read("wpmz/waylines.wpml"))
    ns = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
    got = [float(a.text) for a in root.iterfind(".//wpml:aircraftHeading", ns)]
    mount = _core.mount_transform([0, 0, 0], 0.0, 10.0, 45.0)
    want = []
    for r in _read_flight(run):
        if r["capture"] in ("view", "frame"):
            pose = [float(r[k]) for k in ("x", "y", "z", "yaw")]
            fwd = (_core.gimbal_transform([*pose, float(r["pitch"])]) @ mount)[:3, 0]
            want.append(HEADING - math.degrees(math.atan2(fwd[1], fwd[0])))
    assert len(got) == len(want) > 3
    diff = (np.array(got) - np.array(want) + 180.0) % 360.0 - 180.0
    assert np.abs(diff).max() < 0.01, diff
    # the files without a gimbal command give the camera's yaw on the vehicle (positive right)
    rows = [r for r in _csv(tmp_path / "ex" / "mission.csv") if r["action"] in ("view", "frame")]
    assert len(rows) == len(want)
    assert all(float(r["gimbal_yaw_deg"]) == pytest.approx(-45.0, abs=0.01) for r in rows)
    geo = json.loads((tmp_path / "ex" / "mission.geojson").read_text())["features"][1:]
    yaws = [f["properties"]["gimbal_yaw_deg"] for f in geo]
    np.testing.assert_allclose(yaws, [float(r["gimbal_yaw_deg"]) for r in rows], atol=1e-3)


def test_mission_items_are_counted_and_a_file_over_its_autopilots_limit_is_named(
    run_dir, tmp_path, capsys, monkeypatch
):
    """export.json counts each MAVLink file's mission items (as an independent read of the file
    counts them, home included in the .waypoints' upload); a file holding more than its
    autopilot keeps is a warning on the console naming the file and the limit, one at the limit
    is not."""
    import nbvkit.export as ex
    from nbvkit.cli import main

    s = export_mission(run_dir, "qgc", ORIGIN, HEADING, tmp_path / "a")
    plan = len(json.loads((tmp_path / "a" / "mission.plan").read_text())["mission"]["items"])
    with open(tmp_path / "a" / "mission.waypoints") as f:
        wpl = sum(1 for ln in f.read().splitlines()[1:] if int(ln.split("\t")[0]) >= 0)
    # the upload's items: ArduPilot counts home (sequence 0) among them
    assert wpl == 1 + sum(1 for ln in open(tmp_path / "a" / "mission.waypoints") if ln[0] != "Q"
                          and int(ln.split("\t")[0]) > 0)  # fmt: skip
    assert s["mission_items"] == {"mission.plan": plan, "mission.waypoints": wpl}
    saved = json.loads((tmp_path / "a" / "export.json").read_text())
    assert saved["mission_items"] == s["mission_items"]
    limits = {".plan": ("PX4", plan), ".waypoints": ("ArduPilot on a Pixhawk 1", wpl - 1)}
    monkeypatch.setattr(ex.items, "MAX_MISSION_ITEMS", limits)
    assert ex.items.item_warnings(s["mission_items"]) == [
        f"1 of 1 .waypoints files hold more mission items than ArduPilot on a Pixhawk 1 keeps "
        f"({wpl - 1:,}; mission.waypoints: {wpl:,}): its upload fails there. Split the flight "
        f"(--max-items {wpl - 1:,}, or a shorter --flight-time), or fly a run with fewer "
        "in-flight frames (planner.frame_step, profiling.camera_step)"
    ]
    monkeypatch.setattr(ex.items, "MAX_MISSION_ITEMS", {k: (w, 5) for k, (w, _) in limits.items()})
    args = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--out", str(tmp_path / "b")]
    assert main([*args, "--flight-time", str(s["mission"]["time_min"] / 3)]) == 0
    err = capsys.readouterr().err.splitlines()
    b = json.loads((tmp_path / "b" / "export.json").read_text())
    said = "nbvkit export: warning: "
    assert len(b["sorties"]) >= 3 and all(ln.startswith(said) for ln in err)
    assert b["warnings"] == [ln[len(said) :] for ln in err]
    for suffix in (".plan", ".waypoints"):
        assert sum(f"of {len(b['sorties'])} {suffix} files hold more" in ln for ln in err) == 1


def test_max_items_splits_the_flight_into_sorties_whose_files_an_autopilot_keeps(
    run_dir, tmp_path, capsys
):
    """--max-items N: every .plan and .waypoints file holds at most N mission items (read back
    as QGroundControl and Mission Planner read them: JSON items, lines after the header), every
    capture is flown in exactly one sortie, and no file warns; with a battery too, the sorties
    keep both limits. Bad values are refused by name before any file is written."""
    from nbvkit.cli import main

    whole = export_mission(run_dir, "qgc", ORIGIN, HEADING, tmp_path / "whole")
    n = max(whole["mission_items"].values()) // 3
    args = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--format", "qgc,csv"]
    assert main([*args, "--max-items", str(n), "--out", str(tmp_path / "a")]) == 0
    printed = capsys.readouterr()
    s = json.loads((tmp_path / "a" / "export.json").read_text())
    assert s["budget"]["max_items"] == n and s["budget"]["usable_min"] is None
    assert len(s["sorties"]) >= 3 and s["unreachable"] == []
    assert not any("mission items" in w for w in s["warnings"])
    assert "mission items" not in printed.err
    caps = []
    for k in range(1, len(s["sorties"]) + 1):
        plan = json.loads((tmp_path / "a" / f"sortie_{k:02d}.plan").read_text())
        assert len(plan["mission"]["items"]) <= n
        with open(tmp_path / "a" / f"sortie_{k:02d}.waypoints") as f:
            assert len(f.read().splitlines()) - 1 <= n  # home included
        with open(tmp_path / "a" / f"sortie_{k:02d}.csv", newline="") as f:
            caps += [r["flight_row"] for r in csv.DictReader(f) if r["action"] in ("view", "frame")]
    fl = read_run(run_dir)
    assert sorted(map(int, caps)) == [i for i, c in enumerate(fl.capture) if c]
    half = whole["mission"]["time_min"] / 2
    both = export_mission(
        run_dir, "qgc", ORIGIN, HEADING, tmp_path / "b", flight_time_min=half, max_items=n
    )
    assert len(both["sorties"]) >= 3 and max(both["mission_items"].values()) <= n
    usable_s = both["budget"]["usable_min"] * 60
    assert all(x["time_s"] <= usable_s + 1e-6 for x in both["sorties"])
    for bad, words in ((11, "at least 12"), (12.5, "whole number"), (True, "whole number")):
        with pytest.raises(ValueError, match=words):
            export_mission(run_dir, "qgc", ORIGIN, HEADING, tmp_path / "c", max_items=bad)
    assert not (tmp_path / "c").exists()


def test_a_way_back_the_search_out_did_not_reach_is_searched_from_the_point(run_dir, monkeypatch):
    """The search out from the start is capped at what the run's A* searches from each point
    would expand together: for one far point (the last, without a budget) that cap stopped it
    short, and the way back retraced the whole flight (734 m against 397 m on the airliner
    flown by `make`). Where the search out stops short, each point it did not reach is searched
    from the point itself: the same way back as the uncapped search finds, as cheap."""
    from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner, find_launch, load_map

    fl, model = read_run(run_dir), FlightModel()
    occ = load_map(fl)
    find_launch(fl, occ, model)
    caps = [i for i in SortiePlanner.work_rows(fl) if fl.capture[i]]
    full = ReturnPaths(fl, model, occ, caps)
    real = _core.plan_paths_to

    def stopped_short(*args, **kwargs):  # the cap reached before any point
        found = real(*args, **kwargs)
        return SimpleNamespace(paths=[np.zeros((0, 3))] * len(found.paths), capped=True)

    monkeypatch.setattr(_core, "plan_paths_to", stopped_short)
    short = ReturnPaths(fl, model, occ, caps)
    retrace = ReturnPaths(fl, model, occ, []).cost  # no A* way: back along the flight
    saved = [i for i in full.astar if full.cost[i] < 0.5 * retrace[i]]  # far along the flight
    assert len(saved) > 10
    assert all(short.cost[i] < 0.6 * retrace[i] for i in saved)  # not flown back along it
    assert np.mean(short.cost[caps] / full.cost[caps]) < 1.1


def test_the_ways_back_from_one_search_are_what_a_search_from_each_capture_finds(run_dir):
    """ReturnPaths finds the A* ways back of all captures by one search out from the start: each
    capture has one exactly where plan_path from it finds one, as cheap (the cells' path cost
    equal), from the capture to the start; and the choice of A* or retrace follows the
    cheaper."""
    from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner, find_launch, load_map
    from nbvkit.flight_home import stop_rows

    fl, model = read_run(run_dir), FlightModel()
    occ = load_map(fl)
    find_launch(fl, occ, model)
    caps = [i for i in SortiePlanner.work_rows(fl) if fl.capture[i]]
    rp = ReturnPaths(fl, model, occ, caps)
    all_ = _core.plan_paths_to(occ, fl.xyz[caps], fl.start, fl.radius)
    searched = 0
    for k, i in enumerate(caps):
        one = _core.search_path(occ, fl.xyz[i], fl.start, fl.radius, max_expansions=10**8)
        assert (len(all_.paths[k]) > 0) == (len(one.path) > 0), i
        if not len(one.path):
            continue
        np.testing.assert_array_equal(all_.paths[k][0], fl.xyz[i])
        np.testing.assert_array_equal(all_.paths[k][-1], fl.start)
        if len(one.path) > 2:  # searched: the cells' paths cost the same; shortening them
            searched += 1  # adds at most the pieces from the capture and to the start
            assert all_.cells_cost[k] == pytest.approx(one.cells_cost, abs=1e-9)
            length = np.linalg.norm(np.diff(all_.paths[k], axis=0), axis=1).sum()
            assert length <= all_.cells_cost[k] + math.sqrt(3) * occ.resolution + 1e-9, i
        t_all = model.path_time(all_.paths[k])
        retrace = rp.cost[i - 1] + model.leg_times(fl.xyz, stop_rows(fl))[i - 1]
        assert rp.cost[i] == pytest.approx(min(t_all, retrace)), i
        assert (i in rp.astar) == (t_all < retrace), i
    assert searched > 0 and len(rp.astar) > 0


def test_a_report_that_cannot_be_rewritten_leaves_the_run_whole(run_dir, tmp_path, monkeypatch):
    """A full disk (or a read-only run folder) while export rewrites report.html's flight
    section: the export is written and says so in a warning; the run keeps its report and its
    manifest as they were (evaluate and export still read it), no report.html.tmp left."""
    import errno
    import pathlib
    import shutil

    from nbvkit.export import estimate_flight
    from nbvkit.report import flight_section
    from nbvkit.runfolder import is_complete_run, write_manifest

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    report = run / "report.html"
    report.write_text(f"<html><body>{flight_section(estimate_flight(run))}</body></html>")
    write_manifest(run)
    before = {p.name: p.read_bytes() for p in (report, run / "manifest.json")}
    real = pathlib.Path.write_text

    def full_disk(self, *args, **kwargs):
        if self.name == "report.html.tmp":
            real(self, "<html><body>half a rep")
            raise OSError(errno.ENOSPC, "No space left on device", str(self))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", full_disk)
    s = export_mission(run, "csv", ORIGIN, HEADING, tmp_path / "x", flight_time_min=3.0)
    assert not s["report_updated"] and (tmp_path / "x" / "export.json").is_file()
    assert any("report.html not updated" in w and "No space" in w for w in s["warnings"])
    assert {p.name: p.read_bytes() for p in (report, run / "manifest.json")} == before
    assert is_complete_run(run) and not (run / "report.html.tmp").exists()


def test_an_export_interrupted_while_it_replaces_the_report_leaves_the_run_complete(
    run_dir, tmp_path, monkeypatch
):
    """Ctrl-C in the moment the export replaces report.html (its manifest taken off, for the
    report's new size): the run keeps a manifest that vouches for its files (evaluate and export
    still read it), the report it had, and no report.html.tmp."""
    import pathlib
    import shutil

    from nbvkit.export import estimate_flight
    from nbvkit.report import flight_section
    from nbvkit.runfolder import is_complete_run, write_manifest

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    report = run / "report.html"
    report.write_text(f"<html><body>{flight_section(estimate_flight(run))}</body></html>")
    write_manifest(run)
    before = report.read_bytes()
    real = pathlib.Path.replace

    def interrupted(self, target):
        if self.name == "report.html.tmp":
            raise KeyboardInterrupt
        return real(self, target)

    monkeypatch.setattr(pathlib.Path, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export_mission(run, "csv", ORIGIN, HEADING, tmp_path / "x")
    assert (run / "manifest.json").is_file() and is_complete_run(run)
    assert report.read_bytes() == before and not (run / "report.html.tmp").exists()


@pytest.mark.parametrize(
    "option, value, needle",
    [
        ("--speed", "1e-320", "speed must be a finite number >= 0.1 m/s"),
        ("--speed", "1e-300", "speed must be a finite number >= 0.1 m/s"),
        ("--climb-rate", "1e-320", "climb rate must be a finite number >= 0.1 m/s"),
        ("--hover", "1e308", "hover must be 0..3600 s a view"),
    ],
)
def test_flight_model_values_beyond_any_drone_are_refused_by_name(
    run_dir, tmp_path, capsys, option, value, needle
):
    """A crawl or an hour-long hover overflowed the mission's times to inf (a JSON error that
    named no option), or wrote cruiseSpeed 1e-300 into the .plan: refused before any file."""
    from nbvkit.cli import main

    out = tmp_path / "ex"
    argv = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--out", str(out)]
    assert main([*argv, option, value]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err, err
    assert not out.exists()


def test_a_camera_looking_over_the_nose_has_no_gimbal_yaw_at_pitched_views(tmp_path):
    """A camera pitched 20 deg down on its mount, looking over the nose: the gimbal's yaw is 0
    at every capture (the bearings in the local horizon gave up to 1.6e-4 degrees)."""
    run = tmp_path / "run"
    over = [*FAST, "max_iterations=3", "camera.mount_rpy_deg=[0,20,0]"]
    Mission(Config().with_overrides(over)).run(run)
    export_mission(run, "csv,geojson", ORIGIN, HEADING, tmp_path / "ex")
    rows = [r for r in _csv(tmp_path / "ex" / "mission.csv") if r["action"] in ("view", "frame")]
    assert len(rows) > 3 and all(float(r["gimbal_pitch_deg"]) < -19.0 for r in rows)
    assert {float(r["gimbal_yaw_deg"]) for r in rows} == {0.0}
    geo = json.loads((tmp_path / "ex" / "mission.geojson").read_text())["features"][1:]
    assert {f["properties"]["gimbal_yaw_deg"] for f in geo} == {0.0}


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGHUP"])
def test_an_export_killed_while_writing_leaves_nothing_half_written(run_dir, tmp_path, signum):
    """A kill or a hang-up while the files are written: the temporary folder is removed as on
    Ctrl-C (a killed process left .nbvkit-export-* behind), nothing at --out, exit 130."""
    import subprocess
    import sys
    import textwrap

    from conftest import as_from_a_terminal

    script = textwrap.dedent(
        f"""
        import os, signal, sys, time
        import nbvkit.export.writers as w
        from nbvkit.cli import main
        def killed(*args, **kwargs):
            os.kill(os.getpid(), signal.{signum})
            time.sleep(5)  # the handler raises here
        w.write_kml = killed
        sys.exit(main(sys.argv[1:]))
        """
    )
    out = tmp_path / "ex"
    argv = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--out", str(out)]
    p = subprocess.run(
        [sys.executable, "-c", script, *argv, "--format", "qgc,kml"],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=as_from_a_terminal,
    )
    assert p.returncode == 130, (p.returncode, p.stderr)
    assert f"nbvkit export: interrupted by {signum}" in p.stderr and "Traceback" not in p.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_export_killed_outright_leaves_a_temporary_folder_the_next_one_removes(
    run_dir, tmp_path
):
    """SIGKILL while the files are written leaves no time to clean up: its temporary folder
    stayed in the run's folder for good (and `run --overwrite` then refused the folder as holding
    files nbvkit did not write). The next export removes it (its process is gone), and keeps
    one whose process lives."""
    import shutil
    import signal
    import subprocess
    import sys
    import textwrap

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    script = textwrap.dedent(
        """
        import os, signal, sys
        import nbvkit.export.writers as w
        from nbvkit.cli import main
        def killed(*args, **kwargs):
            os.kill(os.getpid(), signal.SIGKILL)
        w.write_kml = killed
        sys.exit(main(sys.argv[1:]))
        """
    )
    argv = ["export", str(run), "--origin", *map(str, ORIGIN), "--format", "qgc,kml"]
    p = subprocess.run([sys.executable, "-c", script, *argv], capture_output=True, timeout=120)
    assert p.returncode == -signal.SIGKILL
    left = list(run.glob(".nbvkit-export-*"))
    assert len(left) == 1 and (left[0] / "mission.plan").is_file()
    alive = run / f".nbvkit-export-{os.getppid()}-0a0b0c0d0e0f"  # a live process's
    alive.mkdir()
    export_mission(run, "csv", ORIGIN, HEADING)
    assert (
        list(run.glob(".nbvkit-export-*")) == [alive] and (run / "export" / "mission.csv").exists()
    )


def _simplify_by_measuring_each_run_again(wps, tol=1e-3):
    """simplify's rule read literally: a plain point is dropped when it and every point dropped
    since the last kept one lie within tol of the segment from that point to the next."""
    keep, run = [wps[0]], []
    for k in range(1, len(wps) - 1):
        w, nxt = wps[k], wps[k + 1]
        same = abs(w.yaw - nxt.yaw) < 1e-12 and abs(w.pitch - nxt.pitch) < 1e-12
        pts, a, b = np.array([*run, w.xyz]), keep[-1].xyz, nxt.xyz
        t = np.clip((pts - a) @ (b - a) / max((b - a) @ (b - a), 1e-300), 0.0, 1.0)
        if w.action in ("waypoint", "transit") and same:
            if np.linalg.norm(pts - (a + t[:, None] * (b - a)), axis=1).max() <= tol:
                run.append(w.xyz)
                continue
        keep.append(w)
        run = []
    return keep + [wps[-1]]


def test_simplify_keeps_what_measuring_every_dropped_point_again_keeps():
    """simplify bounds a run's distance instead of measuring it again at every point: the same
    waypoints kept, on random paths of straight runs in centimetre steps with jitter around the
    tolerance, bends, turns of heading and captures."""
    from nbvkit.export.plan import Waypoint, simplify

    rng = np.random.default_rng(7)
    for trial in range(40):
        p, yaw, wps = np.zeros(3), 0.0, []
        for _ in range(int(rng.integers(1, 6))):  # straight stretches
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            jitter = float(rng.choice([0.0, 1e-4, 4e-4, 1e-3]))
            for _ in range(int(rng.integers(2, 400))):
                p = p + 0.03 * d
                yaw = yaw + (0.1 if rng.random() < 0.01 else 0.0)
                action = "view" if rng.random() < 0.01 else str(rng.choice(["waypoint", "transit"]))
                xyz = p + rng.normal(scale=jitter, size=3)
                wps.append(Waypoint(xyz, yaw, 0.0, action, -1, "nbv"))
        kept, want = simplify(wps), _simplify_by_measuring_each_run_again(wps)
        assert [id(w) for w in kept] == [id(w) for w in want], trial
    line = [Waypoint(np.array([0.0, 0.0, 0.03 * k]), 0.0, 0.0, "transit", -1, "out")
            for k in range(20000)]  # fmt: skip
    assert [float(w.xyz[2]) for w in simplify(line)] == [0.0, 0.03 * 19999]


def test_the_way_out_and_back_is_flown_in_few_items(run_dir, tmp_path):
    """The ways out and back retrace the flight in steps of centimetres: their straight stretches
    are one item each (simplify drops "transit" points on the line as it drops plain ones), so
    a sortie's items go to the work: at 60 items a file every profile point and capture is
    flown (161 were not, on the airliner of 8 views)."""
    from nbvkit.export.plan import Waypoint, simplify

    line = [Waypoint(np.array([0.0, 0.0, z]), 0.5, 0.0, "transit", -1, "back") for z in range(5)]
    kept = simplify([*line, Waypoint(np.array([1.0, 0, 4]), 0.5, 0.0, "home", -1, "back")])
    assert [float(w.xyz[2]) for w in kept] == [0.0, 4.0, 4.0]
    turned = [Waypoint(w.xyz, 0.5 + 0.1 * (k == 2), 0.0, w.action, -1, "back") for k, w in
              enumerate(line)]  # fmt: skip
    assert len(simplify(turned)) == 4  # a heading of its own is kept (and the point before it)
    s = export_mission(run_dir, "qgc,csv", ORIGIN, HEADING, tmp_path / "ex", max_items=60)
    assert s["unreachable"] == [] and max(s["mission_items"].values()) <= 60
    for k in range(1, len(s["sorties"]) + 1):  # no transit point on its neighbours' line
        rows = _csv(tmp_path / "ex" / f"sortie_{k:02d}.csv")
        ll = np.array([[float(r[c]) for c in ("latitude_deg", "longitude_deg")] for r in rows])
        p = np.column_stack(  # local metres (an equirectangular plane: 0.1 mm over this site)
            [
                (ll[:, 1] - ORIGIN[1]) * 111_320.0 * math.cos(math.radians(ORIGIN[0])),
                (ll[:, 0] - ORIGIN[0]) * 111_132.0,
                [float(r["rel_altitude_m"]) for r in rows],
            ]
        )
        for j, r in enumerate(rows[1:-1], 1):
            if r["action"] == "transit" and rows[j + 1]["heading_deg"] == r["heading_deg"]:
                a, b, c = p[j - 1], p[j], p[j + 1]
                t = np.clip((b - a) @ (c - a) / max((c - a) @ (c - a), 1e-18), 0.0, 1.0)
                assert np.linalg.norm(a + t * (c - a) - b) > 5e-4, (k, j)


def test_the_cli_refuses_a_reserve_without_a_battery_and_counts_the_photos(run_dir, tmp_path):
    """--reserve without --flight-time was ignored without a word (no budget, exit 0); the
    console's mission line and sortie table count the frames in flight, which take photos too
    (a sortie of 0 views read as empty)."""
    import subprocess
    import sys

    argv = [
        sys.executable,
        "-m",
        "nbvkit.cli",
        "export",
        str(run_dir),
        "--origin",
        *map(str, ORIGIN),
    ]
    p = subprocess.run([*argv, "--reserve", "50", "--out", str(tmp_path / "a")],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode == 2 and "--reserve" in p.stderr and "--flight-time" in p.stderr
    assert not (tmp_path / "a").exists()
    b = ["--format", "csv", "--flight-time", "1.5", "--out", str(tmp_path / "b")]
    p = subprocess.run([*argv, *b], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    s = json.loads((tmp_path / "b" / "export.json").read_text())
    m = s["mission"]
    assert f"mission: {m['views']} views and {m['frames']} frames in flight" in p.stdout
    rows = p.stdout.split("time_min\n", 1)[1].splitlines()[: len(s["sorties"])]
    assert [ln.split()[:3] for ln in rows] == [
        [str(r["sortie"]), str(r["views"]), str(r["frames"])] for r in s["sorties"]
    ]


def test_the_export_commands_defaults_are_export_missions():
    """`nbvkit export`'s options default to export_mission's own values (they had been said a
    second time in the command, where one could drift from the other)."""
    import inspect

    from nbvkit.cli import build_parser
    from nbvkit.export import export_mission

    args = build_parser().parse_args(["export", "RUN", "--origin", "47", "8", "400"])
    d = {k: v.default for k, v in inspect.signature(export_mission).parameters.items()}
    assert args.format.split(",") == list(d["formats"])
    got = (args.altitude_ref, args.heading, args.speed, args.climb_rate, args.hover)
    assert got == (d["altitude_ref"], d["heading_deg"], d["speed"], d["climb_rate"], d["hover_s"])
    assert args.photo_first == d["photo_first"] and args.reserve is None  # (d's when flown)


def _copy_run(run_dir, to):
    import shutil

    shutil.copytree(run_dir, to)
    return to


def test_a_fifo_in_place_of_a_runs_manifest_or_lock_file_is_refused_not_waited_on(
    run_dir, tmp_path
):
    """Every reader of a run folder checks it first (require_complete_run): a FIFO as its
    manifest.json, or as the lock file beside it, blocked that check forever."""
    import threading

    from nbvkit.runfolder import require_complete_run

    def check(run) -> str:
        out = []

        def go():
            try:
                require_complete_run(run)
                out.append("complete")
            except ValueError as e:
                out.append(str(e))

        t = threading.Thread(target=go, daemon=True)
        t.start()
        t.join(30)
        assert not t.is_alive(), f"the check of {run} blocked"
        return out[0]

    a = _copy_run(run_dir, tmp_path / "a")
    (a / "manifest.json").unlink()
    os.mkfifo(a / "manifest.json")
    assert "has an unreadable manifest.json" in check(a)
    b = _copy_run(run_dir, tmp_path / "b")
    os.mkfifo(tmp_path / ".b.lock")
    assert f"the lock file {tmp_path / '.b.lock'} is not a regular file" in check(b)


def test_an_export_leaves_a_users_files_in_its_folder_alone(run_dir, tmp_path, capsys):
    """--out a folder holding a user's mission.csv or export.json: refused, both kept, before
    any is replaced; an earlier export's files there are replaced."""
    from nbvkit.cli import main

    args = ["export", str(run_dir), "--origin", *map(str, ORIGIN), "--format", "csv", "--out"]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "mission.csv").write_text("data\n")
    (mine / "export.json").write_text('{"mine": 1}\n')
    assert main([*args, str(mine)]) == 2
    err = capsys.readouterr().err
    assert f"{mine} holds mission.csv, export.json, which no earlier export wrote there" in err
    assert (mine / "mission.csv").read_text() == "data\n"
    assert (mine / "export.json").read_text() == '{"mine": 1}\n'
    assert not list(tmp_path.glob(".nbvkit-export-*"))
    ours = tmp_path / "ours"
    assert main([*args, str(ours)]) == 0 and main([*args, str(ours)]) == 0  # its own: replaced


def test_a_damaged_report_or_a_users_file_in_the_run_leave_the_export_and_the_run_whole(
    run_dir, tmp_path
):
    """report.html damaged in place (same size: the manifest passes) is a warning naming it,
    the export written; a user's notes.txt in the run folder stays out of the manifest an
    export rewrites with the report (changing it later made the run refused as damaged)."""
    from nbvkit.export import estimate_flight
    from nbvkit.report import flight_section
    from nbvkit.runfolder import is_complete_run, write_manifest

    run = _copy_run(run_dir, tmp_path / "run")
    report = run / "report.html"
    report.write_text(f"<html><body>{flight_section(estimate_flight(run))}</body></html>")
    write_manifest(run)
    (run / "notes.txt").write_text("mine\n")
    s = export_mission(run, "csv", ORIGIN, HEADING, tmp_path / "x")
    assert s["report_updated"] and is_complete_run(run)
    (run / "notes.txt").write_text("mine, changed\n")
    assert is_complete_run(run)  # the user's file is not the run's
    listed = json.loads((run / "manifest.json").read_text())["files"]
    assert "notes.txt" not in listed and listed["report.html"] == report.stat().st_size
    damaged = bytearray(report.read_bytes())
    damaged[20:22] = b"\xff\xfe"
    report.write_bytes(bytes(damaged))
    s = export_mission(run, "csv", ORIGIN, HEADING, tmp_path / "y")
    assert not s["report_updated"] and (tmp_path / "y" / "export.json").is_file()
    (w,) = [w for w in s["warnings"] if "report.html" in w]
    assert f"{report} is damaged, not a report nbvkit wrote" in w
    assert report.read_bytes() == bytes(damaged) and is_complete_run(run)


def test_a_run_view_refuses_a_mesh_changed_since_the_run(run_dir, tmp_path):
    """run_view coloured a run's cloud against whatever mesh its config names now (the file
    changed, or another put in its place): refused as evaluate refuses it."""
    from nbvkit.runview import run_view

    run = _copy_run(run_dir, tmp_path / "run")
    text = (run / "summary.json").read_text()
    sha = json.loads(text)["mesh_sha1"]
    other = "".join("0" if c != "0" else "1" for c in sha)  # the same size: the manifest passes
    (run / "summary.json").write_text(text.replace(sha, other))
    with pytest.raises(ValueError, match="cannot be coloured: its mesh .* has changed since"):
        run_view(run, view_points=100)


def test_a_runs_files_that_are_no_regular_files_or_positions_beyond_reach_are_named(
    run_dir, tmp_path
):
    """A FIFO as flight.csv was "not found (a run made before ...)", one as map.ot planned
    without the map, saying nothing; a flight row 1e308 m away was refused naming no file."""
    from nbvkit.export.plan import read_run

    for name in ("flight.csv", "summary.json", "config.yaml", "map.ot"):
        run = _copy_run(run_dir, tmp_path / name)
        (run / name).unlink()
        os.mkfifo(run / name)
        with pytest.raises(ValueError, match=f"run file {name} .* is a FIFO"):
            read_run(run)
    run = _copy_run(run_dir, tmp_path / "far")
    rows = (run / "flight.csv").read_text().splitlines()
    head = rows[0].split(",")
    cells = rows[3].split(",")
    cells[head.index("z")] = "1e308"
    (run / "flight.csv").write_text("\n".join([*rows[:3], ",".join(cells), *rows[4:]]) + "\n")
    with pytest.raises(ValueError, match=r"flight.csv: row 2 \(line 4\): column z is 1e\+308 m"):
        read_run(run)


def test_the_planners_parts_are_said_even_where_a_run_had_none_of_a_kind():
    from nbvkit.planning.registry import parts_words

    s = {"generators": [], "utility": "surface", "terminations": [], "termination_part": None}
    assert parts_words(s) == "generators none; utility surface; terminations none"
