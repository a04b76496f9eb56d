"""Mission configuration: frozen dataclasses, loaded from YAML, with dotted overrides.

One source of truth. A section that sets C++ options (``map``, ``utility``, ``vehicle``,
``targets``) is generated from the bound options class: its keys, defaults and documentation are
the C++ struct's (nbv/options.hpp); ``section.options()`` builds that struct. Other sensor
defaults are read from their bound options; a test checks that every config default equals its
C++ twin. Python-only keys are documented by their comment here. ``configs/default.yaml`` is
generated from all of it (``python -m nbvkit.config``).

Scenarios (nbvkit.scenarios) are presets: resolving a configuration applies the chosen scenario's
settings to every key the user did not set (``Config.from_dict``, ``load_config`` and
``with_overrides`` all resolve). Unknown keys are rejected with the key's full dotted name.
``Config.to_dict()`` gives the resolved configuration written beside every run's results.
"""
from __future__ import annotations


import math
import re
import typing
from dataclasses import dataclass, field, fields, is_dataclass, make_dataclass, replace
from pathlib import Path
from typing import Any, Optional, Tuple

import numpy as np
import yaml

from . import _core
from .cameras import CAMERA_PRESETS
from .limits import (
    MAX_TEXT_FILE_BYTES,
    MAX_VIEW_RAYS,
    MAX_YAML_NODES,
    Bound,
    check_input_file,
    shorten,
)
from .scenarios import DEFAULT as DEFAULT_SCENARIO
from .scenarios import SCENARIOS


class YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader, also reading 1e-4 / 2E5 as numbers (YAML 1.2; PyYAML's YAML 1.1
    resolver wants a dot and a signed exponent, and reads 1e-4 as a string)."""


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _expanded_nodes(node, limit: int, memo: dict) -> int:
    """Nodes of a composed YAML document once its aliases are expanded (an alias repeats its
    anchor's whole subtree); stops counting past `limit`."""
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = limit + 1  # a node reached again while being counted: a cycle
    n = 1
    if isinstance(node, yaml.SequenceNode):
        children = node.value
    elif isinstance(node, yaml.MappingNode):
        children = [x for pair in node.value for x in pair]
    else:
        children = []
    for child in children:
        n += _expanded_nodes(child, limit, memo)
        if n > limit:
            break
    memo[key] = n
    return n


def parse_yaml(text: str, source: str = "<string>"):
    """YAML text parsed with YamlLoader; ValueError "source:line: problem" on a syntax error, and
    for a document whose aliases expand to more than MAX_YAML_NODES nodes (a "billion laughs")."""
    try:
        loader = YamlLoader(text)
        try:
            node = loader.get_single_node()
            if node is not None and _expanded_nodes(node, MAX_YAML_NODES, {}) > MAX_YAML_NODES:
                raise ValueError(
                    f"{source}: the YAML document expands (through its aliases) to more than "
                    f"{MAX_YAML_NODES:,} values, the limit of a configuration"
                )
            return loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        where = f"{source}:{mark.line + 1}" if mark is not None else source
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ValueError(f"{where}: {shorten(problem, 200)}") from None
    except RecursionError:
        raise ValueError(f"{source}: the YAML document is nested too deeply") from None


def read_yaml_file(path, what: str = "YAML file"):
    """A YAML file parsed (see parse_yaml); FileNotFoundError for a missing path, ValueError
    naming the file for anything but a regular file of at most MAX_TEXT_FILE_BYTES (a directory,
    a FIFO, a device), undecodable text or a syntax error."""
    p = check_input_file(path, what, MAX_TEXT_FILE_BYTES)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"cannot read {what} {p}: {shorten(str(e), 200)}") from None
    return parse_yaml(text, str(p))


#: A list of names in the configuration (YAML list of strings).
Names = Tuple[str, ...]


def bounded(default, bound: Bound):
    """A dataclass field with its default and its range (nbvkit.limits.Bound), checked whenever
    a configuration is built; an integer key without a maximum gets limits.MAX_INT."""
    return field(default=default, metadata={"bound": bound})


def positive(default, hi=None):
    """A field whose value must be > 0 (and <= hi; None stays allowed where the type is
    Optional)."""
    return bounded(default, Bound(lo=0, lo_open=True, hi=hi))


def nonneg(default):
    """A field whose value must be >= 0."""
    return bounded(default, Bound(lo=0))


def within(default, lo, hi):
    """A field whose value must lie in [lo, hi]."""
    return bounded(default, Bound(lo=lo, hi=hi))


_CAM = _core.DepthCameraOptions()
_LAS = _core.LaserScannerOptions()


def _py_field(value):
    """(type, default) of a bound C++ option value in the configuration (vectors: tuples)."""
    if isinstance(value, bool):
        return bool, value
    if isinstance(value, int):
        return int, value
    if isinstance(value, float):
        return float, value
    if isinstance(value, str):
        return str, value
    arr = np.asarray(value, float)
    if arr.shape == (3,):
        return tuple, tuple(float(x) for x in arr)
    raise TypeError(f"no configuration type for a C++ option value {value!r}")


