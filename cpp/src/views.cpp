#include "nbv/views.hpp"

#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "utilities/registry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace nbv {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

using Candidates = Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>;

double logit(double p) { return std::log(p / (1.0 - p)); }

// Cell readers: the workspace grid (fast), or OctoMap's search per cell (the authors' way, kept
// as the reference the grid is checked against and as the benchmark baseline).
struct GridCells {
  const GridView& g;
  float scored(std::size_t idx, const int*) const { return g.scored[idx]; }
  float logodds(std::size_t idx, const int*) const { return g.logodds[idx]; }
  CellFlag flag(std::size_t idx, const int*) const { return g.flags[idx]; }
};

struct OctreeCells {
  const OccupancyMap& map;
  const octomap::OcTree& tree;  // map.octree(), brought up to date once before the walks
  const octomap::OcTreeNode* node(const int* c) const {
    OccupancyMap::Key key = map.min_key();
    for (int a = 0; a < 3; ++a) key[a] = static_cast<octomap::key_type>(key[a] + c[a]);
    return tree.search(key);
  }
  float scored(std::size_t, const int* c) const {
    const octomap::OcTreeNode* n = node(c);
    if (!n) return float(map.cell_entropy(0.0f, CellFlag::Unknown));
    const float l = n->getLogOdds();
    const float e = float(map.cell_entropy(l, CellFlag::Observed));
    return l >= map.grid().rule().occupied_logodds ? -e : e;
  }
  float logodds(std::size_t, const int* c) const {
    const octomap::OcTreeNode* n = node(c);
    return n ? n->getLogOdds() : 0.0f;
  }
  // files and the octree keep no predictions: the grid's flag tells them apart
  CellFlag flag(std::size_t idx, const int* c) const {
    return node(c) ? map.grid().flag(std::int64_t(idx)) : CellFlag::Unknown;
  }
};

struct Job {
  const GridView& grid;
  Candidates cand;
  const Pose& current;
  const ViewCameraModel& camera;
  const UtilityOptions& utility;
  const ValidityOptions& validity;
  bool distance_weight;
};

// One kernel for every utility: validity, then the rays of each valid candidate through the
// grid, each cell handed to the utility in order.
template <class Utility, bool kSkip, class Cells>
ViewScores score(const Job& job, const Cells& cells) {
  const GridView& g = job.grid;
  const Eigen::Index K = job.cand.rows();
  ViewScores out;
  out.utility.setConstant(K, -kInf);
  out.gain.setZero(K);
  out.cells.setZero(K);
  out.occupied_seen.setZero(K);
  out.status.setConstant(K, static_cast<std::int8_t>(ViewStatus::Valid));
  const Points dirs = job.camera.directions();
  const double occ_req = job.utility.require_occupied_probability > 0
                             ? logit(job.utility.require_occupied_probability)
                             : -kInf;
  std::uint32_t cones[26];
  for (int b = 0; b < 26; ++b) cones[b] = bin_cone(b, job.utility.coverage_cone_deg);
  const Eigen::Vector3d here(job.current.x, job.current.y, job.current.z);
  const ValidityOptions& v = job.validity;
  const bool check_segment = v.blocked_path == "reject";
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    thread_local utility::VisitedSet visited;
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const Eigen::Vector3d p(job.cand(k, 0), job.cand(k, 1), job.cand(k, 2));
      auto& st = out.status[k];
      if ((p.array() < v.bounds_min.array()).any() || (p.array() > v.bounds_max.array()).any()) {
        st = static_cast<std::int8_t>(ViewStatus::OutOfBounds);
        continue;
      }
      if (!sphere_is_free(g, p, v.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::Collision);
        continue;
      }
      if (check_segment && !segment_is_free(g, here, p, v.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::PathBlocked);
        continue;
      }
      const Eigen::Isometry3d T =
          pose_to_transform({p.x(), p.y(), p.z(), job.cand(k, 3)}) * job.camera.mount;
      const Eigen::Vector3d o = T.translation();
      const Eigen::Matrix3d R = T.linear();
      visited.reset(g.storage_size());
      utility::ViewContext ctx{g, job.utility, visited, cones};
      Utility u(ctx);
      int occ = 0;
      for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
        const Eigen::Vector3d ds = dirs.row(r).transpose();
        const Eigen::Vector3d dw = R * ds;
        u.begin_ray(dw);
        bool ray_occ = false;
        walk_ray<kSkip>(g, o, dw, job.camera.max_range / ds.x(),
                        [&](std::size_t idx, const int* c, double t) {
                          const float s = cells.scored(idx, c);
                          if (!ray_occ && std::signbit(s)) {  // the ray's first occupied cell
                            ray_occ = true;
                            if (cells.logodds(idx, c) > occ_req) ++occ;
                          }
                          return u.visit(cells, idx, c, t, s);
                        });
      }
      out.gain[k] = u.gain();
      out.cells[k] = u.cells();
      out.occupied_seen[k] = occ;
      if (job.utility.require_occupied && occ == 0) {
        st = static_cast<std::int8_t>(ViewStatus::SeesNoOccupied);
        continue;
      }
      double value = u.gain();
      if (job.distance_weight) value *= std::exp(-job.utility.distance_lambda * (p - here).norm());
      out.utility[k] = value;
    }
  });
  return out;
}

