// Next-best-view candidate evaluation (paper sec. 3.4 and the utilities of its peers): validity
// (navigation bounds, collision sphere, flight segment) and a utility per candidate, all in one
// call, by walking the camera's rays through the map's workspace grid (3D-DDA).
//
// A utility is a small policy (cpp/src/utilities/*.hpp) that sees every cell each ray enters,
// in order, and says when the ray stops; cpp/src/utilities/registry.hpp lists them by name. See
// UtilityOptions::name for the list and each header for the exact definition.
#pragma once

#include "nbv/common.hpp"
#include "nbv/grid_view.hpp"
#include "nbv/huge_pages.hpp"
#include "nbv/options.hpp"

#include <array>
#include <cstdint>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

namespace nbv {

class OccupancyMap;

/// The camera model used to score views: a pinhole grid of rays over the field of view.
#define NBV_VIEW_CAMERA_OPTIONS(X)                                                        \
  X(int, rays_x, 47,                                                                      \
    "rays across the horizontal field of view (the authors: one per map cell on the far " \
    "plane, 47 at 0.2 m; ViewCameraModel.for_resolution)")                                \
  X(int, rays_y, 34, "rays across the vertical field of view (34 at 0.2 m)")              \
  X(double, hfov_deg, 60.0, "horizontal field of view, degrees")                          \
  X(double, vfov_deg, 45.0, "vertical field of view, degrees")                            \
  X(double, max_range, 8.0, "depth limit along the optical axis, m")                      \
  X(Eigen::Isometry3d, mount, Eigen::Isometry3d::Identity(),                              \
    "T_body_sensor: the camera's fixed mount on the vehicle (4 x 4)")                     \
  X(double, pixel_pitch_deg, 60.0 / 640.0,                                                \
    "the sensor's angle between neighbouring pixels, degrees (the coarser axis): how "    \
    "densely its samples land, for the surface utility's dense_spacing")

struct ViewCameraModel {
  NBV_VIEW_CAMERA_OPTIONS(NBV_DECLARE_OPTION)

