// A coverage tour's plan over what candidate views would newly cover (nbv/coverage.hpp): the
// views a selection takes, the order they are flown in, and prize collection, in one call with
// a typed result (the surface planner's tour generator, python/nbvkit/planning/generators/tour.py).
#pragma once

#include "nbv/coverage.hpp"

#include <vector>

namespace nbv {

/// How a plan chooses and orders its views. Areas are in m^2; a coverage weight of 1 is
/// cell_area m^2 (the map's cell face).
struct TourPlanOptions {
  /// true: prize-collecting insertion tours (select_tours, the first transit charged and free),
  /// the one worth more after prize collection; false: a greedy set cover, then the shortest
  /// open tour through it (solve_tour)
  bool insertion = true;
  double min_gain = 0.0;   ///< m^2 a view must add to be chosen
  double rate = 0.0;       ///< m^2 of new surface per metre of flight a view must pay for
  double cell_area = 1.0;  ///< m^2 of a coverage weight of 1
  int max_views = 1000;    ///< views a selection takes at most
  void validate() const;   ///< std::invalid_argument naming the field at fault
};

/// A plan: the candidates a selection took (`chosen`, each with the area it adds), the flight
/// order of those kept after prize collection (`order`, indices into chosen), and what it is
/// worth. With no view kept, what no tour paid for: the views a set cover takes at min_gain.
struct TourPlan {
  /// candidate indices: an insertion tour's in its insertion order, a set cover's as it took them
  std::vector<int> chosen;
  std::vector<double> gains;  ///< m^2 each chosen view adds, when it was taken
  std::vector<int> order;     ///< the flight order of the views kept: indices into chosen
  double value = 0.0;         ///< m^2: the kept views' gains - rate x the kept tour's length
  double length = 0.0;        ///< m: from the start through the kept views, in order
  int unpaid = 0;             ///< with no view kept: views adding min_gain that no tour paid for
  double unpaid_area = 0.0;   ///< m^2 those views add
  /// The candidate indices of the kept views in flight order (chosen[order]).
  std::vector<int> flight() const;
};

/// Drops stretches of the open tour `order` (indices into points (N, 3), gains (N,) in m^2) from
/// `start` while some run of consecutive views adds less than `rate` m^2 per metre of the flight
/// its removal saves (a single view's detour, or a far cluster's transit there and back), the
/// worst deficit (rate x saving - gain) first. Returns the kept order. rate <= 0: order as it is.
/// The arithmetic is numpy's, step for step (the tour generator's flights are those it flew
/// when this was Python).
std::vector<int> prize_collect(const Eigen::Vector3d& start, const PointsRef& points,
                               const std::vector<double>& gains, std::vector<int> order,
                               double rate);

/// The plan over coverage sets of candidates at `positions` (K, 3) from `start`.
/// Insertion: each select_tours tour (its views and gains) is ordered by the shorter of its
/// insertion order and solve_tour over its views, then prize-collected; the tour with the larger
/// value is the plan (ties: the one charged its first transit). Cover: select_cover's views,
/// solve_tour, prize collection. Deterministic.
TourPlan plan_tour(const CoverageRef& coverage, const PointsRef& positions,
                   const Eigen::Vector3d& start, const TourPlanOptions& options);

}  // namespace nbv
