// Scoring a reconstructed point cloud against ground truth (a mesh, sampled, or a point cloud):
// the paper's cell-count coverage, area coverage, precision, completeness / accuracy / F-score
// at distance thresholds, and the Chamfer distance.
#pragma once

#include "nbv/common.hpp"
#include "nbv/kdtree.hpp"
#include "nbv/mesh.hpp"
#include "nbv/options.hpp"
#include "nbv/point_cloud.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace nbv {

/// Default ground-truth sampling density (points per m^2), chosen by measurement on the 727 m^2
/// twinjet (../shared/meshes/twinjet.obj); see the docstring of nbvkit.evaluate for the figures.
constexpr double kDefaultGtDensity = 1000.0;

#define NBV_EVALUATION_OPTIONS(X)                                                           \
  X(std::vector<double>, resolutions, (std::vector<double>{0.05, 0.1, 0.5}),                \
    "m; cell sizes of the coverage / area-coverage / precision grids (the paper's three)")  \
  X(std::vector<double>, taus, (std::vector<double>{0.05, 0.1}),                            \
    "m; distance thresholds of completeness / accuracy / F-score")                          \
  X(double, gt_density, kDefaultGtDensity,                                                  \
    "ground-truth samples per m^2 of mesh surface (mesh ground truth only)")                \
  X(std::uint64_t, seed, 0, "seed of the ground-truth surface sampling")                    \
  X(std::uint64_t, max_gt_points, 8'000'000,                                                \
    "upper bound on the number of ground-truth samples (area * density is capped to it)")   \
  X(std::uint64_t, part_points, std::uint64_t(1) << 22,                                     \
    "distances are scored one part of the cloud at a time, a kd-tree of at most this many " \
    "points (about 54 bytes each) at once; the same figures, but for the rounding of the "  \
    "mean distances")

struct EvaluationOptions {
  NBV_EVALUATION_OPTIONS(NBV_DECLARE_OPTION)

  void validate() const;
};

struct EvaluationResult {
  std::vector<double> resolutions, taus;
  // Per resolution:
  std::vector<double> coverage;       ///< GT cells also holding a cloud point / GT cells
  std::vector<double> area_coverage;  ///< GT samples whose cell holds a cloud point / GT samples
  std::vector<double> precision;      ///< cloud cells also holding a GT sample / cloud cells
  std::vector<std::int64_t> gt_cells, cloud_cells, covered_cells;
  // Per resolution, relative to the observable surface (only if has_observable; see
  // Evaluator::set_observable): a cell is observable if it holds an observable GT sample.
  bool has_observable = false;
  std::vector<double> coverage_observable;       ///< covered observable cells / observable cells
  std::vector<double> area_coverage_observable;  ///< observable samples in covered cells / obs.
  /// every GT sample (observable or not) in the covered cells that hold an observable sample / GT
  /// samples: with area_coverage and area_coverage_observable it splits the covered unobservable
  /// samples into those sharing a cell with observable ones (a thin part's far face) and the rest
  std::vector<double> area_coverage_observable_cells;
  std::vector<double> observable_fraction;  ///< observable cells / GT cells
  std::vector<std::int64_t> observable_cells, covered_observable_cells;
  double observable_area_fraction = 0;  ///< observable GT samples / GT samples (area share)
  // Per tau:
  std::vector<double> completeness;  ///< GT samples within tau (<=) of a cloud point / GT samples
  std::vector<double> accuracy;      ///< cloud points within tau (<=) of a GT sample / cloud points
  std::vector<double> fscore;        ///< 2PR / (P + R), P = accuracy, R = completeness; 0 if both 0
  /// 0.5 * (mean cloud->GT + mean GT->cloud nearest distance), metres; valid only if has_chamfer
  /// (false for an empty cloud).
  bool has_chamfer = false;
  double chamfer = 0, mean_cloud_to_gt = 0, mean_gt_to_cloud = 0;
  std::int64_t n_points = 0, n_gt_points = 0;
  bool from_mesh = false;  ///< GT was a mesh (sampled) rather than a reference cloud
  double gt_density = 0;   ///< samples per m^2 actually used (mesh GT only)
  double gt_area = 0;      ///< mesh surface area, m^2 (mesh GT only)
  std::uint64_t seed = 0;
  std::vector<std::string> warnings;                      ///< e.g. the GT sample count was capped
  std::vector<std::pair<std::string, double>> timings_s;  ///< wall time of each phase, seconds
};