  /// Rays per map-resolution step on the far plane (the authors' choice: 47 x 34 at 0.2 m).
  static ViewCameraModel for_resolution(double hfov_deg, double vfov_deg, double max_range,
                                        double resolution);
  /// (rays_x * rays_y, 3) unit directions in the sensor frame (x forward).
  Points directions() const;
  void validate() const;  ///< throws std::invalid_argument naming the bad field
};

#define NBV_UTILITY_OPTIONS(X)                                                                  \
  X(std::string, name, "ig",                                                                    \
    "ig (paper: entropy of the distinct cells the rays reach, each ray ending at the first "    \
    "occupied cell) | ig_distance (ig * exp(-distance_lambda * d), the authors' option) | "     \
    "occlusion_aware | unobserved_voxel | rear_side_voxel | rear_side_entropy | "               \
    "proximity_count | average_entropy (Isler et al. 2016 / Delmerico et al. 2018) | "          \
    "four_term (Almadhoun et al. 2019) | surface (expected new surface)")                       \
  X(double, distance_lambda, 0.5,                                                               \
    "1/m; ig_distance and four_term weigh the gain by exp(-distance_lambda * d), d the "        \
    "straight distance to the view (authors: 0.5)")                                             \
  X(bool, require_occupied, true,                                                               \
    "a view must see an occupied cell: the first occupied cell of some ray (paper sec. 3.4.2)") \
  X(double, require_occupied_probability, 0.0,                                                  \
    "if > 0, that cell must also have p above it (authors: 0.8)")                               \
  X(double, min_visibility, 1e-3,                                                               \
    "occlusion-aware family: a ray stops when its visibility falls below this")                 \
  X(double, frontier_prior, 0.5,                                                                \
    "surface: probability that an unknown cell next to an occupied or predicted cell (6 "       \
    "faces) holds surface")                                                                     \
  X(double, unknown_prior, 0.005, "surface: the same for any other unknown cell")               \
  X(double, coverage_cone_deg, 75.0,                                                            \
    "surface, four_term: a cell seen by the camera from within this angle of a viewing "        \
    "direction is covered for it")                                                              \
  X(double, density_target, 50.0,                                                               \
    "four_term: camera hits in a cell at which its density counts as full")                     \
  X(double, weight_entropy, 1.0, "four_term: w_H, the weight of the normalised entropy")        \
  X(double, weight_density, 1.0, "four_term: w_rho, the weight of the missing density")         \
  X(double, weight_prediction, 1.0, "four_term: w_p, the weight of the predicted share")        \
  X(double, dense_spacing, 0.0,                                                                 \
    "surface: the sample spacing (m) that dense coverage needs; a cell the camera would see "   \
    "at range r and incidence i counts min(1, dense_spacing * cos(i) / (r * pixel pitch)) "     \
    "(incidence from the cell's open faces; 1 where they give none); 0: no density weight")     \
  X(double, max_incidence_deg, 90.0,                                                            \
    "surface: an observed surface cell counts for a ray that meets it within this angle of "    \
    "its normal (from its open faces; a cell whose open faces give none always counts): a "     \
    "grazing view adds no dense surface; 90: any ray")                                          \
  X(int, incidence_min_patches, 16,                                                             \
    "surface: max_incidence_deg applies to a cell once this many of the 16 squares of its "     \
    "face (a quarter of the resolution on a side, seen along the axis nearest its normal) "     \
    "hold a camera hit: its face is sampled densely (0: every cell)")

struct UtilityOptions {
  NBV_UTILITY_OPTIONS(NBV_DECLARE_OPTION)
  void validate() const;  ///< throws std::invalid_argument naming the bad field or utility
};

#define NBV_VALIDITY_OPTIONS(X)                                                                \
  X(double, collision_radius, 0.8,                                                             \
    "m: every cell within this distance of the view must be known and free")                   \
  X(Eigen::Vector3d, bounds_min, Eigen::Vector3d::Constant(-1e300),                            \
    "navigation bounds, lower corner (m)")                                                     \
  X(Eigen::Vector3d, bounds_max, Eigen::Vector3d::Constant(1e300),                             \
    "navigation bounds, upper corner (m)")                                                     \
  X(std::string, blocked_path, "reject",                                                       \
    "a view whose straight flight from the current pose crosses occupied or unknown space: "   \
    "'reject' it, or 'plan' (not checked here: the caller plans a path through known free "    \
    "space)")                                                                                  \
  X(bool, keep_off_hits, true,                                                                 \
    "given the camera observations, the collision sphere also keeps off every cell the "       \
    "camera has hit (rays passing beside a surface that cuts a cell can carve it free in the " \
    "map); false: off unknown and occupied cells alone (the paper's scenarios)")

struct ValidityOptions {
  NBV_VALIDITY_OPTIONS(NBV_DECLARE_OPTION)
  void validate() const;
};

/// Why a candidate is not valid (0 = valid). The names are view_status_names().
enum class ViewStatus : std::int8_t {
  Valid = 0,
  OutOfBounds = 1,
  Collision = 2,       ///< an occupied or unknown cell within the collision radius
  PathBlocked = 3,     ///< the straight segment crosses occupied or unknown space
  SeesNoOccupied = 4,  ///< the paper's constraint: no occupied cell in view
};
/// "valid", "out_of_bounds", "collision", "path_blocked", "sees_no_occupied", by ViewStatus value.
const std::vector<std::string>& view_status_names();

struct ViewScores {
  Eigen::VectorXd utility;        ///< (K,) the score to maximise; -inf where the view is invalid
  Eigen::VectorXd gain;           ///< (K,) the utility's own value, before any distance weight
  Eigen::VectorXi cells;          ///< (K,) distinct cells that added to the gain
  Eigen::VectorXi occupied_seen;  ///< (K,) rays that reached an occupied cell
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> status;  ///< (K,) ViewStatus
};

/// Candidate views, one a row: (K, 4) x, y, z, yaw (a level camera) or (K, 5) x, y, z, yaw,
/// pitch (the camera gimbal's, radians, > 0 looks down; nbv/common.hpp's Pose).
using ViewPoses = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ViewPosesRef = Eigen::Ref<const ViewPoses>;
/// Row k of `views` as a Pose (pitch 0 where there are 4 columns).
inline Pose view_pose(const ViewPosesRef& views, Eigen::Index k) {
  return {views(k, 0), views(k, 1), views(k, 2), views(k, 3), views.cols() > 4 ? views(k, 4) : 0.0};
}
/// Throws std::invalid_argument unless `views` has 4 or 5 columns of finite numbers and every
/// pitch is within +-pi/2.
void check_view_poses(const ViewPosesRef& views);

/// A candidate view as the key of a memo of walks (ViewMemo, CoverageMemo): its x, y, z, yaw and
/// pitch bit for bit (a pitch of -0.0 keyed as 0.0: both are the level camera). Two pitches at
/// one position are two entries; a level view's key hashes as it did before views had a pitch.
using PoseKey = std::array<std::uint64_t, 5>;
PoseKey pose_key(double x, double y, double z, double yaw, double pitch = 0.0);
inline PoseKey pose_key(const Pose& p) { return pose_key(p.x, p.y, p.z, p.yaw, p.pitch); }
struct PoseKeyHash {
  std::size_t operator()(const PoseKey& k) const;
};
/// What a memo of walks did with the views asked of it, so far.
struct MemoStats {
  std::int64_t reused = 0;   ///< views answered from their record, without a walk
  std::int64_t stale = 0;    ///< views whose record no longer held (then walked)
  std::int64_t walked = 0;   ///< views walked and kept (stale ones included)
  std::int64_t evicted = 0;  ///< records dropped to keep the memo within its bytes (CoverageMemo)
  /// views left unwalked on their recorded estimate, without its coarse walk (CoverageMemo)
  std::int64_t estimated = 0;
};

/// What the paper's IG walks of candidate views found, kept from one scoring call to the next
/// (aeplanner caches gains; this cache is exact). Per candidate pose, its four doubles bit for
/// bit: the distinct cells its rays reached, each with its occupancy then; the cells where rays
/// stopped at an occupied cell; the neutral bricks they stepped over. Where a later call scores
/// the same pose, every kept cell has kept its occupancy and every stepped-over brick is still
/// neutral, each ray would walk the same cells and stop at the same one: the gain is summed again
/// over the kept cells and the stops are counted again, without a walk; otherwise the view is
/// walked and kept anew. The sum is the walk's to the last bit: each cell's entropy is a float of
/// at least 2^-8 (or zero), a multiple of 2^-31, so every partial sum below 2^22 is exact, in any
/// order; a view outside those bounds (only extreme clamping thresholds give such entropies) is
/// walked. Entries that none of the last `keep_calls` calls used are dropped (8: a
/// Scenario 5 mission walks 3.3 % fewer views than with 2, and holds about 1 MB); a call
/// with a different camera or grid geometry clears the memo. Used by the utilities whose walks can
/// be replayed (ig, ig_distance) on the grid; others walk every view.
class ViewMemo {
 public:
  explicit ViewMemo(int keep_calls = 8);

