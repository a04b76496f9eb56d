// A read-only view of an occupancy map's workspace grid for the ray-walking kernels (view
// scoring, coverage sets, surface targets), and the 3D-DDA ray walk they share.
#pragma once

#include "nbv/common.hpp"
#include "nbv/surface_observations.hpp"
#include "nbv/workspace_grid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

namespace nbv {

class OccupancyMap;
class SurfaceObservations;

/// Cell (i, j, k) covers origin + res * [i, i+1) x [j, j+1) x [k, k+1); its arrays' index is
/// layout.id(i, j, k) (WorkspaceGrid's brick layout). Valid while the map is alive and unchanged.
struct GridView {
  double resolution = 0.2;
  Eigen::Vector3d origin =
      Eigen::Vector3d::Zero();  ///< world coordinate of cell (0, 0, 0)'s corner
  int nx = 0, ny = 0, nz = 0;
  GridLayout layout;
  CellPools cells;  ///< per cell by id: entropy negated when occupied, log-odds, flag
  const std::uint8_t* brick_live = nullptr;      ///< per brick (id >> 6): live (not neutral) cells
  const std::uint8_t* brick_open = nullptr;      ///< per brick: known, not occupied cells (64: all)
  const std::uint8_t* brick_occupied = nullptr;  ///< per brick: occupied cells
  float unknown_entropy = 0.6931472f;            ///< an unknown cell's (the largest) entropy
  std::int64_t predicted_cells = 0;              ///< cells set by symmetry prediction
  /// Camera observations (SurfaceObservations' sparse storage), or null: per brick its block,
  /// and per block of 64 cells the bitmask of the 26 direction bins each has been seen from and
  /// the number of camera hits in it and where they fell. Read them with seen(id), hits(id) and
  /// patches(id).
  const std::uint32_t* seen_blocks = nullptr;
  const std::uint32_t* seen_pool = nullptr;
  const std::uint16_t* hits_pool = nullptr;
  const std::uint64_t* patches_pool = nullptr;
  /// When the bricks of the grid's cells and of the camera observations last changed, the epochs
  /// this view was taken at (every change so far stamped at most those), and whose stamps they
  /// are (BrickStamps::id): what CoverageMemo checks its records against.
  const std::uint32_t* grid_stamps = nullptr;
  const std::uint32_t* seen_stamps = nullptr;
  std::uint32_t grid_epoch = 0, seen_epoch = 0;
  std::uint64_t grid_id = 0, seen_id = 0;
  /// Navigation only: the height A* paths keep above (plan_path, plan_paths_to, FreeComponent
  /// pass only through cells whose top is above it, so their waypoints keep it to within half a
  /// cell): the views' ground clearance (vehicle.min_altitude). -inf: no floor but the grid's.
  double path_floor = -std::numeric_limits<double>::infinity();

