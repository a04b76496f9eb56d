"""The sensors: the RGB-D camera on its gimbal and the 2D laser scanner, their settings (the
``camera`` and ``laser`` sections), the named cameras, and one builder each.

Named cameras: ``camera.preset`` fills the camera keys (and the room its stand-off needs) that a
configuration does not set itself, as a scenario fills the planner's.

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

import math
from dataclasses import dataclass

from . import _core
from .work_limits import MAX_VIEW_RAYS
from .settings import choice, nonneg, positive, section_error, triple, within

_CAM = _core.DepthCameraOptions()
_LAS = _core.LaserScannerOptions()

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
        # views are scored with one ray per map cell (0.2 m) at the near stand-off (0.45 x 24 m)
        # rather than at the 24 m far plane (138 x 100 rays): 9 x fewer cells in the coverage
        # sets, which held 161 M cells (5.4 GB) for one plan of a 100 m plant
        "utility.rays_x": 64,
        "utility.rays_y": 48,
    },
}


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D camera (paper Table 1); mount = T_body_sensor as xyz (m) + roll/pitch/yaw (deg).

    The camera rides a gimbal between the body and its mount: a view is (x, y, z, yaw, pitch),
    T_world_camera = T(x, y, z) Rz(yaw) Ry(pitch) mount, pitch > 0 looking DOWN (REP-103, the
    sign of mount_rpy_deg's pitch). ``gimbal_pitch_deg`` [min, max] is the pitch range it can
    hold, in degrees within [-90, 90]: [-30, 90] is 30 deg up to straight down, as inspection
    UAVs; [0, 0] the fixed level camera (the paper's scenarios)."""

    preset: str = choice("rgbd", tuple(CAMERA_PRESETS))  # named camera: rgbd (paper), inspection
    width: int = within(_CAM.width, 1, 16_000)
    height: int = within(_CAM.height, 1, 16_000)
    hfov_deg: float = _CAM.hfov_deg  # horizontal field of view, deg
    vfov_deg: float = _CAM.vfov_deg  # vertical field of view, deg
    min_range: float = _CAM.min_range  # m; nearer surface gives no depth
    max_range: float = positive(_CAM.max_range, 1000)
    noise_k: float = nonneg(_CAM.noise_k)  # the authors used 0.0025 (sigma = k z^2)
    mount_xyz: tuple = triple((0.0, 0.0, 0.0))  # m, the camera on the gimbal (body frame)
    mount_rpy_deg: tuple = triple((0.0, 0.0, 0.0))  # roll, pitch (> 0 down), yaw of the mount, deg
    gimbal_pitch_deg: tuple = (-30.0, 90.0)  # [min, max] deg, > 0 looks down; [0, 0]: level
    frame_stride: int = within(1, 1, 64)  # in-flight frames at 1/N the pixels on each axis
    frame_refine: bool = False  # with frame_stride > 1: full resolution where a frame could add

    def check(self, key: str) -> None:
        check_gimbal(self.gimbal_pitch_deg, key + ".gimbal_pitch_deg")


@dataclass(frozen=True)
class LaserConfig:
    """The 2D laser scanner (paper Table 1)."""

    fov_deg: float = _LAS.fov_deg  # the scan's fan, deg
    resolution_deg: float = _LAS.resolution_deg  # deg between beams
    min_range: float = _LAS.min_range  # m; nearer surface gives no return
    max_range: float = positive(_LAS.max_range, 1000)
    noise_sigma: float = nonneg(_LAS.noise_sigma)
    mount_xyz: tuple = triple((0.0, 0.0, 0.0))  # m, the scanner on the body
    mount_rpy_deg: tuple = triple((0.0, 10.0, 0.0))  # pitched 10 deg down (Table 1)


def check_gimbal(pitch_range, key: str = "camera.gimbal_pitch_deg") -> None:
    """Raises ValueError unless camera.gimbal_pitch_deg is [min, max], finite, within [-90, 90]
    deg, min <= max, and holds 0 (level: a pose of 4 numbers, start_pose's among them)."""
    if len(pitch_range) != 2:
        raise ValueError(
            f"config key {key!r} must be 2 numbers [min, max] (deg, > 0 looks down), "
            f"got {list(pitch_range)!r}"
        )
    lo, hi = pitch_range
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"config key {key!r} must be finite, got {list(pitch_range)!r}")
    if not (-90.0 <= lo <= 90.0 and -90.0 <= hi <= 90.0):
        raise ValueError(
            f"config key {key!r}: a pitch must be within [-90, 90] deg (90: straight down, -90: "
            f"straight up), got {list(pitch_range)!r}"
        )
    if lo > hi:
        raise ValueError(f"config key {key!r}: min {lo:g} > max {hi:g} deg")
    if not lo <= 0.0 <= hi:
        raise ValueError(
            f"config key {key!r} must include 0 (level: a pose of 4 numbers, as start_pose "
            f"may be), got {list(pitch_range)!r}"
        )


_CAMERA_KEYS = ("width", "height", "hfov_deg", "vfov_deg", "min_range", "max_range", "noise_k")
_LASER_KEYS = ("fov_deg", "resolution_deg", "min_range", "max_range", "noise_sigma")


def camera_kwargs(camera: CameraConfig) -> dict:
    """The DepthCamera / DepthCameraOptions keywords of a camera section."""
    return {k: getattr(camera, k) for k in _CAMERA_KEYS}


def laser_kwargs(laser: LaserConfig) -> dict:
    """The LaserScanner / LaserScannerOptions keywords of a laser section."""
    return {k: getattr(laser, k) for k in _LASER_KEYS}


