// Views aimed at patches of surface targets (nbvkit.planning.placement.place_views): per patch,
// out along its normal at each stand-off, straight on and to either side, the camera tilted or
// pitched so the patch stays in its vertical field of view. One pass in C++ with the C library's
// trigonometry, as Python's math module computes it: the same poses to the last bit.
#pragma once

#include "nbv/common.hpp"

#include <cstdint>
#include <vector>

namespace nbv {

/// The camera and placement settings place_patch_views needs, angles in radians.
struct PlacementGeometry {
  double half = 0.0;       ///< half the vertical field of view less the elevation margin
  double mount = 0.0;      ///< the mount's pitch (> 0: down)
  double mount_yaw = 0.0;  ///< the mount's yaw
  double spread = 0.0;     ///< azimuth of the side views either side of the normal (0: none)
  bool gimbal = false;     ///< also face, by the gimbal's pitch, patches the level view cannot
  double lo_pitch = 0.0, hi_pitch = 0.0;  ///< the gimbal's limits
  std::vector<double> reach;              ///< stand-off distances, m
};

using Poses5 = Eigen::Matrix<double, Eigen::Dynamic, 5, Eigen::RowMajor>;
using Bands = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

struct PlacedViews {
  Poses5 poses;                     ///< (K, 5) x, y, z, yaw, pitch
  std::vector<std::int64_t> owner;  ///< (K,) the patch of each view
  Bands bands;                      ///< (K, 2) the lowest and highest elevation in view
};

/// Views of the patches (centres and unit normals (P, 3)); horizontal (P,): the length of each
/// normal's horizontal part (Python's math.hypot of its x and y, passed in: the C library's
/// hypot rounds differently in about one case in 200). Patch-major, then pitch (level first),
/// azimuth, stand-off, as place_views documents them.
PlacedViews place_patch_views(const PointsRef& centers, const PointsRef& normals,
                              const std::vector<double>& horizontal, const PlacementGeometry& p);

}  // namespace nbv
