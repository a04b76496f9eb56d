#include "nbv/views.hpp"

#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "view_kernel.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

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
      if (!job.grid.observed())                                                       \
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
  check(max_incidence_deg, max_incidence_deg > 0 && max_incidence_deg <= 90, "max_incidence_deg",
        "in (0, 90]");
  check(incidence_min_patches, incidence_min_patches >= 0 && incidence_min_patches <= 16,
        "incidence_min_patches", "in [0, 16]");
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

// ---- what candidates' rays reach -------------------------------------------------------------

namespace {

/// A cell one of a view's rays reached: its id, and the ray (and the axis of the face it entered
/// through, -1 for none) of the smallest range so far.
struct Reached {
  std::uint64_t id;
  double range;
  std::int32_t ray;
  std::int8_t axis;
};

/// Per thread: which record of the current view holds a cell. Brick by brick (the grid's bricks
/// of 64 cells): an open-addressing table from a brick's id to a block of 64 record numbers, one
/// per cell of the brick (kNone: not reached yet). A ray crosses a few cells per brick and its
/// neighbours cross the same bricks, so a walk mostly finds its block at hand (the last one) or
/// in a small table; the blocks sit together in one pool. Both are cleared per view.
class CellSlots {
 public:
  static constexpr std::uint32_t kNone = ~std::uint32_t(0);
  void begin_view() {
    // room for twice the bricks of the largest view so far
    std::size_t size = 1024;
    while (size < 2 * blocks_) size *= 2;
    if (keys_.size() < size) keys_.resize(size), at_.resize(size);
    mask_ = keys_.size() - 1;
    shift_ = 64 - __builtin_ctzll(keys_.size());
    std::fill(keys_.begin(), keys_.end(), kEmpty);
    blocks_ = 0;
  }
  /// The 64 record numbers of brick `brick`'s cells (valid until the next call).
  std::uint32_t* block(std::uint64_t brick) {
    if (2 * (blocks_ + 1) > keys_.size()) grow();
    std::size_t h = std::size_t((brick * 0x9E3779B97F4A7C15ull) >> shift_);
    for (;; h = (h + 1) & mask_) {
      if (keys_[h] == brick) return &pool_[std::size_t(at_[h]) * 64];
      if (keys_[h] == kEmpty) break;
    }
    keys_[h] = brick;
    at_[h] = std::uint32_t(blocks_);
    if (pool_.size() < 64 * (blocks_ + 1))
      pool_.resize(std::max<std::size_t>(4096, 2 * pool_.size()));
    std::uint32_t* b = &pool_[64 * blocks_++];
    std::fill(b, b + 64, kNone);
    return b;
  }

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);
  void grow() {
    std::vector<std::uint64_t> keys(2 * keys_.size(), kEmpty);
    std::vector<std::uint32_t> at(keys.size());
    mask_ = keys.size() - 1;
    shift_ = 64 - __builtin_ctzll(keys.size());
    for (std::size_t i = 0; i < keys_.size(); ++i) {
      if (keys_[i] == kEmpty) continue;
      std::size_t h = std::size_t((keys_[i] * 0x9E3779B97F4A7C15ull) >> shift_);
      while (keys[h] != kEmpty) h = (h + 1) & mask_;
      keys[h] = keys_[i];
      at[h] = at_[i];
    }
    keys_.swap(keys);
    at_.swap(at);
  }
  std::vector<std::uint64_t> keys_;  // brick ids (kEmpty: free)
  std::vector<std::uint32_t> at_;    // their blocks in pool_
  std::vector<std::uint32_t> pool_;  // blocks of 64 record numbers
  std::size_t blocks_ = 0, mask_ = 0;
  int shift_ = 64;
};

/// Which face a ray entering the workspace from outside crosses first: the axis whose
/// entering boundary it reaches last (clip_to_grid's t0).
int entry_axis(const GridView& g, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const Eigen::Vector3d pos = (o - g.origin) / g.resolution;
  const int n[3] = {g.nx, g.ny, g.nz};
  int axis = -1;
  double best = -kernel::kInf;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) continue;
    const double t = ((d[a] > 0 ? 0.0 : double(n[a])) - pos[a]) / d[a];
    if (t > best) best = t, axis = a;
  }
  return axis;
}

