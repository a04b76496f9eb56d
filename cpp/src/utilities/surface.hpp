// Expected new surface (nbvkit's surface utility): how much surface the view would be the first
// to observe from its side, the quantity dense coverage is made of.
//
// Per ray, walking from the camera: an observed occupied cell is surface; it counts P_vis if the
// camera has not yet seen it from within coverage_cone_deg of this ray's direction (from the
// same side), and ends the ray. A predicted cell (symmetry) is surface with its predicted
// probability p: it counts P_vis * p and lets P_vis * (1 - p) through. An unknown cell holds
// surface with a prior - frontier_prior when a face neighbour is occupied or predicted (the
// surface goes on into the unknown), unknown_prior elsewhere - and counts and passes on the
// same way. With max_incidence_deg < 90 an observed surface cell counts only for a ray that
// meets it within that angle of its normal (from its open faces), and still ends the ray: a
// grazing ray lays few samples on a face the camera has already sampled densely (once at least
// incidence_min_patches of the 16 squares of the face hold a camera hit). A cell the camera
// observations mark saturated (their saturation_hits) counts for no ray. Free cells pass. Each
// cell counts once per view (for the first ray that credits it); rays end below min_visibility.
// With dense_spacing > 0 each credit is also weighted by how densely the camera would sample the
// cell: min(1, dense_spacing cos(i) / (r pitch)), r the range, i the incidence on the cell's
// surface (its normal the sum of its open face directions, free or unknown neighbours; cos(i) = 1
// where they give none, as for unknown cells). The result is in cells of new surface: roughly the
// area the view would add, in units of resolution^2. Needs the camera observations.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct Surface {
  static constexpr bool kSkipNeutral = true;  // neutral cells are free: they pass, add nothing
  static constexpr bool kNeedsSurface = true;
  explicit Surface(ViewContext& ctx) : ctx_(ctx), marks_(ctx.visited.marks()) {}
  ~Surface() { marks_.keep(); }
  void begin_ray(const Eigen::Vector3d& d) {
    dir_ = d;  // unit (ViewCameraModel::directions)
    vis_ = 1.0;
    bin_ = std::int8_t(direction_bin(-d));
    cone_ = ctx_.cones[bin_];
  }
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double t, float scored) {
    const CellFlag flag = cells.flag(idx, c);
    if (flag == CellFlag::Observed) {
      if (!std::signbit(scored)) return true;  // free
      if ((ctx_.grid.seen(idx) & cone_) == 0 && !ctx_.grid.saturated(idx) &&
          facing(cells, idx, c) && marks_.insert(idx))
        credit(idx, density(cells, c, t, true));
      return false;
    }
    double p;
    bool prior = false;
    if (flag == CellFlag::Predicted) {
      p = sigmoid(cells.logodds(idx, c));
    } else {
      prior = !cells.near_surface(idx, c);
      p = prior ? ctx_.options.unknown_prior : ctx_.options.frontier_prior;
    }
    if (marks_.insert(idx)) credit(idx, p * density(cells, c, t, false), prior);
    vis_ *= 1.0 - p;
    return vis_ >= ctx_.options.min_visibility;
  }
  double gain() const { return gain_; }
  int cells() const { return cells_; }

 private:
  /// The density weight of a cell at range `range` (1 without dense_spacing); `surface`: an
  /// occupied cell, whose open faces give the incidence.
  template <class Cells>
  double density(const Cells& cells, const int* c, double range, bool surface) const {
    const double k = ctx_.dense_range;
    if (k <= 0.0) return 1.0;
    const double cos_i = surface ? incidence_cos(cells, c) : 1.0;
    return std::min(1.0, k * cos_i / std::max(range, 1e-12));
  }
  /// |cos| of the angle between this ray and the open-face normal of the cell at c; 1 where its
  /// open faces give none.
  template <class Cells>
  double incidence_cos(const Cells& cells, const int* c) const {
    double n[3];
    const double nn = normal(cells, c, n);
    return nn > 0.0 ? cosine(n) / nn : 1.0;
  }
  /// The open-face normal of the cell at c (its open face directions summed) and its length.
  template <class Cells>
  double normal(const Cells& cells, const int* c, double n[3]) const {
    open_face_normal(ctx_.grid, cells, c, n);
    return std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  }
  double cosine(const double n[3]) const {
    return std::abs(n[0] * dir_.x() + n[1] * dir_.y() + n[2] * dir_.z());
  }
  /// Whether this ray meets the observed surface cell idx (at c, or null: from its id) within
  /// max_incidence_deg of its open-face normal. Always without max_incidence_deg, where the open
  /// faces give no normal, and while fewer than incidence_min_patches of the 16 squares of the
  /// cell's face (seen along the axis nearest its normal) hold a camera hit.
  template <class Cells>
  bool facing(const Cells& cells, std::size_t idx, const int* c) const {
    if (ctx_.min_cos <= 0.0) return true;
    const std::uint64_t patches = ctx_.grid.patches(idx);
    const int need = ctx_.options.incidence_min_patches;
    auto dense = [&](int axis) {
      return __builtin_popcount(unsigned(std::uint16_t(patches >> (16 * axis)))) >= need;
    };
    if (!dense(0) && !dense(1) && !dense(2)) return true;
    int at[3];
    if (!c) {
      ctx_.grid.layout.coords(idx, at[0], at[1], at[2]);
      c = at;
    }
    double n[3];
    const double nn = normal(cells, c, n);
    if (nn <= 0.0 || cosine(n) >= ctx_.min_cos * nn) return true;
    const int axis = std::abs(n[0]) >= std::abs(n[1]) ? (std::abs(n[0]) >= std::abs(n[2]) ? 0 : 2)
                                                      : (std::abs(n[1]) >= std::abs(n[2]) ? 1 : 2);
    return !dense(axis);
  }
  void credit(std::size_t idx, double p, bool prior = false) {
    gain_ += vis_ * p;
    ++cells_;
    if (ctx_.credits) ctx_.credits->push_back({std::int64_t(idx), bin_, float(vis_ * p), prior});
  }
  ViewContext& ctx_;
  VisitedSet::Marks marks_;
  std::uint32_t cone_ = 0;
  std::int8_t bin_ = 0;
  double vis_ = 1.0, gain_ = 0.0;
  Eigen::Vector3d dir_ = Eigen::Vector3d::UnitX();
  int cells_ = 0;
};

}  // namespace nbv::utility
