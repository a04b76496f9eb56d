#include "nbv/tour.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace nbv {
namespace {

constexpr double kBlocked = 1e12;  // an impassable leg: avoided whenever possible

double path_cost(const Eigen::MatrixXd& D, const std::vector<int>& p) {
  double c = 0.0;
  for (std::size_t i = 1; i < p.size(); ++i) c += D(p[i - 1], p[i]);
  return c;
}

}  // namespace

Tour solve_tour_matrix(const Eigen::MatrixXd& D_in, bool improve) {
  const Eigen::Index n = D_in.rows();
  if (n < 1 || D_in.cols() != n)
    throw std::invalid_argument("tour distance matrix must be square with the start at row 0");
  Eigen::MatrixXd D = D_in;
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) {
      if (std::isnan(D(i, j)) || D(i, j) < 0)
        throw std::invalid_argument("tour distances must be >= 0 (inf: impassable)");
      if (!std::isfinite(D(i, j))) D(i, j) = kBlocked;
    }
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = i + 1; j < n; ++j)
      if (std::fabs(D(i, j) - D(j, i)) > 1e-9 * std::max(1.0, std::fabs(D(i, j))))
        throw std::invalid_argument("tour distance matrix must be symmetric");
  // path p over matrix indices, p[0] = 0 the start
  std::vector<int> p{0};
  std::vector<char> used(std::size_t(n), 0);
  used[0] = 1;
  for (Eigen::Index step = 1; step < n; ++step) {  // nearest neighbour (ties: lower index)
    const int last = p.back();
    int best = -1;
    for (int j = 1; j < n; ++j)
      if (!used[std::size_t(j)] && (best < 0 || D(last, j) < D(last, best))) best = j;
    used[std::size_t(best)] = 1;
    p.push_back(best);
  }
  const int m = int(p.size());
  bool better = improve;
  while (better) {
    better = false;
    // 2-opt: reverse p[i..j]; the end of the path is open
    for (int i = 1; i < m - 1 && !better; ++i)
      for (int j = i + 1; j < m; ++j) {
        double delta = D(p[i - 1], p[j]) - D(p[i - 1], p[i]);
        if (j + 1 < m) delta += D(p[i], p[j + 1]) - D(p[j], p[j + 1]);
        if (delta < -1e-9) {
          std::reverse(p.begin() + i, p.begin() + j + 1);
          better = true;
          break;
        }
      }
    if (better) continue;
    // Or-opt: move a run of 1-3 views (as is or reversed) elsewhere
    for (int len = 1; len <= 3 && !better; ++len)
      for (int i = 1; i + len - 1 < m && !better; ++i) {
        const int a = p[i - 1], s = p[i], e = p[i + len - 1];
        const int after = i + len < m ? p[i + len] : -1;
        const double removed =
            D(a, s) + (after >= 0 ? D(e, after) - D(a, after) : 0.0);  // saving when cut out
        for (int j = 0; j < m && !better; ++j) {
          if (j >= i - 1 && j < i + len) continue;  // insert between p[j] and p[j + 1]
          const int u = p[j], v = j + 1 < m ? p[j + 1] : -1;
          for (int rev = 0; rev < 2; ++rev) {
            const int first = rev ? e : s, last = rev ? s : e;
            const double added = D(u, first) + (v >= 0 ? D(last, v) - D(u, v) : 0.0);
            if (added - removed < -1e-9) {
              std::vector<int> run(p.begin() + i, p.begin() + i + len);
              if (rev) std::reverse(run.begin(), run.end());
              std::vector<int> q(p.begin(), p.begin() + i);
              q.insert(q.end(), p.begin() + i + len, p.end());
              const int at = j < i ? j + 1 : j + 1 - len;
              q.insert(q.begin() + at, run.begin(), run.end());
              if (path_cost(D, q) < path_cost(D, p) - 1e-9) {
                p = std::move(q);
                better = true;
              }
              break;
            }
          }
        }
      }
  }
  Tour t;
  for (int i = 1; i < m; ++i) t.order.push_back(p[std::size_t(i)] - 1);
  t.length = path_cost(D_in.unaryExpr([](double v) { return std::isfinite(v) ? v : kBlocked; }), p);
  return t;
}

Tour solve_tour(const PointsRef& points, const Eigen::Vector3d& start, bool improve) {
  require_finite(points, "tour points");
  if (!start.allFinite()) throw std::invalid_argument("tour start contains NaN or infinite values");
  const Eigen::Index n = points.rows() + 1;
  Eigen::MatrixXd D(n, n);
  auto pt = [&](Eigen::Index i) -> Eigen::Vector3d {
    return i == 0 ? start : Eigen::Vector3d(points.row(i - 1).transpose());
  };
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) D(i, j) = (pt(i) - pt(j)).norm();
  return solve_tour_matrix(D, improve);
}

}  // namespace nbv