def cpp_section(
    name: str, options_cls, doc: str, only=None, before=(), after=(), extra=(), bounds=None
):
    """A frozen config dataclass whose keys mirror a bound C++ options class: their names,
    defaults and documentation come from it (``options_cls.fields()``); `only` keeps some of them.
    `before` / `after`: Python-only keys as (name, type, default, doc). `extra`: more bound
    options classes whose every field is a key too (after the first class's; names must not
    clash). `bounds`: key -> Bound of the keys whose range is checked here (beyond the C++
    options' own checks; every integer key also gets limits.MAX_INT). The class gets
    ``FIELD_DOCS`` (key -> documentation), ``OPTIONS`` (the first bound class), ``OPTIONS_ALL``
    (all of them), ``options()`` (the first C++ options built from this section) and
    ``options_for(cls)`` (any of them)."""
    classes = (options_cls,) + tuple(extra)
    keys = {
        cls: [f for f in cls.fields() if cls is not options_cls or only is None or f in only]
        for cls in classes
    }
    docs, spec, bounds = {}, [], dict(bounds or {})

    def spec_field(fname, default):
        if fname in bounds:
            return bounded(default, bounds.pop(fname))
        return field(default=default)

    for fname, tp, default, fdoc in before:
        spec.append((fname, tp, spec_field(fname, default)))
        docs[fname] = fdoc
    for cls in classes:
        defaults = cls()
        for fname in keys[cls]:
            if fname in docs:
                raise ValueError(f"{name}: key {fname!r} is set twice")
            tp, default = _py_field(getattr(defaults, fname))
            spec.append((fname, tp, spec_field(fname, default)))
            docs[fname] = cls.fields()[fname]
    for fname, tp, default, fdoc in after:
        spec.append((fname, tp, spec_field(fname, default)))
        docs[fname] = fdoc
    if bounds:
        raise ValueError(f"{name}: bounds of unknown keys {sorted(bounds)}")
    cpp_fields = [f for cls in classes for f in keys[cls]]

    def options_for(self, cls):
        return cls(**{f: getattr(self, f) for f in keys[cls]})

    def options(self):
        return options_for(self, options_cls)

    return make_dataclass(
        name,
        spec,
        frozen=True,
        namespace={
            "__doc__": doc,
            "FIELD_DOCS": docs,
            "OPTIONS": options_cls,
            "OPTIONS_ALL": classes,
            "options": options,
            "options_for": options_for,
            "CPP_FIELDS": tuple(cpp_fields),
            "__module__": __name__,
        },
    )


@dataclass(frozen=True)
class MeshConfig:
    """The structure's mesh file."""

    path: Optional[str] = None  # None: the shipped generated airliner
    scale: float = positive(1.0)
    up: str = "z"  # the file's up axis: "z" or "y"
    shift: tuple = (0.0, 0.0, 0.0)  # m added after scale and up; results are in the shifted frame


@dataclass(frozen=True)
class WorkspaceConfig:
    """The NBV workspace (map bounds for entropy, utility and navigation).

    Default: the structure's bounding box grown by ``margin_xy`` on each side and squared up to a
    square footprint (as the paper's 40 x 40 m), from ``min(0, bbox z min)`` (the ground) to
    ``bbox z max + margin_z``. For the shipped airliner (35.0 x 30.0 x 7.5 m) this gives
    40.0 x 40.0 x 10.0 m. Explicit ``bounds_min``/``bounds_max`` override it.
    """

    margin_xy: float = nonneg(2.5)
    margin_z: float = nonneg(2.5)
    square: bool = True
    bounds_min: Optional[tuple] = None
    bounds_max: Optional[tuple] = None


