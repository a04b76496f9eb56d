// Symmetry detection and prediction: geometry, matching, mean shift and the pipelines. The PCL
// stages are in symmetry_pcl.cpp.
#include "nbv/symmetry.hpp"

#include "nbv/parallel.hpp"
#include "nbv/point_cloud.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <stdexcept>

namespace nbv {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr Eigen::Index kMinPoints = 10;

class Stopwatch {
 public:
  explicit Stopwatch(StageTimes& out) : out_(out), t_(clock::now()) {}
  void lap(const char* name) {
    const auto now = clock::now();
    out_.emplace_back(name, std::chrono::duration<double>(now - t_).count());
    t_ = now;
  }

 private:
  using clock = std::chrono::steady_clock;
  StageTimes& out_;
  clock::time_point t_;
};

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

Points centred(const PointsRef& p, const Eigen::Vector3d& c) {
  Points out = p;
  out.rowwise() -= c.transpose();
  return out;
}

/// The centroid of `points`, rounded to a multiple of `voxel` (if > 0).
Eigen::Vector3d grid_anchor(const PointsRef& points, double voxel) {
  const Eigen::Vector3d c = points.colwise().mean().transpose();
  return voxel > 0 ? Eigen::Vector3d((c / voxel).array().round() * voxel) : c;
}

/// The plane shifted from world to a frame whose origin is at c (and back with -c).
Eigen::Vector4d shift_plane(const Eigen::Vector4d& pl, const Eigen::Vector3d& c) {
  return {pl[0], pl[1], pl[2], pl[3] - pl.head<3>().dot(c)};
}

Points reflect_normals(const Points& n, const Eigen::Vector3d& m) {
  Points out = n;
  const Eigen::VectorXd s = n * m;
  out -= 2.0 * s * m.transpose();
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------- options

SymmetryKeypoints symmetry_keypoints_from_string(const std::string& name) {
  if (name == "sift") return SymmetryKeypoints::Sift;
  if (name == "iss") return SymmetryKeypoints::Iss;
  if (name == "uniform") return SymmetryKeypoints::Uniform;
  throw std::invalid_argument("keypoints must be 'sift', 'iss' or 'uniform', got '" + name + "'");
}

std::string to_string(SymmetryKeypoints k) {
  switch (k) {
    case SymmetryKeypoints::Sift:
      return "sift";
    case SymmetryKeypoints::Iss:
      return "iss";
    case SymmetryKeypoints::Uniform:
      return "uniform";
  }
  return "?";
}

void SymmetryOptions::validate() const {
  auto fin = [](double v) { return std::isfinite(v); };
  require(fin(voxel_size) && voxel_size >= 0, "voxel_size must be >= 0 metres (0 disables)");
  require(normal_k >= 3, "normal_k must be >= 3");
  require(fin(normal_radius) && normal_radius >= 0,
          "normal_radius must be >= 0 metres (0: use normal_k)");
  require(fin(sift_min_scale) && sift_min_scale > 0, "sift_min_scale must be > 0 metres");
  require(sift_octaves >= 1, "sift_octaves must be >= 1");
  require(sift_scales_per_octave >= 1, "sift_scales_per_octave must be >= 1");
  require(fin(sift_min_contrast) && sift_min_contrast >= 0, "sift_min_contrast must be >= 0");
  require(fin(iss_salient_radius) && iss_salient_radius > 0,
          "iss_salient_radius must be > 0 metres");
  require(fin(iss_non_max_radius) && iss_non_max_radius > 0,
          "iss_non_max_radius must be > 0 metres");
  require(fin(uniform_leaf) && uniform_leaf > 0, "uniform_leaf must be > 0 metres");
  require(fin(fpfh_radius) && fpfh_radius > 0, "fpfh_radius must be > 0 metres");
  require(!std::isnan(max_descriptor_distance) && max_descriptor_distance > 0,
          "max_descriptor_distance must be > 0 (inf: no limit)");
  require(fin(min_pair_distance) && min_pair_distance >= 0,
          "min_pair_distance must be >= 0 metres");
  require(fin(max_normal_angle_deg) && max_normal_angle_deg > 0 && max_normal_angle_deg <= 180,
          "max_normal_angle_deg must be in (0, 180]");
  require(matches_per_keypoint >= 1, "matches_per_keypoint must be >= 1");
  require(fin(bandwidth) && bandwidth > 0 && bandwidth < 1, "bandwidth must be in (0, 1)");
  require(mean_shift_seeds >= 1, "mean_shift_seeds must be >= 1");
  require(mean_shift_max_iterations >= 1, "mean_shift_max_iterations must be >= 1");
  require(candidate_modes >= 1, "candidate_modes must be >= 1");
  require(refine_iterations >= 0, "refine_iterations must be >= 0");
  require(refine_max_points >= 100, "refine_max_points must be >= 100");
  require(fin(refine_max_distance) && refine_max_distance > 0,
          "refine_max_distance must be > 0 metres");
  require(fin(consistency_radius) && consistency_radius > 0,
          "consistency_radius must be > 0 metres");
  require(fin(consistency_tolerance) && consistency_tolerance > 0,
          "consistency_tolerance must be > 0 metres");
  require(fin(facing_angle_deg) && facing_angle_deg > 0 && facing_angle_deg <= 90,
          "facing_angle_deg must be in (0, 90]");
  require(min_support >= 1, "min_support must be >= 1");
  require(fin(min_confidence) && min_confidence >= 0 && min_confidence <= 1,
          "min_confidence must be in [0, 1]");
}

void SymmetricPredictionOptions::validate() const {
  auto fin = [](double v) { return std::isfinite(v); };
  require(fin(icp_voxel_size) && icp_voxel_size >= 0,
          "icp_voxel_size must be >= 0 metres (0 disables)");
  require(icp_normal_k >= 3, "icp_normal_k must be >= 3");
  require(fin(icp_max_correspondence) && icp_max_correspondence > 0,
          "icp_max_correspondence must be > 0 metres");
  require(fin(icp_transformation_epsilon) && icp_transformation_epsilon >= 0,
          "icp_transformation_epsilon must be >= 0");
  require(fin(icp_fitness_epsilon) && icp_fitness_epsilon >= 0, "icp_fitness_epsilon must be >= 0");
  require(icp_max_iterations >= 1, "icp_max_iterations must be >= 1");
  require(fin(max_correction_angle_deg) && max_correction_angle_deg >= 0,
          "max_correction_angle_deg must be >= 0");
  require(fin(max_correction_offset) && max_correction_offset >= 0,
          "max_correction_offset must be >= 0 metres");
  require(fin(explained_tolerance) && explained_tolerance >= 0,
          "explained_tolerance must be >= 0 metres");
}

// ---------------------------------------------------------------------------- geometry

Eigen::Vector4d canonical_plane(const Eigen::Vector4d& plane) {
  require(plane.allFinite(), "plane must be finite");
  const double len = plane.head<3>().norm();
  require(len > 1e-12, "plane normal must not be zero");
  Eigen::Vector4d p = plane / len;
  Eigen::Index k = 0;
  p.head<3>().cwiseAbs().maxCoeff(&k);
  if (p[k] < 0) p = -p;
  return p + Eigen::Vector4d::Zero();  // -0.0 -> 0.0
}

Eigen::Vector4d plane_from_pair(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  const Eigen::Vector3d diff = p - q;
  const double len = diff.norm();
  require(std::isfinite(len) && len > 0, "a plane needs two distinct finite points");
  const Eigen::Vector3d n = diff / len;
  Eigen::Vector4d pl;
  pl << n, n.dot(0.5 * (p + q));
  return canonical_plane(pl);
}

Eigen::Matrix4d reflection_matrix(const Eigen::Vector4d& plane) {
  const Eigen::Vector4d pl = canonical_plane(plane);
  const Eigen::Vector3d n = pl.head<3>();
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() -= 2.0 * n * n.transpose();
  M.topRightCorner<3, 1>() = 2.0 * pl[3] * n;
  return M;
}

Points reflect_points(const PointsRef& points, const Eigen::Vector4d& plane) {
  const Eigen::Vector4d pl = canonical_plane(plane);
  const Eigen::Vector3d n = pl.head<3>();
  Points out = points;
  const Eigen::VectorXd s = (points * n).array() - pl[3];
  out -= 2.0 * s * n.transpose();
  return out;
}

Eigen::Vector4d plane_from_improper_isometry(const Eigen::Matrix4d& M,
                                             double* residual_rotation_deg) {
  require(M.allFinite(), "transform must be finite");
  const Eigen::Matrix3d A = M.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = M.topRightCorner<3, 1>();
  require(A.determinant() < 0, "transform is not improper (det > 0): it has no mirror plane");
  const Eigen::Matrix3d S = 0.5 * (A + A.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(S);
  const Eigen::Vector3d n = es.eigenvectors().col(0).normalized();  // eigenvalues ascending
  Eigen::Vector4d pl;
  pl << n, 0.5 * n.dot(t);
  if (residual_rotation_deg) {
    // A = R_n(phi) * (I - 2 n n^T): the rotation left, R = A * reflection, has angle phi.
    const Eigen::Matrix3d R = A * (Eigen::Matrix3d::Identity() - 2.0 * n * n.transpose());
    const double c = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
    *residual_rotation_deg = std::acos(c) * 180.0 / kPi;
  }
  return canonical_plane(pl);
}

double plane_angle_deg(const Eigen::Vector4d& a, const Eigen::Vector4d& b) {
  const double c = std::abs(a.head<3>().normalized().dot(b.head<3>().normalized()));
  return std::acos(std::min(1.0, c)) * 180.0 / kPi;
}

double plane_offset_at(const Eigen::Vector4d& a, const Eigen::Vector4d& b,
                       const Eigen::Vector3d& c) {
  const Eigen::Vector4d pa = canonical_plane(a), pb = canonical_plane(b);
  // c's projection on a, then its distance to b.
  const Eigen::Vector3d on_a = c - (pa.head<3>().dot(c) - pa[3]) * pa.head<3>();
  return std::abs(pb.head<3>().dot(on_a) - pb[3]);
}

Fpfh mirror_fpfh(const Fpfh& d) {
  Fpfh out = d;
  // f2 = v . n_t changes sign under a reflection: reverse its 11 bins (columns 11..21).
  for (int b = 0; b < 11; ++b) out.col(11 + b) = d.col(21 - b);
  return out;
}

namespace detail {

void check_neighbourhoods(const PointsRef& points, double radius, const std::string& key) {
  const std::size_t n = std::size_t(points.rows());
  if (n == 0) return;
  const std::size_t samples = std::min<std::size_t>(n, 64);
  const double r2 = radius * radius;
  // the histogram's top: r2, or the squared diagonal of the cloud's box where that is less
  const double top = std::min(
      r2, (points.colwise().maxCoeff() - points.colwise().minCoeff()).squaredNorm() * 1.0001);
  // Each sample's points within the radius (exact, the sample itself included), counted without
  // storing distances (n may be millions); where too many, again into a histogram of log2 of
  // the squared distance below `top` (bins of 1/16 of a power of two, down to 2^-40 of it).
  constexpr int kBins = 640;
  const auto count = [&](bool histogram) {
    std::vector<std::vector<double>> part(samples);
    parallel_chunks(samples, 1, [&](std::size_t b, std::size_t e) {
      for (std::size_t s = b; s < e; ++s) {
        const Eigen::Vector3d q = points.row(Eigen::Index(s * n / samples)).transpose();
        std::vector<double>& h = part[s];
        h.assign(histogram ? kBins + 1 : 1, 0.0);
        for (std::size_t i = 0; i < n; ++i) {
          const double d2 = (points.row(Eigen::Index(i)).transpose() - q).squaredNorm();
          if (!(d2 <= r2)) continue;
          if (!histogram) {
            h[0] += 1;
            continue;
          }
          const double x = d2 > 0 ? (std::log2(d2 / top) + 40.0) * 16.0 : 0.0;
          h[std::size_t(std::clamp(x, 0.0, double(kBins)))] += 1;
        }
      }
    });
    std::vector<double> total(part[0].size(), 0.0);
    for (const auto& h : part)
      for (std::size_t i = 0; i < h.size(); ++i) total[i] += h[i];
    return total;
  };
  const double scale = double(n) / double(samples);  // a sample's count stands for n / samples
  const double pairs = count(false)[0] * scale;
  if (pairs <= kMaxNeighbourPairs) return;
  // the largest radius within the limit: the upper edge of the last bin the pairs stay within
  const std::vector<double> hist = count(true);
  double sum = 0.0, fits = 0.0;
  for (int i = 0; i <= kBins; ++i) {
    sum += hist[std::size_t(i)] * scale;
    if (sum > kMaxNeighbourPairs) break;
    fits = std::min(radius, std::sqrt(top) * std::exp2(0.5 * (double(i + 1) / 16.0 - 40.0)));
  }
  const std::string advice =
      fits > 0 ? "about " + fmt(fits) + " m or less" : "smaller, or a coarser voxel_size";
  throw std::invalid_argument(
      "symmetry: " + key + " = " + fmt(radius) + " m puts about " +
      std::to_string(std::llround(pairs / double(n))) + " of the " + std::to_string(n) +
      " points searched in each neighbourhood (" + fmt(pairs) + " neighbours in all, at most " +
      fmt(kMaxNeighbourPairs) + "): a search that wide is quadratic in the cloud; use " + key +
      " " + advice);
}

Eigen::Vector4d refine_plane(const PointsRef& points, const KdTree& tree, const Points& normals,
                             const Eigen::Vector4d& plane, int iterations, double max_distance,
                             double min_distance) {
  Eigen::Vector4d pl = canonical_plane(plane);
  for (int it = 0; it < iterations; ++it) {
    const double r = std::max(min_distance, max_distance * std::pow(0.7, it));
    const Eigen::Vector3d n = pl.head<3>();
    // Two unit directions orthogonal to n: the normal's 2 degrees of freedom.
    const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
    const Points R = reflect_points(points, pl);
    const auto [idx, dist] = tree.nearest_each(R);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    int used = 0;
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      if (!(dist[i] <= r) || idx[i] < 0) continue;
      const Eigen::Vector3d m = normals.row(idx[i]).transpose();
      if (m.squaredNorm() == 0) continue;
      const Eigen::Vector3d p = points.row(i).transpose();
      const double s = n.dot(p) - pl[3];
      // residual: distance of the reflection S(p) = p - 2 s n to the partner's tangent plane
      const double res = m.dot(R.row(i).transpose() - tree.point(idx[i]));
      // dS/dn along e: -2 ((e.p) n + s e); dS/dd: 2 n
      const double mn = m.dot(n);
      const Eigen::Vector3d J(-2.0 * (e1.dot(p) * mn + s * m.dot(e1)),
                              -2.0 * (e2.dot(p) * mn + s * m.dot(e2)), 2.0 * mn);
      // Huber weight at a quarter of the radius: stripes of other surfaces should not pull.
      const double k = 0.25 * r, w = std::abs(res) <= k ? 1.0 : k / std::abs(res);
      H += w * J * J.transpose();
      g += w * J * res;
      ++used;
    }
    if (used < 10) break;
    H.diagonal().array() += 1e-9 * std::max(1.0, H.trace());
    Eigen::Vector3d x = -H.ldlt().solve(g);
    if (!x.allFinite()) break;
    // Bounded steps: at most ~3 degrees and the radius per iteration.
    const double rot = x.head<2>().norm();
    if (rot > 0.05) x.head<2>() *= 0.05 / rot;
    x[2] = std::clamp(x[2], -r, r);
    Eigen::Vector4d next;
    next << (n + x[0] * e1 + x[1] * e2).normalized(), pl[3] + x[2];
    pl = next;
    if (x.norm() < 1e-9) break;
  }
  return canonical_plane(pl);
}

Consistency mirror_consistency(const PointsRef& points, const Points& normals, const KdTree& tree,
                               const Points& target_normals, const Eigen::Vector4d& plane,
                               double radius, double tolerance, double facing_angle_deg) {
  Consistency out;
  const Eigen::Vector4d pl = canonical_plane(plane);
  const Eigen::Vector3d n = pl.head<3>();
  // 90 degrees counts every point, including those without a normal.
  const double cos_facing =
      facing_angle_deg >= 90.0 ? -1.0 : std::cos(facing_angle_deg * kPi / 180.0);
  std::vector<Eigen::Index> far;
  far.reserve(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    if (2.0 * std::abs(points.row(i).dot(n) - pl[3]) > radius) far.push_back(i);
  if (far.empty()) return out;
  Points F(static_cast<Eigen::Index>(far.size()), 3);
  for (std::size_t k = 0; k < far.size(); ++k)
    F.row(static_cast<Eigen::Index>(k)) = points.row(far[k]);
  const Points R = reflect_points(F, pl);
  const auto [idx, dist] = tree.nearest_each(R);
  Eigen::Index ok = 0, ok_facing = 0, facing = 0;
  for (std::size_t k = 0; k < far.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    const bool faces = std::abs(normals.row(far[k]).dot(n)) >= cos_facing;
    facing += faces;
    if (!(dist[i] <= radius) || idx[i] < 0) continue;
    const Eigen::Vector3d m = target_normals.row(idx[i]).transpose();
    const Eigen::Vector3d delta = R.row(i).transpose() - tree.point(idx[i]);
    // Without a normal at the partner: point-to-point.
    const double e = m.squaredNorm() > 0 ? std::abs(m.dot(delta)) : delta.norm();
    if (e <= tolerance) {
      ++ok;
      ok_facing += faces;
    }
  }
  out.all = double(ok) / double(far.size());
  out.facing_fraction = double(facing) / double(far.size());
  out.facing = facing > 0 ? double(ok_facing) / double(facing) : 0.0;
  return out;
}

}  // namespace detail

// ---------------------------------------------------------------------------- mean shift

PlaneClusters mean_shift_planes(const Planes& planes, const Eigen::Vector3d& center, double scale,
                                double bandwidth, int seeds, int max_iterations) {
  require(center.allFinite(), "mean shift center must be finite");
  require(std::isfinite(scale) && scale > 0, "mean shift scale must be > 0 metres");
  require(std::isfinite(bandwidth) && bandwidth > 0 && bandwidth < 1,
          "bandwidth must be in (0, 1)");
  require(seeds >= 1 && max_iterations >= 1, "seeds and max_iterations must be >= 1");
  PlaneClusters out;
  const Eigen::Index P = planes.rows();
  out.inliers.setConstant(P, false);
  out.mode_support.resize(0);

  // Votes x = (n, (d - n.c) / scale), unit n; a plane's negation is -x.
  std::vector<Eigen::Vector4d> x;
  std::vector<Eigen::Index> row;
  for (Eigen::Index i = 0; i < P; ++i) {
    const Eigen::Vector4d p = planes.row(i).transpose();
    const double len = p.head<3>().norm();
    if (!p.allFinite() || !(len > 1e-12)) continue;
    const Eigen::Vector3d n = p.head<3>() / len;
    Eigen::Vector4d v;
    v << n, (p[3] / len - n.dot(center)) / scale;
    x.push_back(v);
    row.push_back(i);
  }
  const std::size_t V = x.size();
  if (V == 0) return out;
  const double h2 = bandwidth * bandwidth;
  // Squared distance between a vote and a point, with the vote's nearer sign.
  auto dist2 = [](const Eigen::Vector4d& v, const Eigen::Vector4d& q) {
    return std::min((v - q).squaredNorm(), (v + q).squaredNorm());
  };

  // Vote density (neighbours within the bandwidth) -> seeds.
  std::vector<int> density(V, 0);
  parallel_chunks(V, 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      int c = 0;
      for (std::size_t j = 0; j < V; ++j) c += dist2(x[j], x[i]) <= h2;
      density[i] = c;
    }
  });
  std::vector<std::size_t> order(V);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return density[a] > density[b]; });
  std::vector<std::size_t> seed_ids;
  for (std::size_t i : order) {
    if (static_cast<int>(seed_ids.size()) >= seeds) break;
    bool far = true;
    for (std::size_t s : seed_ids) far = far && dist2(x[s], x[i]) > h2;
    if (far) seed_ids.push_back(i);
  }

  // Flat-kernel mean shift from every seed (each vote takes the sign nearer the estimate).
  struct Mode {
    Eigen::Vector4d x;
    int support;
  };
  std::vector<Mode> modes(seed_ids.size());
  parallel_chunks(seed_ids.size(), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t s = b; s < e; ++s) {
      Eigen::Vector4d q = x[seed_ids[s]];
      for (int it = 0; it < max_iterations; ++it) {
        Eigen::Vector4d sum = Eigen::Vector4d::Zero();
        int c = 0;
        for (const auto& v : x) {
          const double dp = (v - q).squaredNorm(), dm = (v + q).squaredNorm();
          if (dp <= h2) {
            sum += v;
            ++c;
          } else if (dm <= h2) {
            sum -= v;
            ++c;
          }
        }
        if (c == 0) break;
        const Eigen::Vector4d next = sum / c;
        const double shift = (next - q).norm();
        q = next;
        if (shift < 1e-9) break;
      }
      // Back to a unit normal.
      const double len = q.head<3>().norm();
      if (len > 1e-12) {
        q.head<3>() /= len;
      }
      int support = 0;
      for (const auto& v : x) support += dist2(v, q) <= h2;
      modes[s] = {q, support};
    }
  });
  std::stable_sort(modes.begin(), modes.end(),
                   [](const Mode& a, const Mode& b) { return a.support > b.support; });
  std::vector<Mode> distinct;
  for (const auto& m : modes) {
    bool dup = false;
    for (const auto& d : distinct) dup = dup || dist2(d.x, m.x) <= 0.25 * h2;
    if (!dup) distinct.push_back(m);
  }

  auto to_plane = [&](const Eigen::Vector4d& q) {
    Eigen::Vector4d pl;
    pl << q.head<3>(), q[3] * scale + q.head<3>().dot(center);
    return canonical_plane(pl);
  };
  out.modes.resize(static_cast<Eigen::Index>(distinct.size()), 4);
  out.mode_support.resize(static_cast<Eigen::Index>(distinct.size()));
  for (std::size_t i = 0; i < distinct.size(); ++i) {
    out.modes.row(static_cast<Eigen::Index>(i)) = to_plane(distinct[i].x).transpose();
    out.mode_support[static_cast<Eigen::Index>(i)] = distinct[i].support;
  }
  const Eigen::Vector4d best = distinct.front().x;
  out.plane = to_plane(best);
  out.support = distinct.front().support;
  for (std::size_t k = 0; k < V; ++k) out.inliers[row[k]] = dist2(x[k], best) <= h2;
  return out;
}

