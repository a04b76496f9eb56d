"""Mission configuration: frozen dataclasses, loaded from YAML, with dotted overrides.

One source of truth: sensor, map and cloud defaults are read from the C++ option structs' defaults
(the bindings expose them), and a test checks that every default here equals its C++ twin.
Unknown keys are rejected with the key's full dotted name. ``Config.to_dict()`` gives the resolved
configuration written beside every run's results.
"""
from __future__ import annotations


import math
import typing
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Optional

import yaml

from . import _core

_CAM = _core.DepthCameraOptions()
_LAS = _core.LaserScannerOptions()


@dataclass(frozen=True)
class MeshConfig:
    """The structure's mesh file."""

    path: Optional[str] = None  # None: the shipped generated airliner
    scale: float = 1.0
    up: str = "z"  # the file's up axis: "z" or "y"


@dataclass(frozen=True)
class WorkspaceConfig:
    """The NBV workspace (map bounds for entropy, utility and navigation).

    Default: the structure's bounding box grown by ``margin_xy`` on each side and squared up to a
    square footprint (as the paper's 40 x 40 m), from ``min(0, bbox z min)`` (the ground) to
    ``bbox z max + margin_z``. For the shipped airliner (35.0 x 30.0 x 7.5 m) this gives
    40.0 x 40.0 x 10.0 m. Explicit ``bounds_min``/``bounds_max`` override it.
    """

    margin_xy: float = 2.5
    margin_z: float = 2.5
    square: bool = True
    bounds_min: Optional[tuple] = None
    bounds_max: Optional[tuple] = None


