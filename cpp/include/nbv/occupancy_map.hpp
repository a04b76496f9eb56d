// Probabilistic occupancy map: an OctoMap octree (the map of record: .ot/.bt files, cells
// outside the workspace) plus a grid of the workspace box (WorkspaceGrid: fast queries,
// incremental total entropy; cells held only for the bricks written), which integration updates
// first.
//
// Grid. OctoMap's origin-anchored grid: a coordinate c falls in key floor(c / res) + 32768 per
// axis (exactly OctoMap's coordToKey, which first rounds the point to float32 as its point3d
// does; so a point's cell here is the cell OctoMap files it in). The workspace is the box of
// cells whose index range covers [bounds_min, bounds_max): for (-20,-20,0)-(20,20,10) at 0.2 m
// that is 200 x 200 x 50 = 2,000,000 cells. Bounds that lie within 1e-6 of a cell on a grid
// plane are snapped to it (0.3 at 0.1 m is the plane 3, not 3.0000000000000004). Cell (i, j, k)
// of the workspace has the key min_key + (i, j, k), the flat grid index i + nx * (j + ny * k)
// and the centre bounds_min + (i + 0.5, j + 0.5, k + 0.5) * res.
//
// Octree and grid. A workspace cell's value is computed in the grid with OctoMap's own float
// arithmetic (log-odds + update, clamped; no change once clamped) and copied into the octree
// lazily: the octree is brought up to date, one setNodeValue per changed cell in tree order and
// one pruning pass, whenever it is read (octree(), save(), integrate_exact, verify_mirror). The
// result is the octree that per-cell updateNode calls would have built. Cells outside the
// workspace live in the octree only (updated at once) and count in no total.
//
// Occupancy. A cell is occupied when p >= occupancy_threshold (OctoMap's own `>=`), free below,
// unknown when never observed (not stored in the octree; p = 0.5).
//
// Entropy. Binary entropy of p in nats (default) or bits; unknown cells count p = 0.5 (ln 2
// nats, 1 bit). With clamped_entropy_zero (default, the authors' code) a cell at OctoMap's
// clamping thresholds counts zero entropy: that is what makes the paper's Table 2 entropy column
// reachable (a profile scan turns most of the workspace into clamped free cells; without the rule
// each such cell would still hold H(0.12) = 0.367 nats).
//
// Thread safety: const queries may run concurrently, except octree() / save() /
// verify_mirror(), which may bring the octree up to date; the mutating calls (integrate*,
// update_cells, mark_free_segment, set_unknown_cells) must not run concurrently with anything
// else on the same map. C++ callers that share a map between threads hold access_lock() (shared
// for queries, exclusive for the rest); the Python bindings do so around every call, so one map
// may be used from several Python threads. Results do not depend on the number of threads.
#pragma once

#include "nbv/common.hpp"
#include "nbv/huge_pages.hpp"
#include "nbv/options.hpp"
#include "nbv/sensors.hpp"
#include "nbv/workspace_grid.hpp"

#include <octomap/OcTree.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace nbv {

