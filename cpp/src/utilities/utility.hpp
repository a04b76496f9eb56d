// What a view-scoring utility sees, and helpers they share. A utility is a policy struct,
//
//   struct MyUtility {
//     static constexpr bool kSkipNeutral = ...;  // may neutral bricks be stepped over?
//     static constexpr bool kNeedsSurface = ...; // reads camera observations (seen / hits)?
//     explicit MyUtility(ViewContext& ctx);       // one per view
//     void begin_ray(const Eigen::Vector3d& direction);  // world frame, unit
//     template <class Cells>
//     bool visit(const Cells& cells, std::size_t idx, const int* c, double t, float scored);
//     double gain() const;  int cells() const;
//   };
//
// A utility whose gain is the sum of the entropies of the distinct cells its rays reached may
// also declare, for ViewMemo,
//     void skipped(std::size_t idx);  // a neutral cell stepped over (mark its brick)
//     static bool replay(const GridView& g, const ViewMemo::Entry& e, double& gain, int& count);
// replay() scores a view again from its entry, or returns false (then the view is walked).
// A utility whose gain sums the entropies of the distinct cells its rays enter, each ray ending
// at its first occupied cell, may declare kMarksRays = true and
//     void mark_rays(const GridView& g, const RayStart* starts, const bool* active,
//                    const MarkBuffer& buffer, std::size_t* stop);  // mark_rays4 into its set
//     bool sum_marks(const GridView& g);  // after the rays: false to be walked with visit()
// the kernel then walks its rays four at a time (mark_rays4) on the workspace grid.
//
// visit() is called for every cell the ray enters, in order (t: distance from the camera at the
// cell's entry, m; scored: the cell's entropy, negated when occupied) and returns false to end
// the ray. cells.flag(idx, c) / cells.logodds(idx, c) read the rest of a cell. A new utility is
// one header in this folder and one line in registry.hpp.
#pragma once

#include "nbv/grid_view.hpp"
#include "nbv/views.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace nbv::utility {

/// Per-thread set of the cells a view has counted: a bitset over the grid (2 M cells -> 256 KB,
/// small enough for the core's L2 cache), one 64-bit word per brick of the grid's layout, cleared
/// after each view through the words it touched. Marks::insert does not branch on the content:
/// whether a ray's next cell is new follows no pattern a branch predictor learns, and a
/// mispredicted branch per cell cost more than the ray's step.
struct VisitedSet {
  std::vector<std::uint64_t> bits;
  std::vector<std::uint32_t> touched;  ///< the first n_touched: the words that are not zero
  std::size_t n_touched = 0;
  void reset(std::size_t n) {
    const std::size_t words = (n + 63) / 64;
    if (bits.size() != words) {
      bits.assign(words, 0);
      touched.assign(words + 1, 0);  // + 1: insert writes one slot past the words it keeps
      n_touched = 0;
    }
    for (std::size_t k = 0; k < n_touched; ++k) bits[touched[k]] = 0;
    n_touched = 0;
  }
  /// A view's handle on the set, as raw pointers and a count: a utility holds one for its view
  /// (marks() at the start, keep() at the end hands the count back), which lets the compiler keep
  /// all three in registers while a ray walks, where the set's own members were reloaded at
  /// every cell.
  struct Marks {
    std::uint64_t* bits;
    std::uint32_t* touched;
    std::size_t n_touched;
    VisitedSet* set;
    /// Marks cell i; true if it was not marked yet.
    bool insert(std::size_t i) {
      std::uint64_t& w = bits[i >> 6];
      const std::uint64_t old = w, m = std::uint64_t(1) << (i & 63);
      w = old | m;
      touched[n_touched] = static_cast<std::uint32_t>(i >> 6);
      n_touched += old == 0;
      return (old & m) == 0;
    }
    void keep() const { set->n_touched = n_touched; }
  };
  Marks marks() { return {bits.data(), touched.data(), n_touched, this}; }
};

/// a + b where `m`, else a + 0.0 (the same value, a never being -0.0), without a branch.
inline double add_if(double a, double b, bool m) {
  std::uint64_t bits;
  std::memcpy(&bits, &b, sizeof bits);
  bits &= -std::uint64_t(m);
  std::memcpy(&b, &bits, sizeof bits);
  return a + b;
}

/// What a utility credited one cell with: its id, the direction bin (0..25) it was seen from
/// (of cell -> camera), and the weight.
struct Credit {
  std::int64_t cell;
  std::int8_t bin;
  float weight;
  /// an unknown cell credited at the utility's unknown_prior (not next to surface): the
  /// low-weight bulk of a view's credits, which view_coverage may pool per brick
  bool prior = false;
};

struct ViewContext {
  const GridView& grid;
  const UtilityOptions& options;
  VisitedSet& visited;
  const std::uint32_t* cones;    ///< [26]: bin_cone(b, options.coverage_cone_deg)
  std::vector<Credit>* credits;  ///< where to record credits, or null
  /// surface: dense_spacing / the camera's pixel pitch (rad), the range (m) within which a
  /// face-on cell is sampled densely enough; 0: no density weight
  double dense_range = 0.0;
  /// surface: cos(max_incidence_deg); an observed surface cell met by a ray at a lower |cos| of
  /// its open-face normal is not credited (0: every ray)
  double min_cos = 0.0;
};

inline double sigmoid(double logodds) { return 1.0 / (1.0 + std::exp(-logodds)); }

/// Occupancy probability of a cell as the map holds it: 0.5 when unknown.
template <class Cells>
double occupancy(const Cells& cells, std::size_t idx, const int* c) {
  return cells.flag(idx, c) == CellFlag::Unknown ? 0.5 : sigmoid(cells.logodds(idx, c));
}

/// True if one of the cell's neighbours (6 faces, or all 26 with `all26`) is occupied or
/// predicted.
template <class Cells>
bool next_to_surface(const GridView& g, const Cells& cells, const int* c, bool all26 = false) {
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int m = std::abs(dx) + std::abs(dy) + std::abs(dz);
        if (m == 0 || (!all26 && m != 1)) continue;
        const int n[3] = {c[0] + dx, c[1] + dy, c[2] + dz};
        if (!g.contains(n[0], n[1], n[2])) continue;
        const std::size_t j = g.index(n[0], n[1], n[2]);
        if (std::signbit(cells.scored(j, n)) || cells.flag(j, n) == CellFlag::Predicted)
          return true;
      }
  return false;
}

/// The outward normal of an occupied cell's surface as the surface utility estimates it: the sum
/// of the unit vectors towards its open face neighbours (free or unknown; neighbours outside the
/// grid left out), not normalised; zero where they cancel or there are none.
template <class Cells>
void open_face_normal(const GridView& g, const Cells& cells, const int* c, double n[3]) {
  n[0] = n[1] = n[2] = 0.0;
  for (int a = 0; a < 3; ++a)
    for (int s = -1; s <= 1; s += 2) {
      int m[3] = {c[0], c[1], c[2]};
      m[a] += s;
      if (!g.contains(m[0], m[1], m[2])) continue;
      const std::size_t j = g.index(m[0], m[1], m[2]);
      if (!std::signbit(cells.scored(j, m)) || cells.flag(j, m) == CellFlag::Unknown) n[a] += s;
    }
}

}  // namespace nbv::utility