Eigen::Matrix<bool, Eigen::Dynamic, 1> plane_votes(const Planes& planes,
                                                   const Eigen::Vector4d& mode,
                                                   const Eigen::Vector3d& center, double scale,
                                                   double bandwidth) {
  Eigen::Matrix<bool, Eigen::Dynamic, 1> out =
      Eigen::Matrix<bool, Eigen::Dynamic, 1>::Constant(planes.rows(), false);
  auto vote = [&](const Eigen::Vector4d& p, Eigen::Vector4d& v) {
    const double len = p.head<3>().norm();
    if (!p.allFinite() || !(len > 1e-12)) return false;
    const Eigen::Vector3d n = p.head<3>() / len;
    v << n, (p[3] / len - n.dot(center)) / scale;
    return true;
  };
  Eigen::Vector4d q, v;
  if (!vote(mode, q)) return out;
  const double h2 = bandwidth * bandwidth;
  for (Eigen::Index i = 0; i < planes.rows(); ++i)
    if (vote(planes.row(i).transpose(), v))
      out[i] = std::min((v - q).squaredNorm(), (v + q).squaredNorm()) <= h2;
  return out;
}

// ---------------------------------------------------------------------------- detection

namespace {

/// Step 1 of detect_symmetry: the points shifted near the origin (PCL is float) by a whole
/// number of voxels, so that the downsampling grid stays anchored at the world origin (a cloud
/// already voxelised there is kept as it is), and downsampled.
struct PreparedCloud {
  Eigen::Vector3d c0;  ///< the shift: world = local + c0
  Points P;            ///< (N, 3) downsampled points, local frame
  Eigen::Vector3d c;   ///< centroid of P
  double scale = 0;    ///< RMS distance of P from c, metres
};

PreparedCloud prepare_cloud(const PointsRef& points, double voxel_size) {
  PreparedCloud out;
  out.c0 = grid_anchor(points, voxel_size);
  out.P = voxel_size > 0 ? voxelgrid_sampling(centred(points, out.c0), voxel_size)
                         : centred(points, out.c0);
  out.c = out.P.colwise().mean().transpose();
  out.scale = std::sqrt((out.P.rowwise() - out.c.transpose()).rowwise().squaredNorm().mean());
  return out;
}

/// Step 4: each keypoint's most similar (mirrored) other keypoints whose normals are mirror
/// images about the pair's bisector; fills res.pairs, pair_distances and pair_planes (unordered
/// pairs, smallest descriptor distance, in key order).
void match_keypoints(const Points& keypoints, const Points& normals, const Fpfh& F,
                     const SymmetryOptions& o, SymmetryResult& res) {
  const Eigen::Index K = keypoints.rows();
  std::vector<char> valid(static_cast<std::size_t>(K));
  for (Eigen::Index i = 0; i < K; ++i)
    valid[i] = F.row(i).allFinite() && F.row(i).squaredNorm() > 0;
  const Fpfh Fm = o.mirror_descriptors ? mirror_fpfh(F) : F;
  const double cos_normal = std::cos(o.max_normal_angle_deg * kPi / 180.0);
  const double min_d2 = o.min_pair_distance * o.min_pair_distance;
  const int m = o.matches_per_keypoint;
  std::vector<std::vector<std::pair<float, int>>> best(static_cast<std::size_t>(K));
  parallel_chunks(static_cast<std::size_t>(K), 16, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      auto& top = best[i];
      if (!valid[i]) continue;
      const Eigen::Vector3d pi = keypoints.row(static_cast<Eigen::Index>(i)).transpose();
      const Eigen::Vector3d ni = normals.row(static_cast<Eigen::Index>(i)).transpose();
      for (Eigen::Index j = 0; j < K; ++j) {
        if (j == static_cast<Eigen::Index>(i) || !valid[j]) continue;
        const Eigen::Vector3d diff = pi - keypoints.row(j).transpose();
        const double L2 = diff.squaredNorm();
        if (L2 < min_d2 || L2 == 0) continue;
        const Eigen::Vector3d u = diff / std::sqrt(L2);
        const Eigen::Vector3d r = ni - 2.0 * u.dot(ni) * u;  // n_i mirrored about the bisector
        if (std::abs(r.dot(normals.row(j))) < cos_normal) continue;
        const float dd = (F.row(static_cast<Eigen::Index>(i)) - Fm.row(j)).norm();
        if (dd > o.max_descriptor_distance) continue;
        if (static_cast<int>(top.size()) < m) {
          top.emplace_back(dd, int(j));
          std::push_heap(top.begin(), top.end());
        } else if (dd < top.front().first) {
          std::pop_heap(top.begin(), top.end());
          top.back() = {dd, int(j)};
          std::push_heap(top.begin(), top.end());
        }
      }
    }
  });
  std::map<std::pair<int, int>, float> unique;  // unordered pairs, smallest distance
  for (Eigen::Index i = 0; i < K; ++i)
    for (const auto& [dd, j] : best[static_cast<std::size_t>(i)]) {
      const std::pair<int, int> key(std::min(int(i), j), std::max(int(i), j));
      auto it = unique.find(key);
      if (it == unique.end() || dd < it->second) unique[key] = dd;
    }
  const Eigen::Index NP = static_cast<Eigen::Index>(unique.size());
  res.pairs.resize(NP, 2);
  res.pair_distances.resize(NP);
  res.pair_planes.resize(NP, 4);
  Eigen::Index r = 0;
  for (const auto& [key, dd] : unique) {
    res.pairs(r, 0) = key.first;
    res.pairs(r, 1) = key.second;
    res.pair_distances[r] = dd;
    res.pair_planes.row(r) =
        plane_from_pair(keypoints.row(key.first).transpose(), keypoints.row(key.second).transpose())
            .transpose();
    ++r;
  }
}

