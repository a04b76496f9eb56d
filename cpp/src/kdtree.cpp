// The core's one exact nearest-neighbour index (nbv/kdtree.hpp).
#include "nbv/kdtree.hpp"
#include "nbv/parallel.hpp"

#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

namespace nbv {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Number of nodes of a tree over `m` items (median split, leaves of <= leaf items).
std::size_t node_count(std::size_t m, std::size_t leaf, std::map<std::size_t, std::size_t>& memo) {
  if (m <= leaf) return 1;
  auto it = memo.find(m);
  if (it != memo.end()) return it->second;
  const std::size_t c = 1 + node_count(m / 2, leaf, memo) + node_count(m - m / 2, leaf, memo);
  memo.emplace(m, c);
  return c;
}

}  // namespace

// ---------------------------------------------------------------------------- KdTree

namespace {
inline double box_dist2(const double* lo, const double* hi, const double* q) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double v = q[a] < lo[a] ? lo[a] - q[a] : (q[a] > hi[a] ? q[a] - hi[a] : 0.0);
    d2 += v * v;
  }
  return d2;
}
}  // namespace

KdTree::KdTree(const PointsRef& points, int leaf_size)
    : KdTree(
          std::size_t(points.rows()),
          [&points](std::size_t i) {
            const auto r = static_cast<Eigen::Index>(i);
            return Eigen::Vector3d(points(r, 0), points(r, 1), points(r, 2));
          },
          leaf_size) {}

KdTree::KdTree(std::size_t n, const std::function<Eigen::Vector3d(std::size_t)>& point,
               int leaf_size)
    : leaf_size_(std::max(1, leaf_size)) {
  if (n >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw std::invalid_argument("kd-tree: too many points (" + std::to_string(n) + ")");
  pts_.resize(n);
  pos_.resize(n);
  if (n == 0) return;
  std::atomic<bool> finite{true};
  parallel_chunks(n, 1 << 14, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const Eigen::Vector3d p = point(i);
      if (!p.allFinite()) finite.store(false, std::memory_order_relaxed);
      pts_[i] = Item{{p[0], p[1], p[2]}, static_cast<std::uint32_t>(i)};
    }
  });
  if (!finite.load()) throw std::invalid_argument("kd-tree points contains NaN or infinite values");
  std::map<std::size_t, std::size_t> memo;  // at most two subtree sizes per depth
  const std::size_t total = node_count(n, static_cast<std::size_t>(leaf_size_), memo);
  subtree_nodes_.assign(memo.begin(), memo.end());
  nodes_.resize(total);
  core_arena()->execute([&] { build(0, 0, n); });
  subtree_nodes_.clear();
  subtree_nodes_.shrink_to_fit();
  parallel_chunks(n, 1 << 14, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) pos_[pts_[i].id] = static_cast<std::uint32_t>(i);
  });
}

std::size_t KdTree::subtree_nodes(std::size_t m) const {
  if (m <= static_cast<std::size_t>(leaf_size_)) return 1;
  auto it = std::lower_bound(subtree_nodes_.begin(), subtree_nodes_.end(),
                             std::make_pair(m, std::size_t(0)));
  return it->second;
}

void KdTree::build(std::size_t node, std::size_t begin, std::size_t end) {
  Node& nd = nodes_[node];
  for (int a = 0; a < 3; ++a) {
    nd.lo[a] = kInf;
    nd.hi[a] = -kInf;
  }
  for (std::size_t i = begin; i < end; ++i)
    for (int a = 0; a < 3; ++a) {
      nd.lo[a] = std::min(nd.lo[a], pts_[i].p[a]);
      nd.hi[a] = std::max(nd.hi[a], pts_[i].p[a]);
    }
  const std::size_t m = end - begin;
  if (m <= static_cast<std::size_t>(leaf_size_)) {
    nd.a = static_cast<std::int32_t>(begin);
    nd.b = static_cast<std::int32_t>(end);
    nd.leaf = true;
    return;
  }
  int dim = 0;
  for (int a = 1; a < 3; ++a)
    if (nd.hi[a] - nd.lo[a] > nd.hi[dim] - nd.lo[dim]) dim = a;
  const std::size_t mid = begin + m / 2;
  auto first = pts_.begin();
  std::nth_element(first + static_cast<std::ptrdiff_t>(begin),
                   first + static_cast<std::ptrdiff_t>(mid),
                   first + static_cast<std::ptrdiff_t>(end),
                   [dim](const Item& x, const Item& y) { return x.p[dim] < y.p[dim]; });
  const std::size_t left = node + 1, right = node + 1 + subtree_nodes(mid - begin);
  nd.a = static_cast<std::int32_t>(left);
  nd.b = static_cast<std::int32_t>(right);
  nd.leaf = false;
  if (m > (1u << 15)) {
    tbb::parallel_invoke([&] { build(left, begin, mid); }, [&] { build(right, mid, end); });
  } else {
    build(left, begin, mid);
    build(right, mid, end);
  }
}

