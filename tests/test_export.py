"""nbvkit export: each format read back by an independent reader, the geodesy's round trip, a
COLMAP pose against the simulated camera, the battery split, and bad input."""
from __future__ import annotations

import csv
import json
import math
import zipfile

import numpy as np
import pytest

import nbvkit
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
    # per view: a waypoint that holds, a gimbal pitch (1000, horizon-locked) and one image (2000)
    views = [k for k, it in enumerate(items) if it["command"] == 2000]
    n_views = sum(c == "view" for c in fl.capture)
    n_frames = sum(c == "frame" for c in fl.capture)
    assert len(views) == n_views + n_frames
    gimbal = [k for k, it in enumerate(items) if it["command"] == 1000]
    assert len(gimbal) == n_views
    for k in gimbal:
        wp, g, cap = items[k - 1], items[k], items[k + 1]
        assert wp["command"] == 16 and wp["params"][0] == 2.0 and wp["params"][3] is not None
        assert g["frame"] == 2 and g["params"][0] == pytest.approx(0.0, abs=1e-9)  # level view
        assert g["params"][4] == 8
        assert cap["command"] == 2000 and cap["params"][2] == 1  # one image
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
    # headings: the vehicle's yaw as a compass bearing
    for k in on_flight:
        yaw = fl.yaw[int(rows[k]["flight_row"])]
        assert nav[k]["params"][3] == pytest.approx((HEADING - math.degrees(yaw)) % 360, abs=1e-6)
    # starts and ends above the launch point
    assert np.abs(xyz[0] - top).max() < 0.01 and np.abs(xyz[-1] - top).max() < 0.01


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
    # ArduPilot turns by CONDITION_YAW before each view's waypoint
    assert cmds.count(115) == cmds.count(1000)
    for k, c in enumerate(cmds):
        if c == 115:
            assert cmds[k + 1] == 16 and cmds[k + 2] == 1000 and cmds[k + 3] == 2000


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
        assert mc.findtext("wpml:finishAction", namespaces=ns) == "goHome"
        assert mc.find("wpml:droneInfo/wpml:droneEnumValue", ns) is not None
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
        funcs = [
            a.findtext("wpml:actionActuatorFunc", namespaces=ns)
            for a in root.iter("{http://www.dji.com/wpmz/1.0.2}action")
        ]
        assert funcs.count("gimbalRotate") == n_views
        assert funcs.count("takePhoto") == sum(bool(c) for c in fl.capture)
        for p in pms:
            a = p.findtext("wpml:waypointHeadingParam/wpml:waypointHeadingAngle", namespaces=ns)
            assert a is None or -180 <= float(a) < 180
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
    views = list(feats["views"].features())
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
    for f in pts:
        lon, lat, alt = f["geometry"]["coordinates"]
        p = _to_mesh([lat], [lon], [alt])[0]
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
    captured = []
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
        assert plan["plannedHomePosition"] == home
    assert sorted(captured) == view_rows  # every view exactly once
    table = _csv(out / "sorties.csv")
    assert [int(r["sortie"]) for r in table] == [1, 2, 3]
    assert sum(int(r["views"]) for r in table) == len(view_rows)
    assert sum(s["time_s"] for s in budget["sorties"]) >= whole["time_s"] - 1e-6
    assert not (out / "mission.csv").exists()  # the previous export's files were replaced


def test_a_view_beyond_one_battery_is_reported_not_dropped(run_dir, tmp_path):
    from nbvkit.export.plan import FlightModel, ReturnPaths, SortiePlanner

    fl = read_run(run_dir)
    model = FlightModel()
    sp = SortiePlanner(fl, model, ReturnPaths(fl, model, None, []))  # retrace only: far views
    views = [i for i, c in enumerate(fl.capture) if c == "view"]
    usable = sp.cost(views[0], views[0]) + 1.0  # enough for the first view, not the farthest
    sorties, unreachable = sp.split(usable)
    flown = [
        i for s in sorties for i in range(s.first_row, s.last_row + 1) if fl.capture[i] == "view"
    ]
    missed = [u["row"] for u in unreachable if u["capture"] == "view"]
    assert missed and sorted(flown + missed) == views
    assert all(s.time_s <= usable for s in sorties)


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
        ({"formats": "qgc,shapefile"}, ValueError, "unknown export format 'shapefile'"),
        ({"flight_time_min": 0.05}, ValueError, "too short for any view"),
        ({"flight_time_min": -1.0}, ValueError, "flight time"),
        ({"speed": 0.0}, ValueError, "speed"),
    ],
)
def test_bad_input_names_the_problem_and_writes_nothing(run_dir, tmp_path, kwargs, exc, words):
    args = {"formats": "qgc,csv,colmap", "origin": ORIGIN, "out_dir": tmp_path / "ex", **kwargs}
    with pytest.raises(exc, match=words):
        export_mission(run_dir, **args)
    assert list(tmp_path.iterdir()) == []  # no output folder, no temporary folder


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
    (run_dir / "report.html").write_text(f"<html><body>{sec}</body></html>")
    try:
        s = export_mission(run_dir, "csv", ORIGIN, HEADING, tmp_path / "x", flight_time_min=3.0)
        assert s["report_updated"]
        text = (run_dir / "report.html").read_text()
        assert text.count(FLIGHT_BEGIN) == 1 and text.count(FLIGHT_END) == 1
        assert "sortie 1" in text and "#1f77b4" in text
    finally:
        (run_dir / "report.html").unlink()


def test_a_blocked_climb_below_the_start_moves_the_launch_point(run_dir, monkeypatch):
    from nbvkit import flight as plan  # the flight-time model, the launch point, the sorties

    fl = read_run(run_dir)
    occ = plan.load_map(fl)
    s = fl.start
    real = plan._column_clear
    # pretend the structure stands over the ground below the start (as a wing can)
    blocked = lambda f, m, x, y, top: (  # noqa: E731
        np.hypot(x - s[0], y - s[1]) > 1.0 and real(f, m, x, y, top)
    )
    monkeypatch.setattr(plan, "_column_clear", blocked)
    plan.find_launch(fl, occ, plan.FlightModel())
    assert np.hypot(*(fl.launch[:2] - s[:2])) > 1.0 and fl.launch[2] == s[2]
    assert np.allclose(fl.launch_path[0], fl.launch) and np.allclose(fl.launch_path[-1], s)
    assert np.allclose(fl.home, [*fl.launch[:2], fl.workspace["bounds_min"][2]])
    for a, b in zip(fl.launch_path[:-1], fl.launch_path[1:]):
        assert _core.segment_is_free(occ, a, b, fl.radius)
    sp = plan.SortiePlanner(
        fl, plan.FlightModel(), plan.ReturnPaths(fl, plan.FlightModel(), occ, [])
    )
    w = sp.whole().waypoints
    assert w[0].action == "takeoff" and np.allclose(w[0].xyz, fl.launch)
    assert w[-1].action == "home" and np.allclose(w[-1].xyz, fl.launch)
    monkeypatch.setattr(plan, "_column_clear", lambda *a: False)
    with pytest.raises(ValueError, match="no launch point"):
        plan.find_launch(fl, occ, plan.FlightModel())
