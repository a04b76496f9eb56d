#include "nbv/tour_plan.hpp"

#include "nbv/tour.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace nbv {
namespace {

// numpy's arithmetic, step for step: the plans are those the tour generator made in Python.

/// np.linalg.norm(a - b): the squares summed in order.
double distance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  double s = 0.0;
  s += dx * dx;
  s += dy * dy;
  s += dz * dz;
  return std::sqrt(s);
}

/// numpy's pairwise summation (np.sum of a float64 array: 0 + the blocked sum).
double pairwise(const double* a, std::size_t n) {
  if (n < 8) {
    double r = 0.0;
    for (std::size_t i = 0; i < n; ++i) r += a[i];
    return r;
  }
  if (n <= 128) {
    double r[8];
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    std::size_t i = 8;
    for (; i < n - (n % 8); i += 8)
      for (int j = 0; j < 8; ++j) r[j] += a[i + j];
    double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += a[i];
    return res;
  }
  std::size_t n2 = n / 2;
  n2 -= n2 % 8;
  return pairwise(a, n2) + pairwise(a + n2, n - n2);
}

double numpy_sum(const std::vector<double>& v) { return 0.0 + pairwise(v.data(), v.size()); }

/// The stops of a tour: start, then points[order] (rows).
std::vector<Eigen::Vector3d> stops(const Eigen::Vector3d& start, const PointsRef& points,
                                   const std::vector<int>& order) {
  std::vector<Eigen::Vector3d> seq{start};
  for (int k : order) seq.push_back(points.row(k).transpose());
  return seq;
}

/// Each leg's length: leg k ends at the k-th stop after the start.
std::vector<double> legs(const std::vector<Eigen::Vector3d>& seq) {
  std::vector<double> leg(seq.size() - 1);
  for (std::size_t k = 0; k < leg.size(); ++k) leg[k] = distance(seq[k + 1], seq[k]);
  return leg;
}

/// The length of the open tour (np.sum of its legs).
double tour_length(const Eigen::Vector3d& start, const PointsRef& points,
                   const std::vector<int>& order) {
  return numpy_sum(legs(stops(start, points, order)));
}

/// The rows of `points` at `rows`.
Points rows_of(const PointsRef& points, const std::vector<int>& rows) {
  Points out(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = points.row(rows[i]);
  return out;
}

/// A selection (its views and gains in cells) as a plan: its views' tour from `start`
/// (solve_tour's; an insertion tour keeps its own order where that is no longer), prize-collected,
/// measured and valued (the kept views' gains - rate x the kept tour's length).
TourPlan plan_of(const CoverSelection& s, const PointsRef& positions, const Eigen::Vector3d& start,
                 const TourPlanOptions& o) {
  TourPlan p;
  p.chosen = s.views;
  for (double g : s.gains) p.gains.push_back(g * o.cell_area);
  if (p.chosen.empty()) return p;
  const Points pts = rows_of(positions, p.chosen);
  Tour t = solve_tour(pts, start);
  if (o.insertion) {
    std::vector<int> kept(p.chosen.size());
    for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = static_cast<int>(i);
    if (tour_length(start, pts, kept) <= t.length) t.order = kept;
  }
  p.order = prize_collect(start, pts, p.gains, std::move(t.order), o.rate);
  if (p.order.empty()) return p;
  p.length = tour_length(start, pts, p.order);
  std::vector<double> g;
  for (int k : p.order) g.push_back(p.gains[static_cast<std::size_t>(k)]);
  p.value = numpy_sum(g) - o.rate * p.length;
  return p;
}

}  // namespace

void TourPlanOptions::validate() const {
  const auto need = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument("tour plan: " + what);
  };
  need(std::isfinite(min_gain) && min_gain >= 0, "min_gain must be a finite number >= 0 (m^2)");
  need(std::isfinite(rate) && rate >= 0, "rate must be a finite number >= 0 (m^2 per metre)");
  need(std::isfinite(cell_area) && cell_area > 0, "cell_area must be a finite number > 0 (m^2)");
  need(max_views >= 0, "max_views must be >= 0");
}

