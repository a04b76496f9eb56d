// Simulated range sensors ray-cast against a mesh: a pinhole RGB-D (depth) camera and a single
// layer 2D laser scanner. Defaults are the paper's Table 1.
//
// Frames: world z up. A sensor looks along its own +x, with y left and z up (REP-103). The laser's
// pose is T_world_sensor = T_world_body * mount, where mount = T_body_sensor is fixed on the
// vehicle; the camera rides a gimbal that pitches it about the body's y axis first:
// T_world_sensor = T_world_body * Ry(pitch) * mount (pitch > 0 looks down; nbv/common.hpp).
#pragma once

#include "nbv/common.hpp"
#include "nbv/options.hpp"
#include "nbv/raycast.hpp"

#include <atomic>
#include <cstdint>
#include <memory>

namespace nbv {

/// One sensor reading in the world frame.
struct Scan {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< sensor origin, world frame
  Points hits;                ///< (N, 3) surface points hit within range, world frame
  Points free_ends;           ///< (M, 3) ends (at max range) of rays that hit nothing within range
  Eigen::VectorXi hit_rays;   ///< (N,) ray index of each hit (camera: v * width + u)
  Eigen::VectorXi free_rays;  ///< (M,) ray index of each free end
  /// The leading hits a coarse frame kept where refine_frame found nothing a denser frame could
  /// add (0 for a scan as cast): SurfaceObservations::add_scan's saturation does not count them.
  Eigen::Index sparse_hits = 0;
  /// Camera: (H, W) depth along the optical axis in metres, inf where no valid return.
  /// Laser: (1, R) range along each beam in metres, inf where no valid return.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> depth;
};

/// Throws std::invalid_argument for a sensor pose no sensor scans from (what scan checks first):
/// a non-finite transform or a position beyond the representable range.
void check_sensor_pose(const Eigen::Isometry3d& T_world_sensor);

/// Bounds on derived ray counts (a typo must not become a multi-gigabyte allocation).
constexpr std::int64_t kMaxCameraPixels = 16'000'000;
constexpr int kMaxLaserBeams = 1'000'000;

#define NBV_DEPTH_CAMERA_OPTIONS(X)                                                              \
  X(int, width, 640, "pixels")                                                                   \
  X(int, height, 480, "pixels")                                                                  \
  X(double, hfov_deg, 60.0, "horizontal field of view, degrees")                                 \
  X(double, vfov_deg, 45.0, "vertical field of view, degrees")                                   \
  X(double, min_range, 0.5, "metres, depth along the optical axis")                              \
  X(double, max_range, 8.0, "metres, depth along the optical axis")                              \
  X(double, noise_k, 0.0, "depth noise sigma = noise_k * z^2 (m); 0.0025 in the authors' setup") \
  X(std::uint64_t, seed, 0, "noise seed")                                                        \
  X(Eigen::Isometry3d, mount, Eigen::Isometry3d::Identity(), "4x4 T_body_sensor")

struct DepthCameraOptions {
  NBV_DEPTH_CAMERA_OPTIONS(NBV_DECLARE_OPTION)

  void validate() const;
};
/// Pinhole depth camera. Pixel (u, v) (u right, v down, centres at +0.5) looks along
/// (1, -(u + 0.5 - W/2) / fx, -(v + 0.5 - H/2) / fy) in the sensor frame, fx = (W/2)/tan(hfov/2).
class DepthCamera {
 public:
  DepthCamera(std::shared_ptr<const RaycastScene> scene, const DepthCameraOptions& options = {});

