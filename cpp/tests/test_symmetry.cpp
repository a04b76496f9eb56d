// Edge cases of the symmetry core: bisector planes, sign canonicalisation, improper isometries,
// the FPFH mirror map, mean shift across sign flips, bad input.
#include "nbv/symmetry.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

using nbv::Planes;
using nbv::Points;

namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Matrix4d rigid(const Eigen::Vector3d& axis, double deg, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(deg * kPi / 180.0, axis.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t;
  return T;
}

}  // namespace

TEST(Symmetry, PlaneFromPairIsThePerpendicularBisector) {
  const Eigen::Vector3d p(1, 2, 3), q(1, -2, 3);
  const Eigen::Vector4d pl = nbv::plane_from_pair(p, q);
  EXPECT_NEAR(pl[0], 0, 1e-15);
  EXPECT_NEAR(pl[1], 1, 1e-15);
  EXPECT_NEAR(pl[2], 0, 1e-15);
  EXPECT_NEAR(pl[3], 0, 1e-15);
  // order-free, and the midpoint lies on the plane for an arbitrary pair
  const Eigen::Vector3d a(0.3, -7, 2.5), b(4, 1, -3);
  const Eigen::Vector4d ab = nbv::plane_from_pair(a, b), ba = nbv::plane_from_pair(b, a);
  EXPECT_TRUE(ab.isApprox(ba, 1e-12));
  EXPECT_NEAR(ab.head<3>().dot(0.5 * (a + b)), ab[3], 1e-12);
  EXPECT_NEAR(ab.head<3>().norm(), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(ab.head<3>().dot((a - b).normalized())), 1.0, 1e-12);
  EXPECT_THROW(nbv::plane_from_pair(a, a), std::invalid_argument);
}

TEST(Symmetry, CanonicalPlaneNormalisesAndFixesTheSign) {
  const Eigen::Vector4d p = nbv::canonical_plane(Eigen::Vector4d(0, -2, 0, -4));
  EXPECT_TRUE(p.isApprox(Eigen::Vector4d(0, 1, 0, 2)));
  // a plane and its negation canonicalise to the same plane
  const Eigen::Vector4d q(0.3, -0.8, 0.1, 2.0);
  EXPECT_TRUE(nbv::canonical_plane(q).isApprox(nbv::canonical_plane(-q), 1e-15));
  EXPECT_NEAR(nbv::canonical_plane(q).head<3>().norm(), 1.0, 1e-15);
  EXPECT_GT(nbv::canonical_plane(q)[1], 0.0);  // the largest |n_i| (y) is made positive
}

TEST(Symmetry, CanonicalPlaneLargestComponentIsPositiveAndNoNegativeZero) {
  const Eigen::Vector4d p = nbv::canonical_plane(Eigen::Vector4d(-0.0, -3.0, 0.0, 0.0));
  EXPECT_GT(p[1], 0);
  EXPECT_FALSE(std::signbit(p[0]));
  EXPECT_FALSE(std::signbit(p[3]));
  EXPECT_THROW(nbv::canonical_plane(Eigen::Vector4d(0, 0, 0, 1)), std::invalid_argument);
  EXPECT_THROW(nbv::canonical_plane(Eigen::Vector4d(std::nan(""), 1, 0, 0)), std::invalid_argument);
}

TEST(Symmetry, ReflectionIsAnInvolutionWithDeterminantMinusOne) {
  const Eigen::Vector4d pl = nbv::canonical_plane(Eigen::Vector4d(1, 2, -0.5, 3));
  const Eigen::Matrix4d M = nbv::reflection_matrix(pl);
  EXPECT_TRUE((M * M).isApprox(Eigen::Matrix4d::Identity(), 1e-12));
  EXPECT_NEAR((M.topLeftCorner<3, 3>().determinant()), -1.0, 1e-12);
  Points pts(3, 3);
  pts << 0, 0, 0, 10, -3, 2, -1, 7, 5;
  const Points r = nbv::reflect_points(pts, pl);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d mid = 0.5 * (pts.row(i) + r.row(i)).transpose();
    EXPECT_NEAR(pl.head<3>().dot(mid), pl[3], 1e-12);
  }
}

