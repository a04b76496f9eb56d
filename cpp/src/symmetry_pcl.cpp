// The PCL stages of symmetry detection and prediction: normals, keypoints (SIFT / ISS /
// uniform), FPFH, nearest neighbours and ICP. Kept in its own translation unit: PCL's features,
// keypoints and registration headers take ~15 s and ~1 GB to compile.
//
// The kd-tree searches are compiled here, not taken from libpcl_kdtree: Debian builds FLANN's
// header-only search into that library with OpenMP, so every single-point query there opens an
// OpenMP parallel region (one thread, but futex calls: ~600,000 per detection + prediction on
// the airliner profile). Including the implementations instantiates the same FLANN tree and
// search code, without OpenMP, in this unit (the same trees, neighbours and order): detection +
// prediction 1.20 -> 0.63 s with identical results (bench/bench_symmetry.py --against).
#include "nbv/parallel.hpp"
#include "nbv/point_cloud.hpp"
#include "nbv/symmetry.hpp"

#include <pcl/common/transforms.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/keypoints/iss_3d.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/correspondence_estimation.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
#include <pcl/kdtree/impl/kdtree_flann.hpp>  // see the top of the file
#include <pcl/search/impl/kdtree.hpp>        // see the top of the file

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace nbv::detail {
namespace {

/// A float PCL cloud from (N, 3) points and/or normals (pass nullptr for what PointT lacks):
/// pcl::PointXYZ (points), pcl::Normal (normals) or pcl::PointNormal (both); curvature 0.
template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr to_pcl(const PointsRef* points, const Points* normals) {
  const Eigen::Index n = points ? points->rows() : normals->rows();
  auto c = pcl::make_shared<pcl::PointCloud<PointT>>();
  c->resize(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    auto& q = (*c)[static_cast<std::size_t>(i)];
    if constexpr (pcl::traits::has_xyz_v<PointT>) {
      q.x = float((*points)(i, 0));
      q.y = float((*points)(i, 1));
      q.z = float((*points)(i, 2));
    }
    if constexpr (pcl::traits::has_normal_v<PointT>) {
      q.normal_x = float((*normals)(i, 0));
      q.normal_y = float((*normals)(i, 1));
      q.normal_z = float((*normals)(i, 2));
      q.curvature = 0.f;
    }
  }
  c->width = static_cast<std::uint32_t>(c->size());
  c->height = 1;
  c->is_dense = true;
  return c;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const PointsRef& p) {
  return to_pcl<pcl::PointXYZ>(&p, nullptr);
}

int threads() { return std::max(1, get_num_threads()); }

/// PCL's nearest-point correspondence estimation (registration/impl/correspondence_estimation.hpp)
/// with the queries run in parallel: the same search tree, queries and distances as PCL's serial
/// loop, kept in source order, so ICP follows exactly the same iterations.
class ParallelCorrespondenceEstimation
    : public pcl::registration::CorrespondenceEstimation<pcl::PointNormal, pcl::PointNormal> {
 public:
  using Base = pcl::registration::CorrespondenceEstimation<pcl::PointNormal, pcl::PointNormal>;

  void determineCorrespondences(pcl::Correspondences& correspondences,
                                double max_distance) override {
    if (!initCompute()) return;
    const double max_dist_sqr = max_distance * max_distance;
    const auto& idx = *indices_;
    std::vector<pcl::Correspondence> all(idx.size());
    std::vector<char> valid(idx.size(), 0);
    parallel_chunks(idx.size(), 512, [&](std::size_t b, std::size_t e) {
      pcl::Indices index(1);
      std::vector<float> distance(1);
      for (std::size_t i = b; i < e; ++i) {
        tree_->nearestKSearch((*input_)[idx[i]], 1, index, distance);
        if (distance[0] > max_dist_sqr) continue;
        all[i] = pcl::Correspondence(idx[i], index[0], distance[0]);
        valid[i] = 1;
      }
    });
    correspondences.resize(idx.size());
    std::size_t n = 0;
    for (std::size_t i = 0; i < idx.size(); ++i)
      if (valid[i]) correspondences[n++] = all[i];
    correspondences.resize(n);
    deinitCompute();
  }

  pcl::registration::CorrespondenceEstimationBase<pcl::PointNormal, pcl::PointNormal>::Ptr clone()
      const override {
    return pcl::make_shared<ParallelCorrespondenceEstimation>(*this);
  }
};

/// pcl::Registration::getFitnessScore(max_range) with the queries run in parallel: the mean
/// squared distance from each transformed source point to its nearest target point, over those
/// whose squared distance is at most max_range (PCL compares the square with max_range), summed
/// in source order as PCL does, so the value is the same to the last bit.
double fitness_score(const pcl::PointCloud<pcl::PointNormal>& source, const Eigen::Matrix4f& T,
                     const pcl::search::KdTree<pcl::PointNormal>& tree, double max_range) {
  pcl::PointCloud<pcl::PointNormal> moved;
  pcl::transformPointCloud(source, moved, T);
  std::vector<float> d2(moved.size());
  parallel_chunks(moved.size(), 512, [&](std::size_t b, std::size_t e) {
    pcl::Indices index(1);
    std::vector<float> distance(1);
    for (std::size_t i = b; i < e; ++i) {
      tree.nearestKSearch(moved[i], 1, index, distance);
      d2[i] = distance[0];
    }
  });
  double sum = 0.0;
  int nr = 0;
  for (const float d : d2)
    if (d <= max_range) {
      sum += d;
      ++nr;
    }
  return nr > 0 ? sum / nr : std::numeric_limits<double>::max();
}

std::uint32_t float_bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}
float bits_float(std::uint32_t u) {
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

/// 3D SIFT keypoints with the curvature as intensity: pcl::SIFTKeypoint<PointNormal, ...>'s
/// algorithm (PCL 1.13, keypoints/impl/sift_keypoint.hpp) with its per-point loops run in
/// parallel. Every point's filter responses and extremum test are the same float operations on
/// the same sorted neighbour lists as PCL's serial loops, so the keypoints are identical; they
/// are returned per octave in PCL's order (point, then scale).
std::vector<Eigen::Vector3f> sift_keypoints(const pcl::PointCloud<pcl::PointNormal>::Ptr& input,
                                            float min_scale, int nr_octaves,
                                            int nr_scales_per_octave, float min_contrast) {
  std::vector<Eigen::Vector3f> out;
  pcl::PointCloud<pcl::PointNormal>::Ptr cloud(new pcl::PointCloud<pcl::PointNormal>(*input));
  pcl::VoxelGrid<pcl::PointNormal> voxel_grid;
  float scale = min_scale;
  for (int octave = 0; octave < nr_octaves; ++octave) {
    const float s = 1.0f * scale;
    voxel_grid.setLeafSize(s, s, s);
    voxel_grid.setInputCloud(cloud);
    pcl::PointCloud<pcl::PointNormal>::Ptr temp(new pcl::PointCloud<pcl::PointNormal>);
    voxel_grid.filter(*temp);
    cloud = temp;
    if (cloud->size() < 25) break;
    // PCL's SIFT searches sorted: FLANN sorts each radius search by (squared distance, index).
    // This one searches unsorted and sorts the same pairs packed into 64-bit keys (a
    // non-negative float's bits order as its value), the same order, about twice as fast.
    pcl::search::KdTree<pcl::PointNormal> tree(false);
    tree.setInputCloud(cloud);
    const auto& pts = *cloud;
    const std::size_t n = pts.size();

    // Scale space: difference of Gaussian-weighted curvature averages (computeScaleSpace).
    std::vector<float> scales(static_cast<std::size_t>(nr_scales_per_octave + 3));
    for (int i = 0; i <= nr_scales_per_octave + 2; ++i)
      scales[static_cast<std::size_t>(i)] =
          scale * powf(2.0f, (1.0f * static_cast<float>(i) - 1.0f) /
                                 static_cast<float>(nr_scales_per_octave));
    const std::size_t nr_dog = scales.size() - 1;
    Eigen::MatrixXf dog(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(nr_dog));
    const float max_radius = 3.0f * scales.back();
    parallel_chunks(n, 64, [&](std::size_t b, std::size_t e) {
      pcl::Indices nn;
      std::vector<float> d2;
      std::vector<std::uint64_t> keys;
      std::vector<float> dist, curv;
      for (std::size_t i = b; i < e; ++i) {
        tree.radiusSearch(static_cast<pcl::index_t>(i), max_radius, nn, d2);
        keys.resize(nn.size());
        for (std::size_t j = 0; j < nn.size(); ++j)
          keys[j] = (std::uint64_t(float_bits(d2[j])) << 32) | std::uint32_t(nn[j]);
        std::sort(keys.begin(), keys.end());
        dist.resize(keys.size());
        curv.resize(keys.size());
        for (std::size_t j = 0; j < keys.size(); ++j) {
          dist[j] = bits_float(std::uint32_t(keys[j] >> 32));
          curv[j] = pts[static_cast<std::size_t>(keys[j] & 0xffffffffu)].curvature;
        }
        float response = 0.0f;
        for (std::size_t k = 0; k < scales.size(); ++k) {
          const float sigma_sqr = powf(scales[k], 2.0f);
          float num = 0.0f, den = 0.0f;
          for (std::size_t j = 0; j < dist.size(); ++j) {
            const float value = curv[j];
            if (dist[j] <= 9 * sigma_sqr) {
              const float w = std::exp(-0.5f * dist[j] / sigma_sqr);
              num += value * w;
              den += w;
            } else {
              break;
            }
          }
          const float previous = response;
          response = num / den;
          if (k > 0)
            dog(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k - 1)) =
                response - previous;
        }
      }
    });

    // Extrema over the 25 nearest points and the adjacent scales (findScaleSpaceExtrema).
    const int nr = static_cast<int>(nr_dog);
    std::vector<std::vector<char>> is_extremum(n);
    parallel_chunks(n, 64, [&](std::size_t b, std::size_t e) {
      const int k = 25;
      pcl::Indices nn(k);
      std::vector<float> d2(k);
      std::vector<float> lo(static_cast<std::size_t>(nr)), hi(static_cast<std::size_t>(nr));
      for (std::size_t i = b; i < e; ++i) {
        // A point is among its own 25 nearest (a voxel-grid cloud has at most 8 coincident
        // points), so lo and hi bound its own responses: it can only be an extremum at a scale
        // where it has the contrast and is beyond both adjacent scales' responses. Most points
        // are not, and are not searched (the same keypoints, ~2x fewer searches).
        const auto ii = static_cast<Eigen::Index>(i);
        bool candidate = false;
        for (int sc = 1; sc < nr - 1 && !candidate; ++sc) {
          const float val = dog(ii, sc), below = dog(ii, sc - 1), above = dog(ii, sc + 1);
          candidate = std::abs(val) >= min_contrast && ((!(val >= below) && !(val >= above)) ||
                                                        (!(val <= below) && !(val <= above)));
        }
        if (!candidate) continue;
        const std::size_t m = tree.nearestKSearch(static_cast<pcl::index_t>(i), k, nn, d2);
        for (int sc = 0; sc < nr; ++sc) {
          lo[sc] = std::numeric_limits<float>::max();
          hi[sc] = -std::numeric_limits<float>::max();
          for (std::size_t j = 0; j < m; ++j) {
            const float d = dog(nn[j], sc);
            lo[sc] = (std::min)(lo[sc], d);
            hi[sc] = (std::max)(hi[sc], d);
          }
        }
        for (int sc = 1; sc < nr - 1; ++sc) {
          const float val = dog(static_cast<Eigen::Index>(i), sc);
          if (!(std::abs(val) >= min_contrast)) continue;
          const bool minimum = val == lo[sc] && val < lo[sc - 1] && val < lo[sc + 1];
          const bool maximum = val == hi[sc] && val > hi[sc - 1] && val > hi[sc + 1];
          if (minimum || maximum) is_extremum[i].push_back(char(1));
        }
      }
    });
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t r = 0; r < is_extremum[i].size(); ++r)
        out.emplace_back(pts[i].x, pts[i].y, pts[i].z);
    scale *= 2;
  }
  return out;
}

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

