// The PCL stages of symmetry (cpp/src/symmetry_pcl.cpp) against PCL's own classes, which they
// replace or feed differently for speed: the same numbers to the last bit are required, since
// the paper's scenarios must choose the same views as before.
#include "nbv/symmetry.hpp"

#include <gtest/gtest.h>
#include <pcl/features/fpfh_omp.h>
#include <pcl/features/normal_3d.h>
#include <pcl/keypoints/sift_keypoint.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
#include <pcl/keypoints/impl/sift_keypoint.hpp>  // not instantiated for PointNormal in libpcl

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using nbv::Points;

namespace {

/// ~3,000 points on the surface of a box with a cylinder on top, some on an exact 0.1 m lattice
/// (equal distances: FLANN's order among them must be kept), centred near the origin.
Points structure() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < 1800; ++i) {  // box 4 x 2 x 1.5, random points on its faces
    const int face = i % 6;
    const double a = u(rng), b = u(rng);
    Eigen::Vector3d q;
    if (face < 2)
      q = {face ? 2.0 : -2.0, -1.0 + 2 * a, -0.75 + 1.5 * b};
    else if (face < 4)
      q = {-2.0 + 4 * a, face == 3 ? 1.0 : -1.0, -0.75 + 1.5 * b};
    else
      q = {-2.0 + 4 * a, -1.0 + 2 * b, face == 5 ? 0.75 : -0.75};
    p.push_back(q);
  }
  for (int i = 0; i < 900; ++i) {  // cylinder r 0.6, height 1 on the top face
    const double t = 2 * 3.14159265358979 * u(rng), h = u(rng);
    p.emplace_back(0.8 + 0.6 * std::cos(t), 0.6 * std::sin(t), 0.75 + h);
  }
  for (int i = 0; i < 20; ++i)  // a lattice patch on the -y face
    for (int j = 0; j < 12; ++j) p.emplace_back(-1.9 + 0.1 * i, -1.0, -0.6 + 0.1 * j);
  Points out(static_cast<Eigen::Index>(p.size()), 3);
  for (std::size_t i = 0; i < p.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = p[i];
  return out;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr xyz(const Points& p) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    c->push_back(pcl::PointXYZ(float(p(i, 0)), float(p(i, 1)), float(p(i, 2))));
  return c;
}

pcl::PointCloud<pcl::PointNormal>::Ptr with_normals(const Points& p, const Points& n) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    pcl::PointNormal q;
    q.x = float(p(i, 0));
    q.y = float(p(i, 1));
    q.z = float(p(i, 2));
    q.normal_x = float(n(i, 0));
    q.normal_y = float(n(i, 1));
    q.normal_z = float(n(i, 2));
    q.curvature = 0.f;
    c->push_back(q);
  }
  return c;
}

/// PCL's NormalEstimation (serial) with K nearest, oriented away from the centroid as
/// detail::estimate_normals documents.
nbv::detail::NormalsAndCurvature reference_normals(const Points& p, int k) {
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  ne.setInputCloud(xyz(p));
  ne.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  ne.setKSearch(k);
  pcl::PointCloud<pcl::Normal> n;
  ne.compute(n);
  nbv::detail::NormalsAndCurvature out;
  out.normals.setZero(p.rows(), 3);
  out.curvature.setZero(p.rows());
  const Eigen::Vector3d c = p.colwise().mean().transpose();
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    Eigen::Vector3d v(n[i].normal_x, n[i].normal_y, n[i].normal_z);
    if (!v.allFinite() || v.norm() < 1e-6) continue;
    v.normalize();
    if (v.dot(p.row(i).transpose() - c) < 0) v = -v;
    out.normals.row(i) = v.transpose();
    out.curvature[i] = std::isfinite(n[i].curvature) ? n[i].curvature : 0.0;
  }
  return out;
}

}  // namespace

TEST(SymmetryPcl, NormalsAreThoseOfPclsNormalEstimation) {
  const Points p = structure();
  const auto ref = reference_normals(p, 30);
  const auto got = nbv::detail::estimate_normals(p, 30, 0.0);
  EXPECT_TRUE(got.normals == ref.normals);
  EXPECT_TRUE(got.curvature == ref.curvature);
  // The ICP target estimates the same normals through its own tree.
  nbv::detail::IcpTarget target(p);
  const auto t = target.estimate_normals(30);
  EXPECT_TRUE(t.normals == ref.normals);
  EXPECT_TRUE(t.curvature == ref.curvature);
}

