// Surface coverage planning blocks: where surface still needs observing (surface targets), what
// each candidate view would newly cover (coverage sets), and a greedy choice of views that
// covers the most (set cover).
#pragma once

#include "nbv/common.hpp"
#include "nbv/grid_view.hpp"
#include "nbv/options.hpp"
#include "nbv/views.hpp"

#include <array>
#include <cstdint>
#include <limits>
#include <mutex>
#include <unordered_map>
#include <utility>
#include <vector>

namespace nbv {

#define NBV_SURFACE_TARGET_OPTIONS(X)                                                          \
  X(double, coverage_cone_deg, 75.0,                                                           \
    "an open side of a surface cell is covered once the camera has seen the cell from within " \
    "this angle of it")                                                                        \
  X(bool, observed, true, "occupied cells the camera has not covered from every open side")    \
  X(bool, predicted, true, "cells predicted by symmetry")                                      \
  X(bool, frontier, true,                                                                      \
    "unknown cells between known free space and surface (a face neighbour occupied or "        \
    "predicted, another free)")                                                                \
  X(double, frontier_weight, 0.5, "weight of a frontier target (observed ones weigh 1)")

struct SurfaceTargetOptions {
  NBV_SURFACE_TARGET_OPTIONS(NBV_DECLARE_OPTION)
  void validate() const;
};

/// Target kinds. Exploration: unknown space on the face of known free space, away from the
/// surface (exploration_targets).
enum class TargetKind : std::int8_t { Observed = 0, Predicted = 1, Frontier = 2, Exploration = 3 };

/// Cells whose surface still needs observing, in grid id order. normal: the unit direction from
/// which the cell can still add surface (the sum of its open neighbour directions not yet
/// covered; for frontier cells, of its free neighbours); weight: 1 (observed), the predicted
/// probability, or frontier_weight.
struct SurfaceTargets {
  Points positions;  ///< (T, 3) cell centres
  Points normals;    ///< (T, 3) unit vectors
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> kind;
  Eigen::VectorXd weight;
};

/// Needs the camera observations (grid.seen). Parallel over bricks; deterministic.
SurfaceTargets surface_targets(const GridView& grid, const SurfaceTargetOptions& options);

/// The unknown space a view could open (the coverage tour's exploration targets): unknown cells
/// with a known free face neighbour and no occupied or predicted one, among the cells of the box
/// [lo, hi) (cell indices; neighbours outside it count as neither). cells (T, 3) in C order of
/// (i, j, k) (k fastest); free_sides (T, 3) per cell the sum over its free face neighbours of the
/// direction to them (each component -1, 0 or 1; zero where free lies on opposite faces only).
struct ExplorationTargets {
  Eigen::Matrix<std::int32_t, Eigen::Dynamic, 3, Eigen::RowMajor> cells;
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 3, Eigen::RowMajor> free_sides;
};

/// The box of the cells known occupied or predicted, grown by one cell and clipped to the grid,
/// as [lo, hi) cell indices; false when the map holds none.
bool structure_extent(const GridView& grid, Eigen::Vector3i& lo, Eigen::Vector3i& hi);

/// exploration_targets over the box [lo, hi) (clipped to the grid). Parallel over bricks; one
/// pass, without a copy of the grid.
ExplorationTargets exploration_targets(const GridView& grid, Eigen::Vector3i lo,
                                       Eigen::Vector3i hi);

/// Whether each of `points` (N, 3) lies within `within` metres (finite, > 0) of one of `solid`
/// (M, 3), measured as scipy's distance_transform_edt measures it on a grid of cells of
/// max(within / 4, resolution) spanning both: from a point's cell to the nearest cell holding a
/// solid point, centre to centre (exact to a quarter of `within` times the square root of 3 either
/// way). Nothing is kept when `solid` is empty. Through the ball of that radius: round each point
/// where there are fewer points than solid cells, else round each solid cell. A grid of more
/// than 5e8 cells (a byte each) is refused (std::invalid_argument naming `within`).
std::vector<std::uint8_t> near_points(const PointsRef& solid, const PointsRef& points,
                                      double within, double resolution);

/// Exploration targets as targets to place views at (kind Exploration, weight 1): each cell's
/// centre, origin + (cell + 0.5) * resolution (as origin + start * resolution + (cell - start +
/// 0.5) * resolution, start the box's first cell), looked at from the unit sum of the directions
/// to its free neighbours; cells free on opposite faces only (no such side) are left out.
SurfaceTargets exploration_as_targets(const ExplorationTargets& targets,
                                      const Eigen::Vector3d& origin, const Eigen::Vector3i& start,
                                      double resolution);

/// What each candidate view would newly cover, as the surface utility credits it: elements
/// (cell id * 2 + the side of the cell it is seen from) with their expected weight (P_vis *
/// probability of surface), each at most once per view. A cell's sides come from its open
/// neighbours (free or unknown, 26-neighbourhood): a surface open on one side has one side, so
/// views from any angle of it count the cell once; a thin part open on both sides (their
/// directions summing to little) is split along the axis its open directions spread most on.
/// With pool_unknown, unknown space away from surface is one element per brick past those
/// (pooled_element). CSR by candidate; invalid candidates (status != 0) have none. Elements are
/// 32-bit (a grid of up to 2^30 cells; OccupancyMap holds at most 400 M): a large plan holds
/// tens of millions.
struct ViewCoverage {
  Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1> offsets;  ///< (K + 1,)
  Eigen::Matrix<std::int32_t, Eigen::Dynamic, 1> elements;
  Eigen::VectorXf weights;
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> status;  ///< (K,) ViewStatus
  /// (K,) 1: a valid view its coarse walk estimated below min_gain, not walked (coarse_stride)
  Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1> pruned;
  /// (K,) a valid view's gain in cells (the utility's sum over its walk; a pruned view's
  /// estimate); 0 for the others
  Eigen::VectorXd gain;
  /// Elements from here on are pooled bricks of unknown space (pool_unknown; else none), each
  /// holding at most pool_cap (its 64 cells at the unknown prior)
  std::int64_t pooled_from = kNotPooled;
  double pool_cap = 0.0;
  static constexpr std::int64_t kNotPooled = std::numeric_limits<std::int64_t>::max();
};

/// A read-only view of coverage arrays (a ViewCoverage, or arrays held elsewhere: numpy's, by the
/// bindings, without a copy).
struct CoverageRef {
  Eigen::Ref<const Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1>> offsets;
  Eigen::Ref<const Eigen::Matrix<std::int32_t, Eigen::Dynamic, 1>> elements;
  Eigen::Ref<const Eigen::VectorXf> weights;
  Eigen::Ref<const Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1>> status;
  std::int64_t pooled_from = ViewCoverage::kNotPooled;  ///< as ViewCoverage's
  double pool_cap = 0.0;
  CoverageRef(const ViewCoverage& c)  // NOLINT: a ViewCoverage is its own view
      : offsets(c.offsets),
        elements(c.elements),
        weights(c.weights),
        status(c.status),
        pooled_from(c.pooled_from),
        pool_cap(c.pool_cap) {}
  CoverageRef(decltype(offsets) o, decltype(elements) e, decltype(weights) w, decltype(status) st)
      : offsets(o), elements(e), weights(w), status(st) {}
};

/// What view_coverage walks found, kept from one call to the next (the same answers, fewer walks).
/// Per candidate pose, its four doubles bit for bit: the view's coverage set, gain, cell count
/// and occupied rays, and the epochs of the map's and the camera observations' stamps it was
/// walked at (GridView). A later call over the same map and observations takes the record
/// instead of walking while no brick that meets the view's frustum (its camera's field of view
/// out to max_range) has changed in the camera observations since, and no brick within one brick
/// of one that does in the map: a view's walk reads the observations of the cells its rays
/// enter, all within the frustum, and the map's cells around them too (for the utility's
/// frontier test, a cell's surface normal and a coverage element's side), all within one cell
/// of a cell it entered. The frustum holds more than the rays reach (the space behind the
/// surface they stop at): a record is dropped for some changes that would not change the walk,
/// never kept through one that would, and costs the walk nothing to make. A view left unwalked
/// on its coarse estimate (view_coverage's coarse_stride) is kept too, as that estimate: while
/// it holds, a later call at the same stride compares it with its min_gain without walking the
/// coarse rays again (the same estimate). Validity (bounds,
/// collision, path) is checked anew in every call. Entries that none of the last `keep_calls`
/// calls used are dropped; a call over another map or observation record, or with another
/// camera, grid or utility, clears the memo. Grids of 2^31 cells or more are walked every time
/// (elements are kept in 32 bits).
class CoverageMemo {
 public:
  /// max_bytes: records beyond it are dropped at the end of a call, those used longest ago
  /// first (a view is then walked again when next asked: the same answers, more time).
  static constexpr std::size_t kDefaultMaxBytes = std::size_t(256) << 20;
  explicit CoverageMemo(int keep_calls = 3, std::size_t max_bytes = kDefaultMaxBytes);

