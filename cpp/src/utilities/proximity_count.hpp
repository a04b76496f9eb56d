// Proximity count (Delmerico et al. 2018): unknown cells close to observed surface are the
// likely surface. Per ray, the sum of P_vis over the unknown cells it enters that touch an
// occupied or predicted cell (26-neighbourhood); P_vis as in visibility.hpp.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct ProximityCount {
  static constexpr bool kSkipNeutral = false;
  static constexpr bool kNeedsSurface = false;
  explicit ProximityCount(ViewContext& ctx)
      : grid_(ctx.grid), min_vis_(ctx.options.min_visibility) {}
  void begin_ray(const Eigen::Vector3d&) { vis_ = 1.0; }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float) {
    if (cells.flag(idx, c) == CellFlag::Unknown && next_to_surface(grid_, cells, c, true)) {
      gain_ += vis_;
      ++cells_;
    }
    vis_ *= 1.0 - occupancy(cells, idx, c);
    return vis_ >= min_vis_;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  const GridView& grid_;
  double min_vis_, vis_ = 1.0, gain_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