TEST(Symmetry, PlaneFromImproperIsometry) {
  const Eigen::Vector4d p1 = nbv::canonical_plane(Eigen::Vector4d(0.1, 1, 0.05, 0.4));
  const Eigen::Matrix4d S1 = nbv::reflection_matrix(p1);
  double residual = -1;
  EXPECT_TRUE(nbv::plane_from_improper_isometry(S1, &residual).isApprox(p1, 1e-12));
  EXPECT_NEAR(residual, 0.0, 1e-6);

  // What ICP returns: a small rigid correction T after the reflection. T o S1 is the
  // reflection about the corrected plane p2 when T = S2 o S1.
  const Eigen::Vector4d p2 = nbv::canonical_plane(Eigen::Vector4d(0, 1, 0, 0));
  const Eigen::Matrix4d T = nbv::reflection_matrix(p2) * S1;
  EXPECT_GT((T.topLeftCorner<3, 3>().determinant()), 0);  // proper
  EXPECT_TRUE(nbv::plane_from_improper_isometry(T * S1, &residual).isApprox(p2, 1e-12));
  EXPECT_NEAR(residual, 0.0, 1e-6);

  // A rotoreflection (rotation about the normal after the mirror) keeps the plane; a glide
  // (translation along the plane) keeps it too.
  const Eigen::Matrix4d R = rigid(p2.head<3>(), 5.0, Eigen::Vector3d(0.7, 0, -0.2));
  const Eigen::Vector4d p3 =
      nbv::plane_from_improper_isometry(R * nbv::reflection_matrix(p2), &residual);
  EXPECT_LT(nbv::plane_angle_deg(p3, p2), 1e-6);
  EXPECT_NEAR(p3[3], p2[3], 1e-12);
  EXPECT_NEAR(residual, 5.0, 1e-6);

  EXPECT_THROW(nbv::plane_from_improper_isometry(
                   rigid(Eigen::Vector3d::UnitZ(), 10, Eigen::Vector3d::Zero())),
               std::invalid_argument);
}

TEST(Symmetry, PlaneAngleAndOffsetAreSignAgnostic) {
  const Eigen::Vector4d a(0, 1, 0, 2), b(0, -1, 0, -2.5);
  EXPECT_NEAR(nbv::plane_angle_deg(a, b), 0.0, 1e-12);
  EXPECT_NEAR(nbv::plane_offset_at(a, b, Eigen::Vector3d(3, 0, 1)), 0.5, 1e-12);
  EXPECT_NEAR(nbv::plane_angle_deg(a, Eigen::Vector4d(1, 0, 0, 0)), 90.0, 1e-12);
}

TEST(Symmetry, MirrorFpfhReversesOnlyTheSecondSubHistogram) {
  nbv::Fpfh d(1, 33);
  for (int b = 0; b < 33; ++b) d(0, b) = float(b);
  const nbv::Fpfh m = nbv::mirror_fpfh(d);
  for (int b = 0; b < 11; ++b) {
    EXPECT_EQ(m(0, b), d(0, b));
    EXPECT_EQ(m(0, 11 + b), d(0, 21 - b));
    EXPECT_EQ(m(0, 22 + b), d(0, 22 + b));
  }
  EXPECT_TRUE(nbv::mirror_fpfh(m).isApprox(d));
}

