#include "nbv/views.hpp"

#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "view_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace nbv {
namespace {

using kernel::Candidates;
using kernel::GridCells;
using kernel::Job;
using kernel::OctreeCells;
using kernel::score;

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
  check_view_poses(cand);
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
  if (!(pixel_pitch_deg > 0 && pixel_pitch_deg < 90))
    throw std::invalid_argument("view camera pixel_pitch_deg must be in (0, 90) degrees");
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
  check(dense_spacing, dense_spacing >= 0, "dense_spacing", ">= 0");
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

// ---- the memo of walks -------------------------------------------------------------------------

ViewMemo::ViewMemo(int keep_calls) : keep_calls_(keep_calls) {
  if (keep_calls < 1)
    throw std::invalid_argument("ViewMemo keep_calls must be >= 1, got " +
                                std::to_string(keep_calls));
}

void check_view_poses(const ViewPosesRef& views) {
  if (views.cols() != 4 && views.cols() != 5)
    throw std::invalid_argument(
        "candidate views must have 4 columns (x, y, z, yaw) or 5 (x, y, z, yaw, pitch), got " +
        std::to_string(views.cols()));
  if (!views.leftCols(4).allFinite())
    throw std::invalid_argument("candidate poses contain NaN or infinite values");
  if (views.cols() == 5)  // non-finite too, named as the pitch
    for (Eigen::Index k = 0; k < views.rows(); ++k)
      require_pitch(views(k, 4), "candidate view " + std::to_string(k));
}

PoseKey pose_key(double x, double y, double z, double yaw, double pitch) {
  PoseKey k;
  const double v[5] = {x, y, z, yaw, pitch == 0 ? 0.0 : pitch};
  for (int a = 0; a < 5; ++a) std::memcpy(&k[a], &v[a], sizeof(double));
  return k;
}

std::size_t PoseKeyHash::operator()(const PoseKey& k) const {
  std::uint64_t h = 0x9E3779B97F4A7C15ull;
  // x, y, z, yaw; then the pitch, only where it is not level: a level view hashes as before
  for (int a = 0; a < 4; ++a) h = (h ^ k[a]) * 0xBF58476D1CE4E5B9ull, h ^= h >> 31;
  if (k[4]) h = (h ^ k[4]) * 0xBF58476D1CE4E5B9ull, h ^= h >> 31;
  return std::size_t(h);
}

static std::size_t entry_bytes(const ViewMemo::Entry& e) {
  return sizeof(e) + sizeof(ViewMemo::Word) * e.words.capacity() +
         4 * (e.stops.capacity() + e.bricks.capacity());
}

std::size_t ViewMemo::bytes() const {
  std::size_t b = 0;
  for (const auto& [k, e] : entries_) b += sizeof(Key) + entry_bytes(e);
  for (const Entry& e : spare_) b += entry_bytes(e);
  return b;
}

void ViewMemo::clear() {
  entries_.clear();
  spare_.clear();
  geometry_.clear();
}

ViewMemo::Entry ViewMemo::take() {
  if (spare_.empty()) return {};
  Entry e = std::move(spare_.back());
  spare_.pop_back();
  e.words.clear();
  e.stops.clear();
  e.bricks.clear();
  return e;
}

void ViewMemo::begin(const std::vector<double>& geometry) {
  // bit for bit: a NaN never reaches here (the options are validated)
  if (geometry != geometry_) {
    entries_.clear();
    geometry_ = geometry;
  }
  ++call_;
}

const ViewMemo::Entry* ViewMemo::find(const Key& k) const {
  const auto it = entries_.find(k);
  return it == entries_.end() ? nullptr : &it->second;
}

void ViewMemo::end(const std::vector<Key>& keys, std::vector<Entry>& fresh,
                   const std::vector<Outcome>& outcome) {
  for (std::size_t k = 0; k < keys.size(); ++k) {
    if (outcome[k] == Outcome::Reused) {
      entries_.at(keys[k]).used = call_;
      ++stats_.reused;
    } else if (outcome[k] == Outcome::Walked || outcome[k] == Outcome::Stale) {
      fresh[k].used = call_;
      Entry& e = entries_[keys[k]];
      std::swap(e, fresh[k]);  // the old record's arrays go back with the unused ones below
      ++stats_.walked;
      stats_.stale += outcome[k] == Outcome::Stale;
    }
  }
  for (Entry& e : fresh)
    if (e.words.capacity()) spare_.push_back(std::move(e));
  for (auto it = entries_.begin(); it != entries_.end();) {
    if (it->second.used > call_ - keep_calls_) {
      ++it;
      continue;
    }
    spare_.push_back(std::move(it->second));
    it = entries_.erase(it);
  }
  // keep no more spare arrays than a call can use
  if (spare_.size() > keys.size()) spare_.resize(keys.size());
}

// ---- scoring ---------------------------------------------------------------------------------

ViewScores evaluate_views(const GridView& g, const Candidates& cand, const Pose& current,
                          const ViewCameraModel& camera, const UtilityOptions& utility,
                          const ValidityOptions& validity, ViewMemo* memo) {
  check_inputs(g, cand, camera, utility, validity);
  return dispatch(Job{g, cand, current, camera, utility, validity, false, {}, memo}, GridCells{g},
                  true);
}

ViewScores evaluate_views_octree(const OccupancyMap& map, const Candidates& cand,
                                 const Pose& current, const ViewCameraModel& camera,
                                 const UtilityOptions& utility, const ValidityOptions& validity,
                                 const SurfaceObservations* surface) {
  const GridView g = grid_view(map, surface);
  check_inputs(g, cand, camera, utility, validity);
  const OctreeCells cells{map, map.octree(), g};
  return dispatch(Job{g, cand, current, camera, utility, validity, false, {}, nullptr}, cells,
                  false);
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
