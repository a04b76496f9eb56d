// The paper's information gain (Eq. 3): the sum of the entropies of the distinct cells the
// view's rays reach, each ray walking free, unknown and predicted-but-free cells from the camera
// and ending at the first occupied cell (inclusive), at the depth limit or where it leaves the
// workspace. Neutral cells (zero entropy) add nothing and are stepped over.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct InformationGain {
  static constexpr bool kSkipNeutral = true;
  static constexpr bool kNeedsSurface = false;
  explicit InformationGain(ViewContext& ctx) : ctx_(ctx) {}
  void begin_ray(const Eigen::Vector3d&) {}
  template <class Cells>
  bool visit(const Cells&, std::size_t idx, const int*, double, float scored) {
    if (scored != 0.0f && ctx_.visited.insert(idx)) {
      gain_ += std::fabs(scored);
      ++cells_;
    }
    return !std::signbit(scored);
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  ViewContext& ctx_;
  double gain_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