/// Parameters of an OccupancyMap. The sensor model probabilities are OctoMap's published
/// defaults, which the authors kept (through octomap_server: exactly 0.7 / 0.4 / 0.12 / 0.97; a
/// bare octomap::OcTree clamps at log-odds -2 / 3.5, i.e. p 0.1192 / 0.971).
#define NBV_OCCUPANCY_MAP_OPTIONS(X)                                                            \
  X(double, prob_hit, 0.7, "occupancy update of a hit cell, in [0.5, 1)")                       \
  X(double, prob_miss, 0.4, "occupancy update of a cell a ray passes through, in (0, 0.5]")     \
  X(double, clamp_min, 0.12, "lower clamping threshold (probability)")                          \
  X(double, clamp_max, 0.97, "upper clamping threshold (probability)")                          \
  X(double, occupancy_threshold, 0.6,                                                           \
    "a cell is occupied when p >= this (OctoMap's >=); the authors' 0.6: a cell hit once and "  \
    "missed once (p 0.61) stays occupied, hit once and missed twice (p 0.51) is free, and "     \
    "cells predicted at the paper's 0.6 count as occupied")                                     \
  X(EntropyUnit, entropy_unit, EntropyUnit::Nats,                                               \
    "unit of every entropy the map reports: nats (the authors') or bits")                       \
  X(bool, clamped_entropy_zero, true,                                                           \
    "cells at a clamping threshold count zero entropy (the authors' code; what makes the "      \
    "paper's Table 2 entropy column reachable); false: the plain binary entropy of every cell") \
  X(bool, deduplicate_end_points, true,                                                         \
    "fast integration: one ray traced per end sub-cell (see end_point_subdivision); false "     \
    "traces every ray: slower, the same cells as OctoMap's insertPointCloud")                   \
  X(int, end_point_subdivision, 2,                                                              \
    "sub-cells per cell edge for grouping ray ends, 1..4 (1 = one ray per end cell, which "     \
    "agrees with insertPointCloud on only ~97-98 % of the touched cells; 2 gives > 99 %)")      \
  X(bool, clip_to_workspace, true,                                                              \
    "integration updates only workspace cells (rays are still traced from their origin): the "  \
    "method reads nothing outside the workspace, and a laser survey from outside it costs a "   \
    "third as much; false: the octree also maps the cells outside, as insertPointCloud does "   \
    "(integrate_exact never clips)")

struct OccupancyMapOptions {
  NBV_OCCUPANCY_MAP_OPTIONS(NBV_DECLARE_OPTION)
  void validate() const;  ///< throws std::invalid_argument naming the bad field
};

/// What one integration did.
struct IntegrationStats {
  std::size_t rays = 0;            ///< input rays (hits + free-space rays)
  std::size_t traced_rays = 0;     ///< rays actually walked (after de-duplicating end cells)
  std::size_t occupied_cells = 0;  ///< cells updated as hit
  std::size_t free_cells = 0;      ///< cells updated as miss
};

class OccupancyMap {
 public:
  using Key = octomap::OcTreeKey;
  static constexpr std::int64_t kMaxCells = 400'000'000;
  static constexpr double kDefaultResolution = 0.2;  ///< cell edge, m (the authors' 0.2)
  /// The default workspace box, m: the paper's 40 x 40 x 10 m.
  static constexpr std::array<double, 3> kDefaultBoundsMin{-20.0, -20.0, 0.0};
  static constexpr std::array<double, 3> kDefaultBoundsMax{20.0, 20.0, 10.0};

  /// resolution in metres; workspace bounds in metres (world frame). Throws std::invalid_argument
  /// for a non-positive or non-finite resolution, non-finite bounds, max <= min, bounds outside
  /// OctoMap's addressable range (+-32768 cells), or more than kMaxCells cells.
  OccupancyMap(double resolution, const Eigen::Vector3d& bounds_min,
               const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options = {});
  ~OccupancyMap();
  OccupancyMap(OccupancyMap&&) noexcept;
  OccupancyMap& operator=(OccupancyMap&&) noexcept;
  OccupancyMap(const OccupancyMap&) = delete;
  OccupancyMap& operator=(const OccupancyMap&) = delete;