/// Step 6: the candidate modes refined and scored on an evenly strided subset of the points; the
/// most mirror-consistent wins and is refined and scored again on every point. Fills res.plane,
/// confidence, consistency_all, facing_fraction, mode_confidence, inliers, support, vote_share.
void choose_plane(const PreparedCloud& pc, const Points& normals, const PlaneClusters& cl,
                  const SymmetryOptions& o, SymmetryResult& res) {
  const Points& P = pc.P;
  const KdTree tree(P);
  const Eigen::Index stride =
      std::max<Eigen::Index>(1, (P.rows() + o.refine_max_points - 1) / o.refine_max_points);
  const Eigen::Index ns = (P.rows() + stride - 1) / stride;
  Points S(ns, 3), SN(ns, 3);
  for (Eigen::Index i = 0; i < ns; ++i) {
    S.row(i) = P.row(i * stride);
    SN.row(i) = normals.row(i * stride);
  }
  Eigen::Index chosen = 0;
  Eigen::Vector4d best_plane = cl.plane;
  double best_conf = -1;
  for (Eigen::Index k = 0; k < cl.modes.rows() && k < o.candidate_modes; ++k) {
    if (k > 0 && cl.mode_support[k] < o.min_support) break;
    Eigen::Vector4d pl = cl.modes.row(k).transpose();
    if (o.refine_iterations > 0)
      pl = detail::refine_plane(S, tree, normals, pl, o.refine_iterations, o.refine_max_distance,
                                o.consistency_radius);
    const double conf = detail::mirror_consistency(S, SN, tree, normals, pl, o.consistency_radius,
                                                   o.consistency_tolerance, o.facing_angle_deg)
                            .facing;
    res.mode_confidence[k] = conf;
    if (conf > best_conf) {
      best_conf = conf;
      best_plane = pl;
      chosen = k;
    }
  }
  if (o.refine_iterations > 0 && stride > 1)
    best_plane = detail::refine_plane(P, tree, normals, best_plane, 3, o.consistency_radius,
                                      o.consistency_radius);
  const auto cons =
      detail::mirror_consistency(P, normals, tree, normals, best_plane, o.consistency_radius,
                                 o.consistency_tolerance, o.facing_angle_deg);
  res.plane = best_plane;
  res.confidence = cons.facing;
  res.consistency_all = cons.all;
  res.facing_fraction = cons.facing_fraction;
  res.mode_confidence[chosen] = cons.facing;
  res.inliers =
      plane_votes(res.pair_planes, cl.modes.row(chosen).transpose(), pc.c, res.scale, o.bandwidth);
  res.support = static_cast<int>(res.inliers.count());
  res.vote_share = double(res.support) / double(res.pairs.rows());
}

