"""nbvkit — next-best-view reconstruction of large structures by a simulated UAV.

Frames: world z up. A vehicle pose is (x, y, z, yaw); its body frame is x forward, y left, z up,
rotated by yaw about world z. Sensors look along their own +x; a sensor's mount is the fixed
transform T_body_sensor, so T_world_sensor = T_world_body @ T_body_sensor. The camera rides a
gimbal: a view is (x, y, z, yaw, pitch), T_world_camera = T_world_body @ Ry(pitch) @ T_body_camera
(gimbal_transform; pitch in radians, > 0 looks down as a mount's pitch, 4 numbers mean level);
the laser keeps its fixed mount. Arrays in are (N, 3) float64 (anything array-like is
converted); arrays out are numpy.
"""
from ._core import (  # noqa: F401  (re-exported)
    CandidateRays,
    CandidateRaysView,
    DepthCamera,
    DepthCameraOptions,
    EvaluationOptions,
    LaserScanner,
    LaserScannerOptions,
    Mesh,
    RaycastOptions,
    RaycastScene,
    Scan,
    SurfaceCloudOptions,
    candidate_rays,
    get_num_threads,
    gimbal_transform,
    mount_transform,
    pose_to_transform,
    set_num_threads,
)
from .mesh import default_mesh_path, file_up_axis, load_mesh, mesh_from_open3d, mesh_to_open3d
from ._core import MAX_COORDINATE  # noqa: F401  (the largest coordinate a pose may have, m)
from ._core import nearest_distances  # noqa: F401
from .cloud import PointCloud, read_points, write_points  # noqa: F401
from .evaluation import Evaluator, evaluate  # noqa: F401
from .observability import ObservableSurface, observable_surface  # noqa: F401
from .mapping import (
    CellFlag,
    CellState,
    IntegrationStats,
    OccupancyMap,
    OccupancyMapOptions,
)  # noqa: F401
from .symmetry import SymmetryResult, detect_symmetry, predict_symmetric  # noqa: F401
from .config import Config, load_config  # noqa: F401
from .mission import Mission, MissionError  # noqa: F401
from .world import World  # noqa: F401
from .scenarios import SCENARIOS  # noqa: F401
from .export import export_mission  # noqa: F401
from .planning.registry import (  # noqa: F401  (your own planner parts: docs/PLUGINS.md)
    register_generator,
    register_termination,
    register_utility,
)
from .plugins import load_plugin  # noqa: F401
from .planning.generators.tour import plan_tour  # noqa: F401  (a tour over your own views)
from ._core import CoverageMemo, SurfaceTargets, TourPlan, surface_targets  # noqa: F401
from .scenarios import register_scenario  # noqa: F401
from .experiment_compare import compare  # noqa: F401  (planners side by side: nbvkit compare)

from ._version import __version__  # noqa: F401, E402

__all__ = [
    "Config",
    "Mission",
    "MissionError",
    "World",
    "SCENARIOS",
    "load_config",
    "export_mission",
    "register_generator",
    "register_termination",
    "register_utility",
    "load_plugin",
    "plan_tour",
    "TourPlan",
    "CoverageMemo",
    "SurfaceTargets",
    "surface_targets",
    "register_scenario",
    "compare",
    "DepthCamera",
    "DepthCameraOptions",
    "LaserScanner",
    "LaserScannerOptions",
    "Mesh",
    "RaycastScene",
    "RaycastOptions",
    "Scan",
    "default_mesh_path",
    "get_num_threads",
    "load_mesh",
    "file_up_axis",
    "MAX_COORDINATE",
    "mesh_from_open3d",
    "mesh_to_open3d",
    "gimbal_transform",
    "mount_transform",
    "pose_to_transform",
    "set_num_threads",
    "PointCloud",
    "SurfaceCloudOptions",
    "read_points",
    "write_points",
    "nearest_distances",
    "Evaluator",
    "EvaluationOptions",
    "evaluate",
    "ObservableSurface",
    "observable_surface",
    "CellFlag",
    "CellState",
    "IntegrationStats",
    "OccupancyMap",
    "OccupancyMapOptions",
    "SymmetryResult",
    "detect_symmetry",
    "predict_symmetric",
    "CandidateRays",
    "CandidateRaysView",
    "candidate_rays",
]