  /// Size of the cell id space (padded to whole bricks).
  std::size_t storage_size() const { return layout.storage_size(); }
  std::size_t index(int i, int j, int k) const { return layout.id(i, j, k); }
  std::size_t index(const Eigen::Vector3i& c) const { return index(c.x(), c.y(), c.z()); }
  bool contains(int i, int j, int k) const {
    return unsigned(i) < unsigned(nx) && unsigned(j) < unsigned(ny) && unsigned(k) < unsigned(nz);
  }
  /// The lowest layer k of cells whose top is above path_floor: the layer cell_of gives a point
  /// at the floor, by the same arithmetic (a view placed at the floor is in a traversable cell
  /// whatever the rounding); 0 without a floor, nz when the floor is above the grid.
  int lowest_path_layer() const {
    const double k = std::floor((path_floor - origin.z()) / resolution);
    return k <= 0.0 ? 0 : k >= double(nz) ? nz : int(k);
  }
  /// The cell holding p; false when p is outside the grid.
  bool cell_of(const Eigen::Vector3d& p, Eigen::Vector3i& c) const;
  Eigen::Vector3d center(int i, int j, int k) const {
    return origin + (Eigen::Vector3d(i, j, k).array() + 0.5).matrix() * resolution;
  }
  bool brick_is_live(std::size_t idx) const { return brick_live[idx >> 6] != 0; }
  /// True when the view holds camera observations.
  bool observed() const { return seen_blocks != nullptr; }
  /// Cell idx's direction-bin mask, camera hits and patch mask (SurfaceObservations::patches;
  /// observed() views only).
  std::uint32_t seen(std::size_t idx) const { return seen_pool[observation_slot(idx)]; }
  std::uint16_t hits(std::size_t idx) const { return hits_pool[observation_slot(idx)]; }
  std::uint64_t patches(std::size_t idx) const { return patches_pool[observation_slot(idx)]; }
  /// Whether the observations mark cell idx saturated (SurfaceObservations::kSaturated).
  bool saturated(std::size_t idx) const {
    return (patches(idx) & SurfaceObservations::kSaturated) != 0;
  }
  std::size_t observation_slot(std::size_t idx) const {
    return std::size_t(seen_blocks[idx >> 6]) << 6 | (idx & 63);
  }
  bool occupied(std::size_t idx) const { return cells.occupied(idx); }
  /// Whether cell idx keeps the vehicle out: unknown, occupied, or (observed() views) holding a
  /// camera hit. A cell the camera has hit holds surface even where the map's log-odds call it
  /// free (rays passing beside a surface that cuts the cell carve it), so the collision checks
  /// keep the vehicle's sphere off every surface point seen, not only off occupied cells.
  bool blocked(std::size_t idx) const {
    return cells.flag_at(idx) == CellFlag::Unknown || occupied(idx) ||
           (observed() && hits(idx) != 0);
  }
  /// This view without the camera observations (observed() false): blocked() of the map alone.
  GridView map_only() const {
    GridView g = *this;
    g.seen_blocks = g.seen_pool = nullptr;
    g.hits_pool = nullptr;
    g.patches_pool = nullptr;
    return g;
  }
  /// Whether none of brick b's 64 cells is blocked() for certain without reading them: all known
  /// and not occupied, and no camera observation in it.
  bool brick_clear(std::size_t b) const {
    return brick_open[b] == 64 && (!observed() || seen_blocks[b] == 0);
  }
  /// Throws std::invalid_argument when the view is incomplete.
  void validate() const;
};

/// The view of a map's grid, with camera observations when `surface` is given (it must have
/// been made for the same map geometry; std::invalid_argument otherwise).
GridView grid_view(const OccupancyMap& map, const SurfaceObservations* surface = nullptr);

/// The part [t0, t1] (grid units) of the ray pos + t d (pos in grid units, d a unit vector) that
/// lies in the grid box [0, n] with t in [0, t_max / resolution]; false if there is none.
inline bool clip_to_grid(const GridView& g, const Eigen::Vector3d& pos, const Eigen::Vector3d& d,
                         double t_max, double& t0, double& t1) {
  const int n[3] = {g.nx, g.ny, g.nz};
  t0 = 0.0;
  t1 = t_max / g.resolution;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (pos[a] < 0.0 || pos[a] >= n[a]) return false;
      continue;
    }
    double ta = (0.0 - pos[a]) / d[a], tb = (n[a] - pos[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1;
}

/// The cell holding grid coordinate p along an axis of n cells, clamped to the grid.
inline int grid_cell(double p, int n) {
  return std::clamp(static_cast<int>(std::floor(p)), 0, n - 1);
}

/// The 3D-DDA's start along one axis: from grid coordinate p in cell c, with da the direction's
/// component, the step (+1, -1 or 0), the parameter (grid units) of the next boundary and the
/// parameter between boundaries.
inline void dda_axis(double da, int c, double p, int& step, double& t_next, double& t_delta) {
  if (da > 0) {
    step = 1;
    t_delta = 1.0 / da;
    t_next = (c + 1 - p) / da;
  } else if (da < 0) {
    step = -1;
    t_delta = -1.0 / da;
    t_next = (c - p) / da;
  } else {
    step = 0;
    t_delta = std::numeric_limits<double>::infinity();
    t_next = t_delta;
  }
}

/// The change of a cell's id for a step along each axis: within a brick +-1 / +-4 / +-16 (in),
/// across a brick boundary +-(brick stride - 3 * in-brick stride) (cross).
inline void dda_id_steps(const GridView& g, const int step[3], std::int64_t in[3],
                         std::int64_t cross[3]) {
  const std::int64_t bstride[3] = {64, 64 * std::int64_t(g.layout.bricks[0]),
                                   64 * std::int64_t(g.layout.bricks[0]) * g.layout.bricks[1]};
  const std::int64_t istride[3] = {1, 4, 16};
  for (int a = 0; a < 3; ++a) {
    in[a] = step[a] * istride[a];
    cross[a] = step[a] * (bstride[a] - 3 * istride[a]);
  }
}

/// Amanatides & Woo 3D-DDA over the grid from o along the unit vector d for t in [0, t_max]
/// (metres), clipped to the grid box. visit(flat_index, cell[3], t_enter) returns false to stop;
/// the walk returns the index of the cell it stopped at, or kNoCell.
/// With kSkipNeutral, cells of bricks without live cells are stepped over without a visit (for
/// walks to which neutral cells - observed free cells of zero entropy - contribute nothing and
/// which they never stop). The cells visited, and their order, do not depend on kSkipNeutral
/// otherwise; skipped(flat_index) is called for each cell stepped over (a no-op by default).
/// Always inlined: compiled apart, the walk reached its visitor's state through memory and
/// reloaded it after every store the visitor made.
struct SkipNothing {
  void operator()(std::size_t) const {}
};
constexpr std::size_t kNoCell = ~std::size_t(0);
template <bool kSkipNeutral, typename Visit, typename Skipped = SkipNothing>
__attribute__((always_inline)) inline std::size_t walk_ray(const GridView& g,
                                                           const Eigen::Vector3d& o,
                                                           const Eigen::Vector3d& d, double t_max,
                                                           Visit&& visit, Skipped&& skipped = {}) {
  const Eigen::Vector3d pos = (o - g.origin) / g.resolution;  // grid units
  const int n[3] = {g.nx, g.ny, g.nz};
  double t0, t1;
  if (!clip_to_grid(g, pos, d, t_max, t0, t1)) return kNoCell;
  const Eigen::Vector3d p0 = pos + t0 * d;
  // Per axis: cell, step, parameter of the next boundary and between boundaries, kept in
  // scalars; the axis to step is chosen without branches (ties as in the classic form: x only if
  // strictly first, else y if strictly before z, else z).
  int c0 = grid_cell(p0[0], n[0]), c1 = grid_cell(p0[1], n[1]), c2 = grid_cell(p0[2], n[2]);
  int s0, s1, s2;
  double tn0, tn1, tn2, td0, td1, td2;
  dda_axis(d[0], c0, pos[0], s0, tn0, td0);
  dda_axis(d[1], c1, pos[1], s1, tn1, td1);
  dda_axis(d[2], c2, pos[2], s2, tn2, td2);
  // The cell id follows the steps.
  const int steps[3] = {s0, s1, s2};
  std::int64_t d_in[3], d_cross[3];
  dda_id_steps(g, steps, d_in, d_cross);
  int edge[3];
  for (int a = 0; a < 3; ++a) edge[a] = steps[a] > 0 ? 3 : 0;
  std::int64_t id = std::int64_t(g.layout.id(c0, c1, c2));
  double t_enter = t0;
  for (;;) {
    const std::size_t idx = std::size_t(id);
    if (!kSkipNeutral || g.brick_is_live(idx)) {
      const int c[3] = {c0, c1, c2};
      if (!visit(idx, c, t_enter * g.resolution)) return idx;
    } else {
      skipped(idx);
    }
    const double t_cross = std::min(std::min(tn0, tn1), tn2);  // the chosen axis's boundary
    if (t_cross > t1) return kNoCell;
    t_enter = t_cross;
    if ((tn0 < tn1) & (tn0 < tn2)) {
      id += (c0 & 3) == edge[0] ? d_cross[0] : d_in[0];
      c0 += s0;
      tn0 += td0;
      if (unsigned(c0) >= unsigned(n[0])) return kNoCell;
    } else if (tn1 < tn2) {
      id += (c1 & 3) == edge[1] ? d_cross[1] : d_in[1];
      c1 += s1;
      tn1 += td1;
      if (unsigned(c1) >= unsigned(n[1])) return kNoCell;
    } else {
      id += (c2 & 3) == edge[2] ? d_cross[2] : d_in[2];
      c2 += s2;
      tn2 += td2;
      if (unsigned(c2) >= unsigned(n[2])) return kNoCell;
    }
  }
}

/// walk_ray's state at a ray's first cell, for walking rays four at a time (mark_rays4): per
/// axis the parameter of the next boundary and between boundaries (grid units), a countdown of
/// the steps left in the grid (plus `floor`, so that it is a multiple of 4 exactly where a step
/// crosses a brick boundary; the ray leaves the grid when it falls below `floor`), and the id's
/// change for a step within a brick (step_in) and the extra change across a brick boundary
/// (step_cross); the end t1 and the first cell's id.
struct RayStart {
  double t_next[3], t_delta[3], t1;
  std::int64_t id, countdown[3], floor[3], step_in[3], step_cross[3];
};

/// Where rays from o start in the grid: o in grid units, whether it lies inside the grid box,
/// and its cell (clamped to the grid). For an origin inside, also what ray_start gives a ray
/// from that cell per axis and step (k = 0, 1, 2 for a step of +1, -1, 0): its id's steps, its
/// countdown and floor (ray_starts4 picks them by the signs of a ray's direction).
struct RayOrigin {
  Eigen::Vector3d pos;
  bool inside = false;
  int cell[3] = {0, 0, 0};
  std::int64_t id = 0;
  std::int64_t step_in[3][3], step_cross[3][3], floor[3][3], countdown[3][3];
};
RayOrigin ray_origin(const GridView& g, const Eigen::Vector3d& o);

/// walk_ray's setup of the ray from `origin` along the unit vector d for t in [0, t_max]
/// (metres); false if it misses the grid (walk_ray visits no cell).
bool ray_start(const GridView& g, const RayOrigin& origin, const Eigen::Vector3d& d, double t_max,
               RayStart& r);

/// ray_start for four rays from one origin, their directions' components d[axis][lane] and
/// their ranges t_max[lane]; active[lane] as ray_start returns. From an origin inside the grid
/// (every view the planner scores) in the lanes of AVX2 registers where the CPU has them
/// (simd = true), with the same arithmetic; one ray at a time otherwise.
void ray_starts4(const GridView& g, const RayOrigin& origin, const double* const* d,
                 const double* t_max, RayStart* r, bool* active, bool simd = true);

/// The most cells a ray visits in the grid (a bound for mark_rays4's buffers).
inline int max_ray_cells(const GridView& g) { return g.nx + g.ny + g.nz + 1; }

/// A set of cells as bits, one 64-bit word per brick of the grid's layout (the word of cell id
/// is id >> 6, its bit id & 63), and the list of the words it has set: a word is appended to
/// `touched` (at n_touched, which then grows) when a mark finds it zero. `touched` must hold
/// one slot past the words it can list.
struct CellMarks {
  std::uint64_t* bits;
  std::uint32_t* touched;
  std::size_t n_touched;
};

/// mark_rays4's buffers: the lanes' cells and runs (the masks of a ray's cells so far in its
/// brick), 4 max_ray_cells(g) each, and a byte per step, max_ray_cells(g) + 32.
struct MarkBuffer {
  std::uint64_t* cells;
  std::uint64_t* runs;
  std::uint8_t* ends;
};

/// The information gain's walk of four rays: marks in `marks` the cells walk_ray<false> enters
/// along each active ray, up to and including its first occupied cell (scored < 0, or -0.0),
/// and gives that cell in stop[l] (kNoCell where the ray ends without one, and for inactive
/// lanes). The rays step in the lanes of AVX2 registers where the CPU has them (simd = true),
/// one at a time otherwise; in the lanes, a ray's cells in one brick are gathered into a mask
/// that goes into the set once.
void mark_rays4(const GridView& g, const RayStart* starts, const bool* active, CellMarks& marks,
                const MarkBuffer& buffer, std::size_t* stop, bool simd = true);

/// walk_ray<false>'s cells of four rays, each active one to its end (no stop): lane l's j-th
/// cell id at ids[4 j + l], count[l] of them (0 for an inactive lane). Stepped in the lanes of
/// AVX2 registers where the CPU has them (simd = true), with walk_ray's comparisons and
/// additions; one ray at a time otherwise. ids holds 4 max_ray_cells(g).
void step_rays4(const GridView& g, const RayStart* starts, const bool* active, std::uint64_t* ids,
                int* count, bool simd = true);

/// Adds the entropies |s[b]| of the cells b in `cells` (a word's 64) to sum in order and the
/// nonzero ones to n, sets `small` where one is nonzero and below 2^-8, and returns the occupied
/// cells among them.
inline std::uint64_t sum_cells(const float* s, std::uint64_t cells, double& sum, int& n,
                               std::uint32_t& small) {
  std::uint64_t occupied = 0;
  for (std::uint64_t m = cells; m; m &= m - 1) {
    const int b = __builtin_ctzll(m);
    std::uint32_t bits;
    std::memcpy(&bits, &s[b], sizeof bits);
    occupied |= std::uint64_t(bits >> 31) << b;
    const std::uint32_t magnitude = bits & 0x7FFFFFFFu;
    small |= magnitude - 1 < (std::uint32_t(127 - 8) << 23) - 1;  // 0 < |s| < 2^-8
    sum += std::fabs(s[b]);
    n += magnitude != 0;
  }
  return occupied;
}

/// The information gain of marked cells: the sum of the entropies |scored| of the cells whose
/// bits are set in bits[w] for the words w listed (those of neutral bricks skipped), and the
/// number of them that are nonzero. True where that sum is exact in any order, so that it equals
/// a sum in any other order bit for bit: no nonzero entropy below 2^-8 (each is then a multiple
/// of 2^-31) and a total below 2^22 (2^53 such units). In AVX2 lanes where the CPU has them.
bool sum_marked(const GridView& g, const std::uint32_t* words, std::size_t n_words,
                const std::uint64_t* bits, double& gain, int& cells, bool simd = true);

/// The 26 direction bins of camera observations: the unit vectors of (i, j, k) in {-1, 0, 1}^3
/// minus the zero vector, bin b = (i+1) + 3 (j+1) + 9 (k+1), skipping 13. Inline: called once
/// a camera hit.
inline int direction_bin(const Eigen::Vector3d& d) {
  // Each component becomes -1, 0 or 1: 0 where it is small against the largest
  // (|d_a| <= tan(22.5 deg) max|d|), so in each coordinate plane the bin is the nearest of the
  // eight directions; elsewhere it approximates the nearest of the 26.
  constexpr double kTan22_5 = 0.41421356237309503;
  const Eigen::Vector3d a = d.cwiseAbs();
  const double t = kTan22_5 * a.maxCoeff();
  int b = 0, mul = 1;
  for (int k = 0; k < 3; ++k, mul *= 3) b += mul * (a[k] > t ? (d[k] > 0 ? 2 : 0) : 1);
  return b < 13 ? b : b - 1;  // 13 is the zero vector
}
/// Unit vector of bin b.
Eigen::Vector3d bin_direction(int b);
/// Bitmask of the bins whose direction is within `cone_deg` of bin b's (b included).
std::uint32_t bin_cone(int b, double cone_deg);
/// bin_cone of every bin b (the table the surface utility and targets read cones from).
std::array<std::uint32_t, 26> bin_cones(double cone_deg);

}  // namespace nbv
