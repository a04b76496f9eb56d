// Rear-side entropy (Delmerico et al. 2018): as rear_side_voxel.hpp, weighted by the entropy of
// the cell behind the ray's first occupied cell (whatever its state), so that surface whose
// far side is already partly known counts less.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct RearSideEntropy {
  static constexpr bool kSkipNeutral = false;
  static constexpr bool kNeedsSurface = false;
  explicit RearSideEntropy(ViewContext&) {}
  void begin_ray(const Eigen::Vector3d&) {
    vis_ = 1.0;
    behind_ = false;
  }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    if (behind_) {
      const double h = std::fabs(scored);
      if (h > 0.0) {
        gain_ += vis_ * h;
        ++cells_;
      }
      return false;
    }
    if (std::signbit(scored)) {
      behind_ = true;
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