/// Ground truth prepared once (samples, their cells at every resolution, and their kd-tree, built
/// by the first call that needs distances, which then holds the samples) to score any number of
/// clouds against it, e.g. every few iterations of a mission: the progress refreshes need the
/// cells alone, so a mission holds 8 M samples as points (0.2 GB) and not as a tree (0.4 GB)
/// until its final results.
class Evaluator {
 public:
  /// Samples the mesh uniformly at options.gt_density points per m^2:
  /// Mesh::sample_surface(round(area * density), seed), capped at max_gt_points with a warning
  /// in the results. Throws std::invalid_argument for bad options or a density so low that no
  /// sample would be drawn. When a copy of the mesh is smaller than the samples (a large
  /// structure's 8 M samples are 192 MB), it keeps the mesh instead and draws the same samples
  /// again when they are next needed (gt_points, set_observable, the distances' kd-tree).
  explicit Evaluator(const Mesh& gt, const EvaluationOptions& options = {});
  /// Uses a reference (ground-truth) point cloud as is. Throws std::invalid_argument if it is
  /// empty or holds NaN/inf.
  explicit Evaluator(const PointsRef& gt_points, const EvaluationOptions& options = {});

  /// Scores `cloud` (N, 3). Throws std::invalid_argument naming "cloud" for NaN/inf. An empty
  /// cloud gives zero fractions and no Chamfer distance. Const and thread-safe.
  EvaluationResult evaluate(const PointsRef& cloud) const;
  /// evaluate() of the clouds' points one cloud after the other (stack_points), the same
  /// result, read in place: no stacked copy, and a kd-tree over one part of them at a time
  /// (EvaluationOptions::part_points).
  EvaluationResult evaluate(const std::vector<const SurfaceCloud*>& clouds) const;
  /// The cell counts of evaluate() alone (coverage, area coverage, precision and their cells),
  /// without the kd-tree and distances: the same figures at a fraction of the cost, e.g. for a
  /// mission's progress reports. Completeness, accuracy, F-score and Chamfer stay zero / absent.
  EvaluationResult evaluate_cells(const PointsRef& cloud) const;
  /// evaluate_cells of the clouds' points one after the other (the same result as of their
  /// points() stacked), read in place: no copy of a cloud of millions of points.
  EvaluationResult evaluate_cells(const std::vector<const SurfaceCloud*>& clouds) const;

  /// Marks which ground-truth samples (in gt_points() order) are observable (see
  /// observable_samples): every later result also reports coverage relative to them. An empty
  /// mask clears it. Throws std::invalid_argument for a mask of the wrong length. Not
  /// thread-safe against concurrent evaluations.
  void set_observable(const std::vector<std::uint8_t>& mask);
  bool has_observable() const { return !observable_.empty(); }
  /// Changes with every set_observable (for CoverageTracker).
  std::uint64_t observable_version() const { return observable_version_; }

  const EvaluationOptions& options() const { return opt_; }
  std::size_t num_gt_points() const { return n_gt_; }
  /// The ground-truth points (samples in sampling order, or the reference cloud): a copy.
  Points gt_points() const;
  /// The ground truth's kd-tree (e.g. for nearest_distances to it), built on first use
  /// (thread-safe) and kept.
  const KdTree& gt_tree() const;
  /// Description of the ground truth as it appears in every result (density, area, warnings).
  const EvaluationResult& gt_info() const { return base_; }

 private:
  static std::pair<Points, EvaluationResult> sample_mesh(const Mesh& gt,
                                                         const EvaluationOptions& options);
  Evaluator(std::pair<Points, EvaluationResult>&& sampled, const EvaluationOptions& options);
  Evaluator(const PointsRef& gt, const EvaluationOptions& options, EvaluationResult base);
  EvaluationResult empty_result(std::int64_t n_points) const;
  /// What a cloud's cells hold at one resolution (see set_cell_figures).
  struct CellTally {
    std::int64_t cloud_cells = 0;  ///< distinct cloud cells
    std::int64_t in_gt = 0;        ///< ... that are GT cells
    std::int64_t covered = 0;      ///< GT cells holding a cloud point
    std::int64_t covered_samples = 0, covered_obs = 0, covered_obs_samples = 0;
    std::int64_t covered_obs_cell_samples = 0;  ///< every sample of the covered observable cells
  };
  /// Writes res's cell figures of resolution k (res from empty_result).
  void set_cell_figures(std::size_t k, const CellTally& t, EvaluationResult& res) const;
  /// Fills res's figures of resolution k from the cloud's n cell keys at that resolution.
  void score_cells(std::size_t k, const std::uint64_t* keys, std::size_t n,
                   EvaluationResult& res) const;
  /// evaluate()'s cells and distances of a cloud of n points, point(i) for i in [0, n) (called
  /// in parallel).
  EvaluationResult score(std::size_t n,
                         const std::function<Eigen::Vector3d(std::size_t)>& point) const;
  struct Grid {
    double r = 0;
    VoxelIndex index;                               ///< GT cell key -> position in samples
    std::vector<std::uint32_t> samples;             ///< GT samples in each cell
    std::vector<std::uint32_t> observable_samples;  ///< observable GT samples in each cell
    std::int64_t observable_cells = 0;
  };
  friend class CoverageTracker;
  std::vector<std::uint8_t> observable_;  ///< per GT sample (constructor order), or empty
  std::int64_t n_observable_ = 0;
  std::uint64_t observable_version_ = 0;
  EvaluationOptions opt_;
  EvaluationResult base_;
  /// Cell keys of the ground truth's points, in order; throws if one is too far from the origin.
  /// `drawn`: the samples drawn again (sample_again), when neither gt_ nor the tree holds them.
  std::vector<std::uint64_t> gt_cell_keys(double r, const Points* drawn = nullptr) const;
  /// Whether the samples must be drawn again (sample_again) to be read.
  bool redraw() const { return !tree_ && mesh_ && gt_.rows() == 0; }
  /// The mesh's samples drawn again: the same points as at construction.
  Points sample_again() const { return mesh_->sample_surface(n_gt_, opt_.seed); }
  std::size_t n_gt_ = 0;
  mutable Points gt_;  ///< the samples until the tree is built (then empty; empty with mesh_)
  std::shared_ptr<const Mesh> mesh_;  ///< kept in place of the samples (see the constructor)
  mutable std::mutex tree_mutex_;
  mutable std::unique_ptr<KdTree> tree_;  ///< of the samples, made by gt_tree()
  std::vector<Grid> grids_;
};

