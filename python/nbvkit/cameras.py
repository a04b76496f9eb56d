"""Named cameras: ``camera.preset`` fills the camera keys (and the room its stand-off needs) that
a configuration does not set itself, as a scenario fills the planner's.

- ``rgbd`` (default): the paper's RGB-D camera (Table 1): 640 x 480 pixels, 60 x 45 deg, depth
  0.5-8 m; a pixel spans 1.44 cm at 8 m. Its keys are the C++ defaults
  (``nbvkit.DepthCameraOptions``), so the preset sets nothing.
- ``inspection``: a camera for large structures (issue 37): the same field of view at twice the
  pixels, 1280 x 960, depth 1-24 m. A pixel spans 2.2 cm at 24 m, so the 5 cm coverage cells hold
  several points at its whole range, and one frame of a flat face 17 m away (its far stand-off,
  0.7 x 24 m) spans about 19 x 14 m. Its frame takes about 4 x the rays of the RGB-D camera's,
  and views planned three times farther out need room: ``workspace.margin_xy`` 17 m (the far
  stand-off) instead of the surface planners' 5 m, and so a larger map.
"""
from __future__ import annotations

#: preset name -> {dotted config key: value}, applied under what the user sets.
CAMERA_PRESETS: dict[str, dict] = {
    "rgbd": {},
    "inspection": {
        "camera.width": 1280,
        "camera.height": 960,
        "camera.hfov_deg": 60.0,
        "camera.vfov_deg": 45.0,
        "camera.min_range": 1.0,
        "camera.max_range": 24.0,
        "workspace.margin_xy": 17.0,
    },
}