  // ---- integration -------------------------------------------------------------------------
  /// Integrates one scan. Hits: the end cell is a hit, the cells from the origin up to (not
  /// including) the end cell are misses. Free ends: every cell from the origin to the end cell
  /// inclusive is a miss. A ray longer than max_range (metres, inf = none) is cut at max_range
  /// and only clears the cells before its cut end (OctoMap's maxrange rule). Per scan each cell
  /// is updated once; a cell both hit and passed through counts as hit (OctoMap's computeUpdate).
  /// A predicted cell touched by an observation restarts from unknown (log-odds 0) first.
  ///
  /// Fast path, in named steps: collect_end_points (per ray, parallel: end cell and sub-cell;
  /// neighbouring rays ending in the same sub-cell merge on the fly), group_end_points (one
  /// group per end sub-cell, end_point_subdivision per axis), classify_end_cells (hit and
  /// free-end cells), trace_free_cells (one ray per group, from the end point nearest the
  /// sub-cell centre, with OctoMap's own DDA arithmetic, in parallel; cells whose miss would
  /// change nothing - clamped free cells - are skipped, whole bricks of them at a time), then
  /// apply_updates (each cell once, in the grid). The only difference from insertPointCloud is
  /// that cells only the untraced rays of a group would have crossed stay as they were: > 99 % of
  /// the touched cells agree (tests, bench/bench_map.cpp). With deduplicate_end_points = false
  /// every ray is traced and the result is identical.
  /// Throws std::invalid_argument for non-finite input or an origin outside the addressable range.
  /// What integrate and integrate_exact check of a scan before they change anything: throws
  /// std::invalid_argument for a non-finite origin or one outside OctoMap's addressable range,
  /// hits or free ends NaN, infinite or beyond +-kMaxCoordinate, or a max_range not > 0.
  void check_scan(const Eigen::Vector3d& origin, const PointsRef& hits, const PointsRef& free_ends,
                  double max_range) const;
  IntegrationStats integrate(const Eigen::Vector3d& origin, const PointsRef& hits,
                             const PointsRef& free_ends,
                             double max_range = std::numeric_limits<double>::infinity());
  IntegrationStats integrate(const Scan& scan,
                             double max_range = std::numeric_limits<double>::infinity());
  /// integrate for a scan that check_scan has passed (integrate_frame checks a frame once, up
  /// front, before the map's update runs beside the other two): the points are not read again.
  IntegrationStats integrate_checked(const Scan& scan, double max_range);
  /// Same semantics through OctoMap's own code: octomap::OcTree::computeUpdate (the key sets
  /// insertPointCloud builds), free rays added with computeRayKeys, then insertPointCloud's
  /// update loop (updateNode per cell: misses, then hits). The reference the fast path is held to.
  IntegrationStats integrate_exact(const Eigen::Vector3d& origin, const PointsRef& hits,
                                   const PointsRef& free_ends,
                                   double max_range = std::numeric_limits<double>::infinity());

  /// One hit (occupied = true) or miss update of every distinct cell holding one of `points` /
  /// of `keys` (e.g. to clear the space a vehicle has flown through). Predictions are discarded
  /// first, as by integrate. Returns the number of distinct cells. Throws for non-finite points.
  std::size_t update_cells(const PointsRef& points, bool occupied);
  std::size_t update_cells(const std::vector<Key>& keys, bool occupied);

