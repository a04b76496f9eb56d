// The PCL stages of symmetry detection and prediction: normals, keypoints (SIFT / ISS /
// uniform), FPFH, nearest neighbours and ICP. Kept in its own translation unit: PCL's features,
// keypoints and registration headers take ~15 s and ~1 GB to compile.
#include "nbv/parallel.hpp"
#include "nbv/symmetry.hpp"

#include <pcl/features/fpfh_omp.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/keypoints/iss_3d.h>
#include <pcl/keypoints/sift_keypoint.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace nbv::detail {
namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const PointsRef& p) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  c->resize(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    (*c)[i] = pcl::PointXYZ(float(p(i, 0)), float(p(i, 1)), float(p(i, 2)));
  c->width = static_cast<std::uint32_t>(c->size());
  c->height = 1;
  c->is_dense = true;
  return c;
}

pcl::PointCloud<pcl::Normal>::Ptr normals_to_pcl(const Points& n) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
  c->resize(static_cast<std::size_t>(n.rows()));
  for (Eigen::Index i = 0; i < n.rows(); ++i) {
    auto& q = (*c)[i];
    q.normal_x = float(n(i, 0));
    q.normal_y = float(n(i, 1));
    q.normal_z = float(n(i, 2));
    q.curvature = 0.f;
  }
  c->width = static_cast<std::uint32_t>(c->size());
  c->height = 1;
  return c;
}

pcl::PointCloud<pcl::PointNormal>::Ptr point_normals_to_pcl(const PointsRef& p, const Points& n) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  c->resize(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    auto& q = (*c)[i];
    q.x = float(p(i, 0));
    q.y = float(p(i, 1));
    q.z = float(p(i, 2));
    q.normal_x = float(n(i, 0));
    q.normal_y = float(n(i, 1));
    q.normal_z = float(n(i, 2));
    q.curvature = 0.f;
  }
  c->width = static_cast<std::uint32_t>(c->size());
  c->height = 1;
  return c;
}

int threads() { return std::max(1, get_num_threads()); }

/// Index of the nearest point of `tree` to each query position (unique, ascending).
std::vector<int> snap(const pcl::KdTreeFLANN<pcl::PointXYZ>& tree,
                      const std::vector<Eigen::Vector3f>& queries) {
  std::vector<int> out;
  out.reserve(queries.size());
  pcl::Indices idx(1);
  std::vector<float> d2(1);
  for (const auto& q : queries) {
    if (!q.allFinite()) continue;
    if (tree.nearestKSearch(pcl::PointXYZ(q.x(), q.y(), q.z()), 1, idx, d2) == 1)
      out.push_back(idx[0]);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace

NormalsAndCurvature estimate_normals(const PointsRef& points, int k, double radius) {
  NormalsAndCurvature out;
  const Eigen::Index n = points.rows();
  out.normals.setZero(n, 3);
  out.curvature.setZero(n);
  if (n == 0) return out;
  auto cloud = to_pcl(points);
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(static_cast<unsigned>(threads()));
  ne.setInputCloud(cloud);
  auto tree = pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  ne.setSearchMethod(tree);
  if (radius > 0)
    ne.setRadiusSearch(radius);
  else
    ne.setKSearch(std::min<int>(k, static_cast<int>(n)));
  pcl::PointCloud<pcl::Normal> normals;
  ne.compute(normals);
  const Eigen::Vector3d c = points.colwise().mean().transpose();
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& q = normals[i];
    Eigen::Vector3d v(q.normal_x, q.normal_y, q.normal_z);
    if (!v.allFinite() || v.norm() < 1e-6) continue;  // left zero: FPFH skips zero normals
    v.normalize();
    // Away from the centroid: equivariant under any reflection whose plane holds the centroid.
    if (v.dot(points.row(i).transpose() - c) < 0) v = -v;
    out.normals.row(i) = v.transpose();
    out.curvature[i] = std::isfinite(q.curvature) ? q.curvature : 0.0;
  }
  return out;
}

std::vector<int> detect_keypoints(const PointsRef& points, const NormalsAndCurvature& nc,
                                  const SymmetryOptions& o) {
  const Eigen::Index n = points.rows();
  if (n == 0) return {};
  auto cloud = to_pcl(points);
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  std::vector<Eigen::Vector3f> where;

  switch (o.keypoints) {
    case SymmetryKeypoints::Sift: {
      auto pn = point_normals_to_pcl(points, nc.normals);
      for (Eigen::Index i = 0; i < n; ++i) (*pn)[i].curvature = float(nc.curvature[i]);
      // SIFTKeypointFieldSelector<PointNormal> reads the curvature as the intensity.
      pcl::SIFTKeypoint<pcl::PointNormal, pcl::PointWithScale> sift;
      sift.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointNormal>>());
      sift.setScales(float(o.sift_min_scale), o.sift_octaves, o.sift_scales_per_octave);
      sift.setMinimumContrast(float(o.sift_min_contrast));
      sift.setInputCloud(pn);
      pcl::PointCloud<pcl::PointWithScale> kp;
      sift.compute(kp);
      for (const auto& q : kp) where.emplace_back(q.x, q.y, q.z);
      break;
    }
    case SymmetryKeypoints::Iss: {
      pcl::ISSKeypoint3D<pcl::PointXYZ, pcl::PointXYZ> iss;
      iss.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
      iss.setSalientRadius(o.iss_salient_radius);
      iss.setNonMaxRadius(o.iss_non_max_radius);
      iss.setThreshold21(0.975);
      iss.setThreshold32(0.975);
      iss.setMinNeighbors(5);
      iss.setNumberOfThreads(static_cast<unsigned>(threads()));
      iss.setInputCloud(cloud);
      pcl::PointCloud<pcl::PointXYZ> kp;
      iss.compute(kp);
      for (const auto& q : kp) where.emplace_back(q.x, q.y, q.z);
      break;
    }
    case SymmetryKeypoints::Uniform: {
      // One keypoint per cell: the point nearest the cell's centroid (cells in first-seen order).
      const Points cent = voxel_downsample(points, o.uniform_leaf);
      for (Eigen::Index i = 0; i < cent.rows(); ++i)
        where.emplace_back(float(cent(i, 0)), float(cent(i, 1)), float(cent(i, 2)));
      break;
    }
  }
  return snap(tree, where);
}

