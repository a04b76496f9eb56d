// The paper's information gain (Eq. 3): the sum of the entropies of the distinct cells the
// view's rays reach, each ray walking free, unknown and predicted-but-free cells from the camera
// and ending at the first occupied cell (inclusive), at the depth limit or where it leaves the
// workspace. Neutral cells (zero entropy) add nothing and are stepped over.
#pragma once

#include "utility.hpp"

#include <cstring>
#include <vector>

namespace nbv::utility {

struct InformationGain {
  static constexpr bool kSkipNeutral = true;
  static constexpr bool kNeedsSurface = false;
  static constexpr bool kIdsOnly = true;  // visit() reads a cell's id and score only
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
  /// One ray's cells in walk_ray's order (ids[stride j], j < count), as visit() would take
  /// them, with neutral bricks stepped over (kSkip; marked as skipped() does with kRecord):
  /// returns the cell the ray stopped at (its first occupied), or kNoCell. Compiled apart, with
  /// its state in locals: inlined into the kernel, its sum was kept on the stack.
  template <bool kSkip, bool kRecord>
  __attribute__((noinline)) std::size_t visit_ray(const GridView& g, const std::int64_t* ids,
                                                  int stride, int count) {
    const std::uint8_t* live = g.brick_live;
    const float* scored = g.scored;
    VisitedSet::Marks m = marks_;
    double gain = gain_;
    int cells = cells_;
    std::size_t stop = kNoCell;
    // kRecord: the neutral bricks entered, marked after the ray (as skipped() does) by their
    // first cell's bit: marked cell by cell, each mark waited on the one before into its word
    thread_local std::vector<std::uint32_t> entered_bricks;
    if (kRecord && entered_bricks.size() <= std::size_t(count))
      entered_bricks.resize(std::size_t(count) + 1);
    std::uint32_t* entered = entered_bricks.data();
    std::size_t n_entered = 0, last = ~std::size_t(0);
    for (int j = 0; j < count; ++j) {
      const auto idx = std::size_t(ids[std::ptrdiff_t(j) * stride]);
      if (kSkip && live[idx >> 6] == 0) {
        if constexpr (kRecord) {
          entered[n_entered] = std::uint32_t(idx >> 6);
          n_entered += (idx >> 6) != last;
          last = idx >> 6;
        }
        continue;
      }
      const float s = scored[idx];
      const bool counts = m.insert(idx) & (s != 0.0f);
      gain = add_if(gain, std::fabs(s), counts);
      cells += counts;
      if (std::signbit(s)) {
        stop = idx;
        break;
      }
    }
    for (std::size_t e = 0; e < n_entered; ++e) m.insert(std::size_t(entered[e]) << 6);
    marks_ = m;
    gain_ = gain;
    cells_ = cells;
    return stop;
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
    for (const ViewMemo::Word& w : e.words) {
      const float* s = g.scored + std::size_t(w.word) * 64;
      std::uint64_t occ = 0;
      for (std::uint64_t m = w.cells; m; m &= m - 1) {
        const int b = __builtin_ctzll(m);
        std::uint32_t bits;
        std::memcpy(&bits, &s[b], sizeof bits);
        occ |= std::uint64_t(bits >> 31) << b;
        const std::uint32_t magnitude = bits & 0x7FFFFFFFu;
        small |= magnitude - 1 < (std::uint32_t(127 - 8) << 23) - 1;  // 0 < |s| < 2^-8
        sum += std::fabs(s[b]);
        n += magnitude != 0;
      }
      changed |= occ ^ w.occupied;
    }
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