TEST(SymmetryPcl, FpfhIsThatOfPclsFpfhEstimation) {
  const Points p = structure();
  const auto nc = nbv::detail::estimate_normals(p, 30, 0.0);
  std::vector<int> idx;
  for (int i = 0; i < p.rows(); i += 37) idx.push_back(i);
  const double radius = 0.5;

  pcl::FPFHEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh(2);
  fpfh.setInputCloud(xyz(p));
  auto normals = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    normals->push_back(
        pcl::Normal(float(nc.normals(i, 0)), float(nc.normals(i, 1)), float(nc.normals(i, 2))));
  fpfh.setInputNormals(normals);
  fpfh.setIndices(pcl::make_shared<pcl::Indices>(idx.begin(), idx.end()));
  fpfh.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  fpfh.setRadiusSearch(radius);
  pcl::PointCloud<pcl::FPFHSignature33> ref;
  fpfh.compute(ref);

  const nbv::Fpfh got = nbv::detail::compute_fpfh(p, nc.normals, idx, radius);
  ASSERT_EQ(got.rows(), static_cast<Eigen::Index>(ref.size()));
  int differing = 0;
  for (std::size_t k = 0; k < ref.size(); ++k)
    for (int b = 0; b < 33; ++b)
      differing += !(got(static_cast<Eigen::Index>(k), b) == ref[k].histogram[b]);
  EXPECT_EQ(differing, 0);
}

TEST(SymmetryPcl, SiftKeypointsAreThoseOfPclsSiftKeypoint) {
  const Points p = structure();
  const auto nc = nbv::detail::estimate_normals(p, 30, 0.0);
  nbv::SymmetryOptions o;
  o.keypoints = nbv::SymmetryKeypoints::Sift;
  o.sift_min_scale = 0.1;
  const std::vector<int> got = nbv::detail::detect_keypoints(p, nc, o);

  auto cloud = with_normals(p, nc.normals);
  for (Eigen::Index i = 0; i < p.rows(); ++i) (*cloud)[i].curvature = float(nc.curvature[i]);
  pcl::SIFTKeypoint<pcl::PointNormal, pcl::PointWithScale> sift;
  sift.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointNormal>>());
  sift.setScales(float(o.sift_min_scale), o.sift_octaves, o.sift_scales_per_octave);
  sift.setMinimumContrast(float(o.sift_min_contrast));
  sift.setInputCloud(cloud);
  pcl::PointCloud<pcl::PointWithScale> kp;
  sift.compute(kp);
  // detect_keypoints snaps each keypoint to its nearest cloud point (unique, ascending).
  pcl::search::KdTree<pcl::PointXYZ> tree;
  tree.setInputCloud(xyz(p));
  std::vector<int> ref;
  pcl::Indices nn(1);
  std::vector<float> d2(1);
  for (const auto& q : kp) {
    tree.nearestKSearch(pcl::PointXYZ(q.x, q.y, q.z), 1, nn, d2);
    ref.push_back(nn[0]);
  }
  std::sort(ref.begin(), ref.end());
  ref.erase(std::unique(ref.begin(), ref.end()), ref.end());
  EXPECT_GT(ref.size(), 10u);
  EXPECT_EQ(got, ref);
}

TEST(SymmetryPcl, IcpIsPclsIcpWithNormals) {
  const Points p = structure();
  nbv::detail::IcpTarget target(p);
  const auto nc = target.estimate_normals(30);
  // The source: the target moved by a small rigid motion.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.03, Eigen::Vector3d(0.2, 0.3, 1).normalized()).toRotationMatrix();
  const Points src = ((p * R.transpose()).rowwise() + Eigen::RowVector3d(0.05, -0.04, 0.02));
  const Points src_n = nc.normals * R.transpose();
  nbv::SymmetricPredictionOptions o;
  const auto got = target.align(src, src_n, o);

  pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> icp;
  auto s = with_normals(src, src_n), t = with_normals(p, nc.normals);
  icp.setInputSource(s);
  icp.setInputTarget(t);
  icp.setMaxCorrespondenceDistance(o.icp_max_correspondence);
  icp.setTransformationEpsilon(o.icp_transformation_epsilon);
  icp.setEuclideanFitnessEpsilon(o.icp_fitness_epsilon);
  icp.setMaximumIterations(o.icp_max_iterations);
  pcl::PointCloud<pcl::PointNormal> aligned;
  icp.align(aligned);
  EXPECT_TRUE(icp.hasConverged());
  EXPECT_EQ(got.converged, icp.hasConverged());
  EXPECT_TRUE(got.transform == icp.getFinalTransformation().cast<double>());
  EXPECT_EQ(got.fitness, icp.getFitnessScore(o.icp_max_correspondence));
  // And it undoes the motion.
  EXPECT_LT((got.transform.topLeftCorner<3, 3>() * R - Eigen::Matrix3d::Identity()).norm(), 1e-3);
}