  using Stats = MemoStats;
  Stats stats() const { return stats_; }
  std::size_t entries() const { return entries_.size(); }
  std::size_t bytes() const;  ///< memory held by the entries' arrays
  int keep_calls() const { return keep_calls_; }
  void clear();
  /// Held by a caller for the length of a scoring call when calls may come from several threads.
  std::mutex& mutex() { return mutex_; }

  // ---- for the scoring kernel ----
  /// 64 cells of the grid's layout (one brick: ids 64 word ... 64 word + 63) a view reached.
  struct Word {
    std::uint64_t cells;     ///< bit b: cell 64 word + b was reached
    std::uint64_t occupied;  ///< bit b: ... and was occupied then
    std::uint32_t word;
  };
  struct Entry {
    std::vector<Word> words;
    std::vector<std::uint32_t> stops;   ///< per ray that stopped: its occupied cell's id
    std::vector<std::uint32_t> bricks;  ///< neutral bricks stepped over
    std::int64_t used = 0;              ///< the last call that used or made it
  };
  using Key = PoseKey;
  /// Starts a call: clears the memo if `geometry` (camera and grid) differs from the last call's.
  void begin(const std::vector<double>& geometry);
  const Entry* find(const Key& k) const;
  /// An empty entry to record into, with the arrays of a dropped one (their pages already
  /// touched: a fresh array's first writes cost more than the walk that fills it).
  Entry take();
  /// What a call did with each candidate.
  enum class Outcome : std::uint8_t { NotScored, Reused, Walked, Stale };
  /// Ends a call: keeps the fresh entries, marks the reused ones used, drops the unused.
  void end(const std::vector<Key>& keys, std::vector<Entry>& fresh,
           const std::vector<Outcome>& outcome);