namespace {

/// PCL's normals of `points` oriented away from their centroid, as NormalsAndCurvature.
NormalsAndCurvature oriented(const PointsRef& points, const pcl::PointCloud<pcl::Normal>& normals) {
  NormalsAndCurvature out;
  const Eigen::Index n = points.rows();
  out.normals.setZero(n, 3);
  out.curvature.setZero(n);
  const Eigen::Vector3d c = points.colwise().mean().transpose();
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& q = normals[static_cast<std::size_t>(i)];
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

/// pcl::NormalEstimationOMP of `cloud` through `tree` (built on it): K nearest, or a radius.
template <typename PointT>
pcl::PointCloud<pcl::Normal> pcl_normals(const typename pcl::PointCloud<PointT>::Ptr& cloud,
                                         const typename pcl::search::KdTree<PointT>::Ptr& tree,
                                         int k, double radius) {
  pcl::NormalEstimationOMP<PointT, pcl::Normal> ne(static_cast<unsigned>(threads()));
  ne.setInputCloud(cloud);
  ne.setSearchMethod(tree);
  if (radius > 0)
    ne.setRadiusSearch(radius);
  else
    ne.setKSearch(std::min<int>(k, static_cast<int>(cloud->size())));
  pcl::PointCloud<pcl::Normal> normals;
  ne.compute(normals);
  return normals;
}

}  // namespace

NormalsAndCurvature estimate_normals(const PointsRef& points, int k, double radius) {
  if (points.rows() == 0) return oriented(points, {});
  auto cloud = to_pcl(points);
  auto tree = pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  tree->setInputCloud(cloud);
  return oriented(points, pcl_normals<pcl::PointXYZ>(cloud, tree, k, radius));
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
      auto pn = to_pcl<pcl::PointNormal>(&points, &nc.normals);
      for (Eigen::Index i = 0; i < n; ++i) (*pn)[i].curvature = float(nc.curvature[i]);
      where = sift_keypoints(pn, float(o.sift_min_scale), o.sift_octaves, o.sift_scales_per_octave,
                             float(o.sift_min_contrast));
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
      const Points cent = voxelgrid_sampling(points, o.uniform_leaf);
      for (Eigen::Index i = 0; i < cent.rows(); ++i)
        where.emplace_back(float(cent(i, 0)), float(cent(i, 1)), float(cent(i, 2)));
      break;
    }
  }
  return snap(tree, where);
}

