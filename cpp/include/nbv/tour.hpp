// Visiting order of a set of views: an open travelling-salesman path from a start, by nearest
// neighbour then 2-opt and Or-opt improvement until no move shortens it.
#pragma once

#include "nbv/common.hpp"

#include <vector>

namespace nbv {

struct Tour {
  std::vector<int> order;  ///< indices into the points, each once
  double length = 0.0;     ///< start -> points in order (no return), in the distance's unit
};

/// Open tour from `start` through every row of `points` (N, 3), Euclidean distances.
/// With improve = false only the nearest-neighbour tour. Deterministic.
Tour solve_tour(const PointsRef& points, const Eigen::Vector3d& start, bool improve = true);

/// The same over a distance matrix D ((N + 1) x (N + 1), row/column 0 the start; need not be
/// symmetric or metric, e.g. flight distances around obstacles). Non-finite entries are
/// impassable: the tour avoids them when it can.
Tour solve_tour_matrix(const Eigen::MatrixXd& D, bool improve = true);

}  // namespace nbv
