// Which parts of a structure's surface a camera could see at all: for each surface sample, is
// there a collision-free vehicle pose of the navigation space from which the depth camera sees
// it (in its frustum and range, not grazing, nothing in between)? Embree ray casts, one call.
#pragma once

#include "nbv/common.hpp"
#include "nbv/options.hpp"
#include "nbv/raycast.hpp"
#include "nbv/sensors.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace nbv {

#define NBV_OBSERVABILITY_OPTIONS(X)                                                           \
  X(double, pose_spacing, 2.0,                                                                 \
    "m; the largest spacing of the lattice of candidate vehicle positions filling the "        \
    "navigation box, faces included (bench/bench_observable.py measures its convergence)")     \
  X(double, collision_radius, 0.8, "m; a candidate position nearer the mesh is in collision")  \
  X(double, max_incidence_deg, 85.0,                                                           \
    "largest angle between the line of sight and the surface normal (either side) at which a " \
    "sample counts as seen")                                                                   \
  X(int, yaw_steps, 8, "yaw offsets tried each side of the yaw that centres a sample")         \
  X(double, gimbal_min_deg, 0.0,                                                               \
    "the camera gimbal's pitch range, deg (> 0 looks down; camera.gimbal_pitch_deg): the "     \
    "pitch that centres a sample vertically, within it, is tried; [0, 0]: the fixed mount")    \
  X(double, gimbal_max_deg, 0.0, "the top of that range, deg")

struct ObservabilityOptions {
  NBV_OBSERVABILITY_OPTIONS(NBV_DECLARE_OPTION)

  void validate() const;
};

struct ObservabilityResult {
  std::vector<std::uint8_t> observable;  ///< (N,) 1 where some pose sees the sample
  Points poses;                          ///< (P, 3) the reachable, collision-free positions
  std::int64_t lattice_points = 0;       ///< candidate positions before collision / reachability
  std::int64_t colliding = 0;            ///< within collision_radius of the mesh
  std::int64_t unreachable = 0;          ///< free but sealed in (not connected to the outside)
  std::vector<std::pair<std::string, double>> timings_s;
};

/// Observability of surface samples `points` (N, 3, on the mesh of `scene`) with unit normals
/// `normals` (N, 3; their sign does not matter) by `camera` (its mount, FOV and depth range; the
/// mount's pitch and roll matter, its yaw does not, the vehicle's yaw is free) carried by a
/// vehicle whose position stays in the box [nav_min, nav_max].
///
/// Poses: each axis of the box split evenly into the fewest steps of at most
/// options.pose_spacing, both faces included (a lattice about the box's centre left up to a
/// spacing unflown at each face: the air above a roof, the band under a wing); a point is kept
/// if the mesh is farther than collision_radius from it (an Embree point query) and the vehicle
/// can fly there from outside: it is connected (a flood fill) through lattice edges that the
/// mesh does not cross and along which the collision sphere fits (checked at points at most half
/// a radius apart) to a free position on the box's sides or top whose ray out of the box escapes
/// the mesh (with none, to any free position from which a ray along +-x, +-y or +z escapes; the
/// ground, below, is not part of the mesh). Positions sealed inside a closed structure, or
/// behind an opening narrower than the vehicle, are dropped; a camera outside may still see
/// through the opening.
/// The camera sits at position + mount translation (its horizontal part ignored: yaw is free).
/// With a gimbal (either bound nonzero), the camera turns by the pitch p that centres
/// the sample vertically, clamped to the range: T_body_camera = Ry(p) mount (as
/// gimbal_transform; the mount's translation is not turned).
///
/// A sample is observable from a pose if, for some yaw (the one centring it horizontally and
/// options.yaw_steps offsets on each side, across the frustum's half diagonal), it lies inside
/// the pinhole frustum with depth along the optical axis in [min_range, max_range], the line of
/// sight is within max_incidence_deg of the normal, and an Embree occlusion ray from the sample
/// to the camera hits nothing. Samples are visited in Morton order (0.25 m cells); the position
/// that saw the previous sample is tried first, then positions nearest first; the first success
/// decides.
/// The pixel grid is not simulated: any direction inside the frustum counts (at 640 x 480 the
/// pixel footprint at 8 m is 1.4 cm, under the finest 5 cm coverage cell).
ObservabilityResult observable_samples(const RaycastScene& scene, const PointsRef& points,
                                       const PointsRef& normals, const DepthCameraOptions& camera,
                                       const Eigen::Vector3d& nav_min,
                                       const Eigen::Vector3d& nav_max,
                                       const ObservabilityOptions& options = {});

/// True if some mesh triangle is within `radius` of `p` (Embree point query).
bool mesh_within(const RaycastScene& scene, const Eigen::Vector3d& p, double radius);

/// The distance from `p` to the mesh's nearest triangle where it is at most `max_distance` (may
/// be infinite), else infinity (an Embree point query whose radius shrinks to the nearest found).
double mesh_distance(const RaycastScene& scene, const Eigen::Vector3d& p, double max_distance);

}  // namespace nbv