def camera_mount(camera: CameraConfig):
    """T_body_camera (4, 4) of a camera section (the gimbal turns it by the view's pitch)."""
    return _core.mount_transform(camera.mount_xyz, *camera.mount_rpy_deg)


def build_camera(camera: CameraConfig, scene, seed: int, **changes) -> _core.DepthCamera:
    """The depth camera of a camera section over `scene`; `changes` replace some of its keys
    (e.g. a coarse noise-free probe: width=32, height=24, noise_k=0)."""
    return _core.DepthCamera(
        scene, **{**camera_kwargs(camera), **changes}, seed=seed, mount=camera_mount(camera)
    )


def build_frame_camera(camera: CameraConfig, scene, seed: int):
    """The camera of in-flight frames: camera.frame_stride times fewer pixels on each axis (at
    least one), the same field of view, range and mount; None at frame_stride 1 (the camera
    itself takes them)."""
    n = camera.frame_stride
    return None if n == 1 else build_camera(camera, scene, seed, **_strided(camera, n))


#: A preview (World.novelty) takes 1 pixel in PREVIEW_STRIDE on each axis: 80 x 60 of 640 x 480.
PREVIEW_STRIDE = 8


def build_preview_camera(camera: CameraConfig, scene):
    """The camera of a frame's preview (World.novelty): PREVIEW_STRIDE times fewer pixels on
    each axis (at least one), the same field of view, range and mount, no noise."""
    return build_camera(camera, scene, 0, **_strided(camera, PREVIEW_STRIDE), noise_k=0.0)


def _strided(camera: CameraConfig, n: int) -> dict:
    """width and height of 1 pixel in n of the camera's on each axis (at least one)."""
    return dict(width=max(1, camera.width // n), height=max(1, camera.height // n))


def build_laser(laser: LaserConfig, scene, seed: int) -> _core.LaserScanner:
    """The laser scanner of a laser section over `scene`, on its fixed mount."""
    mount = _core.mount_transform(laser.mount_xyz, *laser.mount_rpy_deg)
    return _core.LaserScanner(scene, **laser_kwargs(laser), seed=seed, mount=mount)


def build_view_camera(camera: CameraConfig, utility, resolution: float):
    """The scoring camera (ViewCameraModel): one ray per map cell of `resolution` on the far
    plane unless the utility section's rays_x / rays_y say otherwise; mounted as the camera."""
    vc = _core.ViewCameraModel.for_resolution(
        camera.hfov_deg, camera.vfov_deg, camera.max_range, resolution
    )
    return vc.copy(
        rays_x=utility.rays_x or vc.rays_x,
        rays_y=utility.rays_y or vc.rays_y,
        mount=camera_mount(camera),
        pixel_pitch_deg=max(camera.hfov_deg / camera.width, camera.vfov_deg / camera.height),
    )


def view_rays_across(camera: CameraConfig, resolution: float) -> tuple[int, int]:
    """(rays_x, rays_y) of the view camera that follows the map cells on the far plane
    (ViewCameraModel.for_resolution), computed before it is built (for its size check)."""

    def across(fov):
        return math.ceil(2 * camera.max_range * math.tan(math.radians(fov) / 2) / resolution)

    return across(camera.hfov_deg), across(camera.vfov_deg)


def check_view_camera(camera: CameraConfig, laser: LaserConfig, utility, resolution: float):
    """Builds what a mission derives from the sensor sections alone (the sensors' options and
    ray counts, the view camera model), so that a bad value fails before any work, naming the
    section; the view camera's rays per candidate view are bounded (MAX_VIEW_RAYS) before they
    are built."""
    u, c = utility, camera
    checks = (
        ("camera", c, lambda: _core.DepthCameraOptions(**camera_kwargs(c))),
        ("laser", laser, lambda: _core.LaserScannerOptions(**laser_kwargs(laser))),
        ("utility", u, lambda: build_view_camera(c, u, resolution)),
    )
    if not (u.rays_x and u.rays_y) and 0 < c.hfov_deg < 180 and 0 < c.vfov_deg < 180:
        across_x, across_y = view_rays_across(c, resolution)
        _check_view_rays(c, u, resolution, u.rays_x or across_x, u.rays_y or across_y)
    for name, section, make in checks:
        try:
            built = make()
        except (ValueError, TypeError) as e:
            derived = ""
            if name == "utility" and not (u.rays_x and u.rays_y):
                derived = f" (null rays_x / rays_y follow map.resolution = {resolution:g})"
            raise section_error(section, name, e, derived) from None
    _check_view_rays(c, u, resolution, built.rays_x, built.rays_y)


def _check_view_rays(camera, utility, resolution: float, rays_x: int, rays_y: int) -> None:
    """ValueError when the view camera's rays per candidate view exceed MAX_VIEW_RAYS."""
    u = utility
    rays = rays_x * rays_y
    if rays <= MAX_VIEW_RAYS:
        return
    if u.rays_x and u.rays_y:
        what = "utility.rays_x x rays_y"
        fits = f"utility.rays_x x rays_y <= {MAX_VIEW_RAYS:,} would fit"
    else:
        what = f"camera.max_range = {camera.max_range:g}"
        fit = camera.max_range * math.sqrt(MAX_VIEW_RAYS / rays) * 0.99
        fits = (
            f"camera.max_range <= {fit:.4g} (null utility.rays_x / rays_y give one ray per map "
            f"cell on the far plane at map.resolution = {resolution:g}), or "
            "utility.rays_x / rays_y set, would fit"
        )
    raise ValueError(
        f"the view camera: {what} makes "
        f"{rays_x} x {rays_y} = {rays:,} rays per candidate view, more than the "
        f"limit {MAX_VIEW_RAYS:,} (checked before any work); {fits}"
    )
