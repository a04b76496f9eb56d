// Reflective-symmetry detection and symmetric prediction (paper sec. 3.2.2, Fig. 3).
//
// detect_symmetry: voxel downsampling -> normals (K nearest) -> keypoints (3D SIFT on curvature,
// ISS or uniform) -> FPFH at the keypoints (full cloud as search surface) -> each keypoint matched
// to its most similar *mirrored* other keypoint -> perpendicular-bisector plane per pair ->
// mean shift over plane parameters -> dominant plane, support, mirror-consistency confidence.
// predict_symmetric: reflect the cloud about a plane -> ICP of the reflection onto the cloud ->
// corrected plane (the -1 eigenvector of the improper isometry ICP o reflection) -> reflected
// points not already explained by an observed point.
//
// Planes are Eigen::Vector4d [nx, ny, nz, d]: unit normal n, n . p = d for p on the plane.
// All PCL code lives in src/symmetry_pcl.cpp; nothing here exposes a PCL type.
#pragma once

#include "nbv/common.hpp"
#include "nbv/kdtree.hpp"
#include "nbv/options.hpp"

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace nbv {

/// (P, 4) float64 row-major: planes [nx, ny, nz, d], one per row.
using Planes = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;
/// (P, 2) int32 row-major: index pairs.
using IndexPairs = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;
/// (K, 33) float32 row-major: FPFH descriptors (three 11-bin sub-histograms f1 | f2 | f3).
using Fpfh = Eigen::Matrix<float, Eigen::Dynamic, 33, Eigen::RowMajor>;
/// Per-stage wall-clock times: (stage name, seconds), in pipeline order.
using StageTimes = std::vector<std::pair<std::string, double>>;

enum class SymmetryKeypoints {
  Sift,     ///< 3D SIFT (pcl::SIFTKeypoint) with the curvature as intensity (authors; default)
  Iss,      ///< intrinsic shape signatures (pcl::ISSKeypoint3D)
  Uniform,  ///< one keypoint per cell of a coarse voxel grid (the point nearest the centroid)
};
/// "sift" | "iss" | "uniform" (std::invalid_argument otherwise) and back.
SymmetryKeypoints symmetry_keypoints_from_string(const std::string& name);
std::string to_string(SymmetryKeypoints k);

/// The options of detect_symmetry, by pipeline step (see nbv/options.hpp for the X-macro).
#define NBV_SYMMETRY_OPTIONS(X)                                                                   \
  /* -- 1. preprocessing */                                                                       \
  X(double, voxel_size, 0.2,                                                                      \
    "voxel-grid cell for downsampling the input, m (centroid per cell, grid anchored at the "     \
    "world origin); 0 disables. 0.2 m, twice the profile's laser voxel: measured on laser "       \
    "profiles of the airliner and the twinjet it is 2-4x faster than 0.1 m with the same plane "  \
    "accuracy and confidence, and finds the plane in more sparse profiles")                       \
  X(int, normal_k, 50, "neighbours for the normal and curvature estimate (authors: K = 50)")      \
  X(double, normal_radius, 0.0, "> 0: radius search of this many m for the normals instead of K") \
  /* -- 2. keypoints */                                                                           \
  X(SymmetryKeypoints, keypoints, SymmetryKeypoints::Sift,                                        \
    "'sift' (3D SIFT on the curvature, the authors'), 'iss' (intrinsic shape signatures) or "     \
    "'uniform' (one keypoint per cell of a uniform_leaf grid, the point nearest its centroid)")   \
  X(double, sift_min_scale, 0.1, "SIFT: smallest scale, m (authors)")                             \
  X(int, sift_octaves, 3, "SIFT: octaves (authors)")                                              \
  X(int, sift_scales_per_octave, 4, "SIFT: scales per octave (authors)")                          \
  X(double, sift_min_contrast, 1e-4, "SIFT: minimum contrast (authors)")                          \
  X(double, iss_salient_radius, 0.6, "ISS: salient radius, m")                                    \
  X(double, iss_non_max_radius, 0.4, "ISS: non-maximum suppression radius, m")                    \
  X(double, uniform_leaf, 0.5, "'uniform' keypoints: grid cell, m")                               \
  /* -- 3. descriptors */                                                                         \
  X(double, fpfh_radius, 1.0,                                                                     \
    "FPFH support radius, m (should exceed the normals' neighbourhood, ~0.8 m at K = 50 on the "  \
    "0.2 m grid; 0.8 and 1.5 m measured about as good)")                                          \
  /* -- 4. matching */                                                                            \
  X(bool, mirror_descriptors, true,                                                               \
    "compare a keypoint's FPFH with the mirrored FPFH of the others (FPFH is not "                \
    "mirror-invariant, see mirror_fpfh); false: with the plain FPFH (the authors' code)")         \
  X(double, max_descriptor_distance, std::numeric_limits<double>::infinity(),                     \
    "pairs whose descriptor distance (L2 over the 33 bins, each sub-histogram sums to 100) "      \
    "exceeds this are dropped (authors: 10; inf keeps every best match)")                         \
  X(double, min_pair_distance, 0.5,                                                               \
    "pairs closer than this, m, are not candidates (a point is its own mirror image on the "      \
    "plane; close pairs give ill-defined bisector normals)")                                      \
  X(double, max_normal_angle_deg, 25.0,                                                           \
    "the normals of a pair must be mirror images about the pair's bisector plane within this "    \
    "angle, degrees (sign-agnostic); 180 disables the check")                                     \
  X(int, matches_per_keypoint, 1,                                                                 \
    "matches kept per keypoint: its most similar candidates (1: the paper's 'the keypoint with "  \
    "the most similar features')")                                                                \
  /* -- 5. mean shift over planes */                                                              \
  X(double, bandwidth, 0.08,                                                                      \
    "mean-shift flat-kernel bandwidth in plane space: |n_a - n_b| (about the angle in radians) "  \
    "with the offset difference divided by the cloud's RMS radius (independent of the "           \
    "structure's size and position), in (0, 1)")                                                  \
  X(int, mean_shift_seeds, 50,                                                                    \
    "mean-shift seeds (authors: 50): the pair planes of highest vote density, one bandwidth "     \
    "apart")                                                                                      \
  X(int, mean_shift_max_iterations, 100, "mean-shift iterations per seed, at most")               \
  X(int, candidate_modes, 10,                                                                     \
    "modes refined and scored (those with at least min_support, and always the first); the one "  \
    "of highest confidence wins. 1: the mode of most support, as the paper")                      \
  /* -- 6. refinement, confidence and acceptance */                                               \
  X(int, refine_iterations, 10,                                                                   \
    "Gauss-Newton iterations of reflective point-to-plane ICP refining a mode (0 disables): "     \
    "reflections are paired with their nearest observed point within a radius shrinking x0.7 "    \
    "per iteration from refine_max_distance to consistency_radius")                               \
  X(double, refine_max_distance, 1.0, "refinement's first pairing radius, m")                     \
  X(int, refine_max_points, 4000,                                                                 \
    "candidates are refined and scored on an evenly strided subset of at most this many points; " \
    "the winner is then refined (3 more iterations) and scored on every point")                   \
  X(double, consistency_radius, 0.5,                                                              \
    "a reflected point is consistent when its nearest observed point q is within this many m "    \
    "and it lies within consistency_tolerance of q's tangent plane (point-to-plane: a laser "     \
    "profile samples surfaces in stripes)")                                                       \
  X(double, consistency_tolerance, 0.1, "see consistency_radius, m")                              \
  X(double, facing_angle_deg, 60.0,                                                               \
    "only points whose normal is within this angle, degrees (sign-agnostic), of the plane's "     \
    "normal count towards the confidence: a surface perpendicular to a plane maps onto itself, "  \
    "which is no evidence of symmetry. 90 counts every point")                                    \
  X(int, min_support, 8, "pairs voting for the dominant plane, at least")                         \
  X(double, min_confidence, 0.7,                                                                  \
    "mirror consistency of the surfaces facing the plane, at least (SymmetryResult.confidence)")

struct SymmetryOptions {
  NBV_SYMMETRY_OPTIONS(NBV_DECLARE_OPTION)
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct SymmetryResult {
  /// [nx, ny, nz, d] of the dominant plane (unit n, n . p = d), sign canonical (the largest
  /// |component| of n positive). NaN when no pair survived matching (then support = 0).
  /// Reported even when not accepted, for diagnostics: use it only if `accepted`.
  Eigen::Vector4d plane = Eigen::Vector4d::Constant(std::numeric_limits<double>::quiet_NaN());
  int support = 0;          ///< pairs within the bandwidth of the dominant plane
  double vote_share = 0.0;  ///< support / number of pairs
  /// Mirror consistency in [0, 1]: of the downsampled points farther than consistency_radius / 2
  /// from the plane (nearer ones could match their own neighbourhood) whose normal faces the
  /// plane (facing_angle_deg), the fraction whose reflection is consistent with the observed
  /// points (see consistency_radius). Unobserved parts of the structure lower it: it measures
  /// the evidence, not the truth. 0 without a plane or without facing points.
  double confidence = 0.0;
  /// Diagnostics of the chosen plane: the same consistency over all points farther than
  /// consistency_radius / 2 from the plane, and the fraction of those that face it.
  double consistency_all = 0.0;
  double facing_fraction = 0.0;
  bool accepted = false;
  std::string reason;              ///< why not accepted ("" when accepted)
  std::size_t num_points = 0;      ///< points after downsampling
  Points keypoints;                ///< (K, 3) keypoint positions (points of the downsampled cloud)
  IndexPairs pairs;                ///< (P, 2) matched keypoint indices (unordered pairs, i < j)
  Eigen::VectorXd pair_distances;  ///< (P,) descriptor distance of each pair
  Planes pair_planes;              ///< (P, 4) bisector plane of each pair (canonical sign)
  Eigen::Matrix<bool, Eigen::Dynamic, 1> inliers;  ///< (P,) pair votes for the dominant plane
  Planes modes;  ///< (M, 4) mean-shift modes, most support first (before refinement)
  Eigen::VectorXi mode_support;  ///< (M,)
  Eigen::VectorXd
      mode_confidence;  ///< (M,) confidence of the refined candidates; NaN if not checked
  double scale = 0.0;   ///< metres: the cloud's RMS radius used by the mean shift
  StageTimes timings;
};

/// Detects the dominant reflective-symmetry plane of a point cloud (N, 3), any pose.
/// Throws std::invalid_argument for non-finite points, bad options or fewer than 10 points.
SymmetryResult detect_symmetry(const PointsRef& points, const SymmetryOptions& options = {});

// ---------------------------------------------------------------------------- mean shift

struct PlaneClusters {
  /// The dominant mode (canonical sign); NaN if there were no planes.
  Eigen::Vector4d plane = Eigen::Vector4d::Constant(std::numeric_limits<double>::quiet_NaN());
  int support = 0;  ///< planes within the bandwidth of the mode (either sign)
  Eigen::Matrix<bool, Eigen::Dynamic, 1> inliers;  ///< (P,)
  Planes modes;                                    ///< (M, 4) distinct modes, most support first
  Eigen::VectorXi mode_support;                    ///< (M,)
};

/// Mean shift (flat kernel) over planes (P, 4). A plane and its negation are the same: every
/// plane votes with both signs, so no cluster is split at a sign boundary. Distance between
/// planes a, b: sqrt(|n_a - n_b|^2 + ((d_a - n_a.c) - (d_b - n_b.c))^2 / scale^2), i.e. offsets
/// are measured from `center` and divided by `scale` (metres). Seeds: up to `seeds` planes of
/// highest vote density, one bandwidth apart. Rows need not have unit normals (they are
/// normalised); rows with a zero or non-finite normal are ignored.
PlaneClusters mean_shift_planes(const Planes& planes, const Eigen::Vector3d& center, double scale,
                                double bandwidth, int seeds = 50, int max_iterations = 100);
/// (P,) which planes lie within `bandwidth` of `mode` (either sign), in mean_shift_planes' metric.
Eigen::Matrix<bool, Eigen::Dynamic, 1> plane_votes(const Planes& planes,
                                                   const Eigen::Vector4d& mode,
                                                   const Eigen::Vector3d& center, double scale,
                                                   double bandwidth);

// ---------------------------------------------------------------------------- prediction

/// The options of predict_symmetric.
#define NBV_SYMMETRIC_PREDICTION_OPTIONS(X)                                                      \
  X(bool, icp, true, "refine the plane by ICP of the reflection onto the cloud (the paper)")     \
  X(double, icp_voxel_size, 0.1,                                                                 \
    "downsampling before ICP, m (the profile's laser voxel); 0 disables")                        \
  X(int, icp_normal_k, 50, "neighbours for the normals of point-to-plane ICP (authors: 50)")     \
  X(bool, icp_point_to_plane, true,                                                              \
    "point-to-plane ICP (pcl::IterativeClosestPointWithNormals, the authors' 'ICP with "         \
    "normals'); false: point-to-point (pcl::IterativeClosestPoint)")                             \
  X(double, icp_max_correspondence, 1.0, "ICP correspondence distance, m (authors: 1)")          \
  X(double, icp_transformation_epsilon, 1e-3,                                                    \
    "ICP convergence: squared translation step, m^2 (authors: 1e-3)")                            \
  X(double, icp_fitness_epsilon, 1e-2,                                                           \
    "ICP convergence: relative change of the mean squared error (authors: 1e-2)")                \
  X(int, icp_max_iterations, 50, "ICP iterations, at most")                                      \
  X(double, max_correction_angle_deg, 15.0,                                                      \
    "ICP corrections of the plane beyond this angle, degrees, are rejected (the plane is kept)") \
  X(double, max_correction_offset, 2.0,                                                          \
    "ICP corrections of the plane beyond this offset, m, are rejected (the plane is kept)")      \
  X(double, explained_tolerance, 0.2,                                                            \
    "a reflected point within this distance, m, of an observed point is already explained and "  \
    "is not predicted")

struct SymmetricPredictionOptions {
  NBV_SYMMETRIC_PREDICTION_OPTIONS(NBV_DECLARE_OPTION)
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct SymmetricPrediction {
  Points predicted;             ///< (M, 3) reflected points not explained by observed ones
  Eigen::Vector4d plane;        ///< the corrected plane (canonical sign), or the input plane
  Eigen::Vector4d input_plane;  ///< the plane given (normalised, canonical sign)
  /// 4x4 improper isometry ICP o reflection (the reflection alone without ICP).
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  bool icp_converged = false;  ///< PCL's hasConverged()
  bool icp_applied = false;    ///< the ICP correction was used for `plane`
  double icp_fitness = std::numeric_limits<double>::quiet_NaN();  ///< mean squared distance, m^2
  double residual_rotation_deg = 0.0;  ///< rotation left after the reflection (0: pure mirror)
  StageTimes timings;
};

/// Reflects `points` (N, 3) about `plane` (refined by ICP unless options.icp is false) and keeps
/// the reflections farther than explained_tolerance from every input point. Throws
/// std::invalid_argument for non-finite input, a plane with a zero normal or too few points.
SymmetricPrediction predict_symmetric(const PointsRef& points, const Eigen::Vector4d& plane,
                                      const SymmetricPredictionOptions& options = {});

// ---------------------------------------------------------------------------- geometry helpers

/// Perpendicular bisector of p and q: n = (p - q) / |p - q|, d = n . (p + q) / 2 (canonical
/// sign). Throws std::invalid_argument if p == q.
Eigen::Vector4d plane_from_pair(const Eigen::Vector3d& p, const Eigen::Vector3d& q);
/// Normalises n to unit length (d scaled alike) and flips the sign so that the largest
/// |component| of n is positive (ties: the first). Throws std::invalid_argument for a zero or
/// non-finite normal.
Eigen::Vector4d canonical_plane(const Eigen::Vector4d& plane);
/// 4x4 homogeneous reflection x -> x - 2 (n . x - d) n.
Eigen::Matrix4d reflection_matrix(const Eigen::Vector4d& plane);
/// Points reflected about a plane.
Points reflect_points(const PointsRef& points, const Eigen::Vector4d& plane);
/// The mirror plane of an improper isometry x -> A x + t (det A ~ -1): n = the eigenvector of
/// A's symmetric part with the smallest eigenvalue (-1 for a reflection), d = n . t / 2
/// (components of t along the plane, a glide, are ignored). `residual_rotation_deg`, if given,
/// receives the rotation left about n (0 for a pure reflection). Throws std::invalid_argument
/// if det A > 0 (a proper motion has no mirror plane).
Eigen::Vector4d plane_from_improper_isometry(const Eigen::Matrix4d& M,
                                             double* residual_rotation_deg = nullptr);
/// Angle between two planes' normals in degrees, sign-agnostic (0..90).
double plane_angle_deg(const Eigen::Vector4d& a, const Eigen::Vector4d& b);
/// Offset between two planes at a point c: |(n_b . c - d_b)| after aligning b's sign with a,
/// i.e. how far c's projection on a lies from b. Metres.
double plane_offset_at(const Eigen::Vector4d& a, const Eigen::Vector4d& b,
                       const Eigen::Vector3d& c);

/// The FPFH of a point's mirror image, computed from the point's own FPFH. Reflection keeps
/// u = n_s and d, flips v = d x u and keeps w = u x v up to the reflection, so of PCL's three
/// features (f1 = atan2(w.n_t, u.n_t), f2 = v.n_t, f3 = u.d / |d|) only f2 changes sign: its
/// 11 bins are reversed; f1 and f3 are unchanged. (Checked empirically by a test on a mirrored
/// cloud.) Rows of `descriptors` are mirrored independently.
Fpfh mirror_fpfh(const Fpfh& descriptors);

// ---------------------------------------------------------------------------- PCL stages

/// The stages behind detect_symmetry, exposed for tests and benchmarks. Points are assumed
/// centred near the origin (float precision); normals are oriented away from the centroid of
/// `points` (mirror-equivariant for any plane through the centroid).
namespace detail {
struct NormalsAndCurvature {
  Points normals;             ///< (N, 3) unit normals (NaN rows where undefined)
  Eigen::VectorXd curvature;  ///< (N,) surface variation lambda0 / (lambda0 + lambda1 + lambda2)
};
NormalsAndCurvature estimate_normals(const PointsRef& points, int k, double radius);
/// Indices into points of the detected keypoints (unique, ascending).
std::vector<int> detect_keypoints(const PointsRef& points, const NormalsAndCurvature& normals,
                                  const SymmetryOptions& options);
/// The most points all the neighbourhoods of one radius search over a cloud may hold together
/// (each point's neighbours summed over the cloud): the cost of normals by radius, ISS and FPFH
/// grows with it (FPFH about 0.2 us a pair on two cores).
constexpr double kMaxNeighbourPairs = 2e8;
/// Refuses, naming `key`, a `radius` whose neighbourhoods over `points` would hold more than
/// kMaxNeighbourPairs points in all: a radius that spans much of the cloud makes its search
/// quadratic (hours on a large structure's profile, not a loop). Estimated from the exact counts
/// of up to 64 points spread evenly over the rows; the message gives the largest radius within
/// the limit by the same estimate.
void check_neighbourhoods(const PointsRef& points, double radius, const std::string& key);
/// FPFH at points[indices] with every point as search surface.
Fpfh compute_fpfh(const PointsRef& points, const Points& normals, const std::vector<int>& indices,
                  double radius);
/// The plane refined by reflective point-to-plane ICP (see SymmetryOptions::refine_iterations):
/// `queries` are reflected and paired with their nearest points of `tree`, whose normals are
/// `target_normals` (zero rows are ignored).
Eigen::Vector4d refine_plane(const PointsRef& queries, const KdTree& tree,
                             const Points& target_normals, const Eigen::Vector4d& plane,
                             int iterations, double max_distance, double min_distance);
/// Mirror consistency of `points` about `plane` (see SymmetryResult::confidence).
struct Consistency {
  double facing = 0.0;           ///< over the points facing the plane (the confidence)
  double all = 0.0;              ///< over all points away from the plane
  double facing_fraction = 0.0;  ///< facing points / points away from the plane
};
Consistency mirror_consistency(const PointsRef& queries, const Points& query_normals,
                               const KdTree& tree, const Points& target_normals,
                               const Eigen::Vector4d& plane, double radius, double tolerance,
                               double facing_angle_deg);
struct IcpResult {
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();  ///< maps source onto target
  bool converged = false;
  double fitness = std::numeric_limits<double>::quiet_NaN();
};
/// The target of predict_symmetric's ICP: a PCL cloud of `points` and its FLANN tree, built once
/// for the target's normals and for every correspondence search of the alignment (PCL would
/// build the same tree three times).
class IcpTarget {
 public:
  explicit IcpTarget(const PointsRef& points);
  ~IcpTarget();
  IcpTarget(const IcpTarget&) = delete;
  IcpTarget& operator=(const IcpTarget&) = delete;
  /// estimate_normals(points, k, 0), kept as the target's normals for align().
  NormalsAndCurvature estimate_normals(int k);
  /// Point-to-plane (or point-to-point) ICP of `source` onto the target.
  IcpResult align(const PointsRef& source, const Points& source_normals,
                  const SymmetricPredictionOptions& options);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};
}  // namespace detail

}  // namespace nbv