  /// One miss update of every UNKNOWN cell that touches the volume swept by a sphere of `radius`
  /// (metres) along the segment a-b (cells holding a and b included): the space a vehicle of that
  /// radius has flown through is free. Observed cells are left alone, so repeating it along a
  /// flight does not keep lowering their entropy. Returns the number of cells updated. Throws
  /// for non-finite input or radius < 0.
  std::size_t mark_free_segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);

  /// Every UNKNOWN workspace cell holding at least one of `points` gets log-odds(probability)
  /// (clamped to the clamping thresholds, as OctoMap's setNodeValue does) and is flagged
  /// predicted. Returns the number of cells set. Points outside the workspace are ignored.
  /// Throws for non-finite points or probability outside (0, 1).
  std::size_t set_unknown_cells(const PointsRef& points, double probability = 0.6);

  // ---- per-point queries (points in metres, world frame) ------------------------------------
  CellState state(const Eigen::Vector3d& p) const;
  double probability(const Eigen::Vector3d& p) const;  ///< 0.5 for unknown
  double entropy(const Eigen::Vector3d& p) const;      ///< in the map's unit
  bool is_predicted(const Eigen::Vector3d& p) const;
  /// Bulk versions over rows of `points` (parallel). Points outside the workspace are answered
  /// from the octree; points outside the addressable range are unknown.
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> states(const PointsRef& points) const;
  Eigen::VectorXd probabilities(const PointsRef& points) const;
  Eigen::VectorXd entropies(const PointsRef& points) const;
  Eigen::Matrix<bool, Eigen::Dynamic, 1> predicted(const PointsRef& points) const;

  // ---- workspace totals and cells -------------------------------------------------------------
  /// Total workspace entropy in the map's unit, maintained incrementally: O(1).
  double total_entropy() const { return grid_.total_entropy(); }
  /// Same, recomputed by a sweep over the grid (equal to total_entropy() exactly).
  double recompute_total_entropy() const { return grid_.recompute_total_entropy(); }
  CellCounts counts() const { return grid_.counts(); }
  /// Centres (M, 3) of the occupied workspace cells, in flat-index order (in_order = false: in
  /// the grid's brick order, without the sort).
  Points occupied_cells(bool in_order = true) const;
  /// The workspace grid (cell values, flags, entropies, brick summary).
  const WorkspaceGrid& grid() const { return grid_; }
  /// Number of workspace cells whose grid value disagrees with the octree (0 when in sync;
  /// brings the octree up to date first). Walks the octree once per cell: for tests.
  std::int64_t verify_mirror() const;

  // ---- geometry --------------------------------------------------------------------------------
  double resolution() const { return res_; }
  const OccupancyMapOptions& options() const { return opt_; }
  Eigen::Vector3d bounds_min() const;  ///< cell-aligned lower corner of the workspace
  Eigen::Vector3d bounds_max() const;  ///< cell-aligned upper corner of the workspace
  const std::array<int, 3>& dims() const { return grid_.dims(); }  ///< (nx, ny, nz)
  const Key& min_key() const { return min_key_; }                  ///< key of cell (0, 0, 0)
  std::int64_t num_cells() const { return grid_.num_cells(); }
  /// OctoMap's key of a point (float32-rounded as OctoMap does); false outside the addressable
  /// range.
  bool coord_to_key(const Eigen::Vector3d& p, Key& key) const;
  /// Centre of a cell (double precision).
  Eigen::Vector3d key_to_coord(const Key& key) const;
  bool in_workspace(const Key& key) const {
    const auto& d = grid_.dims();
    return unsigned(int(key[0]) - int(min_key_[0])) < unsigned(d[0]) &&
           unsigned(int(key[1]) - int(min_key_[1])) < unsigned(d[1]) &&
           unsigned(int(key[2]) - int(min_key_[2])) < unsigned(d[2]);
  }
  /// The grid id of a key's cell (WorkspaceGrid's layout), -1 outside the workspace.
  std::int64_t index_of(const Key& key) const {
    if (!in_workspace(key)) return -1;
    return std::int64_t(grid_.layout().id(int(key[0]) - min_key_[0], int(key[1]) - min_key_[1],
                                          int(key[2]) - min_key_[2]));
  }
  /// The key of a grid id (which must be a cell's, not padding).
  Key key_at(std::int64_t id) const;
  /// Entropy in the map's unit of a cell with this log-odds and flag (the rule of the totals).
  double cell_entropy(float logodds, CellFlag flag) const {
    return grid_.rule().entropy(logodds, flag);
  }

  /// The octree (map of record), brought up to date first. Read-only: changing it behind the
  /// map's back breaks the grid.
  const octomap::OcTree& octree() const;
  /// The map's reader-writer lock (see Thread safety above); the map itself never takes it.
  std::shared_mutex& access_lock() const { return access_.mutex(); }

  // ---- files ----------------------------------------------------------------------------------
  /// Writes `.ot` (OcTree::write: full probabilities) or `.bt` (writeBinaryConst: maximum
  /// likelihood free/occupied), both readable by octovis. Throws std::invalid_argument for
  /// another extension, std::runtime_error when the file cannot be written.
  void save(const std::string& path) const;
  /// Reads a `.ot` / `.bt` file. Without bounds the workspace is the tree's metric bounding box.
  /// Coarse (pruned) leaves are expanded to their resolution cells in the grid; every cell read
  /// is flagged observed (files do not record predictions). Throws FileNotFound for a missing
  /// file, std::invalid_argument naming the file for an unknown extension, unreadable data, a
  /// damaged file (check_map_file: cut short, padded, miscounted, NaN log-odds; not a regular
  /// file) or a resolution outside [1e-4, 100] m.
  static OccupancyMap load(const std::string& path,
                           const std::optional<Eigen::Vector3d>& bounds_min = std::nullopt,
                           const std::optional<Eigen::Vector3d>& bounds_max = std::nullopt,
                           const OccupancyMapOptions& options = {});

  /// Walks the cells OctoMap's computeRayKeys(origin, end) returns, in order (origin cell
  /// first, end cell excluded), calling emit(key) for each; the same float/double arithmetic
  /// as OctoMap, without its fixed 100,000-key buffer. An emit that returns bool ends the walk
  /// by returning false. Returns false when an end is outside the addressable range (nothing
  /// emitted), like computeRayKeys.
  template <typename Emit>
  static bool walk_ray_keys(const octomap::OcTree& tree, const octomap::point3d& origin,
                            const octomap::point3d& end, Emit&& emit);

 private:
  struct EndPoint;  // one end point group of a scan (see integrate)
  struct EndCells {
    std::vector<Key> occupied, free;
  };
  OccupancyMap(std::unique_ptr<octomap::OcTree> tree, const Eigen::Vector3d& bounds_min,
               const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options);
  void init_geometry(const Eigen::Vector3d& bmin, const Eigen::Vector3d& bmax);
  void apply_tree_params();
  CellRule cell_rule() const;
  void grid_from_tree();
  void ensure_scratch();
  std::uint32_t next_stamp(unsigned n);
  /// Cell i's page of the scratch arrays is written (threads may race: the same value).
  void mark_written(std::size_t i) {
    __atomic_store_n(&scratch_written_[i >> kScratchPageShift], std::uint8_t(1), __ATOMIC_RELAXED);
  }
  /// Hands the scratch's pages back once more than kScratchPages have been written since.
  void bound_scratch();
  /// Every page of the scratch back to the kernel (it reads zero), the stamps from the start.
  void release_scratch();

  // integrate after check_scan, and its steps
  IntegrationStats integrate_points(const Eigen::Vector3d& origin, const PointsRef& hits,
                                    const PointsRef& free_ends, double max_range);
  std::vector<std::vector<EndPoint>> collect_end_points(const octomap::point3d& origin,
                                                        const PointsRef& hits,
                                                        const PointsRef& free_ends,
                                                        double max_range) const;
  std::vector<EndPoint> group_end_points(std::vector<std::vector<EndPoint>> candidates,
                                         std::uint32_t stamp);
  EndCells classify_end_cells(const std::vector<EndPoint>& groups, std::uint32_t s_occ,
                              std::uint32_t s_free);
  void trace_free_cells(const octomap::point3d& origin, const std::vector<EndPoint>& groups,
                        std::uint32_t s_occ, std::uint32_t s_free, EndCells& cells);
  /// One miss per key of `misses` and one hit per key of `hits` (disjoint, each key once): the
  /// grid value of each workspace cell becomes OctoMap's updateNode result; cells outside the
  /// workspace are updated in the octree.
  void apply_updates(const std::vector<Key>& misses, const std::vector<Key>& hits);
  /// Sets workspace cell i in the grid and queues it for the octree.
  void set_cell(std::int64_t i, float logodds, CellFlag flag);
  /// Copies every queued grid cell into the octree (tree order), then prunes once.
  void sync_octree() const;
  /// A point's workspace cell from the grid, or another cell from the octree; false: unknown.
  bool find_cell(const Eigen::Vector3d& p, CellFlag& flag, float& logodds) const;
  /// integrate_exact's path: one updateNode on an up-to-date octree, copied into the grid.
  void update_cell(const Key& key, bool hit);

  mutable std::unique_ptr<octomap::OcTree> tree_;
  OccupancyMapOptions opt_;
  double res_ = 0.2;
  Key min_key_;
  WorkspaceGrid grid_;
  float occ_thres_log_ = 0, clamp_min_log_ = 0, clamp_max_log_ = 0, hit_log_ = 0, miss_log_ = 0;
  // workspace cells whose grid value the octree does not hold yet: a bit per cell of each brick,
  // and the bricks holding any
  mutable std::vector<std::uint64_t> stale_cells_;
  mutable std::vector<std::uint32_t> stale_bricks_;

  // integration scratch per workspace cell, made on first integrate. Its pages go back to the
  // kernel (ReleasableArray::release) once the scans since the last release have written more
  // than kScratchPages of them: it holds what recent scans touched, not what the whole mission
  // did (a page written again after a release costs a fault, ~4 us on this project's machine).
  static constexpr int kScratchPageShift = 10;        // 1,024 cells: 4 KiB of either array
  static constexpr std::size_t kScratchPages = 8192;  // 32 MiB of either array
  ReleasableArray<std::uint32_t> stamp_;              // per cell: last stamp written
  ReleasableArray<std::int32_t> group_of_;            // per cell: valid where stamped
  std::vector<std::uint8_t> scratch_written_;         // per page: written since the release
  std::uint32_t stamp_counter_ = 0;
  AccessLock access_;
};

