// Next-best-view candidate evaluation: validity (bounds, collision sphere, flight segment),
// information-gain utility by ray walks (3D-DDA) over the map's dense workspace mirror, and the
// termination's count of viewable cells. Section 3.3-3.5 of the paper.
#pragma once

#include "nbv/common.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace nbv {

class OccupancyMap;

/// Read-only view of a dense, axis-aligned cell grid (the occupancy map's workspace mirror).
/// Cell (i, j, k) covers origin + res * [i, i+1) x [j, j+1) x [k, k+1); its flat index is
/// i + nx * (j + ny * k).
struct DenseGridView {
  double resolution = 0.2;
  Eigen::Vector3d origin =
      Eigen::Vector3d::Zero();  ///< world coordinate of cell (0,0,0)'s min corner
  int nx = 0, ny = 0, nz = 0;
  const float* logodds = nullptr;       ///< per cell log-odds; unknown cells must hold 0
  const std::uint8_t* known = nullptr;  ///< per cell: 0 = unknown, else observed or predicted
  const float* scored = nullptr;        ///< per cell entropy, negated when occupied (WorkspaceGrid)
  float occupied_logodds = 0.405f;      ///< a known cell is occupied when logodds >= this

  std::size_t num_cells() const { return static_cast<std::size_t>(nx) * ny * nz; }
  bool cell_of(const Eigen::Vector3d& p, Eigen::Vector3i& c) const;
  std::size_t index(const Eigen::Vector3i& c) const {
    return static_cast<std::size_t>(c.x()) +
           static_cast<std::size_t>(nx) * (c.y() + static_cast<std::size_t>(ny) * c.z());
  }
  void validate() const;
};

/// The view of an occupancy map's workspace mirror (valid while the map is alive and unchanged).
DenseGridView grid_view(const OccupancyMap& map);

/// The camera model used to score views: a pinhole ray grid over the field of view.
struct ViewCameraModel {
  int rays_x = 47;  ///< rays across the horizontal FOV
  int rays_y = 34;  ///< rays across the vertical FOV
  double hfov_deg = 60.0;
  double vfov_deg = 45.0;
  double max_range = 8.0;                                   ///< depth along the optical axis, m
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();  ///< T_body_sensor

  /// Rays per map-resolution step on the far plane (the authors' choice: 47 x 34 at 0.2 m).
  static ViewCameraModel for_resolution(double hfov_deg, double vfov_deg, double max_range,
                                        double resolution);
  /// (rays_x * rays_y, 3) unit directions in the sensor frame.
  Points directions() const;
  void validate() const;
};

struct UtilityOptions {
  enum class Kind { InformationGain, InformationGainDistance };
  Kind kind = Kind::InformationGain;
  double distance_lambda = 0.5;  ///< 1/m, for IG * exp(-lambda * distance)
  /// The view must see a cell that stops a ray (occupied). If > 0, the seen cell must also have
  /// p > this (the authors' 0.8). 0 = any occupied cell (paper).
  double require_occupied_probability = 0.0;
  bool require_occupied = true;
};

struct ValidityOptions {
  double collision_radius = 0.8;                                   ///< m
  Eigen::Vector3d bounds_min = Eigen::Vector3d::Constant(-1e300);  ///< navigation bounds
  Eigen::Vector3d bounds_max = Eigen::Vector3d::Constant(1e300);
  bool check_segment = true;  ///< the straight segment from the current pose must be clear
};

enum class ViewStatus : std::int8_t {
  Valid = 0,
  OutOfBounds = 1,
  Collision = 2,       ///< an occupied or unknown cell within the collision radius
  PathBlocked = 3,     ///< the straight segment crosses occupied or unknown space
  SeesNoOccupied = 4,  ///< the paper's constraint: no occupied cell in view
};

struct ViewScores {
  Eigen::VectorXd utility;        ///< (K,) utility; -inf where the view is not valid
  Eigen::VectorXd gain;           ///< (K,) information gain (sum of entropies of visible cells)
  Eigen::VectorXi cells_seen;     ///< (K,) distinct cells visited by the rays
  Eigen::VectorXi occupied_seen;  ///< (K,) rays ending on an occupied cell
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> status;  ///< (K,) ViewStatus
};

/// True if every cell that intersects the sphere (center, radius) is known and not occupied.
bool sphere_is_free(const DenseGridView& grid, const Eigen::Vector3d& center, double radius);
/// True if spheres every resolution/2 along the segment a-b are all free.
bool segment_is_free(const DenseGridView& grid, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                     double radius);

/// Scores K candidate vehicle poses (rows x, y, z, yaw) from the current pose in one call,
/// in parallel over candidates. The gain of a view is the sum of the entropies of the distinct
/// workspace cells its rays visit: each ray walks free, unknown and predicted-but-not-occupied
/// cells from the sensor origin and stops at the first occupied cell (inclusive), at the depth
/// limit, or where it leaves the workspace (nothing outside counts).
ViewScores evaluate_views(
    const DenseGridView& grid,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& candidates,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity);

/// The same scores reading each cell through OctoMap's search (one tree descent per cell visit),
/// as the authors' implementation did: the reference the mirror must agree with, and the
/// benchmark baseline. Validity checks still use the mirror.
ViewScores evaluate_views_octree(
    const OccupancyMap& map,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& candidates,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity);

/// Number of map cells a camera frustum can observe (paper Eq. 5): V_frustum / V_cell, or with
/// count_partial the expected number of cells the frustum touches, partial boundary cells
/// included: vol(F (+) cell) / V_cell, the volume of the frustum's Minkowski sum with one cell
/// (exact for a convex body and an axis-aligned cell, here for the frustum at zero yaw).
double viewable_cells(double hfov_deg, double vfov_deg, double min_range, double max_range,
                      double resolution, bool count_partial);

/// A* through known free space (26-connected cells whose collision sphere is free). Returns the
/// waypoints from a to b (a first, b last) or an empty list if there is none within
/// max_expansions. The path's length is the sum of its segments.
std::vector<Eigen::Vector3d> plan_path(const DenseGridView& grid, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, double radius,
                                       std::size_t max_expansions = 200000);

}  // namespace nbv