MapConfig = cpp_section(
    "MapConfig",
    _core.OccupancyMapOptions,
    "The occupancy map (OctoMap) and its entropy.",
    before=[
        ("resolution", float, _core.OccupancyMap.DEFAULT_RESOLUTION, "cell edge, m (authors: 0.2)")
    ],
    bounds={"resolution": Bound(lo=0, lo_open=True)},
)


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D camera (paper Table 1); mount = T_body_sensor as xyz (m) + roll/pitch/yaw (deg).

    The camera rides a gimbal between the body and its mount: a view is (x, y, z, yaw, pitch),
    T_world_camera = T(x, y, z) Rz(yaw) Ry(pitch) mount, pitch > 0 looking DOWN (REP-103, the
    sign of mount_rpy_deg's pitch). ``gimbal_pitch_deg`` [min, max] is the pitch range it can
    hold, in degrees within [-90, 90]: [-30, 90] is 30 deg up to straight down, as inspection
    UAVs; [0, 0] the fixed level camera (the paper's scenarios)."""

    preset: str = "rgbd"  # a named camera (nbvkit.cameras): rgbd (the paper's), inspection
    width: int = within(_CAM.width, 1, 16_000)
    height: int = within(_CAM.height, 1, 16_000)
    hfov_deg: float = _CAM.hfov_deg
    vfov_deg: float = _CAM.vfov_deg
    min_range: float = _CAM.min_range
    max_range: float = positive(_CAM.max_range, 1000)
    noise_k: float = nonneg(_CAM.noise_k)  # the authors used 0.0025 (sigma = k z^2)
    mount_xyz: tuple = (0.0, 0.0, 0.0)
    mount_rpy_deg: tuple = (0.0, 0.0, 0.0)
    gimbal_pitch_deg: tuple = (-30.0, 90.0)  # [min, max] deg, > 0 looks down; [0, 0]: level


@dataclass(frozen=True)
class LaserConfig:
    """The 2D laser scanner (paper Table 1)."""

    fov_deg: float = _LAS.fov_deg
    resolution_deg: float = _LAS.resolution_deg
    min_range: float = _LAS.min_range
    max_range: float = positive(_LAS.max_range, 1000)
    noise_sigma: float = nonneg(_LAS.noise_sigma)
    mount_xyz: tuple = (0.0, 0.0, 0.0)
    mount_rpy_deg: tuple = (0.0, 10.0, 0.0)  # pitched 10 deg down (Table 1)


_CLOUD = _core.SurfaceCloudOptions()


@dataclass(frozen=True)
class CloudConfig:
    """The reconstructed point clouds."""

    camera_voxel: float = positive(_CLOUD.voxel_size)  # m, authors' RGB-D voxel filter
    laser_voxel: float = positive(0.1)  # m, authors' profile voxel filter
    min_z: float = _CLOUD.min_z  # m above the ground (workspace.ground_height): lower dropped


VehicleConfig = cpp_section(
    "VehicleConfig",
    _core.ValidityOptions,
    "The UAV: collision sphere and how it flies between views.",
    only=("collision_radius", "blocked_path"),
    after=[
        (
            "start_clear_radius",
            float,
            3.0,
            "m; unknown cells this near the start are known free before the first scan: the "
            "vehicle took off there (with less than ~2 m the strict collision rule leaves a "
            "camera-only start only yaw turns: every 1 m step's sphere reaches outside the "
            "camera's 45 deg vertical FOV); 0 disables",
        ),
        (
            "clear_swept_volume",
            bool,
            True,
            "the vehicle's own swept volume (collision radius along the flown path) is known free",
        ),
        (
            "widen_swept_volume",
            bool,
            True,
            "the swept volume made known free reaches half a cell diagonal past the collision "
            "radius, so the cells the flown path crosses pass A*'s test (the sphere at each cell's "
            "centre) and the vehicle can always plan its way back along its own flight; false: "
            "the radius alone (the paper's scenarios)",
        ),
        (
            "path_expansions",
            int,
            200000,
            "cells an A* search to a view expands at most; a view the vehicle's free component "
            "holds is searched again without the cap",
        ),
    ],
    bounds={
        "collision_radius": Bound(lo=0, lo_open=True),
        "start_clear_radius": Bound(lo=0, hi=1000),
        "path_expansions": Bound(lo=1, hi=400_000_000),
    },
)


@dataclass(frozen=True)
class SamplingConfig:
    """Viewpoint sampling, Eq. 2: CGVS lattice and the AGVS scale sigma**alpha."""

    method: str = "agvs"  # "cgvs" (alpha fixed at 0) or "agvs"
    delta_d: float = positive(1.0)  # m
    delta_theta: float = nonneg(math.pi / 4)  # rad
    sigma: float = positive(1.5)
    alpha_max: int = within(5, 0, 100)
    stuck_threshold: float = positive(0.005)  # |dE_v| below this counts as stuck (paper)
    stuck_window: int = within(3, 1, 10**6)  # stuck iterations in a row before alpha grows
    scale_cap: Optional[float] = positive(None)  # authors' code: 7.5
    oscillation_is_stuck: bool = False  # authors' code: an A-B-A-B oscillation counts as stuck


UtilityConfig = cpp_section(
    "UtilityConfig",
    _core.UtilityOptions,
    "How candidate views are scored (paper sec. 3.4 and the peers' utilities).",
    before=[
        (
            "rays_x",
            Optional[int],
            None,
            "rays across the horizontal FOV; null: one per map cell on the far plane (47 at 0.2 m)",
        ),
        ("rays_y", Optional[int], None, "rays across the vertical FOV; null: 34 at 0.2 m"),
    ],
    bounds={
        "rays_x": Bound(lo=0, lo_open=True, hi=4096),
        "rays_y": Bound(lo=0, lo_open=True, hi=4096),
        "distance_lambda": Bound(lo=0),
    },
)

TargetsConfig = cpp_section(
    "TargetsConfig",
    _core.SurfaceTargetOptions,
    "Surface still to observe, which the surface planners aim views at.",
)


@dataclass(frozen=True)
class PlacementConfig:
    """Views aimed at surface targets (tour and frontier generators)."""

    cluster_size: float = positive(1.5)  # m; targets grouped per cube of this size and side faced
    standoffs: tuple = (0.45, 0.7)  # view distances from a target patch, x camera.max_range
    azimuth_spread_deg: float = within(30.0, 0, 180)  # views this far either side of the normal
    elevation_margin_deg: float = within(4.0, 0, 90)  # patches kept this far inside vertical FOV


@dataclass(frozen=True)
class TourConfig:
    """The coverage-tour generator: set cover of views over the surface targets, a shortest
    tour through them, flown; then again, until no planned view is worth its flight."""

    # how a plan chooses views: "cover" (greedy set cover, then a shortest tour) or "insertion"
    # (prize-collecting: new surface - rate x added tour length, by cheapest insertion)
    selection: str = "insertion"
    min_gain: float = nonneg(1.2)  # m^2 of new surface a view must add to enter a plan (RESULTS.md)
    rate: float = nonneg(0.75)  # m^2 of new surface per metre of tour a planned view must pay for
    max_plans: int = within(0, 0, 10**6)  # tours planned at most (0: until a plan is empty)
    # a stranded patch: all its views fail the collision test for want of known free space;
    # a view whose rays reach where they would be gets this share of its weight
    access_weight: float = nonneg(0.0)  # a stranded patch's share credited to a view opening it
    # once no view of the surface the map shows is worth its flight, plans also weigh views of
    # the unknown space within the structure's extent (unknown cells bordering free space)
    explore: bool = True  # then also plan views that open unknown space; false: stop there


@dataclass(frozen=True)
class FrontierConfig:
    """The frontier generator: views aimed at the nearest surface targets, each iteration."""

    patches: int = within(40, 1, 100_000)  # target patches per iteration: nearest, heaviest first


@dataclass(frozen=True)
class PlannerConfig:
    """The planner's parts (nbvkit.planning): generators, terminations, how a view is chosen."""

    generators: Names = ("tour",)  # lattice | frontier | tour (first with views left leads)
    terminations: Names = ("budget",)  # entropy | stall | budget (any one ends the mission)
    min_gain: float = nonneg(0.8)  # m^2 of new surface (surface utility; else utility units); 0 any
    travel_lambda: float = nonneg(0.15)  # 1/m; a view ranks by utility * exp(-travel_lambda * path)
    # on a smaller structure (mapped surface A), m^2 thresholds x A/reference_area, tour.rate x
    # its square root (parts.threshold_scale); the profiles of the 35 m airliners map 417-502 m^2
    reference_area: float = nonneg(400.0)  # m^2 of mapped surface below which thresholds shrink


@dataclass(frozen=True)
class StallConfig:
    """Surface-coverage stall: the chosen views stopped adding surface."""

    window: int = within(5, 1, 10**6)  # consecutive views
    min_gain: float = nonneg(0.8)  # m^2 of new surface each added, at most


@dataclass(frozen=True)
class BudgetConfig:
    """Hard limits (0: none), checked after every view."""

    max_distance_m: float = nonneg(0.0)
    max_views: int = nonneg(0)
    max_time_s: float = nonneg(0.0)


@dataclass(frozen=True)
class TerminationConfig:
    """Termination, sec. 3.5: |dE_v| < threshold for `window` iterations."""

    threshold: float = positive(0.001)  # |dE_v| (paper)
    window: int = within(5, 1, 10**6)  # consecutive iterations (paper)
    count_partial_cells: bool = True  # C_view counts cells the frustum touches partially


@dataclass(frozen=True)
class ProfilingConfig:
    """Adaptive circular profiling (Algorithm 1), its grown-hull variant and the bounding-box
    profiler."""

    enabled: bool = True  # fly the laser profile before the camera
    # circular (Algorithm 1), hull (its loop round the grown XY hull) or bbox (the box's faces)
    method: str = "hull"
    waypoints: int = within(4, 1, 1000)  # N, points around the structure (authors: 5)
    margin: float = positive(4.0, 1e4)  # d: margin added to the bounding radius, m (authors: 4)
    sweep_step: float = positive(0.025)  # m between laser scans: a 40 Hz scanner at 1 m/s (authors)
    camera_step: float = nonneg(1.0)  # m between profile camera frames; 0: none (paper)
    z_min: Optional[float] = None  # sweep bounds; None: the workspace's z range
    z_max: Optional[float] = None
    max_segment: float = positive(7.0)  # arcs are flown as straight segments of at most this, m
    flight_margin: float = within(30.0, 0, 1e4)  # the flight volume: workspace grown by this, m
    # fly the last arc back to the first waypoint after the last sweep (Algorithm 1's loop)
    close_circle: bool = False
    return_to_start: bool = False  # fly back to the start pose before the camera stage
    arcs: str = "descending"  # level (Algorithm 1), or descending from one sweep end to the other


SymmetryConfig = cpp_section(
    "SymmetryConfig",
    _core.SymmetryOptions,
    """Symmetry detection and prediction (sec. 3.2.2), owned by nbvkit.symmetry.

    The mission's keys, then every option of detect_symmetry (SymmetryOptions) and of
    predict_symmetric (SymmetricPredictionOptions), named, defaulted and documented by the C++
    structs.""",
    before=[
        ("mode", str, "predict", "none | report (detect, write nothing) | predict (into the map)"),
        ("refresh_every", int, 10, "views between re-predictions from the camera cloud (0: never)"),
        ("prediction_probability", float, 0.6, "of a predicted cell (paper; authors' code: 0.7)"),
    ],
    extra=(_core.SymmetricPredictionOptions,),
    bounds={
        "refresh_every": Bound(lo=0, hi=10**6),
        "prediction_probability": Bound(lo=0.5, hi=1, lo_open=True, hi_open=True),
        "max_descriptor_distance": Bound(inf=True),
        "normal_k": Bound(hi=1000),
        "sift_octaves": Bound(hi=16),
        "sift_scales_per_octave": Bound(hi=32),
        "matches_per_keypoint": Bound(hi=100),
        "mean_shift_seeds": Bound(hi=10_000),
        "mean_shift_max_iterations": Bound(hi=100_000),
        "candidate_modes": Bound(hi=1000),
        "refine_iterations": Bound(hi=1000),
        "refine_max_points": Bound(hi=10**7),
        "icp_normal_k": Bound(hi=1000),
        "icp_max_iterations": Bound(hi=100_000),
    },
)


@dataclass(frozen=True)
class EvaluationConfig:
    """Scoring against the ground truth."""

    gt_density: Optional[float] = positive(None)  # points per m^2; None: nbvkit.evaluate's default
    coverage_every: int = nonneg(25)  # iterations between coverage refreshes in the progress/CSV


ObservabilityConfig = cpp_section(
    "ObservabilityConfig",
    _core.ObservabilityOptions,
    "The observable surface (nbvkit.observable_surface): what the camera could see at all.",
    only=("pose_spacing", "max_incidence_deg", "yaw_steps"),  # the radius is the vehicle's
    before=[
        (
            "enabled",
            bool,
            True,
            "compute it at the end of a mission (cached under the run/sweep folder)",
        )
    ],
    bounds={
        "pose_spacing": Bound(lo=0, lo_open=True),
        "max_incidence_deg": Bound(lo=0, lo_open=True),
        "yaw_steps": Bound(lo=0, hi=180),
    },
)


@dataclass(frozen=True)
class ReportConfig:
    """End-of-run outputs: mesh.ply (Poisson), figures/coverage.png, report.html."""

    enabled: bool = True  # write them at the end of every mission
    mesh: bool = True  # reconstruct and score mesh.ply from the final cloud
    poisson_depth: int = within(8, 1, 12)  # octree depth of open3d's Poisson (experiments: 7)
    mesh_max_points: int = within(60000, 1, 10**7)  # the cloud is voxel-thinned to ~this many
    density_quantile: float = within(0.05, 0, 1)  # vertices of the lowest Poisson densities trimmed
    trim_distance: float = nonneg(0.3)  # m; vertices farther than this from the cloud are trimmed
    html: bool = True  # write report.html (plotly, self-contained)
    view_points: int = within(50000, 1, 2 * 10**6)  # ground-truth samples in the report's 3D view


@dataclass(frozen=True)
class Config:
    """A mission: scenario (Table 2 row), start (0..4), NBV iteration cap, and the sections."""

    seed: int = within(0, 0, 2**64 - 2)  # noise and sampling seed; same seed, same mission
    scenario: str = DEFAULT_SCENARIO  # a preset (nbvkit.scenarios): profile, 1..5, surface, ...
    start: int = within(0, 0, 4)  # which of the five predefined start poses
    start_pose: Optional[tuple] = None  # (x, y, z, yaw[, pitch]) instead of a predefined start
    max_iterations: Optional[int] = within(None, 0, 10**6)  # views; null: 0.5 per m^2 of surface
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
    targets: TargetsConfig = field(default_factory=TargetsConfig)
    placement: PlacementConfig = field(default_factory=PlacementConfig)
    tour: TourConfig = field(default_factory=TourConfig)
    frontier: FrontierConfig = field(default_factory=FrontierConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    termination: TerminationConfig = field(default_factory=TerminationConfig)
    stall: StallConfig = field(default_factory=StallConfig)
    budget: BudgetConfig = field(default_factory=BudgetConfig)
    profiling: ProfilingConfig = field(default_factory=ProfilingConfig)
    symmetry: SymmetryConfig = field(default_factory=SymmetryConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    observability: ObservabilityConfig = field(default_factory=ObservabilityConfig)
    report: ReportConfig = field(default_factory=ReportConfig)
    # what the user set (nested dict), applied over the scenario's preset; not a key
    _user: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        # the scenario's preset fills every key the user did not set (Config() resolves too)
        if self.scenario not in SCENARIOS:
            raise ValueError(
                f"config key 'scenario' must be one of {', '.join(SCENARIOS)}; "
                f"got {shorten(self.scenario)}"
            )
        for key, value in SCENARIOS[self.scenario].settings.items():
            if not _has_dotted(self._user, key):
                _set_field(self, key, value)
        # then the named camera's keys (and its stand-off room), under what the user set
        for key, value in CAMERA_PRESETS.get(self.camera.preset, {}).items():
            if not _has_dotted(self._user, key):
                _set_field(self, key, value)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: dict | None) -> "Config":
        """A configuration from a nested dict of the keys to set; the rest come from the
        scenario's preset and the defaults."""
        return _build(cls, dict(data or {}), "")

    @classmethod
    def from_yaml(cls, path: str | Path) -> "Config":
        p = Path(path)
        data = read_yaml_file(p, "config file") or {}
        if not isinstance(data, dict):
            raise ValueError(
                f"config file {p} must hold a mapping of keys, got {type(data).__name__}"
            )
        return cls.from_dict(data)

    def with_overrides(self, overrides: list[str] | dict | None) -> "Config":
        """Apply ``key=value`` strings (dotted keys for nested sections; values parsed as YAML)
        on top of what the user set so far; a new scenario brings its own preset."""
        if overrides is None:
            return self
        if isinstance(overrides, str) or not isinstance(overrides, (list, tuple, dict)):
            raise TypeError(
                "overrides must be a list of 'key=value' strings or a dict, "
                f"got {type(overrides).__name__}"
            )
        if not overrides:
            return self
        if not isinstance(overrides, dict) and not all(isinstance(o, str) for o in overrides):
            raise TypeError("overrides must be a list of 'key=value' strings")
        items = overrides.items() if isinstance(overrides, dict) else [_split(o) for o in overrides]
        data = _deep_copy(self._user)
        for key, value in items:
            _check_dotted(key)
            _put_dotted(data, key, value)
        return Config.from_dict(data)

    def to_dict(self) -> dict:
        return _to_plain(self)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _split(item: str) -> tuple[str, Any]:
    if "=" not in item:
        raise ValueError(f"override {shorten(item)} must look like key=value")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ValueError(f"override {shorten(item)} has an empty key")
    try:
        value = parse_yaml(raw) if raw.strip() else None
    except ValueError as e:
        raise ValueError(f"override {shorten(item)}: cannot parse the value: {e}") from None
    return key, value


def _set_dotted(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node = data
    for i, part in enumerate(parts[:-1]):
        if part not in node or not isinstance(node[part], dict):
            raise KeyError(
                f"unknown config key {shorten('.'.join(parts[:i + 1]))} "
                f"(in override {shorten(key)})"
            )
        node = node[part]
    if parts[-1] not in node:
        raise KeyError(f"unknown config key {shorten(key)}")
    node[parts[-1]] = value


def _check_dotted(key: str) -> None:
    """KeyError naming `key` unless it is a key of the configuration."""
    _set_dotted(Config().to_dict(), key, None)


def _put_dotted(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node = data
    for part in parts[:-1]:
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ValueError(f"config key {key!r}: {part!r} is not a section")
    node[parts[-1]] = value


def _has_dotted(data: dict, key: str) -> bool:
    node = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def _set_field(cfg, key: str, value) -> None:
    """Sets a (nested) field of a frozen config in place, coerced to its type (presets)."""
    parts = key.split(".")
    chain = [cfg]
    for part in parts[:-1]:
        chain.append(getattr(chain[-1], part))
    hint = typing.get_type_hints(type(chain[-1]))[parts[-1]]
    new = replace(chain[-1], **{parts[-1]: _coerce(hint, value, key)}) if len(chain) > 1 else None
    if new is None:
        object.__setattr__(cfg, parts[-1], _coerce(hint, value, key))
        return
    for obj, part in zip(reversed(chain[:-1]), reversed(parts[:-1])):
        if obj is cfg:
            object.__setattr__(cfg, part, new)
            return
        new = replace(obj, **{part: new})


def _deep_copy(d):
    return {k: _deep_copy(v) if isinstance(v, dict) else v for k, v in d.items()}


def _to_plain(obj: Any) -> Any:
    if is_dataclass(obj):
        return {
            f.name: _to_plain(getattr(obj, f.name))
            for f in fields(obj)
            if not f.name.startswith("_")
        }
    if isinstance(obj, tuple):
        return [_to_plain(x) for x in obj]
    return obj


def _build(cls, data: dict, prefix: str):
    if not isinstance(data, dict):
        raise ValueError(f"config section {prefix.rstrip('.') or '<root>'} must be a mapping")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls) if not f.name.startswith("_")}
    for k in data:
        if k not in known:
            raise KeyError(
                f"unknown config key {shorten(prefix + str(k))}; known keys here: "
                f"{', '.join(sorted(known))}"
            )
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _coerce(hints[name], value, prefix + name)
    if cls is Config:
        kwargs["_user"] = _deep_copy(data)  # what the scenario's preset must not override
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
        raise ValueError(f"config key {key!r} must be true or false, got {shorten(value)}")
    if tp is int:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or (isinstance(value, float) and not (math.isfinite(value) and value == int(value)))
        ):
            raise ValueError(f"config key {key!r} must be an integer, got {shorten(value)}")
        return int(value)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"config key {key!r} must be a number, got {shorten(value)}")
        try:
            return float(value)
        except OverflowError:  # an integer past 1e308
            raise ValueError(f"config key {key!r} must be finite, got {shorten(value)}") from None
    if tp is str:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return str(value)  # e.g. scenario: 5
        if not isinstance(value, str):
            raise ValueError(f"config key {key!r} must be a string, got {shorten(value)}")
        return value
    if tp == Names:
        if (
            isinstance(value, str)
            or not isinstance(value, (list, tuple))
            or not all(isinstance(x, str) for x in value)
        ):
            raise ValueError(f"config key {key!r} must be a list of names, got {shorten(value)}")
        return tuple(value)
    if tp is tuple:
        if (
            not isinstance(value, (list, tuple))
            or len(value) > 16
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
        ):
            raise ValueError(f"config key {key!r} must be a list of numbers, got {shorten(value)}")
        try:
            return tuple(float(x) for x in value)
        except OverflowError:
            raise ValueError(f"config key {key!r} must be finite, got {shorten(value)}") from None
    return value


_CHOICES = {
    "mesh.up": ("y", "z"),
    "map.entropy_unit": ("nats", "bits"),
    "vehicle.blocked_path": ("reject", "plan"),
    "sampling.method": ("cgvs", "agvs"),
    "utility.name": tuple(_core.utility_names()),
    "camera.preset": tuple(CAMERA_PRESETS),
    "scenario": tuple(SCENARIOS),
    "symmetry.mode": ("none", "report", "predict"),
    "tour.selection": ("cover", "insertion"),
    "profiling.method": ("circular", "hull", "bbox"),
    "profiling.arcs": ("level", "descending"),
    "symmetry.keypoints": ("sift", "iss", "uniform"),
}
_TRIPLES = {
    "mesh.shift",
    "camera.mount_xyz",
    "camera.mount_rpy_deg",
    "laser.mount_xyz",
    "laser.mount_rpy_deg",
    "workspace.bounds_min",
    "workspace.bounds_max",
}


def field_bound(cls, f) -> Bound:
    """The range of field `f` of config class `cls` (its declared Bound; an integer key without
    a maximum gets limits.MAX_INT; NaN and infinities are refused unless it says so)."""
    hint = typing.get_type_hints(cls)[f.name]
    if typing.get_origin(hint) is typing.Union:  # Optional[X]
        (hint,) = [a for a in typing.get_args(hint) if a is not type(None)]  # noqa: E721
    return f.metadata.get("bound", Bound()).for_type(hint)


def bounds_table() -> list[tuple[str, str, str, str]]:
    """(key, type, default, range) of every numeric key of the configuration (docs)."""
    rows = []

    def walk(cls, prefix):
        for f in fields(cls):
            if f.name.startswith("_"):
                continue
            hint = typing.get_type_hints(cls)[f.name]
            if is_dataclass(hint):
                walk(hint, prefix + f.name + ".")
                continue
            inner = hint
            if typing.get_origin(hint) is typing.Union:
                (inner,) = [a for a in typing.get_args(hint) if a is not type(None)]  # noqa: E721
            if inner in (int, float):
                default = getattr(cls(), f.name) if cls is not Config else getattr(Config(), f.name)
                rng = field_bound(cls, f).describe() or "any finite"
                rows.append((prefix + f.name, inner.__name__, repr(default), rng))

    walk(Config, "")
    return rows


def _validate(obj, prefix: str) -> None:
    for f in fields(obj):
        key = prefix + f.name
        v = getattr(obj, f.name)
        if key in _CHOICES and v not in _CHOICES[key]:
            raise ValueError(
                f"config key {key!r} must be one of {', '.join(_CHOICES[key])}; got {shorten(v)}"
            )
        field_bound(type(obj), f).check(key, v)
        if key in _TRIPLES and v is not None:
            if len(v) != 3:
                raise ValueError(f"config key {key!r} must have 3 numbers, got {shorten(list(v))}")
            if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in v):
                raise ValueError(
                    f"config key {key!r} must be 3 finite numbers, got {shorten(list(v))}"
                )
    if hasattr(obj, "OPTIONS"):  # a section of C++ options: their own checks, named here
        try:
            for cls in obj.OPTIONS_ALL:
                obj.options_for(cls)
        except (ValueError, TypeError) as e:
            raise _section_error(obj, prefix.rstrip("."), e) from None
    if prefix == "placement." and not (obj.standoffs and all(0 < x <= 1 for x in obj.standoffs)):
        raise ValueError(
            "config key 'placement.standoffs' must be fractions of the camera range in (0, 1], "
            f"got {shorten(list(obj.standoffs))}"
        )
    if prefix == "planner.":
        from .planning.registry import check_names

        check_names(obj.generators, obj.terminations)
    if prefix == "camera.":
        _check_gimbal(obj.gimbal_pitch_deg)
    if prefix == "" and obj.start_pose is not None and len(obj.start_pose) not in (4, 5):
        raise ValueError(
            "config key 'start_pose' must be 4 numbers (x, y, z, yaw) or 5 (x, y, z, yaw, "
            f"pitch), got {shorten(list(obj.start_pose))}"
        )
    if prefix == "" and obj.start_pose is not None:
        if not all(math.isfinite(x) for x in obj.start_pose):
            raise ValueError(
                f"config key 'start_pose' must be finite numbers, got {list(obj.start_pose)!r}"
            )
        if len(obj.start_pose) == 5:
            lo, hi = obj.camera.gimbal_pitch_deg
            pitch = math.degrees(obj.start_pose[4])
            if not lo - 1e-9 <= pitch <= hi + 1e-9:
                raise ValueError(
                    f"config key 'start_pose': its pitch {obj.start_pose[4]!r} rad "
                    f"({pitch:g} deg) is outside camera.gimbal_pitch_deg [{lo:g}, {hi:g}] deg"
                )
    if prefix == "" and not obj.planner.generators and not obj.profiling.enabled:
        raise ValueError(
            "config key 'planner.generators' is empty and profiling is off "
            "(profiling.enabled = false): the mission would fly nothing; name a generator "
            f"({', '.join(_generator_names())}) or enable profiling"
        )
    if prefix == "":
        _check_derived(obj)
    if prefix == "workspace." and (obj.bounds_min is None) != (obj.bounds_max is None):
        raise ValueError(
            "config keys 'workspace.bounds_min' and 'workspace.bounds_max' go together"
        )