  using Stats = MemoStats;
  Stats stats() const { return stats_; }
  std::size_t entries() const { return entries_.size(); }
  std::size_t bytes() const;  ///< memory held by the entries' arrays
  int keep_calls() const { return keep_calls_; }
  std::size_t max_bytes() const { return max_bytes_; }
  void clear();
  /// Held by a caller for the length of a call when calls may come from several threads.
  std::mutex& mutex() { return mutex_; }

  // ---- for view_coverage ----
  struct Entry {
    std::vector<std::pair<std::uint32_t, float>> set;  ///< (element, weight), by element
    double gain = 0.0;
    int cells = 0, occupied = 0;
    /// > 0: the record of a view left unwalked at this coarse_stride: gain is its estimate, and
    /// it holds no set
    int coarse_stride = 0;
    std::uint32_t grid_epoch = 0, seen_epoch = 0;
    std::int64_t used = 0;  ///< the last call that used or made it
  };
  using Key = PoseKey;
  /// Starts a call over `grid` (its stamps and epochs) with `geometry` (camera, grid, utility):
  /// clears the memo if either differs from the last call's; false if this grid cannot be kept.
  bool begin(const GridView& grid, const std::vector<double>& geometry);
  /// The entry of `key` if it holds for this call's grid, else null (a record that no longer
  /// holds is replaced by the view's new walk, and counted stale, in end()). sensor: the view's
  /// camera pose (gimbal_sensor_transform), camera: the camera its rays are walked with.
  const Entry* find(const Key& key, const Eigen::Isometry3d& sensor,
                    const ViewCameraModel& camera) const;
  /// Ends a call: keeps `fresh[k]` for each walked view (walked[k] == 1; 2: walked, its record
  /// not kept, and any older one dropped; 3: left unwalked, the record of its estimate), marks
  /// the reused ones used (reused[k] == 1: its record; 2: its estimate), drops the unused.
  void end(const std::vector<Key>& keys, std::vector<Entry>& fresh,
           const std::vector<std::uint8_t>& walked, const std::vector<std::uint8_t>& reused);
  /// The bytes a record holds with `elements` coverage elements and their weights: what bytes()
  /// counts of it, and what max_bytes bounds.
  static std::size_t entry_bytes(const Entry& e, std::size_t elements);

