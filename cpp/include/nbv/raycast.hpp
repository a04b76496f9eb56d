// Embree ray casting over a triangle mesh.
#pragma once

#include "nbv/common.hpp"
#include "nbv/mesh.hpp"
#include "nbv/options.hpp"

#include <embree3/rtcore.h>

#include <memory>

namespace nbv {

#define NBV_RAYCAST_OPTIONS(X)     \
  X(bool, high_quality_bvh, false, \
    "build a high-quality BVH (slower build, ~1.3x faster traversal; worth it for long missions)")

struct RaycastOptions {
  NBV_RAYCAST_OPTIONS(NBV_DECLARE_OPTION)

  void validate() const {}
};
/// An Embree scene over one mesh. Thread-safe for concurrent queries after construction.
/// Hit distances are refined in double precision against the hit triangle, so a hit point
/// `o + t d` lies on the triangle to ~1e-9 m even far from the origin. Embree holds float32
/// coordinates relative to origin(): zero for a mesh within kLocalExtent of the world's origin,
/// else its bounding box's centre (at UTM coordinates float32 is 0.5 m apart, and hits there
/// fell on the planes of triangles the rays passed beside: up to 6.8 cm off the surface; at
/// 30 km, 2 mm apart, a scan's depths moved by up to 1.2 mm against the same scan at the origin).
class RaycastScene {
 public:
  explicit RaycastScene(const Mesh& mesh, const RaycastOptions& options = {});
  ~RaycastScene();
  RaycastScene(const RaycastScene&) = delete;
  RaycastScene& operator=(const RaycastScene&) = delete;

  const Mesh& mesh() const { return mesh_; }
  /// The Embree scene, in coordinates relative to origin(): subtract it from every point given.
  RTCScene handle() const { return scene_; }
  const Eigen::Vector3d& origin() const { return origin_; }

  /// m: a mesh whose coordinates all lie within this of the world's origin is given to Embree
  /// as it is (float32 rounds them by at most 0.06 mm), one reaching farther relative to its
  /// centre.
  static constexpr double kLocalExtent = 1024.0;

  /// The largest magnitude of a ray direction's component that intersect takes.
  static constexpr double kMaxDirection = 1e18;

  /// Casts rays o_i + t d_i, t in [t_near, t_far] (d_i need not be unit; t is then in units of
  /// |d_i|... use unit directions to get metres). Writes t (inf where nothing is hit) and the hit
  /// triangle (-1 where nothing is hit). `origins` is (1, 3) for a shared origin or (N, 3).
  /// Throws std::invalid_argument for non-finite rays, an origin beyond kMaxCoordinate or a
  /// direction's component beyond kMaxDirection.
  void intersect(const PointsRef& origins, const PointsRef& directions, double t_near, double t_far,
                 Eigen::VectorXd& t, Eigen::VectorXi& prim) const;

  /// Casts rays from one origin `o` along R * d_i (d_i unit directions in a sensor frame, rows of
  /// `dirs_sensor`) in packets of 16 with Embree's coherent flag; ray i is valid for
  /// t in [0, t_far[i]]. Consecutive rows should be spatially coherent (e.g. 4x4 pixel tiles).
  /// Writes t (double-refined, inf where nothing is hit).
  void intersect_coherent(const Eigen::Vector3d& o, const Eigen::Matrix3d& R,
                          const Points& dirs_sensor, const Eigen::VectorXd& t_far,
                          Eigen::VectorXd& t, bool parallel = true) const;

  /// Exact (double precision) distance along o + t d to the plane of triangle `prim`.
  double refine(const Eigen::Vector3d& o, const Eigen::Vector3d& d, int prim, double t_float) const;

 private:
  Mesh mesh_;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace nbv