def _check_gimbal(pitch_range) -> None:
    """Raises ValueError unless camera.gimbal_pitch_deg is [min, max], finite, within [-90, 90]
    deg, min <= max, and holds 0 (the planners fly level views until they choose pitches)."""
    key = "camera.gimbal_pitch_deg"
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
            f"config key {key!r} must include 0 (level): nbvkit's planners fly level views "
            f"until they choose pitches, got {list(pitch_range)!r}"
        )


def _generator_names():
    from .planning.registry import GENERATORS

    return tuple(GENERATORS)


def camera_kwargs(cfg) -> dict:
    """The DepthCamera / DepthCameraOptions keywords of a configuration's camera section."""
    c = cfg.camera
    keys = ("width", "height", "hfov_deg", "vfov_deg", "min_range", "max_range", "noise_k")
    return {k: getattr(c, k) for k in keys}


def laser_kwargs(cfg) -> dict:
    """The LaserScanner / LaserScannerOptions keywords of a configuration's laser section."""
    la = cfg.laser
    keys = ("fov_deg", "resolution_deg", "min_range", "max_range", "noise_sigma")
    return {k: getattr(la, k) for k in keys}


def view_camera(cfg):
    """The scoring camera (ViewCameraModel) of a configuration: one ray per map cell on the far
    plane unless utility.rays_x / rays_y say otherwise; mounted as the camera."""
    c, u = cfg.camera, cfg.utility
    vc = _core.ViewCameraModel.for_resolution(
        c.hfov_deg, c.vfov_deg, c.max_range, cfg.map.resolution
    )
    return vc.copy(
        rays_x=u.rays_x or vc.rays_x,
        rays_y=u.rays_y or vc.rays_y,
        mount=_core.mount_transform(c.mount_xyz, *c.mount_rpy_deg),
        pixel_pitch_deg=max(c.hfov_deg / c.width, c.vfov_deg / c.height),
    )


