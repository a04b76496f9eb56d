// Average entropy (Delmerico et al. 2018): the entropy the rays collect divided by the number of
// cells they traverse (each ray ending at its first occupied cell, as ig.hpp; per ray, not
// distinct), which favours views that look at uncertain cells rather than long rays of free
// space.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct AverageEntropy {
  static constexpr bool kSkipNeutral = false;  // neutral cells count as traversed
  static constexpr bool kNeedsSurface = false;
  explicit AverageEntropy(ViewContext&) {}
  void begin_ray(const Eigen::Vector3d&) {}
  template <class Cells>
  bool visit(const Cells&, std::size_t, const int*, double, float scored) {
    sum_ += std::fabs(scored);
    ++cells_;
    return !std::signbit(scored);
  }
  double gain() const { return cells_ ? sum_ / cells_ : 0.0; }
  int cells() const { return cells_; }

 private:
  double sum_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
