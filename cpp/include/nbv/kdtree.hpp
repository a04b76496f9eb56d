// Exact Euclidean nearest neighbours over a fixed point set: the one kd-tree of the core (the
// evaluation's cloud <-> ground-truth distances, symmetry's mirror partners and prediction).
#pragma once

#include "nbv/common.hpp"

#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

namespace nbv {

/// Exact Euclidean nearest-neighbour index over a fixed point set: a kd-tree (median splits on
/// the widest axis) whose every node keeps the tight bounding box of its points, so a query far
/// from the set (an unobserved part of a structure, an outlier) prunes by box distance as a BVH
/// would. Leaves of `leaf_size` points are stored contiguously in double precision. The build is
/// parallel (TBB); queries are const and thread-safe.
class KdTree {
 public:
  explicit KdTree(const PointsRef& points, int leaf_size = 12);
  /// The same tree over n points given one at a time by point(i), i in [0, n) (called in
  /// parallel): e.g. the points of several clouds read in place, without a stacked copy.
  KdTree(std::size_t n, const std::function<Eigen::Vector3d(std::size_t)>& point,
         int leaf_size = 12);

  std::size_t size() const { return pts_.size(); }
  /// Nearest point to q: (index into the constructor's points, squared distance in m^2).
  /// (-1, inf) for an empty tree. `hint` (an index, or -1) is a point believed to be close
  /// (e.g. the previous query's answer); it only speeds the search up. Ties go to the point of
  /// lowest index among the equally near ones, and the distance is always the exact minimum.
  std::pair<Eigen::Index, double> nearest(const Eigen::Vector3d& q, Eigen::Index hint = -1) const;
  /// The same, looking only for points nearer than sqrt(bound2): (-1, bound2) when none is
  /// (a bound from an earlier search, e.g. in another tree, prunes this one).
  std::pair<Eigen::Index, double> nearest(const Eigen::Vector3d& q, Eigen::Index hint,
                                          double bound2) const;
  /// Nearest neighbours of many queries (N, 3), in parallel: (N,) indices into the constructor's
  /// points (-1 for an empty tree) and (N,) Euclidean distances in metres (inf if none).
  std::pair<Eigen::VectorXi, Eigen::VectorXd> nearest_each(const PointsRef& queries) const;
  /// The points' indices in tree order: consecutive entries are spatially close, so queries
  /// issued in this order are cache-friendly.
  std::vector<std::uint32_t> order() const;
  /// The k-th point in tree order, and its index among the constructor's points.
  Eigen::Vector3d point_at(std::size_t k) const {
    return {pts_[k].p[0], pts_[k].p[1], pts_[k].p[2]};
  }
  std::uint32_t id_at(std::size_t k) const { return pts_[k].id; }
  /// The constructor's point of index i.
  Eigen::Vector3d point(Eigen::Index i) const {
    return point_at(pos_[static_cast<std::size_t>(i)]);
  }
  /// The points in the constructor's order.
  Points points() const;

 private:
  struct Item {
    double p[3];
    std::uint32_t id;
  };
  struct Node {
    double lo[3], hi[3];  ///< tight bounding box of the node's points
    std::int32_t a, b;    ///< inner: children; leaf: item range [a, b)
    bool leaf;
  };
  void build(std::size_t node, std::size_t begin, std::size_t end);
  std::size_t subtree_nodes(std::size_t m) const;
  void search(const Node& node, const double* q, double& best, std::int64_t& best_pos) const;

  int leaf_size_;
  std::vector<Item> pts_;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> pos_;  ///< original index -> position in pts_
  /// (subtree size, node count) for every subtree size above leaf_size_, sorted (build only).
  std::vector<std::pair<std::size_t, std::size_t>> subtree_nodes_;
};

/// Lowers best2[k], the squared distance from the k-th point of `queries` (tree order) to the
/// nearest point found so far, to the nearest point of `targets` where that is nearer (parallel):
/// over several target trees in turn, best2 ends as the exact squared distance to their union.
void tree_nearest_lower(const KdTree& targets, const KdTree& queries, std::vector<double>& best2);
/// (Q,) exact distance (metres) from each query to its nearest target; inf if there are no
/// targets. Parallel over queries; deterministic.
Eigen::VectorXd nearest_distances(const PointsRef& targets, const PointsRef& queries);
/// The same against the targets' tree, built once for many calls.
Eigen::VectorXd nearest_distances(const KdTree& targets, const PointsRef& queries);
/// Distances from every point of `queries`, in its tree order, to the nearest point of `targets`
/// (parallel; a query's answer seeds the next one's search).
std::vector<double> tree_nearest(const KdTree& targets, const KdTree& queries);

}  // namespace nbv