def _check_derived(cfg) -> None:
    """Builds what a mission derives from the configuration alone (the sensors' options and ray
    counts, the view camera model), so that a bad value fails here, before any work, naming the
    section."""
    u = cfg.utility
    checks = (
        ("camera", lambda: _core.DepthCameraOptions(**camera_kwargs(cfg))),
        ("laser", lambda: _core.LaserScannerOptions(**laser_kwargs(cfg))),
        ("utility", lambda: view_camera(cfg)),
    )
    c = cfg.camera
    if not (u.rays_x and u.rays_y) and 0 < c.hfov_deg < 180 and 0 < c.vfov_deg < 180:
        # the view camera's rays follow the map cells on the far plane (ViewCameraModel.
        # for_resolution): bounded before they are built
        def across(fov):
            return math.ceil(2 * c.max_range * math.tan(math.radians(fov) / 2) / cfg.map.resolution)

        _check_view_rays(cfg, u.rays_x or across(c.hfov_deg), u.rays_y or across(c.vfov_deg))
    for section, build in checks:
        try:
            built = build()
        except (ValueError, TypeError) as e:
            derived = ""
            if section == "utility" and not (u.rays_x and u.rays_y):
                derived = f" (null rays_x / rays_y follow map.resolution = {cfg.map.resolution:g})"
            raise _section_error(getattr(cfg, section), section, e, derived) from None
    _check_view_rays(cfg, built.rays_x, built.rays_y)


