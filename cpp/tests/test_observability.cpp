// The observability kernel: point queries, the line of sight, the frustum under a free yaw,
// and positions sealed inside a closed hull.
#include "nbv/observability.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <memory>

using nbv::Mesh;
using nbv::Points;

namespace {

Mesh wall(double x) {  // the plane x = const, 2 m wide, from z = 1 to z = 3, facing -x and +x
  Points v(4, 3);
  v << x, -1, 1, x, 1, 1, x, 1, 3, x, -1, 3;
  nbv::Faces f(2, 3);
  f << 0, 1, 2, 0, 2, 3;
  return Mesh::from_arrays(v, f);
}

Mesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, bool inward = false) {
  Points v(8, 3);
  for (int i = 0; i < 8; ++i)
    v.row(i) << (i & 1 ? hi.x() : lo.x()), (i & 2 ? hi.y() : lo.y()), (i & 4 ? hi.z() : lo.z());
  nbv::Faces f(12, 3);
  f << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1,
      3, 5, 3, 7, 5;
  if (inward) f.col(0).swap(f.col(1));
  return Mesh::from_arrays(v, f);
}

Mesh merge(const Mesh& a, const Mesh& b) {
  Points v(a.vertices.rows() + b.vertices.rows(), 3);
  v << a.vertices, b.vertices;
  nbv::Faces f(a.faces.rows() + b.faces.rows(), 3);
  f << a.faces, (b.faces.array() + static_cast<int>(a.vertices.rows())).matrix();
  return Mesh::from_arrays(v, f);
}

Points row(double x, double y, double z) {
  Points p(1, 3);
  p << x, y, z;
  return p;
}

}  // namespace

TEST(Observability, PointQueryFindsTrianglesWithinTheRadius) {
  const nbv::RaycastScene scene(wall(0.0));
  EXPECT_TRUE(nbv::mesh_within(scene, {0.5, 0, 2}, 0.6));
  EXPECT_FALSE(nbv::mesh_within(scene, {0.7, 0, 2}, 0.6));
  EXPECT_TRUE(nbv::mesh_within(scene, {0.0, 1.3, 3.3}, 0.5));  // near the corner (1, 3)
  EXPECT_FALSE(nbv::mesh_within(scene, {0.0, 1.4, 3.4}, 0.5));
}

TEST(Observability, PointQueryMeasuresTheDistanceToTheNearestTriangle) {
  // a wall at x = 0 (y in [-1, 1], z in [1, 3]) and a box [4, 5]^3: each point's nearest
  // triangle by hand, none beyond max_distance
  const nbv::RaycastScene scene(
      merge(wall(0.0), box(Eigen::Vector3d(4, 4, 4), Eigen::Vector3d(5, 5, 5))));
  constexpr double inf = std::numeric_limits<double>::infinity();
  EXPECT_NEAR(nbv::mesh_distance(scene, {0.5, 0, 2}, inf), 0.5, 1e-12);      // the wall's face
  EXPECT_NEAR(nbv::mesh_distance(scene, {0.0, 4, 3}, inf), 3.0, 1e-12);      // its edge y = 1
  EXPECT_NEAR(nbv::mesh_distance(scene, {-3, -5, 1}, inf), 5.0, 1e-12);      // its corner
  EXPECT_NEAR(nbv::mesh_distance(scene, {4.5, 4.5, 4.6}, inf), 0.4, 1e-12);  // inside the box
  EXPECT_NEAR(nbv::mesh_distance(scene, {3.5, 4.5, 4.5}, inf), 0.5, 1e-12);  // beside it
  EXPECT_NEAR(nbv::mesh_distance(scene, {3.5, 4.5, 4.5}, 0.5), 0.5, 1e-12);  // at the limit
  EXPECT_EQ(nbv::mesh_distance(scene, {3.5, 4.5, 4.5}, 0.49), inf);          // beyond it
  EXPECT_EQ(nbv::mesh_distance(scene, {0.5, 0, 2}, 0.0), inf);
}

TEST(Observability, AWallIsSeenFromBothSidesAndFrustumLimitsApply) {
  const nbv::RaycastScene scene(wall(0.0));
  nbv::DepthCameraOptions cam;  // horizontal, 60 x 45 deg, 0.5 - 8 m
  nbv::ObservabilityOptions o;
  o.pose_spacing = 0.5;
  o.collision_radius = 0.3;
  const Points normal = row(1, 0, 0);
  // in a box beside the wall at the sample's height: seen
  auto r = nbv::observable_samples(scene, row(0, 0, 2), normal, cam, {1, -1, 2}, {3, 1, 2}, o);
  EXPECT_EQ(r.observable[0], 1);
  r = nbv::observable_samples(scene, row(0, 0, 2), normal, cam, {-3, -1, 2}, {-1, 1, 2}, o);
  EXPECT_EQ(r.observable[0], 1);
  // only positions 10 m above the sample: outside a horizontal camera's 22.5 deg half FOV...
  r = nbv::observable_samples(scene, row(0, 0, 2), normal, cam, {1, -1, 12}, {4, 1, 12}, o);
  EXPECT_EQ(r.observable[0], 0);
  // ...but inside once the camera is pitched 60 deg down (mount)
  cam.mount = nbv::mount_transform(Eigen::Vector3d::Zero(), 0, 60, 0);
  r = nbv::observable_samples(scene, row(0, 0, 2), normal, cam, {1, -1, 8}, {4, 1, 8}, o);
  EXPECT_EQ(r.observable[0], 1);
  // beyond the far range
  cam = nbv::DepthCameraOptions{};
  r = nbv::observable_samples(scene, row(0, 0, 2), normal, cam, {12, -1, 2}, {14, 1, 2}, o);
  EXPECT_EQ(r.observable[0], 0);
}

TEST(Observability, PositionsSealedInsideAHullAreUnreachable) {
  // a hollow box: 0.2 m walls around a 4 x 4 x 4 m hall
  const Mesh hull = merge(box({-2.2, -2.2, -2.2}, {2.2, 2.2, 2.2}),
                          box({-2, -2, -2}, {2, 2, 2}, /*inward=*/true));
  const nbv::RaycastScene scene(hull);
  nbv::ObservabilityOptions o;
  o.pose_spacing = 0.5;
  o.collision_radius = 0.3;
  Points p(2, 3), n(2, 3);
  p << -2, 0, 0, -2.2, 0, 0;  // on the inner wall, on the outer wall
  n << 1, 0, 0, -1, 0, 0;
  const auto r = nbv::observable_samples(scene, p, n, {}, {-6, -6, -6}, {6, 6, 6}, o);
  EXPECT_GT(r.unreachable, 0);
  EXPECT_EQ(r.observable[0], 0);
  EXPECT_EQ(r.observable[1], 1);
  for (Eigen::Index i = 0; i < r.poses.rows(); ++i)
    EXPECT_FALSE(r.poses.row(i).cwiseAbs().maxCoeff() < 2.0) << r.poses.row(i);
}

TEST(Observability, RejectsBadInput) {
  const nbv::RaycastScene scene(wall(0.0));
  nbv::ObservabilityOptions o;
  o.pose_spacing = -1;
  EXPECT_THROW(
      nbv::observable_samples(scene, row(0, 0, 2), row(1, 0, 0), {}, {1, 1, 1}, {2, 2, 2}, o),
      std::invalid_argument);
  Points two(2, 3);
  two.setZero();
  EXPECT_THROW(nbv::observable_samples(scene, row(0, 0, 2), two, {}, {1, 1, 1}, {2, 2, 2}),
               std::invalid_argument);
}
