#include "nbv/frame_integration.hpp"

#include "nbv/parallel.hpp"

#include <tbb/parallel_invoke.h>

#include <stdexcept>

namespace nbv {

FrameIntegration integrate_frame(OccupancyMap& map, SurfaceCloud& cloud,
                                 SurfaceObservations& surface, const Scan& scan, double max_range,
                                 const DepthCamera* next_camera, const Pose* next_pose) {
  // Checked first: what any of the three would refuse (the map's origin and points, the cloud's
  // keys, which also check the hits; the observations need finite hits and origin), and the
  // next frame's pose as the camera's scan checks it.
  map.check_sensor_origin(scan.origin, max_range);
  require_finite(scan.free_ends, "free-space ray ends");
  if (bool(next_camera) != bool(next_pose))
    throw std::invalid_argument("integrate_frame: a next frame needs both a camera and a pose");
  Eigen::Isometry3d next_T = Eigen::Isometry3d::Identity();
  if (next_camera) {
    require_pitch(next_pose->pitch, "next camera view");
    next_T = gimbal_sensor_transform(*next_pose, next_camera->options().mount);
    check_sensor_pose(next_T);
  }
  const std::vector<std::uint64_t> keys = cloud.voxel_keys(scan.hits);
  FrameIntegration out;
  const auto integrate_map = [&] { out.map = map.integrate(scan, max_range); };
  const auto add_points = [&] {
    out.cloud_voxels = cloud.add_keyed(scan.hits, keys);
    out.new_cells = surface.add_scan(scan.origin, scan.hits);
  };
  core_arena()->execute([&] {
    if (next_camera)
      tbb::parallel_invoke(integrate_map, add_points,
                           [&] { out.next_scan = next_camera->scan(next_T); });
    else
      tbb::parallel_invoke(integrate_map, add_points);
  });
  return out;
}

}  // namespace nbv
