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
  static constexpr bool kMarksRays = true;  // mark_rays(), sum_marks()
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
  /// Four rays of the view from their starts: the cells each enters up to its first occupied
  /// one marked in the set (mark_rays4; neutral bricks' cells too, which the memo's record
  /// reads as bricks stepped over, and nothing else reads), and that cell in stop[l]. The gain and
  /// count are summed over the marks once the view's rays are done (sum_marks).
  void mark_rays(const GridView& g, const RayStart* starts, const bool* active,
                 const MarkBuffer& buffer, std::size_t* stop) {
    CellMarks cells{marks_.bits, marks_.touched, marks_.n_touched};
    mark_rays4(g, starts, active, cells, buffer, stop);
    marks_.n_touched = cells.n_touched;
  }
  /// After mark_rays's rays: the gain and count over the cells they marked (sum_marked).
  /// False where that sum could differ from visit()'s, in the order of the walk (a nonzero
  /// entropy below 2^-8 or a sum of 2^22 or more): the marks are then cleared and the gain and
  /// count zeroed, for the view to be walked again with visit().
  bool sum_marks(const GridView& g) {
    if (sum_marked(g, marks_.touched, marks_.n_touched, marks_.bits, gain_, cells_)) return true;
    for (std::size_t i = 0; i < marks_.n_touched; ++i) marks_.bits[marks_.touched[i]] = 0;
    marks_.n_touched = 0;
    gain_ = 0.0;
    cells_ = 0;
    return false;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

  // ---- replay (ViewMemo) ----
  /// A neutral cell stepped over: its brick is marked by its first cell's bit, which no cell of
  /// a neutral brick holds otherwise (ViewMemo records it as a stepped-over brick).
  void skipped(std::size_t idx) { marks_.insert(idx & ~std::size_t(63)); }
  /// The gain and count of a view from the cells its walk reached; false if one of them changed
  /// its occupancy since, or if the sum could depend on its order (see ViewMemo).
  static bool replay(const GridView& g, const ViewMemo::Entry& e, double& gain, int& count) {
    double sum = 0.0;
    int n = 0;
    std::uint64_t changed = 0;
    std::uint32_t small = 0;  // a nonzero entropy below 2^-8
    for (const ViewMemo::Word& w : e.words)
      changed |= sum_cells(g.cells.brick_scored(w.word), w.cells, sum, n, small) ^ w.occupied;
    gain = sum;
    count = n;
    return changed == 0 && small == 0 && sum < 4194304.0;  // 2^22
  }

 private:
  VisitedSet::Marks marks_;
  double gain_ = 0.0;
  int cells_ = 0;
};

}  // namespace nbv::utility