TEST(Symmetry, MeanShiftMergesBothSignsOfAPlane) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 0.01);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Planes P(0, 4);
  auto push = [&](const Eigen::Vector4d& p) {
    P.conservativeResize(P.rows() + 1, 4);
    P.row(P.rows() - 1) = p.transpose();
  };
  // 40 votes for y = 1 (half stored with the opposite sign), 30 for x = -2, 50 outliers
  for (int i = 0; i < 40; ++i) {
    Eigen::Vector4d p(g(rng), 1 + g(rng), g(rng), 1 + 5 * g(rng));
    push(i % 2 ? Eigen::Vector4d(-p) : p);
  }
  for (int i = 0; i < 30; ++i) push(Eigen::Vector4d(1 + g(rng), g(rng), g(rng), -2 + 5 * g(rng)));
  for (int i = 0; i < 50; ++i) push(Eigen::Vector4d(u(rng), u(rng), u(rng), 20 * u(rng)));
  const nbv::PlaneClusters c = nbv::mean_shift_planes(P, Eigen::Vector3d::Zero(), 10.0, 0.08);
  EXPECT_LT(nbv::plane_angle_deg(c.plane, Eigen::Vector4d(0, 1, 0, 1)), 1.0);
  EXPECT_NEAR(c.plane[3], 1.0, 0.05);
  EXPECT_GE(c.support, 38);
  EXPECT_LE(c.support, 42);
  ASSERT_GE(c.modes.rows(), 2);
  EXPECT_LT(nbv::plane_angle_deg(c.modes.row(1).transpose(), Eigen::Vector4d(1, 0, 0, -2)), 1.0);
  EXPECT_EQ(c.inliers.count(), c.support);
}

TEST(Symmetry, MeanShiftEdgeCases) {
  const nbv::PlaneClusters empty =
      nbv::mean_shift_planes(Planes(0, 4), Eigen::Vector3d::Zero(), 1.0, 0.1);
  EXPECT_EQ(empty.support, 0);
  EXPECT_TRUE(empty.plane.array().isNaN().all());
  Planes bad(2, 4);
  bad << 0, 0, 0, 1, std::nan(""), 1, 0, 0;  // ignored rows
  EXPECT_EQ(nbv::mean_shift_planes(bad, Eigen::Vector3d::Zero(), 1.0, 0.1).support, 0);
  Planes one(1, 4);
  one << 0, 0, -2, 3;
  const nbv::PlaneClusters c = nbv::mean_shift_planes(one, Eigen::Vector3d::Zero(), 1.0, 0.1);
  EXPECT_EQ(c.support, 1);
  EXPECT_TRUE(c.plane.isApprox(Eigen::Vector4d(0, 0, 1, -1.5)));
  EXPECT_THROW(nbv::mean_shift_planes(one, Eigen::Vector3d::Zero(), 0.0, 0.1),
               std::invalid_argument);
  EXPECT_THROW(nbv::mean_shift_planes(one, Eigen::Vector3d::Zero(), 1.0, 1.5),
               std::invalid_argument);
}