void KdTree::search(const Node& nd, const double* q, double& best, std::int64_t& best_pos) const {
  if (nd.leaf) {
    for (std::int32_t i = nd.a; i < nd.b; ++i) {
      const double* p = pts_[static_cast<std::size_t>(i)].p;
      const double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 < best) {
        best = d2;
        best_pos = i;
      }
    }
    return;
  }
  const Node& l = nodes_[static_cast<std::size_t>(nd.a)];
  const Node& r = nodes_[static_cast<std::size_t>(nd.b)];
  const double dl = box_dist2(l.lo, l.hi, q), dr = box_dist2(r.lo, r.hi, q);
  if (dl <= dr) {
    if (dl < best) search(l, q, best, best_pos);
    if (dr < best) search(r, q, best, best_pos);
  } else {
    if (dr < best) search(r, q, best, best_pos);
    if (dl < best) search(l, q, best, best_pos);
  }
}

std::pair<Eigen::Index, double> KdTree::nearest(const Eigen::Vector3d& q, Eigen::Index hint) const {
  return nearest(q, hint, kInf);
}

std::pair<Eigen::Index, double> KdTree::nearest(const Eigen::Vector3d& q, Eigen::Index hint,
                                                double bound2) const {
  double best = bound2;
  std::int64_t best_pos = -1;
  if (pts_.empty()) return {-1, best};
  const double qq[3] = {q.x(), q.y(), q.z()};
  if (hint >= 0 && static_cast<std::size_t>(hint) < pos_.size()) {
    const std::uint32_t p = pos_[static_cast<std::size_t>(hint)];
    const double* h = pts_[p].p;
    const double d2 = (qq[0] - h[0]) * (qq[0] - h[0]) + (qq[1] - h[1]) * (qq[1] - h[1]) +
                      (qq[2] - h[2]) * (qq[2] - h[2]);
    if (d2 < best) {
      best = d2;
      best_pos = p;
    }
  }
  const Node& root = nodes_[0];
  if (box_dist2(root.lo, root.hi, qq) < best) search(root, qq, best, best_pos);
  if (best_pos < 0) return {-1, best};
  return {static_cast<Eigen::Index>(pts_[static_cast<std::size_t>(best_pos)].id), best};
}

std::pair<Eigen::VectorXi, Eigen::VectorXd> KdTree::nearest_each(const PointsRef& queries) const {
  std::pair<Eigen::VectorXi, Eigen::VectorXd> out{Eigen::VectorXi::Constant(queries.rows(), -1),
                                                  Eigen::VectorXd::Constant(queries.rows(), kInf)};
  if (pts_.empty() || queries.rows() == 0) return out;
  parallel_chunks(static_cast<std::size_t>(queries.rows()), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      const auto r = nearest(Eigen::Vector3d(queries.row(k).transpose()));
      out.first[k] = static_cast<int>(r.first);
      out.second[k] = std::sqrt(r.second);
    }
  });
  return out;
}

Points KdTree::points() const {
  Points out(static_cast<Eigen::Index>(pts_.size()), 3);
  for (const Item& it : pts_) out.row(it.id) << it.p[0], it.p[1], it.p[2];
  return out;
}

std::vector<std::uint32_t> KdTree::order() const {
  std::vector<std::uint32_t> out(pts_.size());
  for (std::size_t i = 0; i < pts_.size(); ++i) out[i] = pts_[i].id;
  return out;
}

void tree_nearest_lower(const KdTree& targets, const KdTree& queries, std::vector<double>& best2) {
  if (best2.size() != queries.size())
    throw std::invalid_argument("tree_nearest_lower: one distance per query");
  if (targets.size() == 0) return;
  parallel_chunks(queries.size(), 2048, [&](std::size_t b, std::size_t e) {
    Eigen::Index hint = -1;
    for (std::size_t k = b; k < e; ++k) {
      const auto r = targets.nearest(queries.point_at(k), hint, best2[k]);
      if (r.first < 0) continue;
      hint = r.first;
      best2[k] = r.second;
    }
  });
}

std::vector<double> tree_nearest(const KdTree& targets, const KdTree& queries) {
  std::vector<double> out(queries.size(), kInf);  // squared, then the distances
  tree_nearest_lower(targets, queries, out);
  for (double& d : out) d = std::sqrt(d);
  return out;
}

Eigen::VectorXd nearest_distances(const PointsRef& targets, const PointsRef& queries) {
  require_coordinates(targets, "targets");  // beyond +-1e9 m the squares overflowed to inf
  return nearest_distances(KdTree(targets), queries);
}

Eigen::VectorXd nearest_distances(const KdTree& targets, const PointsRef& queries) {
  require_coordinates(queries, "queries");
  const KdTree q(queries);  // for a cache-friendly query order
  const std::vector<double> d = tree_nearest(targets, q);
  Eigen::VectorXd out(static_cast<Eigen::Index>(d.size()));
  for (std::size_t k = 0; k < d.size(); ++k) out[q.id_at(k)] = d[k];
  return out;
}

}  // namespace nbv