/// Evaluator::evaluate_cells of growing SurfaceClouds, kept up to date between calls: a mission's
/// progress refreshes. Each call returns exactly what evaluate_cells(clouds) would, but only the
/// voxels added or moved since the last call are looked at again.
///
/// A SurfaceCloud grows by add(): voxels are appended, and a voxel's centroid moves exactly when
/// its point count changes. The tracker keeps, per point, the count it last saw and the cell it
/// lies in at every resolution (4 + 4 per resolution bytes), and per cloud cell the number of
/// points in it; a cloud cell holding a point that is also a GT cell is a covered cell. A call
/// re-keys only the points whose count changed, moves those whose cell changed, and adds the new
/// ones. A cloud that was cleared or replaced (another stamp()), or a different number of clouds,
/// starts that cloud's (or every) count again.
///
/// Holds a reference to the Evaluator, which must outlive it. Not thread-safe.
class CoverageTracker {
 public:
  explicit CoverageTracker(const Evaluator& evaluator);
  /// The figures of evaluator.evaluate_cells(clouds) for the clouds as they are now. Throws
  /// std::invalid_argument (nothing changed) if a point is too far from the origin for a grid.
  EvaluationResult update(const std::vector<const SurfaceCloud*>& clouds);
  /// Bytes held (per-point and per-cell state).
  std::size_t bytes() const;

 private:
  struct Cloud {
    std::uint64_t stamp = 0;
    GrowArray<std::uint32_t> count;              ///< per point: the voxel count last seen
    std::vector<GrowArray<std::uint32_t>> cell;  ///< per resolution and point: its cell (id)
  };
  struct Cells {                   ///< one resolution's cloud cells
    VoxelIndex index;              ///< key -> dense id
    HugeVector<std::uint32_t> n;   ///< points in the cell
    HugeVector<std::uint32_t> gt;  ///< the GT cell (Evaluator::Grid position) or kMissing
    std::int64_t occupied = 0;     ///< cells with n > 0
    std::int64_t covered = 0;      ///< ... of which GT cells
    std::int64_t covered_samples = 0, covered_obs = 0, covered_obs_samples = 0;
    std::int64_t covered_obs_cell_samples = 0;  ///< every sample of the covered observable cells
  };
  void reset();
  std::uint32_t cell_of(std::size_t k, std::uint64_t key);
  void add_point(std::size_t k, std::uint32_t cell);
  void remove_point(std::size_t k, std::uint32_t cell);
  void count_observable(std::size_t k);

  const Evaluator& ev_;
  std::vector<Cloud> clouds_;
  std::vector<Cells> cells_;
  std::uint64_t observable_version_ = 0;
};

/// Evaluator(gt, options).evaluate(cloud): scores `cloud` (N, 3) against a mesh sampled at
/// options.gt_density points per m^2.
EvaluationResult evaluate(const Mesh& gt, const PointsRef& cloud,
                          const EvaluationOptions& options = {});

/// Evaluator(gt, options).evaluate(cloud) with a reference (ground-truth) point cloud (M, 3).
EvaluationResult evaluate_points(const PointsRef& gt, const PointsRef& cloud,
                                 const EvaluationOptions& options = {});

/// The packed key (pack_voxel) of each point's cell on the evaluation's grid of cell r (m),
/// anchored at the origin: a coordinate on a cell boundary, up to rounding, is in the cell above
/// (try_cell_key). Throws std::invalid_argument naming `what` if a point is too far from the
/// origin for the grid (2^20 cells per axis) and for an r that is not a positive number.
std::vector<std::uint64_t> point_cell_keys(const PointsRef& points, double r, const char* what);

}  // namespace nbv