 private:
  int keep_calls_;
  std::int64_t call_ = 0;
  std::vector<double> geometry_;
  std::unordered_map<Key, Entry, PoseKeyHash> entries_;
  std::vector<Entry> spare_;  // dropped entries, for their arrays
  Stats stats_;
  std::mutex mutex_;
};

/// Scores K candidate views (rows x, y, z, yaw or x, y, z, yaw, pitch) from the current pose in
/// one call, in parallel over candidates. Rays are cast from the camera
/// (gimbal_sensor_transform(view, mount): T(x, y, z) Rz(yaw) Ry(pitch) mount) over its field of
/// view to max_range depth and walk the workspace grid; nothing outside the workspace counts.
/// Utilities that read camera observations (surface, four_term) need grid.seen / grid.hits.
/// With a memo (kept by the caller across calls), views of the ig utilities scored before at the
/// same pose may be re-summed from their record instead of walked: the same scores.
/// Throws std::invalid_argument for non-finite candidates, a pitch beyond +-pi/2, or bad
/// options.
ViewScores evaluate_views(const GridView& grid, const ViewPosesRef& candidates, const Pose& current,
                          const ViewCameraModel& camera, const UtilityOptions& utility,
                          const ValidityOptions& validity, ViewMemo* memo = nullptr);

/// The same scores reading each cell through OctoMap's search (one tree descent per cell
/// visit), as the authors' implementation did: the reference the grid walk must agree with, and
/// the benchmark baseline. Validity checks still use the grid.
ViewScores evaluate_views_octree(const OccupancyMap& map, const ViewPosesRef& candidates,
                                 const Pose& current, const ViewCameraModel& camera,
                                 const UtilityOptions& utility, const ValidityOptions& validity,
                                 const SurfaceObservations* surface = nullptr);

/// What the camera rays of K candidate views reach (candidate_rays), for a utility written
/// elsewhere (in Python) over them. Per candidate k, its cells are the rows
/// [offsets[k], offsets[k + 1]) of the per-cell arrays, in the order its rays first reached them
/// (ray by ray, each from the camera outwards): the DISTINCT workspace cells its rays entered.
struct CandidateRays {
  template <class T>
  using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  Vector<std::int64_t> offsets;  ///< (K + 1,) offsets[0] = 0, offsets[K] = N
  // Per cell, N each (3 N for centers); in huge pages where the kernel offers them, first
  // touched by the threads that fill them: on this project's virtual machine the page faults of
  // first writes to fresh 4 KiB pages cost more than the walks (huge_pages.hpp).
  /// the cell's flat workspace index i + nx (j + ny k) (OccupancyMap.index_of's)
  HugeBuffer<std::int64_t> index;
  HugeBuffer<double> centers;      ///< (N, 3) row-major: cell centres, world frame (m)
  HugeBuffer<double> probability;  ///< occupancy probability sigmoid(log-odds); unknown 0.5
  HugeBuffer<float> logodds;       ///< the map's log-odds, as it holds them; unknown 0
  HugeBuffer<std::int8_t> state;   ///< CellState: -1 unknown, 0 free, 1 occupied
  /// metres from the camera to where a ray entered the cell, the smallest over the rays (0 for
  /// the camera's own cell; where the camera is outside the workspace, a ray's first cell is
  /// entered where the ray enters the workspace)
  HugeBuffer<double> range;
  /// radians in [0, pi/2], for the ray of the smallest range (the first of equal ones): the angle
  /// between it and the cell's normal: for an occupied cell, the surface normal the surface
  /// utility estimates (utility::open_face_normal), for other cells, and for an occupied one
  /// whose open faces give no normal, the normal of the face the ray entered through. NaN for
  /// the camera's own cell (entered through no face).
  HugeBuffer<double> incidence;
  /// with camera observations (grid.seen / grid.hits; `observed`): the cell's direction-bin mask
  /// and camera hits; empty without
  HugeBuffer<std::uint32_t> seen;
  HugeBuffer<std::uint16_t> hits;
  bool observed = false;
  /// (K,) rays that ended at an occupied cell of log-odds above require_occupied_probability's
  /// (evaluate_views' occupied_seen)
  Eigen::VectorXi occupied_seen;
  /// (K,) ViewStatus, as evaluate_views gives it for the same utility options. Views out of
  /// bounds, in collision or with a blocked path were not walked: they have no cells. A view
  /// that sees no occupied cell (SeesNoOccupied) keeps the cells it reached.
  Vector<std::int8_t> status;
  Eigen::Index size() const { return status.size(); }     ///< K
  std::size_t num_cells() const { return index.size(); }  ///< N
  Eigen::Vector3d center(std::size_t i) const {
    return {centers[3 * i], centers[3 * i + 1], centers[3 * i + 2]};
  }
};

/// The most cells candidate_rays returns in one call: half the memory this process may use (the
/// machine's, or its address-space limit where lower), at kCandidateCellBytes a cell (its arrays
/// and the walk's record). 12,000 views of a 0.1 m map, 0.33 MB each, had no bound.
std::size_t max_candidate_cells();
constexpr std::size_t kCandidateCellBytes = 91;

/// Walks the camera rays of K candidate views (rows as evaluate_views' candidates) exactly as
/// evaluate_views does - the same rays (camera.directions() on the gimbal), each ending at its
/// first occupied cell (inclusive), at the camera's max_range depth or where it leaves the
/// workspace - and records the distinct cells each view's rays reached (CandidateRays). One call
/// for all candidates, in parallel over them; each candidate's cells do not depend on the
/// threads. Validity and status as evaluate_views's; of `utility` only require_occupied and
/// require_occupied_probability are read (they decide SeesNoOccupied and occupied_seen).
/// Throws std::invalid_argument for non-finite candidates, a pitch beyond +-pi/2, or bad
/// options; std::length_error once their cells pass max_candidate_cells() (a memory bound).
CandidateRays candidate_rays(const GridView& grid, const ViewPosesRef& candidates,
                             const Pose& current, const ViewCameraModel& camera,
                             const UtilityOptions& utility, const ValidityOptions& validity);

/// Names of the registered utilities.
std::vector<std::string> utility_names();

/// Number of map cells a camera frustum can observe (paper Eq. 5): V_frustum / V_cell, or with
/// count_partial the expected number of cells the frustum touches, partial boundary cells
/// included: vol(F (+) cell) / V_cell, the volume of the frustum's Minkowski sum with one cell
/// (exact for a convex body and an axis-aligned cell, here for the frustum at zero yaw).
double viewable_cells(double hfov_deg, double vfov_deg, double min_range, double max_range,
                      double resolution, bool count_partial);

}  // namespace nbv
