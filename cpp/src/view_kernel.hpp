// The view-scoring kernel shared by evaluate_views and view_coverage (internal to the core):
// validity, then every ray of each valid candidate through the grid, each cell handed to the
// utility policy in order.
#pragma once

#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "nbv/views.hpp"
#include "utilities/registry.hpp"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <type_traits>

namespace nbv::kernel {

constexpr double kInf = std::numeric_limits<double>::infinity();

using Candidates = ViewPosesRef;  // (K, 4) level views or (K, 5) with the gimbal's pitch

inline double logit(double p) { return std::log(p / (1.0 - p)); }

// Cell readers: the workspace grid (fast), or OctoMap's search per cell (the authors' way, kept
// as the reference the grid is checked against and as the benchmark baseline). near_surface is
// utility::next_to_surface (6 faces) of the cell.
struct GridCells {
  const GridView& g;
  float scored(std::size_t idx, const int*) const { return g.cells.scored_at(idx); }
  float logodds(std::size_t idx, const int*) const { return g.cells.logodds_at(idx); }
  CellFlag flag(std::size_t idx, const int*) const { return g.cells.flag_at(idx); }
  bool near_surface(std::size_t, const int* c) const {
    return utility::next_to_surface(g, *this, c);
  }
};

// The grid as one byte per cell, for a call that walks many views with a utility that reads
// only whether a cell is occupied (the sign of `scored`: +-1 here), its flag, and log-odds
// where it stops (Surface, view_coverage): it lets the walks read one cache line per brick of
// 64 cells where they read a float and a flag per cell. A brick's bytes are filled the first
// time a walk reads one of them (a large structure's grid holds tens of millions of cells, of
// which a call reads a few: filling them all cost a plant's call 80 MB written and faulted in),
// in a buffer kept from one call to the next and zeroed where the call filled it. near_surface
// is worked out the first time a walk asks and kept in the cell's byte for the rest of the
// call, in which the grid does not change. Two threads may both fill a brick, or work a cell
// out, and store the same bytes (a refill only forgets what near_surface kept).
class PackedCells {
 public:
  explicit PackedCells(const GridView& g) : g(g), buf_(take(g.storage_size())) {}
  ~PackedCells() { give_back(std::move(buf_)); }
  PackedCells(const PackedCells&) = delete;
  PackedCells& operator=(const PackedCells&) = delete;

  float scored(std::size_t idx, const int*) const { return byte(idx) & kOccupied ? -1.f : 1.f; }
  float logodds(std::size_t idx, const int*) const { return g.cells.logodds_at(idx); }
  CellFlag flag(std::size_t idx, const int*) const { return CellFlag((byte(idx) >> 1) & 3); }
  // c may be null (the four-lane walks give cell ids alone): then worked out from idx
  bool near_surface(std::size_t idx, const int* c) const {
    std::uint8_t v = byte(idx);
    if (!(v & kKnown)) {
      int at[3];
      if (!c) {
        g.layout.coords(idx, at[0], at[1], at[2]);
        c = at;
      }
      v |= kKnown | (utility::next_to_surface(g, *this, c) ? kNear : 0);
      __atomic_store_n(&buf_.bytes[idx], v, __ATOMIC_RELAXED);
    }
    return v & kNear;
  }
  const GridView& g;

 private:
  static constexpr std::uint8_t kOccupied = 1, kKnown = 8, kNear = 16, kFilled = 32;  // flag: 1-2
  struct Free {
    void operator()(std::uint8_t* p) const { std::free(p); }
  };
  using Bytes = std::unique_ptr<std::uint8_t[], Free>;
  // Zero where no call is filling it; calloc'd, so pages no call has read stay unmapped.
  struct Buffer {
    std::size_t cells = 0;
    Bytes bytes;   // a byte per cell
    Bytes filled;  // a byte per brick: 1 where this call filled it
  };