Fpfh compute_fpfh(const PointsRef& points, const Points& normals, const std::vector<int>& indices,
                  double radius) {
  // pcl::FPFHEstimationOMP::computeFeature (PCL 1.13, features/impl/fpfh_omp.hpp) in TBB, with
  // PCL's own SPFH and weighting functions. An SPFH adds the same increment, 100 / (n - 1), to
  // its bins once per neighbour, so it does not depend on the neighbours' order, and neither does
  // the set of points that need one: those two steps search unsorted. The weighting sums floats
  // in the order of the neighbours, so it searches sorted, as PCL does. The descriptors are the
  // same to the last bit.
  Fpfh out(static_cast<Eigen::Index>(indices.size()), 33);
  if (indices.empty()) return out;
  auto cloud = to_pcl(points);
  auto nrm = to_pcl<pcl::Normal>(nullptr, &normals);
  pcl::search::KdTree<pcl::PointXYZ> tree(false);
  tree.setInputCloud(cloud);
  using Estimation = pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33>;

  // 1. The points whose SPFH is needed: every neighbour of a keypoint (ascending, unique).
  std::vector<int> need;
  {
    std::vector<char> mark(cloud->size(), 0);
    pcl::Indices nn;
    std::vector<float> d2;
    for (const int i : indices)
      if (tree.radiusSearch((*cloud)[static_cast<std::size_t>(i)], radius, nn, d2) > 0)
        for (const auto j : nn) mark[static_cast<std::size_t>(j)] = 1;
    for (std::size_t j = 0; j < mark.size(); ++j)
      if (mark[j]) need.push_back(static_cast<int>(j));
  }

  // 2. Their SPFH signatures (11 bins per feature, PCL's default), one row each.
  const auto m = static_cast<Eigen::Index>(need.size());
  Eigen::MatrixXf h1 = Eigen::MatrixXf::Zero(m, 11), h2 = Eigen::MatrixXf::Zero(m, 11),
                  h3 = Eigen::MatrixXf::Zero(m, 11);
  std::vector<int> row(cloud->size(), 0);
  parallel_chunks(need.size(), 32, [&](std::size_t b, std::size_t e) {
    Estimation local;
    pcl::Indices nn;
    std::vector<float> d2;
    for (std::size_t r = b; r < e; ++r) {
      const int p = need[r];
      row[static_cast<std::size_t>(p)] = static_cast<int>(r);
      if (tree.radiusSearch((*cloud)[static_cast<std::size_t>(p)], radius, nn, d2) == 0) continue;
      local.computePointSPFHSignature(*cloud, *nrm, p, static_cast<int>(r), nn, h1, h2, h3);
    }
  });

  // 3. Each keypoint's FPFH: its neighbours' SPFH weighted by 1 / squared distance.
  tree.setSortedResults(true);
  parallel_chunks(indices.size(), 8, [&](std::size_t b, std::size_t e) {
    Estimation local;
    pcl::Indices nn;
    std::vector<float> d2;
    Eigen::VectorXf hist;
    for (std::size_t k = b; k < e; ++k) {
      const auto ki = static_cast<Eigen::Index>(k);
      if (tree.radiusSearch((*cloud)[static_cast<std::size_t>(indices[k])], radius, nn, d2) == 0) {
        out.row(ki).setConstant(std::numeric_limits<float>::quiet_NaN());
        continue;
      }
      for (auto& j : nn) j = row[static_cast<std::size_t>(j)];
      local.weightPointSPFHSignature(h1, h2, h3, nn, d2, hist);
      for (int c = 0; c < 33; ++c) out(ki, c) = hist[c];
    }
  });
  return out;
}