def _check_view_rays(cfg, rays_x: int, rays_y: int) -> None:
    """ValueError when the view camera's rays per candidate view exceed MAX_VIEW_RAYS."""
    u = cfg.utility
    rays = rays_x * rays_y
    if rays > MAX_VIEW_RAYS:
        if u.rays_x and u.rays_y:
            fits = f"utility.rays_x x rays_y <= {MAX_VIEW_RAYS:,} would fit"
        else:
            fit = cfg.camera.max_range * math.sqrt(MAX_VIEW_RAYS / rays) * 0.99
            fits = (
                f"camera.max_range <= {fit:.4g} (null utility.rays_x / rays_y give one ray per map "
                f"cell on the far plane at map.resolution = {cfg.map.resolution:g}), or "
                "utility.rays_x / rays_y set, would fit"
            )
        what = (
            "utility.rays_x x rays_y"
            if u.rays_x and u.rays_y
            else f"camera.max_range = {cfg.camera.max_range:g}"
        )
        raise ValueError(
            f"the view camera: {what} makes "
            f"{rays_x} x {rays_y} = {rays:,} rays per candidate view, more than the "
            f"limit {MAX_VIEW_RAYS:,} (checked before any work); {fits}"
        )


def _section_error(section, name: str, e: Exception, extra: str = "") -> ValueError:
    """The ValueError of a section's C++ options check: "config key 'map.prob_hit' must be ..."
    when the C++ message starts with a key of the section, else "config section 'map': ..."."""
    msg = shorten(str(e), 300).strip("'\"")
    if msg.startswith(name + " "):  # "camera hfov_deg must be ..."
        msg = msg[len(name) + 1 :]
    first = msg.split(" ", 1)[0]
    if first in {f.name for f in fields(section)}:  # "prob_hit must be ...": name the key
        return ValueError(f"config key {name + '.' + first!r}{msg[len(first):]}{extra}")
    return ValueError(f"config section {name!r}: {msg}{extra}")


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
        TargetsConfig,
        PlacementConfig,
        TourConfig,
        FrontierConfig,
        PlannerConfig,
        TerminationConfig,
        StallConfig,
        BudgetConfig,
        ProfilingConfig,
        SymmetryConfig,
        EvaluationConfig,
        ObservabilityConfig,
        ReportConfig,
    )
]