/// Walks the rays of the camera at T (camera.directions() `dirs`, each to max_range depth) as
/// evaluate_views does, recording in `rec` the distinct cells they reach (slots: which record
/// holds a cell); returns the rays that ended at an occupied cell of log-odds above occ_req. Kept
/// out of its caller (noipa: not inlined, nor specialised for its arguments), so that the
/// caller's thread-local tables come in as plain references that the walk keeps in registers;
/// inlined, GCC looked their thread-local addresses up again at every cell.
[[gnu::noipa]] int walk_view(const GridView& g, const Points& dirs, const Eigen::Isometry3d& T,
                             double max_range, double occ_req, CellSlots& slots,
                             std::vector<Reached>& rec) {
  const Eigen::Vector3d o = T.translation();
  const Eigen::Matrix3d R = T.linear();
  rec.clear();
  slots.begin_view();
  std::uint64_t brick = ~std::uint64_t(0);
  std::uint32_t* block = nullptr;
  int occ = 0;
  for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
    const Eigen::Vector3d ds = dirs.row(r).transpose();
    const Eigen::Vector3d dw = R * ds;
    bool first = true;
    int prev[3] = {0, 0, 0};
    walk_ray<false>(g, o, dw, max_range / ds.x(), [&](std::size_t idx, const int* c, double t) {
      int axis;
      if (first)
        axis = t > 0.0 ? entry_axis(g, o, dw) : -1;
      else
        axis = c[0] != prev[0] ? 0 : c[1] != prev[1] ? 1 : 2;
      first = false;
      prev[0] = c[0], prev[1] = c[1], prev[2] = c[2];
      if ((idx >> 6) != brick) brick = idx >> 6, block = slots.block(brick);
      std::uint32_t& at = block[idx & 63];
      if (at == CellSlots::kNone) {
        at = std::uint32_t(rec.size());
        rec.push_back({idx, t, std::int32_t(r), std::int8_t(axis)});
      } else if (t < rec[at].range) {
        rec[at].range = t, rec[at].ray = std::int32_t(r);
        rec[at].axis = std::int8_t(axis);
      }
      if (!g.cells.occupied(idx)) return true;
      occ += g.cells.logodds_at(idx) > occ_req;  // the ray's first occupied cell
      return false;
    });
  }
  return occ;
}

}  // namespace

std::size_t max_candidate_cells() {
  double bytes = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE));
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
    bytes = std::min(bytes, double(limit.rlim_cur));
  return std::size_t(std::max(bytes, 0.0) / 2 / kCandidateCellBytes);
}

