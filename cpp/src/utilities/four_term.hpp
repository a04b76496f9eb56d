// The authors' four-term utility (Almadhoun et al., Remote Sensing 2019; see
// shared/reference/original-implementation.md):
//   log10(N_occ) * exp(-w_d d) * (1 + w_H H^) * (w_rho (1 - rho^) + w_p P^)
// with, over the distinct cells the rays reach (each ray ending at its first occupied cell):
//   N_occ  occupied cells seen (predicted ones included),
//   H^     their mean entropy over all reached cells, divided by the maximum (ln 2 nats / 1 bit),
//   rho^   the mean over the seen observed occupied cells of min(1, camera hits / density_target)
//          (the reconstruction's density there),
//   P^     the share of predicted cells among the N_occ,
// and the distance weight exp(-w_d d) (w_d = UtilityOptions::distance_lambda) applied by the
// caller. Needs the camera observations.
#pragma once

#include "utility.hpp"

namespace nbv::utility {

struct FourTerm {
  static constexpr bool kSkipNeutral = false;  // neutral cells dilute the mean entropy
  static constexpr bool kNeedsSurface = true;
  explicit FourTerm(ViewContext& ctx) : ctx_(ctx), marks_(ctx.visited.marks()) {}
  ~FourTerm() { marks_.keep(); }
  void begin_ray(const Eigen::Vector3d&) {}
  template <class Cells>
  bool visit(const Cells& cells, std::size_t idx, const int* c, double, float scored) {
    if (!marks_.insert(idx)) return !std::signbit(scored);
    ++reached_;
    entropy_ += std::fabs(scored);
    if (!std::signbit(scored)) return true;
    ++occupied_;
    if (cells.flag(idx, c) == CellFlag::Predicted) {
      ++predicted_;
    } else {
      ++observed_;
      density_ += std::min(1.0, ctx_.grid.hits(idx) / ctx_.options.density_target);
    }
    return false;
  }
  double gain() const {
    if (occupied_ == 0) return 0.0;
    const double h = reached_ ? entropy_ / reached_ / ctx_.grid.unknown_entropy : 0.0;
    const double rho = observed_ ? density_ / observed_ : 0.0;
    const double p = double(predicted_) / occupied_;
    const UtilityOptions& o = ctx_.options;
    return std::log10(double(occupied_)) * (1.0 + o.weight_entropy * h) *
           (o.weight_density * (1.0 - rho) + o.weight_prediction * p);
  }
  int cells() const { return occupied_; }

 private:
  ViewContext& ctx_;
  VisitedSet::Marks marks_;
  double entropy_ = 0.0, density_ = 0.0;
  int reached_ = 0, occupied_ = 0, observed_ = 0, predicted_ = 0;
};

}  // namespace nbv::utility