// ---- implementation of the template --------------------------------------------------------

template <typename Emit>
bool OccupancyMap::walk_ray_keys(const octomap::OcTree& tree, const octomap::point3d& origin,
                                 const octomap::point3d& end, Emit&& emit) {
  // Amanatides & Woo 3D-DDA, step for step as octomap::OcTreeBaseImpl::computeRayKeys (1.9.x).
  Key key_origin, key_end;
  if (!tree.coordToKeyChecked(origin, key_origin) || !tree.coordToKeyChecked(end, key_end))
    return false;
  if (key_origin == key_end) return true;
  const auto go_on = [&](const Key& key) {
    if constexpr (std::is_same_v<decltype(emit(key)), bool>) {
      return emit(key);
    } else {
      emit(key);
      return true;
    }
  };
  if (!go_on(key_origin)) return true;

  octomap::point3d direction = (end - origin);
  const float length = (float)direction.norm();
  direction /= length;

  // The state per axis in scalars (an array indexed by the axis stepped lives in memory, and
  // reading a whole key back after writing one of its 16-bit parts stalls every step).
  const double resolution = tree.getResolution();
  const auto start = [&](unsigned i, int& step, double& t_max, double& t_delta) {
    step = direction(i) > 0.0 ? 1 : direction(i) < 0.0 ? -1 : 0;
    if (step != 0) {
      double voxelBorder = tree.keyToCoord(key_origin[i]);
      voxelBorder += (float)(step * resolution * 0.5);
      t_max = (voxelBorder - origin(i)) / direction(i);
      t_delta = resolution / std::fabs(direction(i));
    } else {
      t_max = std::numeric_limits<double>::max();
      t_delta = std::numeric_limits<double>::max();
    }
  };
  int s0, s1, s2;
  double t0, t1, t2, d0, d1, d2;
  start(0, s0, t0, d0);
  start(1, s1, t1, d1);
  start(2, s2, t2, d2);
  int k0 = key_origin[0], k1 = key_origin[1], k2 = key_origin[2];
  const int e0 = key_end[0], e1 = key_end[1], e2 = key_end[2];
  while (true) {
    // OctoMap's choice of axis (ties go to the later axis)
    const bool a01 = t0 < t1, a02 = t0 < t2, a12 = t1 < t2;
    if (a01 && a02) {
      if (unsigned(k0 + s0) > 0xFFFFu) break;  // OctoMap asserts here; never reached in practice
      k0 += s0;
      t0 += d0;
    } else if (!a01 && a12) {
      if (unsigned(k1 + s1) > 0xFFFFu) break;
      k1 += s1;
      t1 += d1;
    } else {
      if (unsigned(k2 + s2) > 0xFFFFu) break;
      k2 += s2;
      t2 += d2;
    }
    if (k0 == e0 && k1 == e1 && k2 == e2) break;
    const double dist_from_origin = std::min(std::min(t0, t1), t2);
    if (dist_from_origin > length) break;
    if (!go_on(Key(octomap::key_type(k0), octomap::key_type(k1), octomap::key_type(k2)))) break;
  }
  return true;
}

namespace detail {
/// Where ray end points fall, OccupancyMap::integrate's first step: for n rows of `rows` (3
/// doubles each, `stride` doubles apart) each end cell's key along each axis (OctoMap's
/// coordToKeyChecked of the point in float: floor(rf * c) + 32768), its sub-cell among k^3 and
/// its squared distance to the sub-cell's centre (cell units), and its state: 1 addressable, 0
/// beyond OctoMap's range, 2 not finite. simd: four rows at a time in AVX2 lanes where the CPU
/// has them (the same numbers to the bit); false: one at a time.
struct EndCellBlock {
  std::int32_t* key[3];  // per axis, n keys
  std::int32_t* sub;
  double* d2;
  std::uint8_t* state;
};
void end_cells(const double* rows, std::size_t stride, std::size_t n, double rf, int k,
               const EndCellBlock& out, bool simd = true);
}  // namespace detail

}  // namespace nbv
