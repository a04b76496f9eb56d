// Where the vehicle may be and how it gets there: collision checks against the map (a sphere
// must touch only known free cells) and A* paths through known free space.
#pragma once

#include "nbv/common.hpp"
#include "nbv/grid_view.hpp"

#include <cstddef>
#include <vector>

namespace nbv {

/// True if every cell that intersects the sphere (center, radius) is known and not occupied
/// (false when part of it is outside the grid: unknown).
bool sphere_is_free(const GridView& grid, const Eigen::Vector3d& center, double radius);
/// True if spheres every resolution/2 along the segment a-b are all free.
bool segment_is_free(const GridView& grid, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                     double radius);

/// A* through known free space (26-connected cells whose collision sphere is free). Returns the
/// waypoints from a to b (a first, b last), shortened greedily by line of sight, or an empty
/// list if there is none within max_expansions. The path's length is the sum of its segments.
std::vector<Eigen::Vector3d> plan_path(const GridView& grid, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, double radius,
                                       std::size_t max_expansions = 200000);

/// Length of a polyline (rows are waypoints).
double path_length(const std::vector<Eigen::Vector3d>& path);

}  // namespace nbv