CandidateRays candidate_rays(const GridView& g, const Candidates& cand, const Pose& current,
                             const ViewCameraModel& camera, const UtilityOptions& utility,
                             const ValidityOptions& validity) {
  check_inputs(g, cand, camera, utility, validity);
  const Eigen::Index K = cand.rows();
  CandidateRays out;
  out.occupied_seen.setZero(K);
  out.status.setConstant(K, static_cast<std::int8_t>(ViewStatus::Valid));
  const Points dirs = camera.directions();
  const double occ_req = utility.require_occupied_probability > 0
                             ? kernel::logit(utility.require_occupied_probability)
                             : -kernel::kInf;
  const Eigen::Vector3d here(current.x, current.y, current.z);
  const bool check_segment = validity.blocked_path == "reject";
  std::vector<std::vector<Reached>> reached(static_cast<std::size_t>(K));
  std::atomic<std::size_t> total{0};  // cells reached so far: max_cells at most
  const std::size_t max_cells = max_candidate_cells();

  // The walks: every ray of each valid view, as evaluate_views walks them (walk_ray<false>
  // visits the cells the ig utility's four-lane walk marks, in order).
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    // per thread, kept between calls (their arrays grown once)
    thread_local CellSlots slots;
    thread_local std::vector<Reached> rec;  // a view's cells, then copied to `reached`
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const Pose pose = view_pose(cand, k);
      const Eigen::Vector3d p(pose.x, pose.y, pose.z);
      const ViewStatus st = kernel::view_validity(g, p, here, validity, check_segment);
      out.status[k] = static_cast<std::int8_t>(st);
      if (st != ViewStatus::Valid) continue;
      const Eigen::Isometry3d T = gimbal_sensor_transform(pose, camera.mount);
      const int occ = walk_view(g, dirs, T, camera.max_range, occ_req, slots, rec);
      if (total.fetch_add(rec.size()) + rec.size() > max_cells)
        throw std::length_error(
            "candidate_rays: the " + std::to_string(K) + " candidates' rays reach more than " +
            std::to_string(max_cells) + " cells (" +
            fmt(std::round(double(max_cells * kCandidateCellBytes) / (1 << 30) * 10) / 10) +
            " GiB, half the memory this process may use): give fewer candidates at a time (or "
            "a coarser map or camera)");
      reached[kk].assign(rec.begin(), rec.end());
      out.occupied_seen[k] = occ;
      if (utility.require_occupied && occ == 0)
        out.status[k] = static_cast<std::int8_t>(ViewStatus::SeesNoOccupied);
    }
  });

  // The flat arrays, each view's cells at its offset.
  out.offsets.resize(K + 1);
  out.offsets[0] = 0;
  for (Eigen::Index k = 0; k < K; ++k)
    out.offsets[k + 1] = out.offsets[k] + std::int64_t(reached[std::size_t(k)].size());
  const std::size_t N = std::size_t(out.offsets[K]);
  out.index.resize(N);
  out.centers.resize(3 * N);
  out.probability.resize(N);
  out.logodds.resize(N);
  out.state.resize(N);
  out.range.resize(N);
  out.incidence.resize(N);
  const bool observed = out.observed = g.observed();
  out.seen.resize(observed ? N : 0);
  out.hits.resize(observed ? N : 0);
  const kernel::GridCells cells{g};
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const std::vector<Reached>& rec = reached[kk];
      if (rec.empty()) continue;
      const Eigen::Matrix3d R = gimbal_sensor_transform(view_pose(cand, k), camera.mount).linear();
      std::size_t i = std::size_t(out.offsets[k]);
      for (const Reached& c : rec) {
        const std::size_t id = std::size_t(c.id);
        int cell[3];
        g.layout.coords(id, cell[0], cell[1], cell[2]);
        const CellFlag flag = g.cells.flag_at(id);
        const bool occupied = g.cells.occupied(id);
        out.index[i] = cell[0] + std::int64_t(g.nx) * (cell[1] + std::int64_t(g.ny) * cell[2]);
        const Eigen::Vector3d centre = g.center(cell[0], cell[1], cell[2]);
        for (int a = 0; a < 3; ++a) out.centers[3 * i + std::size_t(a)] = centre[a];
        out.logodds[i] = g.cells.logodds_at(id);
        out.probability[i] = utility::occupancy(cells, id, cell);
        out.state[i] = static_cast<std::int8_t>(flag == CellFlag::Unknown ? CellState::Unknown
                                                : occupied                ? CellState::Occupied
                                                                          : CellState::Free);
        out.range[i] = c.range + 0.0;  // -0.0 (a cell entered at the camera) as 0
        const Eigen::Vector3d d = R * dirs.row(c.ray).transpose();
        double cos_i = std::numeric_limits<double>::quiet_NaN();
        double n[3] = {0.0, 0.0, 0.0};
        if (occupied) utility::open_face_normal(g, cells, cell, n);
        const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (nn > 0.0)
          cos_i = std::abs(n[0] * d.x() + n[1] * d.y() + n[2] * d.z()) / nn;
        else if (c.axis >= 0)
          cos_i = std::abs(d[c.axis]) / d.norm();
        out.incidence[i] = std::isnan(cos_i) ? cos_i : std::acos(std::min(1.0, cos_i));
        if (observed) {
          out.seen[i] = g.seen(id);
          out.hits[i] = g.hits(id);
        }
        ++i;
      }
    }
  });
  return out;
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
