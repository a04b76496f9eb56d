// Rear-side voxel (Delmerico et al. 2018): unknown space directly behind observed surface is
// likely more surface. Per ray: if the cell right after the ray's first occupied cell is unknown,
// it counts P_vis of that occupied cell (the visibility up to the surface, as in
// occlusion_aware.hpp); the ray ends there.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct RearSideVoxel {
  static constexpr bool kSkipNeutral = false;
  static constexpr bool kNeedsSurface = false;
  explicit RearSideVoxel(ViewContext&) {}
  void begin_ray(const Eigen::Vector3d&) {
    vis_ = 1.0;
    behind_ = false;
  }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    if (behind_) {
      if (cells.flag(idx, c) == CellFlag::Unknown) {
        gain_ += vis_;
        ++cells_;
      }
      return false;
    }
    if (std::signbit(scored)) {
      behind_ = true;  // vis_ stays the visibility of the surface cell itself
      return true;
    }
    vis_ *= 1.0 - occupancy(cells, idx, c);
    return true;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  double vis_ = 1.0, gain_ = 0.0;
  bool behind_ = false;
  int cells_ = 0;
};

}  // namespace nbv::utility
