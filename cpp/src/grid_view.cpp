#include "nbv/grid_view.hpp"

#include "nbv/occupancy_map.hpp"
#include "nbv/surface_observations.hpp"

#include <stdexcept>

namespace nbv {

GridView grid_view(const OccupancyMap& map, const SurfaceObservations* surface) {
  const WorkspaceGrid& w = map.grid();
  GridView g;
  g.resolution = map.resolution();
  g.origin = map.bounds_min();
  g.nx = w.dims()[0];
  g.ny = w.dims()[1];
  g.nz = w.dims()[2];
  g.layout = w.layout();
  g.scored = w.scored_data();
  g.logodds = w.logodds_data();
  g.flags = w.flag_data();
  g.brick_live = w.brick_live_data();
  g.brick_open = w.brick_open_data();
  g.unknown_entropy = float(w.rule().entropy(0.0f, CellFlag::Unknown));
  g.grid_stamps = w.stamps().data();
  g.grid_epoch = w.stamps().take_epoch();
  g.grid_id = w.stamps().id();
  if (surface) {
    if (!surface->matches(map))
      throw std::invalid_argument("surface observations were made for another map's grid");
    g.seen = surface->seen_data();
    g.hits = surface->hits_data();
    g.seen_stamps = surface->stamps().data();
    g.seen_epoch = surface->stamps().take_epoch();
    g.seen_id = surface->stamps().id();
  }
  return g;
}

bool GridView::cell_of(const Eigen::Vector3d& p, Eigen::Vector3i& c) const {
  const Eigen::Vector3d q = (p - origin) / resolution;
  c = q.array().floor().cast<int>();
  return contains(c.x(), c.y(), c.z());
}

void GridView::validate() const {
  if (!(resolution > 0) || nx <= 0 || ny <= 0 || nz <= 0 || !scored || !logodds || !flags ||
      !brick_live || !brick_open)
    throw std::invalid_argument("grid view is empty or incomplete");
}

int direction_bin(const Eigen::Vector3d& d) {
  // Each component becomes -1, 0 or 1: 0 where it is small against the largest
  // (|d_a| <= tan(22.5 deg) max|d|), so in each coordinate plane the bin is the nearest of the
  // eight directions; elsewhere it approximates the nearest of the 26.
  constexpr double kTan22_5 = 0.41421356237309503;
  const Eigen::Vector3d a = d.cwiseAbs();
  const double t = kTan22_5 * a.maxCoeff();
  int b = 0, mul = 1;
  for (int k = 0; k < 3; ++k, mul *= 3) b += mul * (a[k] > t ? (d[k] > 0 ? 2 : 0) : 1);
  return b < 13 ? b : b - 1;  // 13 is the zero vector
}

Eigen::Vector3d bin_direction(int b) {
  if (b < 0 || b > 25) throw std::invalid_argument("direction bin must be in 0..25");
  const int v = b < 13 ? b : b + 1;
  return Eigen::Vector3d(v % 3 - 1, (v / 3) % 3 - 1, v / 9 - 1).normalized();
}

std::uint32_t bin_cone(int b, double cone_deg) {
  const double c = std::cos(cone_deg * M_PI / 180.0) - 1e-12;
  const Eigen::Vector3d d = bin_direction(b);
  std::uint32_t mask = 0;
  for (int k = 0; k < 26; ++k)
    if (bin_direction(k).dot(d) >= c) mask |= std::uint32_t(1) << k;
  return mask;
}

}  // namespace nbv