  std::uint8_t byte(std::size_t idx) const {
    const std::uint8_t v = __atomic_load_n(&buf_.bytes[idx], __ATOMIC_RELAXED);
    return __builtin_expect(v & kFilled, kFilled) ? v : fill(idx);
  }
  // Fills the brick of cell idx; returns the cell's byte.
  [[gnu::noinline, gnu::cold]] std::uint8_t fill(std::size_t idx) const {
    const std::size_t brick = idx >> 6;
    std::uint8_t* out = &buf_.bytes[brick << 6];
    if (g.cells.slots[brick] == 0) {  // the shared brick: unknown cells, not occupied
      for (int i = 0; i < 64; ++i) __atomic_store_n(&out[i], kFilled, __ATOMIC_RELAXED);
    } else {
      const float* scored = g.cells.brick_scored(brick);
      const CellFlag* flags = g.cells.brick_flags(brick);
      for (int i = 0; i < 64; ++i)
        __atomic_store_n(&out[i],
                         std::uint8_t(kFilled | std::uint8_t(std::signbit(scored[i])) |
                                      std::uint8_t(flags[i]) << 1),
                         __ATOMIC_RELAXED);
    }
    __atomic_store_n(&buf_.filled[brick], std::uint8_t(1), __ATOMIC_RELAXED);
    return __atomic_load_n(&out[idx & 63], __ATOMIC_RELAXED);
  }

  // One buffer kept between calls (calls at once each take their own).
  static std::mutex& pool_mutex() {
    static std::mutex m;
    return m;
  }
  static Buffer& pooled() {
    static Buffer b;
    return b;
  }
  static Buffer take(std::size_t cells) {
    {
      std::lock_guard<std::mutex> lock(pool_mutex());
      Buffer& b = pooled();
      if (b.bytes && b.cells == cells) return std::move(b);
    }
    Buffer b;
    b.cells = cells;
    b.bytes.reset(static_cast<std::uint8_t*>(std::calloc(std::max<std::size_t>(cells, 1), 1)));
    b.filled.reset(static_cast<std::uint8_t*>(std::calloc((cells >> 6) + 1, 1)));
    if (!b.bytes || !b.filled) throw std::bad_alloc();
    return b;
  }
  static void give_back(Buffer&& b) {
    if (!b.bytes) return;
    std::uint8_t* bytes = b.bytes.get();
    std::uint8_t* filled = b.filled.get();
    parallel_chunks(b.cells >> 6, 1 << 14, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t brick = lo; brick < hi; ++brick)
        if (filled[brick]) {
          std::memset(bytes + (brick << 6), 0, 64);
          filled[brick] = 0;
        }
    });
    std::lock_guard<std::mutex> lock(pool_mutex());
    pooled() = std::move(b);
  }

  Buffer buf_;
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
  const GridView& g;  // the map's grid: its geometry, for near_surface
  bool near_surface(std::size_t, const int* c) const {
    return utility::next_to_surface(g, *this, c);
  }
};

// Whether a view at p can be flown to before its rays are walked: inside the navigation bounds,
// its collision sphere known and free (off the camera's hits too with keep_off_hits), and
// (check_segment) the straight flight from `here` clear.
// The status of evaluate_views and candidate_rays alike (SeesNoOccupied comes after the walk).
inline ViewStatus view_validity(const GridView& g, const Eigen::Vector3d& p,
                                const Eigen::Vector3d& here, const ValidityOptions& v,
                                bool check_segment) {
  if ((p.array() < v.bounds_min.array()).any() || (p.array() > v.bounds_max.array()).any())
    return ViewStatus::OutOfBounds;
  if (!v.keep_off_hits && g.observed())
    return view_validity(g.map_only(), p, here, v, check_segment);
  if (!sphere_is_free(g, p, v.collision_radius)) return ViewStatus::Collision;
  if (check_segment && !segment_is_free(g, here, p, v.collision_radius))
    return ViewStatus::PathBlocked;
  return ViewStatus::Valid;
}

enum Replay : int { kUnknown = 0, kReplayed = 1, kEstimated = 2 };  // Job::replay_view

struct Job {
  const GridView& grid;
  Candidates cand;
  const Pose& current;
  const ViewCameraModel& camera;
  const UtilityOptions& utility;
  const ValidityOptions& validity;
  bool distance_weight;
  /// If set, called after each valid view with what its utility credited (Surface records).
  std::function<void(Eigen::Index, const std::vector<utility::Credit>&)> on_view;
  ViewMemo* memo = nullptr;  ///< walks kept between calls, for utilities with replay()
  /// If set, asked for each valid view before its walk (CoverageMemo's records): kReplayed, the
  /// walk is skipped, the call gave its gain, cells and occupied rays; kEstimated, the call gave
  /// the view's coarse estimate as its gain (for prune_below, in place of the coarse walk);
  /// kUnknown, neither.
  std::function<int(Eigen::Index, double&, int&, int&)> replay_view;
  /// If > 0 (view_coverage's min_gain): before a view's walk, a coarse walk of its rays (every
  /// `coarse_stride`-th across and down) estimates its gain: the coarse rays' gain plus one
  /// fully weighted cell (a cell they missed), times all rays over the coarse ones. A view
  /// estimated below prune_below is not walked: pruned[k] = 1, its gain the estimate, no
  /// on_view. The views walked are walked as without it.
  double prune_below = 0.0;
  int coarse_stride = 1;
  std::vector<std::uint8_t>* pruned = nullptr;
};