TEST(Symmetry, BadInputThrows) {
  Points few(5, 3);
  few.setRandom();
  EXPECT_THROW(nbv::detect_symmetry(few), std::invalid_argument);
  Points nan = Points::Zero(50, 3);
  nan(3, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(nbv::detect_symmetry(nan), std::invalid_argument);
  EXPECT_THROW(nbv::predict_symmetric(nan, Eigen::Vector4d(0, 1, 0, 0)), std::invalid_argument);
  Points ok = Points::Random(50, 3);
  EXPECT_THROW(nbv::predict_symmetric(ok, Eigen::Vector4d(0, 0, 0, 1)), std::invalid_argument);
  nbv::SymmetryOptions o;
  o.bandwidth = 0;
  EXPECT_THROW(nbv::detect_symmetry(ok, o), std::invalid_argument);
  EXPECT_THROW(nbv::symmetry_keypoints_from_string("harris"), std::invalid_argument);
}

TEST(Symmetry, DetectsThePlaneOfASymmetricPointSet) {
  // A box body with two differently sized "wings", mirrored about x = 2, sampled on a grid.
  Points pts(0, 3);
  auto add_box = [&](Eigen::Vector3d lo, Eigen::Vector3d hi, double step) {
    for (double x = lo.x(); x <= hi.x() + 1e-9; x += step)
      for (double y = lo.y(); y <= hi.y() + 1e-9; y += step)
        for (double z = lo.z(); z <= hi.z() + 1e-9; z += step) {
          const bool surface = std::abs(x - lo.x()) < 1e-9 || std::abs(x - hi.x()) < 1e-9 ||
                               std::abs(y - lo.y()) < 1e-9 || std::abs(y - hi.y()) < 1e-9 ||
                               std::abs(z - lo.z()) < 1e-9 || std::abs(z - hi.z()) < 1e-9;
          if (!surface) continue;
          pts.conservativeResize(pts.rows() + 1, 3);
          pts.row(pts.rows() - 1) << x, y, z;
        }
  };
  add_box({0, -5, 0}, {4, 5, 3}, 0.2);       // body, centred on x = 2
  add_box({4, -1, 1}, {10, 1, 1.6}, 0.2);    // right wing
  add_box({-6, -1, 1}, {0, 1, 1.6}, 0.2);    // left wing (mirror)
  add_box({4, 2, 0}, {5.5, 3.5, 2}, 0.25);   // a pod
  add_box({-1.5, 2, 0}, {0, 3.5, 2}, 0.25);  // its mirror
  const nbv::SymmetryResult r = nbv::detect_symmetry(pts);
  EXPECT_TRUE(r.accepted) << r.reason;
  EXPECT_LT(nbv::plane_angle_deg(r.plane, Eigen::Vector4d(1, 0, 0, 2)), 1.0);
  EXPECT_NEAR(std::abs(r.plane[3]), 2.0, 0.05);
}

TEST(Symmetry, NeighbourhoodsSpanningTheCloudAreRefusedWithARadiusThatFits) {
  // a 30 x 30 x 30 lattice at 1 m: 27,000 points, 7.3e8 pairs within a radius spanning it
  Points P(27000, 3);
  for (int i = 0; i < 27000; ++i) P.row(i) << i % 30, (i / 30) % 30, i / 900;
  EXPECT_NO_THROW(nbv::detail::check_neighbourhoods(P, 0.5, "fpfh_radius"));  // itself alone
  EXPECT_NO_THROW(nbv::detail::check_neighbourhoods(P, 1.0, "fpfh_radius"));  // and 6 others
  std::string what;
  try {
    nbv::detail::check_neighbourhoods(P, 1e12, "fpfh_radius");
  } catch (const std::invalid_argument& e) {
    what = e.what();
  }
  ASSERT_NE(what.find("fpfh_radius = 1e+12 m"), std::string::npos) << what;
  ASSERT_NE(what.find("27000 of the 27000"), std::string::npos) << what;
  // the radius it offers holds: within the limit, and a tenth more is not
  const std::string tag = "use fpfh_radius about ";
  const std::size_t at = what.find(tag);
  ASSERT_NE(at, std::string::npos) << what;
  const double fits = std::stod(what.substr(at + tag.size()));
  EXPECT_GT(fits, 1.0);
  EXPECT_LT(fits, 30.0);
  EXPECT_NO_THROW(nbv::detail::check_neighbourhoods(P, fits, "fpfh_radius"));
  EXPECT_THROW(nbv::detail::check_neighbourhoods(P, fits * 1.1, "fpfh_radius"),
               std::invalid_argument);
  // through detect_symmetry, named by its option, before any descriptor
  nbv::SymmetryOptions o;
  o.voxel_size = 0.0;
  o.fpfh_radius = 1e3;
  EXPECT_THROW(
      {
        try {
          nbv::detect_symmetry(P, o);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("fpfh_radius"), std::string::npos);
          throw;
        }
      },
      std::invalid_argument);
}