template <class Cells>
ViewScores dispatch(const Job& job, const Cells& cells, bool skip_neutral) {
  const std::string& name = job.utility.name;
#define NBV_DISPATCH(key, Policy, distance)                                           \
  if (name == key) {                                                                  \
    if constexpr (utility::Policy::kNeedsSurface)                                     \
      if (!job.grid.seen || !job.grid.hits)                                           \
        throw std::invalid_argument("utility '" + name +                              \
                                    "' needs the camera observations (surface=...)"); \
    Job j = job;                                                                      \
    j.distance_weight = distance;                                                     \
    if (skip_neutral && utility::Policy::kSkipNeutral)                                \
      return score<utility::Policy, true>(j, cells);                                  \
    return score<utility::Policy, false>(j, cells);                                   \
  }
  NBV_UTILITIES(NBV_DISPATCH)
#undef NBV_DISPATCH
  throw std::invalid_argument("unknown utility '" + name + "'");
}

void check_inputs(const GridView& g, const Candidates& cand, const ViewCameraModel& camera,
                  const UtilityOptions& utility, const ValidityOptions& validity) {
  g.validate();
  camera.validate();
  utility.validate();
  validity.validate();
  if (!cand.allFinite())
    throw std::invalid_argument("candidate poses contain NaN or infinite values");
}

}  // namespace

// ---- options ---------------------------------------------------------------------------------

const std::vector<std::string>& view_status_names() {
  static const std::vector<std::string> names = {"valid", "out_of_bounds", "collision",
                                                 "path_blocked", "sees_no_occupied"};
  return names;
}

std::vector<std::string> utility_names() {
  std::vector<std::string> out;
#define NBV_NAME(key, Policy, distance) out.push_back(key);
  NBV_UTILITIES(NBV_NAME)
#undef NBV_NAME
  return out;
}

ViewCameraModel ViewCameraModel::for_resolution(double hfov_deg, double vfov_deg, double max_range,
                                                double resolution) {
  if (!(resolution > 0)) throw std::invalid_argument("resolution must be positive");
  ViewCameraModel m;
  m.hfov_deg = hfov_deg;
  m.vfov_deg = vfov_deg;
  m.max_range = max_range;
  m.rays_x =
      static_cast<int>(std::ceil(2.0 * max_range * std::tan(hfov_deg * M_PI / 360.0) / resolution));
  m.rays_y =
      static_cast<int>(std::ceil(2.0 * max_range * std::tan(vfov_deg * M_PI / 360.0) / resolution));
  return m;
}

void ViewCameraModel::validate() const {
  if (rays_x <= 0 || rays_y <= 0 || double(rays_x) * rays_y > 1e7)
    throw std::invalid_argument(
        "view camera needs 1 to 10,000,000 rays (rays_x, rays_y > 0), got " +
        std::to_string(rays_x) + " x " + std::to_string(rays_y));
  if (!(hfov_deg > 0 && hfov_deg < 180 && vfov_deg > 0 && vfov_deg < 180))
    throw std::invalid_argument("view camera field of view must be in (0, 180) degrees");
  if (!(max_range > 0) || !std::isfinite(max_range))
    throw std::invalid_argument("view camera max_range must be positive");
  if (!mount.matrix().allFinite()) throw std::invalid_argument("view camera mount is not finite");
}

Points ViewCameraModel::directions() const {
  Points d(static_cast<Eigen::Index>(rays_x) * rays_y, 3);
  const double fx = (rays_x / 2.0) / std::tan(hfov_deg * M_PI / 360.0);
  const double fy = (rays_y / 2.0) / std::tan(vfov_deg * M_PI / 360.0);
  for (int v = 0; v < rays_y; ++v)
    for (int u = 0; u < rays_x; ++u)
      d.row(static_cast<Eigen::Index>(v) * rays_x + u) =
          Eigen::Vector3d(1.0, -(u + 0.5 - rays_x / 2.0) / fx, -(v + 0.5 - rays_y / 2.0) / fy)
              .normalized();
  return d;
}