// Does the utility declare replay() (utility.hpp)?
template <class U, class = void>
struct Replayable : std::false_type {};
template <class U>
struct Replayable<U, std::void_t<decltype(&U::replay)>> : std::true_type {};

// Does the utility declare kMarksRays (utility.hpp)?
template <class U, class = void>
struct MarksRays : std::false_type {};
template <class U>
struct MarksRays<U, std::void_t<decltype(U::kMarksRays)>> : std::bool_constant<U::kMarksRays> {};

// What a memo entry depends on besides the map: the camera's rays and the grid's geometry.
inline std::vector<double> memo_geometry(const Job& job) {
  const ViewCameraModel& c = job.camera;
  const GridView& g = job.grid;
  std::vector<double> v = {double(c.rays_x), double(c.rays_y), c.hfov_deg,   c.vfov_deg,
                           c.max_range,      g.resolution,     g.origin.x(), g.origin.y(),
                           g.origin.z(),     double(g.nx),     double(g.ny), double(g.nz)};
  v.insert(v.end(), c.mount.matrix().data(), c.mount.matrix().data() + 16);
  return v;
}

// A view's gain, cell count and occupied rays from its memo entry, if the walk it records still
// holds: every stepped-over brick still neutral, every recorded cell of the same occupancy.
template <class Utility>
bool replay(const GridView& g, const ViewMemo::Entry& e, double occ_req, double& gain, int& cells,
            int& occ) {
  for (const std::uint32_t b : e.bricks)
    if (g.brick_live[b]) return false;
  if (!Utility::replay(g, e, gain, cells)) return false;
  occ = 0;
  for (const std::uint32_t s : e.stops) occ += g.cells.logodds_at(s) > occ_req;
  return true;
}