/// The result's keypoints and planes moved from the local frame back to the world (shift c0).
void to_world(SymmetryResult& res, const Eigen::Vector3d& c0) {
  res.keypoints.rowwise() += c0.transpose();
  for (Eigen::Index i = 0; i < res.pair_planes.rows(); ++i)
    res.pair_planes.row(i) =
        canonical_plane(shift_plane(res.pair_planes.row(i).transpose(), -c0)).transpose();
  for (Eigen::Index i = 0; i < res.modes.rows(); ++i)
    res.modes.row(i) = canonical_plane(shift_plane(res.modes.row(i).transpose(), -c0)).transpose();
  if (res.plane.allFinite()) res.plane = canonical_plane(shift_plane(res.plane, -c0));
}

}  // namespace

SymmetryResult detect_symmetry(const PointsRef& points, const SymmetryOptions& o) {
  o.validate();
  require_finite(points, "points");
  require(points.rows() >= kMinPoints, "symmetry detection needs at least " +
                                           std::to_string(kMinPoints) + " points, got " +
                                           std::to_string(points.rows()));
  SymmetryResult res;
  Stopwatch sw(res.timings);
  res.pairs.resize(0, 2);
  res.pair_planes.resize(0, 4);
  res.inliers.resize(0);
  res.pair_distances.resize(0);
  res.keypoints.resize(0, 3);
  res.modes.resize(0, 4);
  res.mode_support.resize(0);
  res.mode_confidence.resize(0);

  // 1. downsampling, near the origin
  const PreparedCloud pc = prepare_cloud(points, o.voxel_size);
  const Points& P = pc.P;
  res.num_points = static_cast<std::size_t>(P.rows());
  res.scale = pc.scale;
  sw.lap("downsample");
  if (P.rows() < kMinPoints || !(res.scale > 0)) {
    res.reason = "too few points after downsampling";
    to_world(res, pc.c0);
    return res;
  }

  // 2. normals, 3. keypoints (those without a normal cannot be matched), 4. descriptors; each
  // radius search first checked against the cloud (a radius spanning it is quadratic)
  if (o.normal_radius > 0) detail::check_neighbourhoods(P, o.normal_radius, "normal_radius");
  if (o.keypoints == SymmetryKeypoints::Iss) {
    detail::check_neighbourhoods(P, o.iss_salient_radius, "iss_salient_radius");
    detail::check_neighbourhoods(P, o.iss_non_max_radius, "iss_non_max_radius");
  }
  detail::check_neighbourhoods(P, o.fpfh_radius, "fpfh_radius");
  const auto nc = detail::estimate_normals(P, o.normal_k, o.normal_radius);
  sw.lap("normals");
  std::vector<int> kp = detail::detect_keypoints(P, nc, o);
  kp.erase(std::remove_if(kp.begin(), kp.end(),
                          [&](int i) { return nc.normals.row(i).squaredNorm() == 0; }),
           kp.end());
  sw.lap("keypoints");
  const Fpfh F = detail::compute_fpfh(P, nc.normals, kp, o.fpfh_radius);
  sw.lap("descriptors");

  // 5. matching: pairs of mirror-similar keypoints, each voting for its bisector plane
  const Eigen::Index K = static_cast<Eigen::Index>(kp.size());
  Points kn(K, 3);
  res.keypoints.resize(K, 3);
  for (Eigen::Index i = 0; i < K; ++i) {
    res.keypoints.row(i) = P.row(kp[static_cast<std::size_t>(i)]);
    kn.row(i) = nc.normals.row(kp[static_cast<std::size_t>(i)]);
  }
  match_keypoints(res.keypoints, kn, F, o, res);
  sw.lap("matching");
  if (res.pairs.rows() == 0) {
    res.inliers.setConstant(0, false);
    res.reason = "no keypoint pairs";
    to_world(res, pc.c0);
    return res;
  }

  // 6. mean shift over the pair planes
  const PlaneClusters cl = mean_shift_planes(res.pair_planes, pc.c, res.scale, o.bandwidth,
                                             o.mean_shift_seeds, o.mean_shift_max_iterations);
  res.modes = cl.modes;
  res.mode_support = cl.mode_support;
  res.mode_confidence = Eigen::VectorXd::Constant(cl.modes.rows(), kNaN);
  sw.lap("mean_shift");

  // 7. refine and score the candidate modes; the most consistent wins
  choose_plane(pc, nc.normals, cl, o, res);
  sw.lap("refine_and_score");

  if (res.support < o.min_support)
    res.reason = "support " + std::to_string(res.support) + " < min_support " +
                 std::to_string(o.min_support);
  else if (res.confidence < o.min_confidence)
    res.reason = "confidence " + fmt(res.confidence) + " < min_confidence " + fmt(o.min_confidence);
  res.accepted = res.reason.empty();
  to_world(res, pc.c0);
  return res;
}

