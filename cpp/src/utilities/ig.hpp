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
  explicit InformationGain(ViewContext& ctx) : marks_(ctx.visited.marks()) {}
  ~InformationGain() { marks_.keep(); }
  void begin_ray(const Eigen::Vector3d&) {}
  template <class Cells>
  bool visit(const Cells&, std::size_t idx, const int*, double, float scored) {
    // Neutral cells in live bricks are marked too (they add nothing either way), so that
    // nothing here branches on the cell.
    const bool counts = marks_.insert(idx) & (scored != 0.0f);
    gain_ = add_if(gain_, std::fabs(scored), counts);
    cells_ += counts;
    return !std::signbit(scored);
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  VisitedSet::Marks marks_;
  double gain_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