std::vector<int> TourPlan::flight() const {
  std::vector<int> out;
  for (int k : order) out.push_back(chosen[static_cast<std::size_t>(k)]);
  return out;
}

std::vector<int> prize_collect(const Eigen::Vector3d& start, const PointsRef& points,
                               const std::vector<double>& gains, std::vector<int> order,
                               double rate) {
  if (gains.size() != static_cast<std::size_t>(points.rows()))
    throw std::invalid_argument("prize_collect: one gain per point");
  std::vector<char> listed(static_cast<std::size_t>(points.rows()), 0);
  for (int k : order) {
    if (k < 0 || k >= points.rows())
      throw std::invalid_argument("prize_collect: order indexes past the points");
    if (listed[std::size_t(k)]++)  // (a tour visits a point once: [0, 0] was kept twice)
      throw std::invalid_argument("prize_collect: order lists point " + std::to_string(k) +
                                  " twice");
  }
  for (double g : gains)
    if (!std::isfinite(g)) throw std::invalid_argument("prize_collect: gains must be finite");
  if (!(rate > 0)) return order;
  while (!order.empty()) {
    const std::vector<Eigen::Vector3d> seq = stops(start, points, order);
    const std::vector<double> leg = legs(seq);
    const std::size_t n = order.size();
    std::vector<double> cum_leg(n + 1, 0.0), cum_gain(n + 1, 0.0);
    for (std::size_t k = 0; k < n; ++k) {  // np.cumsum, a 0 before
      cum_leg[k + 1] = k ? cum_leg[k] + leg[k] : leg[k];
      cum_gain[k + 1] = k ? cum_gain[k] + gains[order[k]] : gains[order[k]];
    }
    double best = 0.0;
    std::size_t bi = n, bj = n;
    for (std::size_t i = 0; i < n; ++i) {  // remove order[i..j]: the best j for each i first
      double top = 0.0;
      std::size_t tj = n;
      for (std::size_t j = i; j < n; ++j) {
        const double inner = cum_leg[j + 1] - cum_leg[i];  // from the view before i through j
        const double after = j + 1 < n ? leg[j + 1] : 0.0;
        const double bridge = j + 1 < n ? distance(seq[j + 2], seq[i]) : 0.0;
        const double saving = inner + after - bridge;
        const double deficit = rate * saving - (cum_gain[j + 1] - cum_gain[i]);
        if (tj == n || deficit > top) top = deficit, tj = j;  // np.argmax: the first largest
      }
      if (top > best + 1e-12) best = top, bi = i, bj = tj;
    }
    if (bi == n) break;
    order.erase(order.begin() + static_cast<std::ptrdiff_t>(bi),
                order.begin() + static_cast<std::ptrdiff_t>(bj) + 1);
  }
  return order;
}

TourPlan plan_tour(const CoverageRef& coverage, const PointsRef& positions,
                   const Eigen::Vector3d& start, const TourPlanOptions& o) {
  o.validate();
  if (positions.rows() != coverage.status.size())
    throw std::invalid_argument("tour plan: one position per candidate of the coverage sets");
  const double min_gain = o.min_gain / o.cell_area;  // in coverage weight
  TourPlan plan;
  std::optional<CoverSelection> cover;  // select_cover's views at min_gain, once made
  if (o.insertion) {
    // anchored at the vehicle, and with the first view's transit free (a far cluster that pays
    // only as a whole): the tour worth more after prize collection is flown
    const auto tours = select_tours(coverage, positions, start, o.rate / o.cell_area, min_gain,
                                    o.max_views, {true, false});
    for (std::size_t t = 0; t < tours.size(); ++t) {
      TourPlan p = plan_of(tours[t], positions, start, o);
      if (t == 0 || p.value > plan.value) plan = std::move(p);
    }
  } else {
    cover = select_cover(coverage, min_gain, o.max_views);
    plan = plan_of(*cover, positions, start, o);
  }
  if (plan.order.empty()) {  // views adding min_gain that no tour paid for
    if (!cover) cover = select_cover(coverage, min_gain, o.max_views);
    plan.unpaid = static_cast<int>(cover->views.size());
    plan.unpaid_area = numpy_sum(cover->gains) * o.cell_area;
  }
  return plan;
}

}  // namespace nbv
