// Where the vehicle may be and how it gets there: collision checks against the map (a sphere
// must touch only known free cells, none of them holding a camera hit when the grid view has the
// camera observations: GridView::blocked) and A* paths through known free space.
#pragma once

#include "nbv/common.hpp"
#include "nbv/grid_view.hpp"

#include <cstddef>
#include <vector>

namespace nbv {

/// True if every cell that intersects the sphere (center, radius) is known and not occupied, and
/// (observed grid views) holds no camera hit: none is GridView::blocked (false when part of it is
/// outside the grid: unknown).
bool sphere_is_free(const GridView& grid, const Eigen::Vector3d& center, double radius);
/// True if spheres every resolution/2 along the segment a-b are all free.
bool segment_is_free(const GridView& grid, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                     double radius);

/// What a plan_path search did: cells it expanded, cells its flood from b reached, whether the
/// flood ended it (b's free component closed without a), and whether it stopped at its cap on
/// expanded cells with cells still to expand (capped: only then may a longer search find a path
/// where this one found none; any other failure is final).
struct PathSearchStats {
  std::size_t expansions = 0, flooded = 0;
  bool flood_ended = false, capped = false;
  double cost = 0.0;  ///< the found cells' path cost (m, a's cell to b's, before shortening)
};

/// Cells an A* search expands at most unless told (vehicle.path_expansions's default, bound as
/// nbvkit._core.DEFAULT_PATH_EXPANSIONS).
inline constexpr std::size_t kDefaultPathExpansions = 200000;

/// A* through known free space (26-connected cells whose collision sphere is free, none below
/// the grid's path_floor: GridView::lowest_path_layer). Returns the
/// waypoints from a to b (a first, b last), shortened greedily by line of sight, or an empty
/// list if there is none within max_expansions. The path's length is the sum of its segments.
/// Beside the search, once it has expanded 1,024 cells, a flood from b steps once per
/// expansion: when b's free component turns out closed without a the search ends (b in a small
/// pocket costs the pocket, not a's whole component); it never changes the answer.
std::vector<Eigen::Vector3d> plan_path(const GridView& grid, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, double radius,
                                       std::size_t max_expansions = kDefaultPathExpansions,
                                       PathSearchStats* stats = nullptr);

/// The paths from many points to one goal (plan_paths_to): per start, its waypoints (the start
/// first, the goal last; empty where there is none) and the cost of the cells' path it was
/// shortened from (m; NaN where the straight flight was free or there is no path).
struct PathsToGoal {
  std::vector<std::vector<Eigen::Vector3d>> paths;
  std::vector<double> cells_cost;
  std::size_t expansions = 0;  ///< cells the search expanded
  bool capped = false;         ///< it stopped at max_expansions with starts still to reach
};

/// What plan_path(grid, start, goal, radius) finds from each row of `starts`, uncapped, by one
/// search: the straight flight where it is free, else a cheapest path over the traversable cells
/// (the same cost as plan_path's; where several tie, perhaps another of them) shortened greedily
/// by line of sight, or none. One search from the goal's cell (the moves are symmetric; A*
/// towards the box of the starts' cells, Dijkstra's search where the goal is inside it) runs
/// until it has reached every start's cell, exhausted the goal's free component, or expanded
/// max_expansions cells (0: no cap); the straight-flight tests and the shortening run in
/// parallel.
PathsToGoal plan_paths_to(const GridView& grid, const PointsRef& starts,
                          const Eigen::Vector3d& goal, double radius,
                          std::size_t max_expansions = 0);

/// The cells plan_path can reach from a: a's free component (traversable cells, 26-connected,
/// reached from a's neighbours as the search expands them), found by one flood. Valid for the
/// grid it was made from while that grid is unchanged.
class FreeComponent {
 public:
  FreeComponent(const GridView& grid, const Eigen::Vector3d& a, double radius);
  /// Per target row: can plan_path reach it from a? True where the straight flight is free, or
  /// where the target's cell is in the component (or is a's own cell, traversable) and its
  /// centre sees the target through free space. plan_path's expansion cap is not applied: a
  /// true here can still be a search cut short there; a false is always a failed search.
  std::vector<std::uint8_t> contains(const GridView& grid, const PointsRef& targets) const;

 private:
  Eigen::Vector3d start_;
  double radius_;
  Eigen::Vector3i start_cell_{0, 0, 0};
  bool start_in_grid_ = false;
  int words_ = 0, ny_ = 0;              // words of 64 cells per row along x; rows along y
  int lowest_layer_ = 0;                // the flooded grid's lowest_path_layer()
  std::vector<std::uint64_t> reached_;  // per word: the component's cells
};

/// plan_path as it was first written (hash maps, a sphere test per cell, no flood): the same
/// path for the same input, kept as the reference the fast search is tested and timed against.
std::vector<Eigen::Vector3d> plan_path_reference(
    const GridView& grid, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius,
    std::size_t max_expansions = kDefaultPathExpansions);

/// Length of a polyline (rows are waypoints).
double path_length(const std::vector<Eigen::Vector3d>& path);

}  // namespace nbv