def documented_yaml() -> str:
    """The default configuration as YAML with each key's comment (configs/default.yaml)."""
    import inspect
    import re

    def comments(cls):
        if hasattr(cls, "FIELD_DOCS"):  # generated from C++ options: their documentation
            return dict(cls.FIELD_DOCS)
        out = {}
        for line in inspect.getsource(cls).splitlines():
            m = re.match(r"\s+(\w+): [^=]+= ([^#]*)(#\s*(.*))?$", line)
            if m:
                out[m.group(1)] = (m.group(4) or "").strip()
        return out

    def flow(k, v):
        return yaml.safe_dump({k: v}, default_flow_style=True, width=1000).strip()[1:-1]

    def with_range(cls, name, comment):
        """The comment with the key's range appended (numeric keys with a declared bound or an
        integer's maximum)."""
        f = {x.name: x for x in fields(cls)}[name]
        hint = typing.get_type_hints(cls)[name]
        if typing.get_origin(hint) is typing.Union:
            hint = next(a for a in typing.get_args(hint) if a is not type(None))  # noqa: E721
        if hint not in (int, float) or ("bound" not in f.metadata and hint is not int):
            return comment
        rng = field_bound(cls, f).describe()
        rng = rng if rng[:1] in ("(", "[") else f"[{rng}]"  # "(0, 1000]" or "[>= 0]"
        return f"{comment} {rng}" if comment else rng

    lines = [
        "# nbvkit default configuration: every key with its default and unit (generated by",
        "# `python -m nbvkit.config`). Unknown keys are rejected. Use it with",
        "# `nbvkit run --config FILE`, or override single keys: `--set map.resolution=0.4`.",
        f"# These are the defaults of the `{DEFAULT_SCENARIO}` scenario; other scenarios are",
        "# presets over them (nbvkit/scenarios.py) - what you set wins over both.",
        "",
    ]
    data = Config().to_dict()
    top = comments(Config)
    for f in fields(Config):
        if f.name.startswith("_"):
            continue
        v = data[f.name]
        if isinstance(v, dict):
            cls = f.default_factory
            doc = (cls.__doc__ or "").strip().splitlines()[0]
            lines.append(f"{f.name}:  # {doc}")
            cm = comments(cls)
            for k, val in v.items():
                c = with_range(cls, k, cm.get(k, ""))
                lines.append(f"  {flow(k, val)}" + (f"  # {c}" if c else ""))
        else:
            c = with_range(Config, f.name, top.get(f.name, ""))
            lines.append(flow(f.name, v) + (f"  # {c}" if c else ""))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(documented_yaml(), end="")
