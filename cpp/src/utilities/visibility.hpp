// The visibility-weighted utilities (Isler et al. 2016; Delmerico et al. 2018). P_vis of a cell
// is the product over the cells before it on the ray of (1 - P_occupied): the product of the free
// probabilities, the correct form (the reference implementation multiplied by P_occupied).
// Unknown cells count P_occupied = 0.5. A cell reached by several rays counts for each. Each
// utility is a sum of P_vis * weight, the weight being a cell indicator or the cell's
// entropy:
// - occlusion_aware (entropy), unobserved_voxel (unknown) and proximity_count (unknown next to
//   occupied or predicted surface, the likely surface): over every cell a ray enters, until
//   P_vis drops below UtilityOptions::min_visibility or the depth limit;
// - rear_side_entropy and rear_side_voxel: only the cell right after the ray's first occupied
//   cell (unknown space behind observed surface is likely more surface), with the P_vis of that
//   occupied cell; the ray ends there.
#pragma once

#include <cmath>

#include "utility.hpp"

namespace nbv::utility {

struct UnknownCell {
  explicit UnknownCell(ViewContext&) {}
  template <class Cells>
  double operator()(const Cells& cells, std::size_t idx, const int* c, float) const {
    return cells.flag(idx, c) == CellFlag::Unknown ? 1.0 : 0.0;
  }
};

struct CellEntropy {
  explicit CellEntropy(ViewContext&) {}
  template <class Cells>
  double operator()(const Cells&, std::size_t, const int*, float scored) const {
    return std::fabs(scored);
  }
};

/// Unknown cells that touch an occupied or predicted cell (26-neighbourhood).
struct UnknownNextToSurface {
  explicit UnknownNextToSurface(ViewContext& ctx) : grid_(ctx.grid) {}
  template <class Cells>
  double operator()(const Cells& cells, std::size_t idx, const int* c, float) const {
    return cells.flag(idx, c) == CellFlag::Unknown && next_to_surface(grid_, cells, c, true);
  }

 private:
  const GridView& grid_;
};

template <class Weight>
struct VisibleSum {
  static constexpr bool kSkipNeutral = false;  // free cells lower the visibility
  static constexpr bool kNeedsSurface = false;
  explicit VisibleSum(ViewContext& ctx) : weight_(ctx), min_vis_(ctx.options.min_visibility) {}
  void begin_ray(const Eigen::Vector3d&) { vis_ = 1.0; }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    const double w = weight_(cells, idx, c, scored);
    if (w > 0.0) {
      gain_ += vis_ * w;
      ++cells_;
    }
    vis_ *= 1.0 - occupancy(cells, idx, c);
    return vis_ >= min_vis_;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  Weight weight_;
  double min_vis_, vis_ = 1.0, gain_ = 0.0;
  int cells_ = 0;
};

template <class Weight>
struct RearSide {
  static constexpr bool kSkipNeutral = false;
  static constexpr bool kNeedsSurface = false;
  explicit RearSide(ViewContext& ctx) : weight_(ctx) {}
  void begin_ray(const Eigen::Vector3d&) {
    vis_ = 1.0;
    behind_ = false;
  }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    if (behind_) {
      const double w = weight_(cells, idx, c, scored);
      if (w > 0.0) {
        gain_ += vis_ * w;
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
  Weight weight_;
  double vis_ = 1.0, gain_ = 0.0;
  bool behind_ = false;
  int cells_ = 0;
};

using OcclusionAware = VisibleSum<CellEntropy>;
using UnobservedVoxel = VisibleSum<UnknownCell>;
using ProximityCount = VisibleSum<UnknownNextToSurface>;
using RearSideEntropy = RearSide<CellEntropy>;
using RearSideVoxel = RearSide<UnknownCell>;

}  // namespace nbv::utility
