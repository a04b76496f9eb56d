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
// visit() is called for every cell the ray enters, in order (t: distance from the camera at the
// cell's entry, m; scored: the cell's entropy, negated when occupied) and returns false to end
// the ray. cells.flag(idx, c) / cells.logodds(idx, c) read the rest of a cell. A new utility is
// one header in this folder and one line in registry.hpp.
#pragma once

#include "nbv/grid_view.hpp"
#include "nbv/views.hpp"

#include <cmath>
#include <cstdint>
#include <vector>

namespace nbv::utility {

/// Per-thread set of the cells a view has counted: a bitset over the grid (2 M cells -> 256 KB,
/// small enough for the core's L2 cache), cleared after each view through the words it touched.
struct VisitedSet {
  std::vector<std::uint64_t> bits;
  std::vector<std::uint32_t> touched;
  void reset(std::size_t n) {
    const std::size_t words = (n + 63) / 64;
    if (bits.size() != words) {
      bits.assign(words, 0);
      touched.clear();
    }
    for (std::uint32_t w : touched) bits[w] = 0;
    touched.clear();
  }
  /// Marks cell i; true if it was not marked yet.
  bool insert(std::size_t i) {
    std::uint64_t& w = bits[i >> 6];
    const std::uint64_t m = std::uint64_t(1) << (i & 63);
    if (w & m) return false;
    if (!w) touched.push_back(static_cast<std::uint32_t>(i >> 6));
    w |= m;
    return true;
  }
};

/// What a utility credited one cell with: its id, the direction bin (0..25) it was seen from
/// (of cell -> camera), and the weight.
struct Credit {
  std::int64_t cell;
  std::int8_t bin;
  float weight;
};

struct ViewContext {
  const GridView& grid;
  const UtilityOptions& options;
  VisitedSet& visited;
  const std::uint32_t* cones;    ///< [26]: bin_cone(b, options.coverage_cone_deg)
  std::vector<Credit>* credits;  ///< where to record credits, or null
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

}  // namespace nbv::utility