Fpfh compute_fpfh(const PointsRef& points, const Points& normals, const std::vector<int>& indices,
                  double radius) {
  Fpfh out(static_cast<Eigen::Index>(indices.size()), 33);
  if (indices.empty()) return out;
  auto cloud = to_pcl(points);
  auto nrm = normals_to_pcl(normals);
  pcl::FPFHEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh(
      static_cast<unsigned>(threads()));
  fpfh.setInputCloud(cloud);
  fpfh.setInputNormals(nrm);
  fpfh.setIndices(pcl::make_shared<pcl::Indices>(indices.begin(), indices.end()));
  fpfh.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  fpfh.setRadiusSearch(radius);
  pcl::PointCloud<pcl::FPFHSignature33> desc;
  fpfh.compute(desc);
  if (desc.size() != indices.size())
    throw std::runtime_error("FPFH returned " + std::to_string(desc.size()) + " descriptors for " +
                             std::to_string(indices.size()) + " keypoints");
  for (std::size_t i = 0; i < desc.size(); ++i)
    for (int b = 0; b < 33; ++b) out(static_cast<Eigen::Index>(i), b) = desc[i].histogram[b];
  return out;
}

struct NearestNeighbors::Impl {
  Points targets;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
};

NearestNeighbors::NearestNeighbors(const PointsRef& targets) : impl_(std::make_unique<Impl>()) {
  impl_->targets = targets;
  if (targets.rows() > 0) impl_->tree.setInputCloud(to_pcl(targets));
}

NearestNeighbors::~NearestNeighbors() = default;

const Points& NearestNeighbors::targets() const { return impl_->targets; }

std::pair<Eigen::VectorXi, Eigen::VectorXd> NearestNeighbors::query(
    const PointsRef& queries) const {
  std::pair<Eigen::VectorXi, Eigen::VectorXd> out{
      Eigen::VectorXi::Constant(queries.rows(), -1),
      Eigen::VectorXd::Constant(queries.rows(), std::numeric_limits<double>::infinity())};
  if (impl_->targets.rows() == 0 || queries.rows() == 0) return out;
  const auto& tree = impl_->tree;
  const auto& targets = impl_->targets;
  parallel_chunks(static_cast<std::size_t>(queries.rows()), 256, [&](std::size_t b, std::size_t e) {
    pcl::Indices idx(1);
    std::vector<float> d2(1);
    for (std::size_t i = b; i < e; ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      const auto q = queries.row(k);
      if (tree.nearestKSearch(pcl::PointXYZ(float(q[0]), float(q[1]), float(q[2])), 1, idx, d2) ==
          1) {
        out.first[k] = idx[0];
        out.second[k] = (targets.row(idx[0]) - q).norm();  // exact, in double precision
      }
    }
  });
  return out;
}

Eigen::VectorXd nearest_distances(const PointsRef& targets, const PointsRef& queries) {
  return NearestNeighbors(targets).query(queries).second;
}

IcpResult icp(const PointsRef& source, const Points& source_normals, const PointsRef& target,
              const Points& target_normals, const SymmetricPredictionOptions& o) {
  IcpResult r;
  auto src = point_normals_to_pcl(source, source_normals);
  auto tgt = point_normals_to_pcl(target, target_normals);
  pcl::PointCloud<pcl::PointNormal> aligned;
  auto run = [&](pcl::IterativeClosestPoint<pcl::PointNormal, pcl::PointNormal>& icp) {
    icp.setInputSource(src);
    icp.setInputTarget(tgt);
    icp.setMaxCorrespondenceDistance(o.icp_max_correspondence);
    icp.setTransformationEpsilon(o.icp_transformation_epsilon);
    icp.setEuclideanFitnessEpsilon(o.icp_fitness_epsilon);
    icp.setMaximumIterations(o.icp_max_iterations);
    icp.align(aligned);
    r.converged = icp.hasConverged();
    r.transform = icp.getFinalTransformation().cast<double>();
    r.fitness = icp.getFitnessScore(o.icp_max_correspondence);
  };
  if (o.icp_point_to_plane) {
    pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> icp;
    run(icp);
  } else {
    pcl::IterativeClosestPoint<pcl::PointNormal, pcl::PointNormal> icp;
    run(icp);
  }
  return r;
}

}  // namespace nbv::detail