  const DepthCameraOptions& options() const { return opt_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  /// (H*W, 3) unit ray directions in the sensor frame, row v * W + u.
  const Points& directions() const { return dirs_; }
  /// Volume (m^3) of the view frustum between the near and far depth planes.
  double frustum_volume() const;

  /// Scans from a sensor pose. With noise on, each call draws the next frame of noise
  /// (deterministic for a given seed and call sequence; see reset_noise).
  Scan scan(const Eigen::Isometry3d& T_world_sensor) const;
  /// Scans from a view (x, y, z, yaw, pitch): the camera rides the gimbal,
  /// T_world_sensor = gimbal_sensor_transform(view, mount) = T(x, y, z) Rz(yaw) Ry(pitch) mount
  /// (pitch > 0 looks down). Throws std::invalid_argument for a pitch beyond +-pi/2.
  Scan scan_pose(const Pose& view) const {
    require_pitch(view.pitch, "camera view");
    return scan(gimbal_sensor_transform(view, opt_.mount));
  }
  /// Scans only the listed pixels (v * W + u, each in [0, W*H), in the order given; listing
  /// neighbours together keeps Embree's packets coherent) as scan would: the same rays, range
  /// limits and noise (the next frame of it). Returns their hits and free ray ends in that order,
  /// hit_rays and free_rays the pixel of each, and depth (1, K) each listed pixel's depth. Throws
  /// std::invalid_argument for a pixel outside the image.
  Scan scan_pixels(const Eigen::Isometry3d& T_world_sensor,
                   const Eigen::Ref<const Eigen::VectorXi>& pixels) const;
  void reset_noise(std::uint64_t seed);

 private:
  /// Pixel p's depth from its ray's distance t of frame `frame`'s noise (inf: no valid return);
  /// `free` is set where the ray hit nothing within the far plane.
  double pixel_depth(double t, Eigen::Index p, std::uint64_t frame, bool& free) const;
  /// Whether a depth is a valid return: within [min, max] depth (a relative 1e-9 tolerance keeps
  /// a surface exactly at a limit, whose depth rounds to a hair beyond it, in range).
  bool in_range(double z) const {
    return !(z < opt_.min_range * (1 - 1e-9) || z > opt_.max_range * (1 + 1e-9));
  }
  std::shared_ptr<const RaycastScene> scene_;
  DepthCameraOptions opt_;
  double fx_, fy_;
  Points dirs_;                    // pixel order
  Points tile_dirs_;               // 4x4 tile order, for coherent packets
  Eigen::VectorXi pixel_to_tile_;  // pixel p's ray in tile order
  Eigen::VectorXd tile_tfar_;
  Eigen::VectorXd cos_;  // pixel order: each ray's cosine to the optical axis (depth / distance)
  mutable std::atomic<std::uint64_t> frame_{0};
};

#define NBV_LASER_SCANNER_OPTIONS(X)                                                    \
  X(double, fov_deg, 180.0, "horizontal field of view, degrees, centred on +x")         \
  X(double, resolution_deg, 0.25, "angle between beams, degrees")                       \
  X(double, min_range, 0.1, "metres along the beam")                                    \
  X(double, max_range, 30.0, "metres along the beam")                                   \
  X(double, noise_sigma, 0.0, "range noise sigma, metres")                              \
  X(std::uint64_t, seed, 0, "noise seed")                                               \
  X(Eigen::Isometry3d, mount, mount_transform(Eigen::Vector3d::Zero(), 0.0, 10.0, 0.0), \
    "4x4 T_body_sensor; default pitched 10 deg down (Table 1), at the body origin")

struct LaserScannerOptions {
  NBV_LASER_SCANNER_OPTIONS(NBV_DECLARE_OPTION)

  int num_beams() const;
  void validate() const;
};
/// Single-layer laser scanner: beams in the sensor's x-y plane at angles -fov/2 ... +fov/2
/// (counter-clockwise from +x toward +y), one every resolution_deg.
class LaserScanner {
 public:
  LaserScanner(std::shared_ptr<const RaycastScene> scene, const LaserScannerOptions& options = {});

  const LaserScannerOptions& options() const { return opt_; }
  /// (R,) beam angles in radians; (R, 3) unit beam directions in the sensor frame.
  const Eigen::VectorXd& angles() const { return angles_; }
  const Points& directions() const { return dirs_; }

  Scan scan(const Eigen::Isometry3d& T_world_sensor) const;
  /// Scans from a vehicle pose through the laser's fixed mount on the body:
  /// T_world_sensor = pose_to_transform(vehicle) * mount. The laser does not ride the camera's
  /// gimbal: the pose's pitch is ignored.
  Scan scan_pose(const Pose& vehicle) const {
    return scan(pose_to_transform(vehicle) * opt_.mount);
  }
  void reset_noise(std::uint64_t seed);

 private:
  std::shared_ptr<const RaycastScene> scene_;
  LaserScannerOptions opt_;
  Eigen::VectorXd angles_;
  Points dirs_;
  Eigen::VectorXd tfar_;
  mutable std::atomic<std::uint64_t> frame_{0};
};

/// Standard normal variate from a counter (seed, frame, index): reproducible under any threading.
double counter_normal(std::uint64_t seed, std::uint64_t frame, std::uint64_t index);

}  // namespace nbv