struct IcpTarget::Impl {
  Points points;
  pcl::PointCloud<pcl::PointNormal>::Ptr cloud;
  pcl::search::KdTree<pcl::PointNormal>::Ptr tree;
};

IcpTarget::IcpTarget(const PointsRef& points) : impl_(std::make_unique<Impl>()) {
  impl_->points = points;
  const Points zero = Points::Zero(points.rows(), 3);
  impl_->cloud = to_pcl<pcl::PointNormal>(&points, &zero);
  impl_->tree = pcl::make_shared<pcl::search::KdTree<pcl::PointNormal>>();
  if (points.rows() > 0) impl_->tree->setInputCloud(impl_->cloud);
}

IcpTarget::~IcpTarget() = default;

NormalsAndCurvature IcpTarget::estimate_normals(int k) {
  const Points& p = impl_->points;
  if (p.rows() == 0) return oriented(p, {});
  NormalsAndCurvature nc =
      oriented(p, pcl_normals<pcl::PointNormal>(impl_->cloud, impl_->tree, k, 0.0));
  // The target's normals as align() uses them (as to_pcl writes them: float, curvature 0).
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    auto& q = (*impl_->cloud)[static_cast<std::size_t>(i)];
    q.normal_x = float(nc.normals(i, 0));
    q.normal_y = float(nc.normals(i, 1));
    q.normal_z = float(nc.normals(i, 2));
    q.curvature = 0.f;
  }
  return nc;
}

