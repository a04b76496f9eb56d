"""Named cameras (camera.preset): the inspection camera for large structures sees a wall beyond
the paper's RGB-D range at the sampling the 5 cm evaluation needs."""
from __future__ import annotations

import numpy as np
import pytest

import nbvkit
from conftest import wall_mesh
from nbvkit.sensors import CAMERA_PRESETS, camera_kwargs
from nbvkit.config import load_config


def test_a_preset_fills_the_camera_keys_the_user_did_not_set():
    c = load_config(overrides=["camera.preset=inspection"])
    want = CAMERA_PRESETS["inspection"]
    assert c.camera.width == want["camera.width"] and c.camera.max_range == want["camera.max_range"]
    assert c.workspace.margin_xy == want["workspace.margin_xy"]  # room for its stand-off
    mine = load_config(overrides=["camera.preset=inspection", "camera.max_range=30"])
    assert mine.camera.max_range == 30 and mine.camera.width == want["camera.width"]
    # the default is the paper's camera, its keys the C++ defaults
    d = load_config().camera
    assert d.preset == "rgbd" and (d.width, d.height, d.max_range) == (640, 480, 8.0)
    with pytest.raises(ValueError, match="camera.preset.*rgbd, inspection"):
        load_config(overrides=["camera.preset=gopro"])


def test_the_inspection_camera_samples_a_wall_20_m_away_finer_than_the_coverage_cell():
    wall = wall_mesh(x=20.0)  # the plane x = 20, facing a camera at the origin looking along +x
    pose = [0.0, 0.0, 0.0, 0.0]
    rgbd = nbvkit.DepthCamera(wall, **camera_kwargs(load_config().camera))
    assert len(rgbd.scan_pose(pose).hits) == 0  # beyond its 8 m
    cfg = load_config(overrides=["camera.preset=inspection"])
    cam = nbvkit.DepthCamera(wall, **camera_kwargs(cfg.camera))
    scan = cam.scan_pose(pose)
    assert len(scan.hits) == cfg.camera.width * cfg.camera.height  # every pixel on the wall
    assert np.allclose(scan.hits[:, 0], 20.0)
    # neighbouring pixels 2 * 20 tan(30 deg) / 1280 = 1.80 cm apart at the centre of the row
    ys = np.sort(np.unique(np.round(scan.hits[:, 1], 6)))
    spacing = np.median(np.diff(ys))
    assert spacing == pytest.approx(2 * 20 * np.tan(np.radians(30)) / 1280, rel=0.02)
    assert spacing < 0.05 / 2  # at least two points across every 5 cm cell