// ---------------------------------------------------------------------------- prediction

SymmetricPrediction predict_symmetric(const PointsRef& points, const Eigen::Vector4d& plane,
                                      const SymmetricPredictionOptions& o) {
  o.validate();
  require_finite(points, "points");
  require(plane.allFinite(), "plane must be 4 finite numbers [nx, ny, nz, d]");
  require(plane.head<3>().norm() > 1e-12, "plane normal must not be zero");
  require(points.rows() >= kMinPoints, "symmetric prediction needs at least " +
                                           std::to_string(kMinPoints) + " points, got " +
                                           std::to_string(points.rows()));
  SymmetricPrediction res;
  Stopwatch sw(res.timings);
  res.input_plane = canonical_plane(plane);
  const Eigen::Vector3d c0 = grid_anchor(points, o.icp_voxel_size);
  const Points Pc = centred(points, c0);
  Eigen::Vector4d pl = canonical_plane(shift_plane(res.input_plane, c0));
  res.transform = reflection_matrix(pl);

  if (o.icp) {
    const Points D = o.icp_voxel_size > 0 ? voxelgrid_sampling(Pc, o.icp_voxel_size) : Pc;
    detail::IcpTarget target(D);
    const auto nc = target.estimate_normals(o.icp_normal_k);
    sw.lap("normals");
    const Points src = reflect_points(D, pl);
    const Points src_n = reflect_normals(nc.normals, pl.head<3>());
    const detail::IcpResult r = target.align(src, src_n, o);
    sw.lap("icp");
    res.icp_converged = r.converged;
    res.icp_fitness = r.fitness;
    const Eigen::Matrix4d M = r.transform * reflection_matrix(pl);
    if (M.allFinite() && M.topLeftCorner<3, 3>().determinant() < 0) {
      double residual = 0;
      const Eigen::Vector4d corrected = plane_from_improper_isometry(M, &residual);
      const double angle = plane_angle_deg(corrected, pl);
      const double offset = plane_offset_at(pl, corrected, Eigen::Vector3d::Zero());
      if (r.converged && angle <= o.max_correction_angle_deg && offset <= o.max_correction_offset) {
        pl = corrected;
        res.transform = M;
        res.icp_applied = true;
        res.residual_rotation_deg = residual;
      }
    }
  }

  const Points R = reflect_points(Pc, pl);
  const Eigen::VectorXd dist = nearest_distances(Pc, R);
  Points pred(R.rows(), 3);
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < R.rows(); ++i)
    if (dist[i] > o.explained_tolerance) pred.row(k++) = R.row(i);
  pred.conservativeResize(k, 3);
  pred.rowwise() += c0.transpose();
  res.predicted = std::move(pred);
  sw.lap("predict");

  // Back to the world frame.
  res.plane = canonical_plane(shift_plane(pl, -c0));
  Eigen::Matrix4d T0 = Eigen::Matrix4d::Identity(), T1 = Eigen::Matrix4d::Identity();
  T0.topRightCorner<3, 1>() = -c0;
  T1.topRightCorner<3, 1>() = c0;
  res.transform = T1 * res.transform * T0;
  return res;
}

}  // namespace nbv