@dataclass(frozen=True)
class MapConfig:
    """The occupancy map (OctoMap) and its entropy."""

    resolution: float = 0.2  # m (authors: 0.2)
    prob_hit: float = 0.7
    prob_miss: float = 0.4
    clamp_min: float = 0.12
    clamp_max: float = 0.97
    occupancy_threshold: float = 0.6  # authors' setup; see OccupancyMapOptions
    entropy_unit: str = "nats"  # "nats" (authors) or "bits"
    clamped_entropy_zero: bool = True  # authors: cells at a clamping bound count zero entropy
    fast_integration: bool = True  # de-duplicated ray ends; False = plain insertPointCloud
    clip_to_workspace: bool = True  # map only workspace cells (the method reads nothing outside)


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D camera (paper Table 1); mount = T_body_sensor as xyz (m) + roll/pitch/yaw (deg)."""

    width: int = _CAM.width
    height: int = _CAM.height
    hfov_deg: float = _CAM.hfov_deg
    vfov_deg: float = _CAM.vfov_deg
    min_range: float = _CAM.min_range
    max_range: float = _CAM.max_range
    noise_k: float = _CAM.noise_k  # the authors used 0.0025 (sigma = k z^2)
    mount_xyz: tuple = (0.0, 0.0, 0.0)
    mount_rpy_deg: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class LaserConfig:
    """The 2D laser scanner (paper Table 1)."""

    fov_deg: float = _LAS.fov_deg
    resolution_deg: float = _LAS.resolution_deg
    min_range: float = _LAS.min_range
    max_range: float = _LAS.max_range
    noise_sigma: float = _LAS.noise_sigma
    mount_xyz: tuple = (0.0, 0.0, 0.0)
    mount_rpy_deg: tuple = (0.0, 10.0, 0.0)  # pitched 10 deg down (Table 1)


@dataclass(frozen=True)
class CloudConfig:
    """The reconstructed point clouds."""

    camera_voxel: float = 0.02  # m, authors' RGB-D voxel filter
    laser_voxel: float = 0.1  # m, authors' profile voxel filter
    min_z: float = 0.3  # m, points below are ground and not registered


@dataclass(frozen=True)
class VehicleConfig:
    """The UAV: collision sphere and how it flies between views."""

    collision_radius: float = 0.8  # m
    # what to do when the straight segment to a candidate crosses occupied/unknown space:
    # "reject" the candidate, or "plan" a path through known free space (A* on the map)
    blocked_path: str = "reject"
    # unknown cells within this radius of the start pose are known free before the first scan:
    # the vehicle flew there (no sensor sees its own surroundings). With less than ~2 m the strict
    # "no unknown cell within the collision radius" rule leaves a camera-only start (Scenario 1)
    # only yaw turns: every 1 m step's sphere reaches outside the camera's 45 deg vertical FOV.
    # 0 disables
    start_clear_radius: float = 3.0
    # the vehicle's own swept volume (collision radius along the flown path) is known free
    clear_swept_volume: bool = True


@dataclass(frozen=True)
class SamplingConfig:
    """Viewpoint sampling, Eq. 2: CGVS lattice and the AGVS scale sigma**alpha."""

    method: str = "agvs"  # "cgvs" (alpha fixed at 0) or "agvs"
    delta_d: float = 1.0  # m
    delta_theta: float = math.pi / 4  # rad
    sigma: float = 1.5
    alpha_max: int = 5
    stuck_threshold: float = 0.005  # |dE_v| below this counts as stuck (paper)
    stuck_window: int = 3  # consecutive stuck iterations before alpha grows (paper)
    scale_cap: Optional[float] = None  # authors' code: 7.5
    oscillation_is_stuck: bool = False  # authors' code: an A-B-A-B oscillation counts as stuck


@dataclass(frozen=True)
class UtilityConfig:
    """Viewpoint evaluation, sec. 3.4."""

    name: str = "ig"  # "ig" (paper) or "ig_distance" (IG * exp(-lambda * distance))
    rays_x: Optional[int] = None  # None: one ray per map cell on the far plane (47 at 0.2 m)
    rays_y: Optional[int] = None  # None: 34 at 0.2 m
    distance_lambda: float = 0.5  # 1/m, for ig_distance (authors' w = 0.5)
    # a view must see an occupied cell (paper); with a value, a cell with p above it (authors: 0.8)
    require_occupied_probability: Optional[float] = None


@dataclass(frozen=True)
class TerminationConfig:
    """Termination, sec. 3.5: |dE_v| < threshold for `window` iterations."""

    threshold: float = 0.001  # |dE_v| (paper)
    window: int = 5  # consecutive iterations (paper)
    count_partial_cells: bool = True  # C_view counts cells the frustum touches partially


@dataclass(frozen=True)
class ProfilingConfig:
    """Adaptive circular profiling (Algorithm 1) and the bounding-box profiler."""

    method: str = "circular"  # "circular" (Algorithm 1) or "bbox" (fly the faces of the box)
    waypoints: int = 5  # N, points around the structure (authors: 5)
    margin: float = 4.0  # d, obstacle margin added to the bounding radius, m (authors: 4)
    sweep_step: float = 0.025  # m between laser scans: a 40 Hz scanner at 1 m/s (authors)
    z_min: Optional[float] = None  # sweep bounds; None: the workspace's z range
    z_max: Optional[float] = None
    max_segment: float = 7.0  # arcs are flown as straight segments of at most this length, m
    flight_margin: float = 30.0  # the profiling flight volume: workspace grown by this, m


@dataclass(frozen=True)
class SymmetryConfig:
    """Symmetry detection and prediction (sec. 3.2.2), owned by nbvkit.symmetry.

    The defaults equal nbvkit.symmetry.SymmetryOptions() / SymmetricPredictionOptions() (a test
    checks)."""

    prediction_probability: float = 0.6  # paper (authors' code: 0.7)
    keypoints: str = "sift"  # "sift" (authors: 3D SIFT on curvature), "iss" or "uniform"
    voxel_size: float = 0.2  # m, downsampling before detection (2x the profile's voxel: measured)
    icp_voxel_size: float = 0.1  # m, downsampling before ICP (the profile's laser voxel)
    normal_k: int = 50  # neighbours for normals (authors: K = 50)
    fpfh_radius: float = 1.0  # m, FPFH support radius
    mirror_descriptors: bool = True  # match against mirrored FPFH (False: authors' plain match)
    bandwidth: float = 0.08  # mean shift: |dn| (~rad) and d-offset / cloud RMS radius
    mean_shift_seeds: int = 50  # (authors: 50)
    candidate_modes: int = 10  # modes refined and scored; the most mirror-consistent wins
    min_support: int = 8  # pairs voting for the plane, at least
    min_confidence: float = 0.7  # mirror consistency of surfaces facing the plane, at least
    icp: bool = True  # refine the plane by ICP of the reflection onto the profile (paper)
    icp_max_correspondence: float = 1.0  # m (authors: 1)
    explained_tolerance: float = 0.2  # m, reflections this near an observed point: not predicted


@dataclass(frozen=True)
class EvaluationConfig:
    """Scoring against the ground truth."""

    gt_density: Optional[float] = None  # points per m^2; None: nbvkit.evaluate's default
    coverage_every: int = 25  # iterations between coverage refreshes in the progress/CSV


@dataclass(frozen=True)
class Config:
    """A mission: scenario (Table 2 row), start (0..4), NBV iteration cap, and the sections."""

    seed: int = 0  # camera/laser noise and sampling seed; the same seed gives the same mission
    scenario: str = "5"  # profile, 1..5 (Table 2); 5 = profiling + symmetry + AGVS
    start: int = 0  # which of the five predefined start poses
    start_pose: Optional[tuple] = None  # (x, y, z, yaw) instead of a predefined start
    max_iterations: int = 1000  # cap on NBV iterations
    progress: bool = True  # progress bar on stderr
    mesh: MeshConfig = field(default_factory=MeshConfig)
    workspace: WorkspaceConfig = field(default_factory=WorkspaceConfig)
    map: MapConfig = field(default_factory=MapConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    laser: LaserConfig = field(default_factory=LaserConfig)
    cloud: CloudConfig = field(default_factory=CloudConfig)
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    utility: UtilityConfig = field(default_factory=UtilityConfig)
    termination: TerminationConfig = field(default_factory=TerminationConfig)
    profiling: ProfilingConfig = field(default_factory=ProfilingConfig)
    symmetry: SymmetryConfig = field(default_factory=SymmetryConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: dict | None) -> "Config":
        return _build(cls, data or {}, "")

    @classmethod
    def from_yaml(cls, path: str | Path) -> "Config":
        p = Path(path)
        if not p.exists():
            raise FileNotFoundError(2, "No such config file", str(p))
        data = yaml.safe_load(p.read_text()) or {}
        if not isinstance(data, dict):
            raise ValueError(
                f"config file {p} must hold a mapping of keys, got {type(data).__name__}"
            )
        return cls.from_dict(data)

    def with_overrides(self, overrides: list[str] | dict | None) -> "Config":
        """Apply ``key=value`` strings (dotted keys for nested sections; values parsed as YAML)."""
        if not overrides:
            return self
        items = overrides.items() if isinstance(overrides, dict) else [_split(o) for o in overrides]
        data = self.to_dict()
        for key, value in items:
            _set_dotted(data, key, value)
        return Config.from_dict(data)

    def to_dict(self) -> dict:
        return _to_plain(self)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _split(item: str) -> tuple[str, Any]:
    if "=" not in item:
        raise ValueError(f"override {item!r} must look like key=value")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ValueError(f"override {item!r} has an empty key")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError as e:
        raise ValueError(f"override {item!r}: cannot parse the value: {e}") from None
    return key, value


def _set_dotted(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node = data
    for i, part in enumerate(parts[:-1]):
        if part not in node or not isinstance(node[part], dict):
            raise KeyError(f"unknown config key {'.'.join(parts[:i + 1])!r} (in override {key!r})")
        node = node[part]
    if parts[-1] not in node:
        raise KeyError(f"unknown config key {key!r}")
    node[parts[-1]] = value


def _to_plain(obj: Any) -> Any:
    if is_dataclass(obj):
        return {f.name: _to_plain(getattr(obj, f.name)) for f in fields(obj)}
    if isinstance(obj, tuple):
        return [_to_plain(x) for x in obj]
    return obj


def _build(cls, data: dict, prefix: str):
    if not isinstance(data, dict):
        raise ValueError(f"config section {prefix.rstrip('.') or '<root>'} must be a mapping")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls)}
    for k in data:
        if k not in known:
            raise KeyError(
                f"unknown config key {prefix + str(k)!r}; known keys here: "
                f"{', '.join(sorted(known))}"
            )
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _coerce(hints[name], value, prefix + name)
    obj = cls(**kwargs)
    _validate(obj, prefix)
    return obj


def _coerce(tp, value, key):
    origin = typing.get_origin(tp)
    if is_dataclass(tp):
        return _build(tp, value if value is not None else {}, key + ".")
    if origin is typing.Union:  # Optional[X]
        if value is None:
            return None
        (inner,) = [a for a in typing.get_args(tp) if a is not type(None)]  # noqa: E721
        return _coerce(inner, value, key)
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise ValueError(f"config key {key!r} must be true or false, got {value!r}")
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
            raise ValueError(f"config key {key!r} must be an integer, got {value!r}")
        return int(value)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"config key {key!r} must be a number, got {value!r}")
        return float(value)
    if tp is str:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return str(value)  # e.g. scenario: 5
        if not isinstance(value, str):
            raise ValueError(f"config key {key!r} must be a string, got {value!r}")
        return value
    if tp is tuple:
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value
        ):
            raise ValueError(f"config key {key!r} must be a list of numbers, got {value!r}")
        return tuple(float(x) for x in value)
    return value


_CHOICES = {
    "mesh.up": ("y", "z"),
    "map.entropy_unit": ("nats", "bits"),
    "vehicle.blocked_path": ("reject", "plan"),
    "sampling.method": ("cgvs", "agvs"),
    "utility.name": ("ig", "ig_distance"),
    "scenario": ("profile", "1", "2", "3", "4", "5"),
    "profiling.method": ("circular", "bbox"),
    "symmetry.keypoints": ("sift", "iss", "uniform"),
}
_POSITIVE = {
    "map.resolution",
    "camera.max_range",
    "laser.max_range",
    "cloud.camera_voxel",
    "cloud.laser_voxel",
    "vehicle.collision_radius",
    "sampling.delta_d",
    "sampling.sigma",
    "termination.threshold",
    "sampling.stuck_threshold",
    "mesh.scale",
    "profiling.waypoints",
    "profiling.sweep_step",
    "profiling.max_segment",
}
_NONNEG = {
    "max_iterations",
    "start",
    "sampling.alpha_max",
    "termination.window",
    "sampling.stuck_window",
    "vehicle.start_clear_radius",
    "camera.noise_k",
    "laser.noise_sigma",
    "utility.distance_lambda",
    "evaluation.coverage_every",
    "workspace.margin_xy",
    "workspace.margin_z",
    "sampling.delta_theta",
}
_TRIPLES = {
    "camera.mount_xyz",
    "camera.mount_rpy_deg",
    "laser.mount_xyz",
    "laser.mount_rpy_deg",
    "workspace.bounds_min",
    "workspace.bounds_max",
}


def _validate(obj, prefix: str) -> None:
    for f in fields(obj):
        key = prefix + f.name
        v = getattr(obj, f.name)
        if key in _CHOICES and v not in _CHOICES[key]:
            raise ValueError(
                f"config key {key!r} must be one of {', '.join(_CHOICES[key])}; got {v!r}"
            )
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"config key {key!r} must be finite, got {v!r}")
        if key in _POSITIVE and v is not None and not v > 0:
            raise ValueError(f"config key {key!r} must be positive, got {v!r}")
        if key in _NONNEG and v is not None and v < 0:
            raise ValueError(f"config key {key!r} must be >= 0, got {v!r}")
        if key in _TRIPLES and v is not None and len(v) != 3:
            raise ValueError(f"config key {key!r} must have 3 numbers, got {list(v)!r}")
    if prefix == "" and obj.start_pose is not None and len(obj.start_pose) != 4:
        raise ValueError(
            "config key 'start_pose' must be 4 numbers (x, y, z, yaw), "
            f"got {list(obj.start_pose)!r}"
        )
    if prefix == "" and not 0 <= obj.start <= 4:
        raise ValueError(
            f"config key 'start' must be 0..4 (five predefined starts), got {obj.start}"
        )
    if prefix == "workspace." and (obj.bounds_min is None) != (obj.bounds_max is None):
        raise ValueError(
            "config keys 'workspace.bounds_min' and 'workspace.bounds_max' go together"
        )


def load_config(
    path: str | Path | None = None, overrides: list[str] | dict | None = None
) -> Config:
    """The default configuration, updated from a YAML file and then from overrides."""
    cfg = Config.from_yaml(path) if path else Config()
    return cfg.with_overrides(overrides)


__all__ = ["Config", "load_config"] + [
    c.__name__
    for c in (
        MeshConfig,
        WorkspaceConfig,
        MapConfig,
        CameraConfig,
        LaserConfig,
        CloudConfig,
        VehicleConfig,
        SamplingConfig,
        UtilityConfig,
        TerminationConfig,
        ProfilingConfig,
        SymmetryConfig,
        EvaluationConfig,
    )
]


def documented_yaml() -> str:
    """The default configuration as YAML with each key's comment (configs/default.yaml)."""
    import inspect
    import re

    def comments(cls):
        out = {}
        for line in inspect.getsource(cls).splitlines():
            m = re.match(r"\s+(\w+): [^=]+= ([^#]*)(#\s*(.*))?$", line)
            if m:
                out[m.group(1)] = (m.group(4) or "").strip()
        return out

    def flow(k, v):
        return yaml.safe_dump({k: v}, default_flow_style=True, width=1000).strip()[1:-1]

    lines = [
        "# nbvkit default configuration: every key with its default and unit (generated by",
        "# `python -m nbvkit.config`). Unknown keys are rejected. Use it with",
        "# `nbvkit run --config FILE`, or override single keys: `--set map.resolution=0.4`.",
        "",
    ]
    data = Config().to_dict()
    top = comments(Config)
    for f in fields(Config):
        v = data[f.name]
        if isinstance(v, dict):
            cls = f.default_factory
            doc = (cls.__doc__ or "").strip().splitlines()[0]
            lines.append(f"{f.name}:  # {doc}")
            cm = comments(cls)
            for k, val in v.items():
                c = cm.get(k, "")
                lines.append(f"  {flow(k, val)}" + (f"  # {c}" if c else ""))
        else:
            c = top.get(f.name, "")
            lines.append(flow(f.name, v) + (f"  # {c}" if c else ""))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(documented_yaml(), end="")
