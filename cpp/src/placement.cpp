#include "nbv/placement.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace nbv {

PlacedViews place_patch_views(const PointsRef& centers, const PointsRef& normals,
                              const std::vector<double>& horizontal, const PlacementGeometry& p) {
  if (normals.rows() != centers.rows() || Eigen::Index(horizontal.size()) != centers.rows())
    throw std::invalid_argument(
        "place_patch_views: centers, normals and horizontal differ in length");
  constexpr double pi = 3.141592653589793;
  std::vector<double> rows, bands;  // row-major: 5 numbers a view, 2 a band
  PlacedViews out;
  // The same operations in the same order as the Python loop it replaces (no fused multiply-add:
  // the build never targets FMA), so the same doubles.
  for (Eigen::Index i = 0; i < centers.rows(); ++i) {
    const double c0 = centers(i, 0), c1 = centers(i, 1), c2 = centers(i, 2);
    const double n0 = normals(i, 0), n1 = normals(i, 1), n2 = normals(i, 2);
    const double h = horizontal[std::size_t(i)];
    const double el_n = std::atan2(n2, h);  // the normal's elevation: the direction patch -> camera
    double pitches[2] = {0.0, 0.0};
    int n_pitch = 1;
    if (p.gimbal && std::abs(-el_n + p.mount) > p.half) {
      const double pitch = std::min(std::max(el_n - p.mount, p.lo_pitch), p.hi_pitch);
      if (pitch != 0.0) pitches[n_pitch++] = pitch;  // clamped to level: the level view's twin
    }
    for (int q = 0; q < n_pitch; ++q) {
      const double pitch = pitches[q];
      const double axis_el = -(p.mount + pitch);  // the optical axis' elevation
      const double el = -std::min(std::max(-el_n, axis_el - p.half), axis_el + p.half);
      const bool head_on = std::abs(el - el_n) < 1e-9;
      double azimuths[6];
      int n_az = 0;
      if (h > 0.3 || (head_on && h > 1e-9)) {
        const double az0 = std::atan2(n1, n0);
        azimuths[n_az++] = az0;
        if (p.spread != 0.0) {
          azimuths[n_az++] = az0 - p.spread;
          azimuths[n_az++] = az0 + p.spread;
        }
      } else if (head_on) {
        azimuths[n_az++] = 0.0;  // straight up or down: one view, any yaw
      } else {
        for (int k = 0; k < 6; ++k) azimuths[n_az++] = double(k) * pi / 3;
      }
      const double band_lo = axis_el - p.half, band_hi = axis_el + p.half;
      for (int a = 0; a < n_az; ++a) {
        const double az = azimuths[a];
        const double ux = std::cos(el) * std::cos(az);
        const double uy = std::cos(el) * std::sin(az);
        const double uz = std::sin(el);
        double yaw = az + pi - p.mount_yaw;
        if (std::abs(ux) + std::abs(uy) > 1e-12) yaw = std::atan2(-uy, -ux) - p.mount_yaw;
        yaw = std::remainder(yaw, 2 * pi);
        for (const double d : p.reach) {
          rows.insert(rows.end(), {c0 + d * ux, c1 + d * uy, c2 + d * uz, yaw, pitch});
          bands.insert(bands.end(), {band_lo, band_hi});
          out.owner.push_back(std::int64_t(i));
        }
      }
    }
  }
  out.poses = Eigen::Map<const Poses5>(rows.data(), Eigen::Index(out.owner.size()), 5);
  out.bands = Eigen::Map<const Bands>(bands.data(), Eigen::Index(out.owner.size()), 2);
  return out;
}

}  // namespace nbv