IcpResult IcpTarget::align(const PointsRef& source, const Points& source_normals,
                           const SymmetricPredictionOptions& o) {
  IcpResult r;
  auto src = to_pcl<pcl::PointNormal>(&source, &source_normals);
  const auto& tgt = impl_->cloud;
  const auto& tree = impl_->tree;
  pcl::PointCloud<pcl::PointNormal> aligned;
  auto run = [&](pcl::IterativeClosestPoint<pcl::PointNormal, pcl::PointNormal>& icp) {
    icp.setCorrespondenceEstimation(pcl::make_shared<ParallelCorrespondenceEstimation>());
    icp.setInputSource(src);
    icp.setInputTarget(tgt);
    icp.setSearchMethodTarget(tree, true);  // built on tgt, which keeps its points
    icp.setMaxCorrespondenceDistance(o.icp_max_correspondence);
    icp.setTransformationEpsilon(o.icp_transformation_epsilon);
    icp.setEuclideanFitnessEpsilon(o.icp_fitness_epsilon);
    icp.setMaximumIterations(o.icp_max_iterations);
    icp.align(aligned);
    r.converged = icp.hasConverged();
    r.transform = icp.getFinalTransformation().cast<double>();
    r.fitness = fitness_score(*src, icp.getFinalTransformation(), *tree, o.icp_max_correspondence);
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