// One kernel for every utility: validity, then the rays of each valid candidate through the
// grid, each cell handed to the utility in order (or, with a memo, the view's earlier walk
// replayed where it still holds).
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
  const std::array<std::uint32_t, 26> cones = bin_cones(job.utility.coverage_cone_deg);
  const Eigen::Vector3d here(job.current.x, job.current.y, job.current.z);
  const ValidityOptions& v = job.validity;
  const bool check_segment = v.blocked_path == "reject";
  const double dense_range =
      job.utility.dense_spacing / (job.camera.pixel_pitch_deg * M_PI / 180.0);
  const double min_cos = job.utility.max_incidence_deg < 90.0
                             ? std::cos(job.utility.max_incidence_deg * M_PI / 180.0)
                             : 0.0;

  // four rays at a time (mark_rays4), for a utility that sums over the distinct cells its rays
  // enter up to their first occupied cell
  constexpr bool kMarks = MarksRays<Utility>::value && std::is_same_v<Cells, GridCells>;
  // the memo (its entries hold cell ids in 32 bits)
  constexpr bool kMemo = Replayable<Utility>::value && kSkip && std::is_same_v<Cells, GridCells>;
  ViewMemo* memo = nullptr;
  if constexpr (kMemo)
    if (job.memo && !job.on_view && g.storage_size() <= (std::size_t(1) << 32)) memo = job.memo;
  std::vector<ViewMemo::Key> keys;
  std::vector<ViewMemo::Entry> fresh;
  std::vector<ViewMemo::Outcome> outcome;
  if (memo) {
    memo->begin(memo_geometry(job));
    keys.resize(std::size_t(K));
    fresh.resize(std::size_t(K));
    outcome.assign(std::size_t(K), ViewMemo::Outcome::NotScored);
    for (auto& e : fresh) e = memo->take();
    for (Eigen::Index k = 0; k < K; ++k) keys[std::size_t(k)] = pose_key(view_pose(job.cand, k));
  }

  // the coarse rays of prune_below
  const bool prune = job.prune_below > 0.0 && job.pruned;
  std::vector<Eigen::Index> coarse_rays;
  if (prune) {
    const int s = std::max(1, job.coarse_stride), nx = job.camera.rays_x;
    for (Eigen::Index r = 0; r < dirs.rows(); ++r)
      if ((r % nx) % s == s / 2 && (r / nx) % s == s / 2) coarse_rays.push_back(r);
    job.pruned->assign(std::size_t(K), 0);
  }
  std::vector<Eigen::Index> all_rays(static_cast<std::size_t>(dirs.rows()));
  std::iota(all_rays.begin(), all_rays.end(), Eigen::Index(0));
  const double coarse_scale =
      double(dirs.rows()) / double(std::max<std::size_t>(coarse_rays.size(), std::size_t(1)));
  // view_coverage's walks four rays at a time (step_rays4), each ray's cells then visited in
  // order: where the surface utility needs no cell's coordinates nor range (no density weight)
  constexpr bool kLanes =
      std::is_same_v<Cells, PackedCells> && std::is_same_v<Utility, utility::Surface>;
  const bool lanes = kLanes && dense_range <= 0.0;
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    thread_local utility::VisitedSet visited;
    thread_local utility::VisitedSet coarse_visited;  // prune_below's walks
    thread_local std::vector<utility::Credit> credits;
    thread_local std::vector<std::uint64_t> mark_cells, mark_runs;  // mark_rays4's buffers
    thread_local std::vector<std::uint8_t> mark_ends;
    thread_local std::vector<std::uint64_t> lane_ids;  // step_rays4's cells
    if (lanes) lane_ids.resize(4 * std::size_t(max_ray_cells(g)));
    std::uint64_t* const ids = lane_ids.data();  // the thread_local's address, looked up once
    // rays[0 .. n) (four at most, the lanes returned) of a camera turned by R, from `from`:
    // their starts in the grid (ray_starts4, inactive past the rays), world directions by
    // component, and ranges
    auto lane_starts = [&](const Eigen::Matrix3d& R, const RayOrigin& from,
                           const Eigen::Index* rays, std::size_t n, RayStart* starts, bool* active,
                           double(&dw)[3][4]) {
      alignas(32) double range[4] = {};
      const int n_lanes = int(std::min<std::size_t>(4, n));
      for (int l = 0; l < n_lanes; ++l) {
        const Eigen::Vector3d ds = dirs.row(rays[l]).transpose();
        const Eigen::Vector3d w = R * ds;
        for (int a = 0; a < 3; ++a) dw[a][l] = w[a];
        range[l] = job.camera.max_range / ds.x();
      }
      const double* const d[3] = {dw[0], dw[1], dw[2]};
      ray_starts4(g, from, d, range, starts, active);
      for (int l = n_lanes; l < 4; ++l) active[l] = false;
      return n_lanes;
    };
    // the same rays' cells, stepped four at a time (step_rays4): lane l's at ids[4 j + l],
    // count[l] of them
    auto step_lanes = [&](const Eigen::Matrix3d& R, const RayOrigin& from, const Eigen::Index* rays,
                          std::size_t n, double(&dw)[3][4], int* count) {
      RayStart starts[4];
      bool active[4] = {false, false, false, false};
      const int n_lanes = lane_starts(R, from, rays, n, starts, active, dw);
      step_rays4(g, starts, active, ids, count);
      return n_lanes;
    };
    if constexpr (kMarks) {
      mark_cells.resize(4 * std::size_t(max_ray_cells(g)));
      mark_runs.resize(mark_cells.size());
      mark_ends.resize(std::size_t(max_ray_cells(g)) + 32);
    }
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const Eigen::Vector3d p(job.cand(k, 0), job.cand(k, 1), job.cand(k, 2));
      auto& st = out.status[k];
      st = static_cast<std::int8_t>(view_validity(g, p, here, v, check_segment));
      if (st != static_cast<std::int8_t>(ViewStatus::Valid)) continue;
      double gain = 0.0;
      int n_cells = 0, occ = 0;
      // Every ray of the view through the grid; with kRecord, the rays' stops go into `rec` and
      // the utility marks the neutral bricks stepped over too (keep() reads the marks).
      auto walk = [&](auto record, ViewMemo::Entry* rec) {
        constexpr bool kRecord = decltype(record)::value;
        // the camera on its gimbal; at pitch 0, pose_to_transform(pose) * mount bit for bit
        const Eigen::Isometry3d T =
            gimbal_sensor_transform(view_pose(job.cand, k), job.camera.mount);
        const Eigen::Vector3d o = T.translation();
        const Eigen::Matrix3d R = T.linear();
        visited.reset(g.storage_size());
        credits.clear();
        utility::ViewContext ctx{
            g,           job.utility, visited, cones.data(), job.on_view ? &credits : nullptr,
            dense_range, min_cos};
        Utility u(ctx);
        bool ray_occ = false;
        auto visit = [&](std::size_t idx, const int* c, double t) {
          const float s = cells.scored(idx, c);
          if (!ray_occ && std::signbit(s)) {  // the ray's first occupied cell
            ray_occ = true;
            if (cells.logodds(idx, c) > occ_req) ++occ;
          }
          return u.visit(cells, idx, c, t, s);
        };
        auto skipped = [&](std::size_t idx) {
          if constexpr (kRecord) u.skipped(idx);
        };
        // a replayable utility stops a ray only at its first occupied cell
        auto end_ray = [&](std::size_t stop) {
          if constexpr (kRecord)
            if (stop != kNoCell) rec->stops.push_back(std::uint32_t(stop));
        };
        const Eigen::Index n_rays = dirs.rows();
        bool walked = false;
        if constexpr (kMarks) {
          // four rays at a time, their cells marked up to each one's first occupied cell
          const RayOrigin from = ray_origin(g, o);
          const MarkBuffer buffer{mark_cells.data(), mark_runs.data(), mark_ends.data()};
          for (Eigen::Index r0 = 0; r0 < n_rays; r0 += 4) {
            RayStart starts[4];
            bool active[4] = {false, false, false, false};
            alignas(32) double dw[3][4] = {};
            const int lanes =
                lane_starts(R, from, &all_rays[std::size_t(r0)], n_rays - r0, starts, active, dw);
            std::size_t stop[4];
            u.mark_rays(g, starts, active, buffer, stop);
            for (int l = 0; l < lanes; ++l) {
              if (stop[l] != kNoCell && cells.logodds(stop[l], nullptr) > occ_req) ++occ;
              end_ray(stop[l]);
            }
          }
          // the gain summed over the marked cells; where that sum could differ from the one
          // in the walk's order, the view is walked again below, cell by cell
          walked = u.sum_marks(g);
          if (!walked) {
            occ = 0;
            if constexpr (kRecord) rec->stops.clear();
          }
        }
        if constexpr (kLanes && !kRecord) {
          const RayOrigin from = lanes ? ray_origin(g, o) : RayOrigin();
          for (Eigen::Index r0 = 0; from.inside && r0 < n_rays; r0 += 4) {
            alignas(32) double dw[3][4] = {};
            int count[4];
            const int n_lanes = step_lanes(R, from, &all_rays[std::size_t(r0)],
                                           std::size_t(n_rays - r0), dw, count);
            // ray by ray, walk_ray<kSkip>'s visits, in its order
            for (int l = 0; l < n_lanes; ++l) {
              u.begin_ray(Eigen::Vector3d(dw[0][l], dw[1][l], dw[2][l]));
              bool first = true;
              for (int j = 0; j < count[l]; ++j) {
                const std::size_t idx = std::size_t(ids[4 * std::size_t(j) + l]);
                if (kSkip && !g.brick_is_live(idx)) continue;
                const float sc = cells.scored(idx, nullptr);
                if (first && std::signbit(sc)) {  // the ray's first occupied cell
                  first = false;
                  if (cells.logodds(idx, nullptr) > occ_req) ++occ;
                }
                if (!u.visit(cells, idx, nullptr, 0.0, sc)) break;
              }
            }
            walked = true;
          }
        }
        for (Eigen::Index r = 0; r < n_rays && !walked; ++r) {
          const Eigen::Vector3d ds = dirs.row(r).transpose();
          const Eigen::Vector3d dw = R * ds;
          u.begin_ray(dw);
          ray_occ = false;
          end_ray(walk_ray<kSkip>(g, o, dw, job.camera.max_range / ds.x(), visit, skipped));
        }
        if (job.on_view) job.on_view(k, credits);
        gain = u.gain();
        n_cells = u.cells();
      };
      // The view's entry from the cells its walk marked (after the utility handed the set back).
      auto keep = [&](ViewMemo::Entry& rec) {
        for (std::size_t i = 0; i < visited.n_touched; ++i) {
          const std::uint32_t w = visited.touched[i];
          if (!g.brick_live[w]) {  // a neutral brick stepped over (IG::skipped)
            rec.bricks.push_back(w);
            continue;
          }
          const std::uint64_t reached = visited.bits[w];
          std::uint64_t occ = 0;
          for (std::uint64_t m = reached; m; m &= m - 1) {
            const int bit = __builtin_ctzll(m);
            occ |= std::uint64_t(std::signbit(g.cells.brick_scored(w)[bit])) << bit;
          }
          rec.words.push_back({reached, occ, w});
        }
      };
      // the gain of the view's coarse rays and one more cell, scaled to all rays (prune_below)
      auto coarse_gain = [&]() {
        const Eigen::Isometry3d T =
            gimbal_sensor_transform(view_pose(job.cand, k), job.camera.mount);
        const Eigen::Vector3d o = T.translation();
        const Eigen::Matrix3d R = T.linear();
        coarse_visited.reset(g.storage_size());
        utility::ViewContext ctx{g,       job.utility, coarse_visited, cones.data(),
                                 nullptr, dense_range, min_cos};
        Utility u(ctx);
        auto visit = [&](std::size_t idx, const int* c, double t) {
          return u.visit(cells, idx, c, t, cells.scored(idx, c));
        };
        const RayOrigin from = lanes ? ray_origin(g, o) : RayOrigin();
        if (from.inside) {  // four rays at a time, as the whole walk
          if constexpr (kLanes)
            for (std::size_t i = 0; i < coarse_rays.size(); i += 4) {
              alignas(32) double dw[3][4] = {};
              int count[4];
              const int n_lanes =
                  step_lanes(R, from, &coarse_rays[i], coarse_rays.size() - i, dw, count);
              for (int l = 0; l < n_lanes; ++l) {
                u.begin_ray(Eigen::Vector3d(dw[0][l], dw[1][l], dw[2][l]));
                for (int j = 0; j < count[l]; ++j) {
                  const std::size_t idx = std::size_t(ids[4 * std::size_t(j) + l]);
                  if (kSkip && !g.brick_is_live(idx)) continue;
                  if (!visit(idx, nullptr, 0.0)) break;
                }
              }
            }
        } else {
          for (const Eigen::Index r : coarse_rays) {
            const Eigen::Vector3d ds = dirs.row(r).transpose();
            const Eigen::Vector3d dw = R * ds;
            u.begin_ray(dw);
            walk_ray<kSkip>(g, o, dw, job.camera.max_range / ds.x(), visit);
          }
        }
        return (u.gain() + 1.0) * coarse_scale;
      };
      const int known = job.replay_view ? job.replay_view(k, gain, n_cells, occ) : kUnknown;
      bool scored = known == kReplayed;
      if (!scored && prune) {
        const double estimate = known == kEstimated ? gain : coarse_gain();
        if (estimate < job.prune_below) {
          (*job.pruned)[kk] = 1;
          out.gain[k] = estimate;
          continue;  // valid, not walked
        }
      }
      if constexpr (kMemo) {
        if (memo && !scored) {
          const ViewMemo::Entry* entry = memo->find(keys[kk]);
          if (entry && replay<Utility>(g, *entry, occ_req, gain, n_cells, occ)) {
            outcome[kk] = ViewMemo::Outcome::Reused;
            scored = true;
          } else {
            outcome[kk] = entry ? ViewMemo::Outcome::Stale : ViewMemo::Outcome::Walked;
            ViewMemo::Entry& rec = fresh[kk];
            walk(std::true_type{}, &rec);
            keep(rec);
            scored = true;
          }
        }
      }
      if (!scored) walk(std::false_type{}, nullptr);
      out.gain[k] = gain;
      out.cells[k] = n_cells;
      out.occupied_seen[k] = occ;
      if (job.utility.require_occupied && occ == 0) {
        st = static_cast<std::int8_t>(ViewStatus::SeesNoOccupied);
        continue;
      }
      double value = gain;
      if (job.distance_weight) value *= std::exp(-job.utility.distance_lambda * (p - here).norm());
      out.utility[k] = value;
    }
  });
  if (memo) memo->end(keys, fresh, outcome);
  return out;
}

}  // namespace nbv::kernel