void UtilityOptions::validate() const {
  const auto names = utility_names();
  if (std::find(names.begin(), names.end(), name) == names.end()) {
    std::ostringstream s;
    s << "unknown utility '" << name << "' (known:";
    for (const auto& n : names) s << " " << n;
    s << ")";
    throw std::invalid_argument(s.str());
  }
  auto check = [](double v, bool ok, const char* field, const char* what) {
    if (!std::isfinite(v) || !ok)
      throw std::invalid_argument(std::string(field) + " must be " + what + ", got " +
                                  std::to_string(v));
  };
  check(distance_lambda, distance_lambda >= 0, "distance_lambda", ">= 0");
  check(require_occupied_probability,
        require_occupied_probability >= 0 && require_occupied_probability < 1,
        "require_occupied_probability", "in [0, 1)");
  check(min_visibility, min_visibility > 0 && min_visibility < 1, "min_visibility", "in (0, 1)");
  check(frontier_prior, frontier_prior >= 0 && frontier_prior < 1, "frontier_prior", "in [0, 1)");
  check(unknown_prior, unknown_prior >= 0 && unknown_prior < 1, "unknown_prior", "in [0, 1)");
  check(coverage_cone_deg, coverage_cone_deg >= 0 && coverage_cone_deg <= 180, "coverage_cone_deg",
        "in [0, 180]");
  check(density_target, density_target > 0, "density_target", "> 0");
  check(weight_entropy, weight_entropy >= 0, "weight_entropy", ">= 0");
  check(weight_density, weight_density >= 0, "weight_density", ">= 0");
  check(weight_prediction, weight_prediction >= 0, "weight_prediction", ">= 0");
}

void ValidityOptions::validate() const {
  if (!std::isfinite(collision_radius) || collision_radius < 0)
    throw std::invalid_argument("collision_radius must be finite and >= 0");
  if (bounds_min.hasNaN() || bounds_max.hasNaN())
    throw std::invalid_argument("navigation bounds contain NaN");
  if (blocked_path != "reject" && blocked_path != "plan")
    throw std::invalid_argument("blocked_path must be 'reject' or 'plan', got '" + blocked_path +
                                "'");
}

// ---- scoring ---------------------------------------------------------------------------------

ViewScores evaluate_views(const GridView& g, const Candidates& cand, const Pose& current,
                          const ViewCameraModel& camera, const UtilityOptions& utility,
                          const ValidityOptions& validity) {
  check_inputs(g, cand, camera, utility, validity);
  return dispatch(Job{g, cand, current, camera, utility, validity, false}, GridCells{g}, true);
}

ViewScores evaluate_views_octree(const OccupancyMap& map, const Candidates& cand,
                                 const Pose& current, const ViewCameraModel& camera,
                                 const UtilityOptions& utility, const ValidityOptions& validity) {
  const GridView g = grid_view(map);
  check_inputs(g, cand, camera, utility, validity);
  const OctreeCells cells{map, map.octree()};
  return dispatch(Job{g, cand, current, camera, utility, validity, false}, cells, false);
}

double viewable_cells(double hfov_deg, double vfov_deg, double min_range, double max_range,
                      double resolution, bool count_partial) {
  if (!(resolution > 0) || !(max_range > min_range) || !(min_range >= 0))
    throw std::invalid_argument(
        "viewable_cells: need resolution > 0 and 0 <= min_range < max_range");
  const double th = std::tan(hfov_deg * M_PI / 360.0), tv = std::tan(vfov_deg * M_PI / 360.0);
  const double n = min_range, f = max_range, s = resolution;
  const double V = 4.0 * th * tv / 3.0 * (f * f * f - n * n * n);
  if (!count_partial) return V / (s * s * s);
  // Projected areas along x (optical axis), y, z and extents along them, at zero yaw.
  const double Ax = (2 * f * th) * (2 * f * tv);
  const double Ay = (f - n) * (n + f) * tv;
  const double Az = (f - n) * (n + f) * th;
  const double Wx = f - n, Wy = 2 * f * th, Wz = 2 * f * tv;
  return (V + s * (Ax + Ay + Az) + s * s * (Wx + Wy + Wz) + s * s * s) / (s * s * s);
}

}  // namespace nbv