 private:
  int keep_calls_;
  std::size_t max_bytes_;
  std::int64_t call_ = 0;
  std::vector<double> geometry_;
  std::uint64_t grid_id_ = 0, seen_id_ = 0;
  /// Whether a brick that meets the frustum of the camera at `sensor` changed after the epochs.
  bool frustum_changed(const Eigen::Isometry3d& sensor, const ViewCameraModel& camera,
                       std::uint32_t grid_epoch, std::uint32_t seen_epoch) const;
  std::vector<std::uint32_t> near_grid_;        // per brick: the newest map stamp within one brick
  const std::uint32_t* seen_stamps_ = nullptr;  // the call's camera observation stamps
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();  // the call's grid: its corner, cell size
  double resolution_ = 1.0;
  std::array<int, 3> bricks_{0, 0, 0};  // and bricks per axis
  std::unordered_map<Key, Entry, PoseKeyHash> entries_;
  Stats stats_;
  std::mutex mutex_;
};

/// With a memo (kept by the caller across calls over the same map and observations), views
/// walked in an earlier call whose record still holds are answered from it: the same arrays.
/// With min_gain > 0 a valid candidate whose weights sum below it keeps its status and an empty
/// set: select_tours and select_tour at that min_gain or above choose the same views and gains
/// (they never take such a candidate), from arrays a plan at a high gain level holds a few
/// hundred of tens of thousands of sets in.
/// With min_gain > 0 and coarse_stride > 0, each candidate not answered by the memo is first
/// walked along every coarse_stride-th ray across and down: the rays' gain plus one fully
/// weighted cell (one they missed), times all rays over those, estimates its gain (high for
/// surface near the camera, where several rays reach each cell; a sample at the far range). One
/// estimated below coarse_margin x min_gain gets an empty set without its whole walk (pruned =
/// 1); the others are walked whole, as without it. With stride 1 and margin 1 the estimate is
/// the gain plus one cell: the same arrays as with coarse_stride 0. A margin above 1 answers
/// the estimate's bias (2.5-3 x the walked gain on the aircraft, docs/RESULTS.md): fewer walks
/// that end below min_gain, and a few views that would reach it left out.
/// With pool_unknown, the credits of unknown cells at the utility's unknown_prior (not next to
/// surface: the bulk of a view's elements, 85-96 % on a 100 m plant, and 3-16 % of its weight)
/// are pooled per brick of 4 x 4 x 4 cells: one element per brick a view's rays credit so, past
/// every cell's (pooled_element(grid, brick)), weighing the sum of the view's credits in it.
/// Its gain and status are unchanged. The selections (select_cover, select_tour) count a pooled
/// brick's cover as the share of its cap (pool_cap: its 64 cells at the unknown prior) covered,
/// the views' cells in it taken as spread at random: a view of weight w adds w (1 - F) to a
/// brick F of which is covered, and F grows by w / cap of what is left (a cell's element adds
/// what its weight exceeds the most it was covered with). Plans hold 12-30x fewer elements on a
/// large structure.
ViewCoverage view_coverage(const GridView& grid, const ViewPosesRef& candidates,
                           const Pose& current, const ViewCameraModel& camera,
                           const UtilityOptions& utility, const ValidityOptions& validity,
                           CoverageMemo* memo = nullptr, double min_gain = 0.0,
                           int coarse_stride = 0, bool pool_unknown = false,
                           double coarse_margin = 1.0);
/// The coverage element of the pooled unknown space of `brick` (view_coverage's pool_unknown):
/// 2 x the grid's cells + brick, past every cell's element (cell x 2 + side).
inline std::uint32_t pooled_element(const GridView& grid, std::size_t brick) {
  return std::uint32_t(grid.storage_size() * 2 + brick);
}

/// Greedy weighted set cover: repeatedly the view whose not-yet-covered elements weigh most
/// (a cell's element counts its weight once covered; a pooled brick's, see view_coverage), until
/// the best adds less than min_gain or max_views are chosen. Lazy evaluation; ties to the lower
/// index. Returns the chosen view indices in the order chosen and each one's marginal gain.
struct CoverSelection {
  std::vector<int> views;
  std::vector<double> gains;
};
CoverSelection select_cover(const CoverageRef& coverage, double min_gain, int max_views);

/// Prize-collecting tour by greedy cheapest insertion: starting from an open tour at `start`,
/// repeatedly insert the candidate (positions (K, 3)) maximising gain - rate * insertion cost,
/// where gain is what it adds to the elements covered so far (as select_cover) and the insertion
/// cost is the extra length of the open tour with it in its best place (between two stops, or
/// at the end), until no candidate adds at least min_gain with a positive value or max_views
/// are in. `rate`: element weight per metre. charge_transit = false: the first view enters
/// free of the flight from `start` to it (the best gain anywhere), so that a cluster of views
/// that together pay for their transit, none of which would alone, can be built; whether the
/// transit is worth it is then for the caller to judge (a prize-collecting pass over the tour).
/// Returns the tour order (candidate indices, start excluded) and each view's gain when it was
/// inserted. Deterministic; ties to the lower index.
CoverSelection select_tour(const CoverageRef& coverage, const PointsRef& positions,
                           const Eigen::Vector3d& start, double rate, double min_gain,
                           int max_views, bool charge_transit = true);
/// select_tour once for each of `charges` (charge_transit), in parallel, over one inverse of the
/// coverage (built once): the same tours as a select_tour call each.
std::vector<CoverSelection> select_tours(const CoverageRef& coverage, const PointsRef& positions,
                                         const Eigen::Vector3d& start, double rate, double min_gain,
                                         int max_views, const std::vector<bool>& charges);

}  // namespace nbv
