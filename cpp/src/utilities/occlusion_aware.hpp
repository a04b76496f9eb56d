// Occlusion-aware information gain (Isler et al. 2016; Delmerico et al. 2018): per ray, the sum
// over the cells it enters of P_vis * H(cell), where P_vis = prod over the cells before it on
// the ray of (1 - P_occupied) - the product of the free probabilities, the correct form (the
// reference implementation multiplied by P_occupied). Unknown cells count P_occupied = 0.5.
// Rays end where P_vis drops below UtilityOptions::min_visibility or at the depth limit; a
// cell reached by several rays counts for each.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct OcclusionAware {
  static constexpr bool kSkipNeutral = false;  // free cells lower the visibility
  static constexpr bool kNeedsSurface = false;
  explicit OcclusionAware(ViewContext& ctx) : min_vis_(ctx.options.min_visibility) {}
  void begin_ray(const Eigen::Vector3d&) { vis_ = 1.0; }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    const double h = std::fabs(scored);
    if (h > 0.0) {
      gain_ += vis_ * h;
      ++cells_;
    }
    vis_ *= 1.0 - occupancy(cells, idx, c);
    return vis_ >= min_vis_;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  double min_vis_, vis_ = 1.0, gain_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
