#include "nbv/occupancy_map.hpp"

#include "nbv/map_file.hpp"
#include "nbv/parallel.hpp"

#include <octomap/AbstractOcTree.h>

#include <immintrin.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace nbv {

namespace {

using Key = octomap::OcTreeKey;
using KeyHash = octomap::OcTreeKey::KeyHash;

constexpr int kTreeMaxVal = 32768;  // OctoMap's tree_max_val at depth 16
constexpr double kSnap = 1e-6;      // bounds within this many cells of a grid plane snap to it

std::string fmt_vec(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

octomap::point3d to_point3d(const Eigen::Vector3d& p) {
  return octomap::point3d(float(p.x()), float(p.y()), float(p.z()));
}

template <typename Row>
octomap::point3d row_point3d(const Row& r) {
  return octomap::point3d(float(r(0)), float(r(1)), float(r(2)));
}

void check_integrate_args(const Eigen::Vector3d& origin, const PointsRef& hits,
                          const PointsRef& free_ends, double max_range) {
  if (!origin.allFinite())
    throw std::invalid_argument("sensor origin contains NaN or infinite values");
  require_coordinates(hits, "hit points");
  require_coordinates(free_ends, "free-space ray ends");
  if (std::isnan(max_range) || !(max_range > 0))
    throw std::invalid_argument("max_range must be > 0 (inf = no limit), got " + fmt(max_range));
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

// ---- options -------------------------------------------------------------------------------

void OccupancyMapOptions::validate() const {
  auto prob = [](double v, double lo, double hi, bool lo_open, bool hi_open, const char* name) {
    const bool ok =
        std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
    if (!ok) {
      std::ostringstream s;
      s << name << " must be in " << (lo_open ? "(" : "[") << lo << ", " << hi
        << (hi_open ? ")" : "]") << ", got " << v;
      throw std::invalid_argument(s.str());
    }
  };
  prob(prob_hit, 0.5, 1.0, false, true, "prob_hit");
  prob(prob_miss, 0.0, 0.5, true, false, "prob_miss");
  prob(clamp_min, 0.0, 0.5, true, false, "clamp_min");
  prob(clamp_max, 0.5, 1.0, false, true, "clamp_max");
  prob(occupancy_threshold, 0.0, 1.0, true, true, "occupancy_threshold");
  if (end_point_subdivision < 1 || end_point_subdivision > 4)
    throw std::invalid_argument("end_point_subdivision must be in 1..4, got " +
                                std::to_string(end_point_subdivision));
  if (entropy_unit != EntropyUnit::Nats && entropy_unit != EntropyUnit::Bits)
    throw std::invalid_argument("entropy_unit must be nats or bits");
}

// ---- construction --------------------------------------------------------------------------

namespace {
// (a 1e308 m map of one cell was built; a file's 1e-9 m one gave bounds of +-4.5e31 m)
void check_resolution(double resolution, const std::string& what) {
  if (!(resolution >= 1e-4 && resolution <= 100))
    throw std::invalid_argument(what + " must be within [0.0001, 100] m, got " + fmt(resolution));
}
}  // namespace

OccupancyMap::OccupancyMap(double resolution, const Eigen::Vector3d& bounds_min,
                           const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options)
    : opt_(options) {
  check_resolution(resolution, "resolution");
  opt_.validate();
  res_ = resolution;
  tree_ = std::make_unique<octomap::OcTree>(resolution);
  apply_tree_params();
  init_geometry(bounds_min, bounds_max);
}

OccupancyMap::OccupancyMap(std::unique_ptr<octomap::OcTree> tree, const Eigen::Vector3d& bounds_min,
                           const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options)
    : tree_(std::move(tree)), opt_(options) {
  opt_.validate();
  res_ = tree_->getResolution();
  apply_tree_params();
  init_geometry(bounds_min, bounds_max);
  grid_from_tree();
}

OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

void OccupancyMap::init_geometry(const Eigen::Vector3d& bmin, const Eigen::Vector3d& bmax) {
  if (!bmin.allFinite() || !bmax.allFinite())
    throw std::invalid_argument("workspace bounds contain NaN or infinite values");
  for (int a = 0; a < 3; ++a)
    if (!(bmax[a] > bmin[a]))
      throw std::invalid_argument(
          "workspace bounds_max must exceed bounds_min on every axis, got " + fmt_vec(bmin) +
          " - " + fmt_vec(bmax));
  const double range_m = kTreeMaxVal * res_;
  std::int64_t kmin[3], kmax[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = bmin[a] / res_, hi = bmax[a] / res_;
    if (std::fabs(lo) > 2.0 * kTreeMaxVal || std::fabs(hi) > 2.0 * kTreeMaxVal)
      throw std::invalid_argument("workspace bounds " + fmt_vec(bmin) + " - " + fmt_vec(bmax) +
                                  " exceed OctoMap's addressable range +-" + fmt(range_m) +
                                  " m at resolution " + fmt(res_));
    kmin[a] = std::int64_t(std::floor(lo + kSnap));
    kmax[a] = std::int64_t(std::ceil(hi - kSnap));
    if (kmax[a] <= kmin[a]) kmax[a] = kmin[a] + 1;  // a box thinner than a cell: its one cell
    if (kmin[a] + kTreeMaxVal < 0 || kmax[a] + kTreeMaxVal > 2 * kTreeMaxVal)
      throw std::invalid_argument("workspace bounds " + fmt_vec(bmin) + " - " + fmt_vec(bmax) +
                                  " exceed OctoMap's addressable range +-" + fmt(range_m) +
                                  " m at resolution " + fmt(res_));
  }
  const std::int64_t nx = kmax[0] - kmin[0], ny = kmax[1] - kmin[1], nz = kmax[2] - kmin[2];
  const double cells = double(nx) * double(ny) * double(nz);
  if (cells > double(kMaxCells))
    throw std::invalid_argument("workspace " + fmt_vec(bmin) + " - " + fmt_vec(bmax) + " at " +
                                fmt(res_) + " m holds " + fmt(cells) +
                                " cells, more than the limit " + std::to_string(kMaxCells) +
                                " (coarser resolution or smaller bounds)");
  for (int a = 0; a < 3; ++a) min_key_[a] = octomap::key_type(kmin[a] + kTreeMaxVal);
  grid_ = WorkspaceGrid({int(nx), int(ny), int(nz)}, cell_rule());
  stale_cells_.assign(grid_.layout().num_bricks(), 0);
  stale_bricks_.clear();
}

void OccupancyMap::apply_tree_params() {
  tree_->setProbHit(opt_.prob_hit);
  tree_->setProbMiss(opt_.prob_miss);
  tree_->setClampingThresMin(opt_.clamp_min);
  tree_->setClampingThresMax(opt_.clamp_max);
  tree_->setOccupancyThres(opt_.occupancy_threshold);
  occ_thres_log_ = tree_->getOccupancyThresLog();
  clamp_min_log_ = tree_->getClampingThresMinLog();
  clamp_max_log_ = tree_->getClampingThresMaxLog();
  hit_log_ = tree_->getProbHitLog();
  miss_log_ = tree_->getProbMissLog();
}

CellRule OccupancyMap::cell_rule() const {
  CellRule r;
  r.occupied_logodds = occ_thres_log_;
  r.clamp_min_logodds = clamp_min_log_;
  r.clamp_max_logodds = clamp_max_log_;
  r.unit = opt_.entropy_unit;
  r.clamped_entropy_zero = opt_.clamped_entropy_zero;
  return r;
}

// ---- geometry ------------------------------------------------------------------------------

Eigen::Vector3d OccupancyMap::bounds_min() const {
  return Eigen::Vector3d((int(min_key_[0]) - kTreeMaxVal) * res_,
                         (int(min_key_[1]) - kTreeMaxVal) * res_,
                         (int(min_key_[2]) - kTreeMaxVal) * res_);
}

Eigen::Vector3d OccupancyMap::bounds_max() const {
  const auto& d = grid_.dims();
  return Eigen::Vector3d((int(min_key_[0]) + d[0] - kTreeMaxVal) * res_,
                         (int(min_key_[1]) + d[1] - kTreeMaxVal) * res_,
                         (int(min_key_[2]) + d[2] - kTreeMaxVal) * res_);
}

bool OccupancyMap::coord_to_key(const Eigen::Vector3d& p, Key& key) const {
  return tree_->coordToKeyChecked(to_point3d(p), key);
}

Eigen::Vector3d OccupancyMap::key_to_coord(const Key& key) const {
  return Eigen::Vector3d(tree_->keyToCoord(key[0]), tree_->keyToCoord(key[1]),
                         tree_->keyToCoord(key[2]));
}

OccupancyMap::Key OccupancyMap::key_at(std::int64_t id) const {
  int i, j, k;
  grid_.layout().coords(std::size_t(id), i, j, k);
  return Key(octomap::key_type(min_key_[0] + i), octomap::key_type(min_key_[1] + j),
             octomap::key_type(min_key_[2] + k));
}

// ---- grid and octree -----------------------------------------------------------------------

void OccupancyMap::grid_from_tree() {
  const GridLayout& layout = grid_.layout();
  const auto& dims = grid_.dims();
  const int lo[3] = {min_key_[0], min_key_[1], min_key_[2]};
  const int hi[3] = {lo[0] + dims[0], lo[1] + dims[1], lo[2] + dims[2]};  // exclusive
  const unsigned depth_max = tree_->getTreeDepth();
  grid_.assign_observed([&](auto&& put) {
    for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
      const int size = 1 << (depth_max - it.getDepth());  // cells per axis of this leaf
      const Key key = it.getKey();
      int b[3], e[3];
      bool empty = false;
      for (int a = 0; a < 3; ++a) {
        const int base = size > 1 ? int(key[a]) - size / 2 : int(key[a]);
        b[a] = std::max(base, lo[a]);
        e[a] = std::min(base + size, hi[a]);
        empty |= b[a] >= e[a];
      }
      if (empty) continue;
      const float l = it->getLogOdds();
      for (int z = b[2]; z < e[2]; ++z)
        for (int y = b[1]; y < e[1]; ++y)
          for (int x = b[0]; x < e[0]; ++x) put(layout.id(x - lo[0], y - lo[1], z - lo[2]), l);
    }
  });
}

void OccupancyMap::set_cell(std::int64_t i, float logodds, CellFlag flag) {
  grid_.set(i, logodds, flag);
  std::uint64_t& cells = stale_cells_[std::size_t(i) >> 6];
  if (!cells) stale_bricks_.push_back(std::uint32_t(std::size_t(i) >> 6));
  cells |= std::uint64_t(1) << (i & 63);
}

namespace {

/// Spreads the 16 bits of v to every third bit of a 48-bit word.
inline std::uint64_t spread3(std::uint64_t v) {
  v &= 0xFFFF;
  v = (v | (v << 16)) & 0x0000FF0000FFull;
  v = (v | (v << 8)) & 0x00F00F00F00Full;
  v = (v | (v << 4)) & 0x0C30C30C30C3ull;
  v = (v | (v << 2)) & 0x249249249249ull;
  return v;
}

/// Morton code whose 3-bit groups, from the top, are OctoMap's child indices from the root down
/// (computeChildIdx: x -> 1, y -> 2, z -> 4): sorting by it is a depth-first walk of the tree.
inline std::uint64_t tree_order(const Key& k) {
  return spread3(k[0]) | (spread3(k[1]) << 1) | (spread3(k[2]) << 2);
}

/// Bottom-up pass over the ancestors of the (sorted) updated cells: prune where all eight
/// children are equal leaves, else set the inner node to its children's maximum - what
/// updateNodeRecurs does on the way back up with lazy_eval = false, done once per node.
void fix_inner_nodes(octomap::OcTree& tree, octomap::OcTreeNode* node, unsigned depth,
                     const std::uint64_t* codes, std::size_t b, std::size_t e) {
  const unsigned tree_depth = tree.getTreeDepth();
  if (depth >= tree_depth || !tree.nodeHasChildren(node)) return;
  const unsigned shift = 3 * (tree_depth - 1 - depth);
  for (std::size_t i = b; i < e;) {
    const unsigned pos = unsigned(codes[i] >> shift) & 7u;
    std::size_t j = i + 1;
    while (j < e && (unsigned(codes[j] >> shift) & 7u) == pos) ++j;
    if (tree.nodeChildExists(node, pos))
      fix_inner_nodes(tree, tree.getNodeChild(node, pos), depth + 1, codes, i, j);
    i = j;
  }
  if (!tree.pruneNode(node)) node->updateOccupancyChildren();
}

/// One leaf write of the octree: setNodeValue(key, value) or updateNode(key, value as an update).
struct LeafWrite {
  std::uint64_t code;  // tree_order(key)
  Key key;
  float value;
};

/// Writes leaves in tree order (lazily), then fixes their ancestors once.
void write_leaves(octomap::OcTree& tree, std::vector<LeafWrite>& writes, bool as_update) {
  if (writes.empty()) return;
  std::sort(writes.begin(), writes.end(),
            [](const LeafWrite& a, const LeafWrite& b) { return a.code < b.code; });
  std::vector<std::uint64_t> codes(writes.size());
  for (std::size_t i = 0; i < writes.size(); ++i) {
    if (as_update)
      tree.updateNode(writes[i].key, writes[i].value, true);
    else
      tree.setNodeValue(writes[i].key, writes[i].value, true);
    codes[i] = writes[i].code;
  }
  fix_inner_nodes(tree, tree.getRoot(), 0, codes.data(), 0, codes.size());
}

}  // namespace

void OccupancyMap::sync_octree() const {
  // in batches: a mission's first save writes tens of millions of cells
  constexpr std::size_t kBatch = std::size_t(1) << 22;
  std::vector<LeafWrite> writes;
  writes.reserve(std::min(kBatch, stale_bricks_.size() * 64));
  for (const std::uint32_t b : stale_bricks_) {
    for (std::uint64_t cells = std::exchange(stale_cells_[b], 0); cells; cells &= cells - 1) {
      const std::int64_t i = std::int64_t(b) << 6 | __builtin_ctzll(cells);
      const Key key = key_at(i);
      writes.push_back(LeafWrite{tree_order(key), key, grid_.logodds(i)});
    }
    if (writes.size() >= kBatch) {
      write_leaves(*tree_, writes, false);
      writes.clear();
    }
  }
  stale_bricks_.clear();
  write_leaves(*tree_, writes, false);
}

const octomap::OcTree& OccupancyMap::octree() const {
  sync_octree();
  return *tree_;
}

// ---- integration ---------------------------------------------------------------------------

void OccupancyMap::ensure_scratch() {
  if (stamp_) return;
  const std::size_t n = grid_.layout().storage_size();
  stamp_ = ReleasableArray<std::uint32_t>(n);
  group_of_ = ReleasableArray<std::int32_t>(n);
  scratch_written_.assign((n >> kScratchPageShift) + 1, 0);
  stamp_counter_ = 0;
}

std::uint32_t OccupancyMap::next_stamp(unsigned n) {
  if (stamp_counter_ > std::numeric_limits<std::uint32_t>::max() - n - 1) release_scratch();
  const std::uint32_t first = stamp_counter_ + 1;
  stamp_counter_ += n;
  return first;
}

void OccupancyMap::bound_scratch() {
  const auto written =
      std::size_t(std::count(scratch_written_.begin(), scratch_written_.end(), std::uint8_t(1)));
  if (written > kScratchPages) release_scratch();
}

void OccupancyMap::release_scratch() {
  stamp_.release();  // every stamp reads zero again
  group_of_.release();
  std::fill(scratch_written_.begin(), scratch_written_.end(), 0);
  stamp_counter_ = 0;
}

void OccupancyMap::update_cell(const Key& key, bool hit) {
  const std::int64_t idx = index_of(key);
  octomap::OcTreeNode* node;
  if (idx >= 0 && grid_.flag(idx) == CellFlag::Predicted) {
    // An observation overrides a prediction: restart from unknown (log-odds 0), then update. On
    // a fresh node OctoMap computes 0 + update, clamped; setNodeValue clamps the same way.
    node = tree_->setNodeValue(key, hit ? hit_log_ : miss_log_, false);
  } else {
    node = tree_->updateNode(key, hit, false);
  }
  if (idx >= 0) grid_.set(idx, node->getLogOdds(), CellFlag::Observed);
}

void OccupancyMap::apply_updates(const std::vector<Key>& misses, const std::vector<Key>& hits) {
  // A workspace cell gets updateNode's value: unknown or predicted cells (an observation
  // restarts a prediction from log-odds 0) take the update, observed ones log-odds + update
  // (OctoMap's float addValue), clamped as updateNodeLogOdds clamps, and nothing changes once
  // a cell is clamped in the update's direction (updateNode's early abort).
  std::vector<LeafWrite> outside;  // cells outside the workspace go to the octree directly
  auto update = [&](const Key& key, bool hit) {
    const float upd = hit ? hit_log_ : miss_log_;
    const std::int64_t idx = index_of(key);
    if (idx < 0) {
      outside.push_back(LeafWrite{tree_order(key), key, upd});
      return;
    }
    float value = upd;
    if (grid_.flag(idx) == CellFlag::Observed) {
      const float l = grid_.logodds(idx);
      if (hit ? l >= clamp_max_log_ : l <= clamp_min_log_) return;
      value = l + upd;
    }
    set_cell(idx, std::min(std::max(value, clamp_min_log_), clamp_max_log_), CellFlag::Observed);
  };
  for (const Key& k : misses) update(k, false);
  for (const Key& k : hits) update(k, true);
  write_leaves(*tree_, outside, true);
}

std::size_t OccupancyMap::update_cells(const PointsRef& points, bool occupied) {
  require_finite(points, "points");
  std::vector<Key> keys;
  keys.reserve(std::size_t(points.rows()));
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    Key key;
    if (tree_->coordToKeyChecked(row_point3d(points.row(r)), key)) keys.push_back(key);
  }
  return update_cells(keys, occupied);  // de-duplicates
}

std::size_t OccupancyMap::update_cells(const std::vector<Key>& keys, bool occupied) {
  std::vector<Key> unique;
  unique.reserve(keys.size());
  std::unordered_set<Key, KeyHash> seen;
  for (const Key& k : keys)
    if (seen.insert(k).second) unique.push_back(k);
  static const std::vector<Key> none;
  if (occupied)
    apply_updates(none, unique);
  else
    apply_updates(unique, none);
  return unique.size();
}

enum : std::uint8_t { kHitFlag = 1, kFreeEndFlag = 2 };

/// A group of rays ending in the same sub-cell of an end cell.
struct OccupancyMap::EndPoint {
  octomap::point3d rep;  // representative end point: the one nearest the sub-cell centre
  float d2;              // its squared distance to the sub-cell centre (cell units)
  Key key;               // end cell
  std::uint16_t sub;     // sub-cell index within the end cell
  std::uint8_t flags;    // some ray of the group is a hit / a free end in range
};

void OccupancyMap::check_scan(const Eigen::Vector3d& origin, const PointsRef& hits,
                              const PointsRef& free_ends, double max_range) const {
  check_integrate_args(origin, hits, free_ends, max_range);
  Key key;
  if (!tree_->coordToKeyChecked(to_point3d(origin), key))
    throw std::invalid_argument("sensor origin " + fmt_vec(origin) +
                                " is outside OctoMap's addressable range");
}

IntegrationStats OccupancyMap::integrate(const Scan& scan, double max_range) {
  return integrate(scan.origin, scan.hits, scan.free_ends, max_range);
}

IntegrationStats OccupancyMap::integrate(const Eigen::Vector3d& origin, const PointsRef& hits,
                                         const PointsRef& free_ends, double max_range) {
  check_scan(origin, hits, free_ends, max_range);
  return integrate_points(origin, hits, free_ends, max_range);
}

IntegrationStats OccupancyMap::integrate_checked(const Scan& scan, double max_range) {
  return integrate_points(scan.origin, scan.hits, scan.free_ends, max_range);
}

IntegrationStats OccupancyMap::integrate_points(const Eigen::Vector3d& origin,
                                                const PointsRef& hits, const PointsRef& free_ends,
                                                double max_range) {
  const octomap::point3d o = to_point3d(origin);
  IntegrationStats stats;
  stats.rays = std::size_t(hits.rows() + free_ends.rows());
  if (stats.rays == 0) return stats;
  auto candidates = collect_end_points(o, hits, free_ends, max_range);
  ensure_scratch();
  const std::uint32_t s_group = next_stamp(3), s_free = s_group + 1, s_occ = s_group + 2;
  const std::vector<EndPoint> groups = group_end_points(std::move(candidates), s_group);
  stats.traced_rays = groups.size();
  EndCells cells = classify_end_cells(groups, s_occ, s_free);
  trace_free_cells(o, groups, s_occ, s_free, cells);
  bound_scratch();
  apply_updates(cells.free, cells.occupied);
  stats.free_cells = cells.free.size();
  stats.occupied_cells = cells.occupied.size();
  return stats;
}

namespace detail {
namespace {

// One row at a time (rows i0 to n), the reference of end_cells_avx2.
void end_cells_scalar(const double* rows, std::size_t stride, std::size_t i0, std::size_t n,
                      double rf, int k, const EndCellBlock& out) {
  const double kd = k, inv_k = 1.0 / k;
  for (std::size_t i = i0; i < n; ++i) {
    const double* r = rows + i * stride;
    bool finite = true, inside = true;
    double d2 = 0;
    int sub = 0;
    for (int a = 2; a >= 0; --a) {
      const double c = r[a];
      finite = finite && std::isfinite(c);
      const double t = rf * double(float(c));
      const bool ok = std::fabs(t) < 1e9;
      int fl = ok ? int(t) : 0;
      fl -= double(fl) > t;  // floor, without a libm call
      const int kv = fl + kTreeMaxVal;
      inside = inside && ok && kv >= 0 && kv < 2 * kTreeMaxVal;
      const double frac = t - fl;  // position within the cell, [0, 1)
      const int sa = ok ? std::min(k - 1, int(frac * kd)) : 0;
      const double dc = frac - (sa + 0.5) * inv_k;
      d2 += dc * dc;
      sub = sub * k + sa;
      out.key[a][i] = kv;
    }
    out.sub[i] = sub;
    out.d2[i] = d2;
    out.state[i] = finite ? std::uint8_t(inside) : std::uint8_t(2);
  }
}

// Four rows at a time in AVX2 lanes: the same operations in the same order (no fused
// multiply-add), so the same numbers to the bit.
__attribute__((target("avx2"))) void end_cells_avx2(const double* rows, std::size_t stride,
                                                    std::size_t n, double rf, int k,
                                                    const EndCellBlock& out) {
  const __m256d vrf = _mm256_set1_pd(rf), vkd = _mm256_set1_pd(double(k));
  const __m256d vinv = _mm256_set1_pd(1.0 / k), half = _mm256_set1_pd(0.5);
  const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
  const __m256d limit = _mm256_set1_pd(1e9), zero = _mm256_setzero_pd();
  const __m128i vk = _mm_set1_epi32(k), km1 = _mm_set1_epi32(k - 1);
  const __m128i max_val = _mm_set1_epi32(kTreeMaxVal), key_end = _mm_set1_epi32(2 * kTreeMaxVal);
  const __m128i minus1 = _mm_set1_epi32(-1);
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const double* r = rows + i * stride;
    __m256d d2 = zero;
    __m128i sub = _mm_setzero_si128(), inside = minus1;
    __m256d finite = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    for (int a = 2; a >= 0; --a) {
      const __m256d c = _mm256_set_pd(r[3 * stride + a], r[2 * stride + a], r[stride + a], r[a]);
      finite = _mm256_and_pd(finite, _mm256_cmp_pd(_mm256_sub_pd(c, c), zero, _CMP_EQ_OQ));
      const __m256d t = _mm256_mul_pd(vrf, _mm256_cvtps_pd(_mm256_cvtpd_ps(c)));
      const __m256d ok = _mm256_cmp_pd(_mm256_and_pd(t, abs_mask), limit, _CMP_LT_OQ);
      const __m256d tc = _mm256_and_pd(t, ok);  // 0 where out of range (never used there)
      const __m256d fl = _mm256_floor_pd(tc);   // = int(t) - (int(t) > t) for |t| < 1e9
      const __m128i fli = _mm256_cvttpd_epi32(fl);
      const __m128i kv = _mm_add_epi32(fli, max_val);
      const __m128i ok32 = _mm256_cvtpd_epi32(_mm256_and_pd(ok, _mm256_set1_pd(-1.0)));
      const __m128i in_range =
          _mm_andnot_si128(_mm_cmpgt_epi32(_mm_setzero_si128(), kv), _mm_cmpgt_epi32(key_end, kv));
      inside = _mm_and_si128(inside, _mm_and_si128(in_range, ok32));
      const __m256d frac = _mm256_sub_pd(tc, fl);
      const __m128i sa = _mm_min_epi32(km1, _mm256_cvttpd_epi32(_mm256_mul_pd(frac, vkd)));
      const __m256d dc =
          _mm256_sub_pd(frac, _mm256_mul_pd(_mm256_add_pd(_mm256_cvtepi32_pd(sa), half), vinv));
      d2 = _mm256_add_pd(d2, _mm256_mul_pd(dc, dc));
      sub = _mm_add_epi32(_mm_mullo_epi32(sub, vk), sa);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out.key[a] + i), kv);
    }
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out.sub + i), sub);
    _mm256_storeu_pd(out.d2 + i, d2);
    const int fin = _mm256_movemask_pd(finite);
    const int ins = _mm_movemask_ps(_mm_castsi128_ps(inside));
    for (int l = 0; l < 4; ++l)
      out.state[i + std::size_t(l)] = (fin >> l & 1) ? std::uint8_t(ins >> l & 1) : std::uint8_t(2);
  }
  end_cells_scalar(rows, stride, i, n, rf, k, out);
}

}  // namespace

void end_cells(const double* rows, std::size_t stride, std::size_t n, double rf, int k,
               const EndCellBlock& out, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (simd && avx2)
    end_cells_avx2(rows, stride, n, rf, k, out);
  else
    end_cells_scalar(rows, stride, 0, n, rf, k, out);
}

}  // namespace detail

std::vector<std::vector<OccupancyMap::EndPoint>> OccupancyMap::collect_end_points(
    const octomap::point3d& o, const PointsRef& hits, const PointsRef& free_ends,
    double max_range) const {
  // Per ray (parallel over fixed chunks): its end point (cut at max_range as OctoMap does), the
  // end cell's key (OctoMap's coordToKeyChecked: floor(resolution_factor * c) + 32768) and the
  // sub-cell of the end point, for a chunk's rays at once (detail::end_cells). Then, in ray
  // order, consecutive rays ending in the same sub-cell (neighbouring pixels) merge into one
  // candidate.
  const std::size_t nh = std::size_t(hits.rows()), n = nh + std::size_t(free_ends.rows());
  const bool cut = std::isfinite(max_range);
  const bool dedup = opt_.deduplicate_end_points;
  const int k = dedup ? opt_.end_point_subdivision : 1;
  const double rf = 1.0 / res_;  // OctoMap's resolution_factor
  const std::size_t chunk = 4096, nchunks = (n + chunk - 1) / chunk;
  std::vector<std::vector<EndPoint>> out(nchunks);
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    std::vector<std::int32_t> keys(3 * chunk), subs(chunk);
    std::vector<double> d2s(chunk), cut_rows(cut ? 3 * chunk : 0);
    std::vector<std::uint8_t> states(chunk), cut_flags(cut ? chunk : 0);
    const detail::EndCellBlock block{{keys.data(), keys.data() + chunk, keys.data() + 2 * chunk},
                                     subs.data(),
                                     d2s.data(),
                                     states.data()};
    for (std::size_t c = cb; c < ce; ++c) {
      std::vector<EndPoint>& cands = out[c];
      cands.reserve(dedup ? 1024 : chunk);
      const std::size_t b = c * chunk, e = std::min(n, (c + 1) * chunk);
      // the chunk's rays in each of the two arrays it may span, hits first
      for (int part = 0; part < 2; ++part) {
        const bool is_hit = part == 0;
        const PointsRef& pts = is_hit ? hits : free_ends;
        const std::size_t off = is_hit ? 0 : nh, stop = is_hit ? nh : n;
        if (std::min(e, stop) <= std::max(b, off)) continue;
        const std::size_t r0 = std::max(b, off) - off, m = std::min(e, stop) - off - r0;
        const std::uint8_t flag = is_hit ? kHitFlag : kFreeEndFlag;
        const double* rows = pts.data() + std::ptrdiff_t(r0) * pts.outerStride();
        std::size_t stride = std::size_t(pts.outerStride());
        if (cut) {  // OctoMap's maxrange rule (computeUpdate), in float
          for (std::size_t i = 0; i < m; ++i) {
            const auto row = pts.row(Eigen::Index(r0 + i));
            octomap::point3d p = row_point3d(row);
            cut_flags[i] = flag;
            if ((p - o).norm() > max_range) {
              p = o + (p - o).normalized() * float(max_range);
              cut_flags[i] = 0;  // the ray clears the cells before its cut end, nothing else
            }
            for (int a = 0; a < 3; ++a) {  // a float overflow is beyond OctoMap's range
              const double v = double(p(a));
              cut_rows[3 * i + std::size_t(a)] = std::isfinite(v) ? v : 1e300;
            }
          }
          rows = cut_rows.data();
          stride = 3;
        }
        detail::end_cells(rows, stride, m, rf, k, block);
        for (std::size_t i = 0; i < m; ++i) {
          if (states[i] != 1) continue;  // OctoMap skips rays whose end it cannot address
          const std::int32_t sub = subs[i];
          const float d2 = float(d2s[i]);
          const std::uint8_t f = cut ? cut_flags[i] : flag;
          Key key;
          for (int a = 0; a < 3; ++a) key[a] = octomap::key_type(keys[std::size_t(a) * chunk + i]);
          const double* r = rows + i * stride;
          const octomap::point3d p{float(r[0]), float(r[1]), float(r[2])};
          if (dedup && !cands.empty() && cands.back().key == key && cands.back().sub == sub) {
            EndPoint& cd = cands.back();
            if (d2 < cd.d2) {
              cd.d2 = d2;
              cd.rep = p;
            }
            cd.flags |= f;
          } else {
            cands.push_back(EndPoint{p, d2, key, std::uint16_t(sub), f});
          }
        }
      }
    }
  });
  return out;
}

std::vector<OccupancyMap::EndPoint> OccupancyMap::group_end_points(
    std::vector<std::vector<EndPoint>> candidates, std::uint32_t s_group) {
  // Serial, in ray order: one group per end sub-cell, found through the stamp array (workspace
  // cells) or a hash map (outside), kk group slots per end cell.
  const bool dedup = opt_.deduplicate_end_points;
  const int k = dedup ? opt_.end_point_subdivision : 1;
  const int kk = k * k * k;
  std::vector<EndPoint> groups;
  std::vector<std::int32_t> slots;  // kk group slots per end cell (-1: none yet)
  std::unordered_map<Key, std::int32_t, KeyHash> outside_cells;
  std::size_t nc = 0;
  for (const auto& v : candidates) nc += v.size();
  groups.reserve(dedup ? std::min<std::size_t>(nc, 1 << 16) : nc);
  for (const auto& chunk : candidates) {
    for (const EndPoint& cd : chunk) {
      if (!dedup) {
        groups.push_back(cd);
        continue;
      }
      std::int32_t base;
      const std::int64_t idx = index_of(cd.key);
      if (idx >= 0) {
        const std::size_t i = std::size_t(idx);
        if (stamp_[i] == s_group) {
          base = group_of_[i];
        } else {
          stamp_[i] = s_group;
          base = group_of_[i] = std::int32_t(slots.size());
          mark_written(i);
          slots.resize(slots.size() + std::size_t(kk), -1);
        }
      } else {
        auto ins = outside_cells.try_emplace(cd.key, std::int32_t(slots.size()));
        if (ins.second) slots.resize(slots.size() + std::size_t(kk), -1);
        base = ins.first->second;
      }
      std::int32_t& slot = slots[std::size_t(base) + cd.sub];
      if (slot < 0) {
        slot = std::int32_t(groups.size());
        groups.push_back(cd);
        continue;
      }
      EndPoint& gr = groups[std::size_t(slot)];
      if (cd.d2 < gr.d2) {
        gr.d2 = cd.d2;
        gr.rep = cd.rep;
      }
      gr.flags |= cd.flags;
    }
  }
  return groups;
}

OccupancyMap::EndCells OccupancyMap::classify_end_cells(const std::vector<EndPoint>& groups,
                                                        std::uint32_t s_occ, std::uint32_t s_free) {
  // Hits first (a cell hit in this scan is never also a miss), then the cells of free ends.
  const bool clip = opt_.clip_to_workspace;
  EndCells out;
  std::unordered_set<Key, KeyHash> occ_out;
  for (const EndPoint& gr : groups) {
    if (!(gr.flags & kHitFlag)) continue;
    const std::int64_t idx = index_of(gr.key);
    if (idx >= 0) {
      if (stamp_[std::size_t(idx)] != s_occ) {
        stamp_[std::size_t(idx)] = s_occ;
        mark_written(std::size_t(idx));
        out.occupied.push_back(gr.key);
      }
    } else if (!clip && occ_out.insert(gr.key).second) {
      out.occupied.push_back(gr.key);
    }
  }
  std::unordered_set<Key, KeyHash> free_out;
  for (const EndPoint& gr : groups) {
    if (!(gr.flags & kFreeEndFlag) || (gr.flags & kHitFlag)) continue;
    const std::int64_t idx = index_of(gr.key);
    if (idx < 0) {
      if (!clip && !occ_out.count(gr.key) && free_out.insert(gr.key).second)
        out.free.push_back(gr.key);
    } else if (stamp_[std::size_t(idx)] != s_occ && stamp_[std::size_t(idx)] != s_free) {
      stamp_[std::size_t(idx)] = s_free;
      mark_written(std::size_t(idx));
      out.free.push_back(gr.key);
    }
  }
  return out;
}

void OccupancyMap::trace_free_cells(const octomap::point3d& o, const std::vector<EndPoint>& groups,
                                    std::uint32_t s_occ, std::uint32_t s_free, EndCells& cells) {
  // One ray per group (parallel over fixed chunks). A workspace cell is claimed for this scan's
  // misses by the first walker that stamps it (atomic; cells hit in this scan keep their stamp).
  // Cells a miss cannot change - observed free cells at the lower clamp, and whole bricks of
  // them - are passed over without a claim. Cells outside the workspace are merged afterwards
  // through a hash set.
  const bool clip = opt_.clip_to_workspace;
  const std::size_t ng = groups.size();
  const std::size_t grain = 32;
  const std::size_t nchunks = (ng + grain - 1) / grain;
  std::vector<std::vector<Key>> chunk_free(nchunks), chunk_out(nchunks);
  std::uint32_t* const stamps = stamp_.data();
  const octomap::OcTree& tree = *tree_;
  const GridLayout& layout = grid_.layout();
  const auto& dims = layout.dims;
  const int mk[3] = {min_key_[0], min_key_[1], min_key_[2]};
  const std::uint8_t* const live = grid_.brick_live_data();
  const CellPools grid = grid_.cells();
  const float clamp_min = clamp_min_log_;
  // A walk steps each axis in one direction only, so a ray from a cell of the workspace that
  // has left it never comes back: with clipping, its walk ends there.
  const bool end_outside = clip && in_workspace(tree.coordToKey(o));
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::vector<Key>& out = chunk_free[c];
      std::vector<Key>& out_outside = chunk_out[c];
      out.reserve(grain * 16);
      for (std::size_t g = c * grain, e = std::min(ng, (c + 1) * grain); g < e; ++g)
        walk_ray_keys(tree, o, groups[g].rep, [&](const Key& key) {
          const int i = int(key[0]) - mk[0], j = int(key[1]) - mk[1], kz = int(key[2]) - mk[2];
          if (unsigned(i) >= unsigned(dims[0]) || unsigned(j) >= unsigned(dims[1]) ||
              unsigned(kz) >= unsigned(dims[2])) {
            if (!clip) out_outside.push_back(key);
            return !end_outside;
          }
          const std::size_t idx = layout.id(i, j, kz);
          if (!live[idx >> 6]) return true;
          const std::size_t c = grid.at(idx);
          if (grid.flags[c] == CellFlag::Observed && grid.logodds[c] <= clamp_min) return true;
          std::uint32_t* st = stamps + idx;
          std::uint32_t cur = __atomic_load_n(st, __ATOMIC_RELAXED);
          while (cur != s_occ && cur != s_free) {
            if (__atomic_compare_exchange_n(st, &cur, s_free, false, __ATOMIC_RELAXED,
                                            __ATOMIC_RELAXED)) {
              mark_written(idx);
              out.push_back(key);
              break;
            }
          }
          return true;
        });
    }
  });
  std::size_t total = cells.free.size();
  for (const auto& v : chunk_free) total += v.size();
  cells.free.reserve(total);
  for (const auto& v : chunk_free) cells.free.insert(cells.free.end(), v.begin(), v.end());
  if (clip) return;
  std::unordered_set<Key, KeyHash> occupied(cells.occupied.begin(), cells.occupied.end());
  std::unordered_set<Key, KeyHash> listed;
  for (const Key& key : cells.free)
    if (!in_workspace(key)) listed.insert(key);
  for (const auto& v : chunk_out)
    for (const Key& key : v)
      if (!occupied.count(key) && listed.insert(key).second) cells.free.push_back(key);
}

IntegrationStats OccupancyMap::integrate_exact(const Eigen::Vector3d& origin, const PointsRef& hits,
                                               const PointsRef& free_ends, double max_range) {
  check_scan(origin, hits, free_ends, max_range);
  const octomap::point3d o = to_point3d(origin);
  sync_octree();
  IntegrationStats stats;
  stats.rays = std::size_t(hits.rows() + free_ends.rows());
  stats.traced_rays = stats.rays;
  const double maxrange = std::isfinite(max_range) ? max_range : -1.0;

  octomap::Pointcloud cloud;
  cloud.reserve(std::size_t(hits.rows()));
  for (Eigen::Index r = 0; r < hits.rows(); ++r) cloud.push_back(row_point3d(hits.row(r)));
  octomap::KeySet free_cells, occupied_cells;
  tree_->computeUpdate(cloud, o, free_cells, occupied_cells, maxrange);

  if (free_ends.rows() > 0) {
    octomap::KeyRay ray;
    for (Eigen::Index r = 0; r < free_ends.rows(); ++r) {
      const octomap::point3d p = row_point3d(free_ends.row(r));
      if (maxrange < 0.0 || (p - o).norm() <= maxrange) {
        if (tree_->computeRayKeys(o, p, ray)) free_cells.insert(ray.begin(), ray.end());
        Key k;
        if (tree_->coordToKeyChecked(p, k)) free_cells.insert(k);
      } else {
        const octomap::point3d dir = (p - o).normalized();
        const octomap::point3d new_end = o + dir * float(maxrange);
        if (tree_->computeRayKeys(o, new_end, ray)) free_cells.insert(ray.begin(), ray.end());
      }
    }
    for (auto it = free_cells.begin(); it != free_cells.end();) {
      if (occupied_cells.count(*it))
        it = free_cells.erase(it);
      else
        ++it;
    }
  }
  // insertPointCloud's update loop: misses, then hits, one updateNode per cell.
  for (const Key& k : free_cells) update_cell(k, false);
  for (const Key& k : occupied_cells) update_cell(k, true);
  stats.free_cells = free_cells.size();
  stats.occupied_cells = occupied_cells.size();
  return stats;
}

std::size_t OccupancyMap::mark_free_segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                            double radius) {
  if (!a.allFinite() || !b.allFinite())
    throw std::invalid_argument("segment ends contain NaN or infinite values");
  if (!std::isfinite(radius) || radius < 0)
    throw std::invalid_argument("radius must be finite and >= 0, got " + fmt(radius));
  Key ka, kb;
  if (!coord_to_key(a, ka) || !coord_to_key(b, kb))
    throw std::invalid_argument("segment ends outside OctoMap's addressable range");
  const Eigen::Vector3d lo = a.cwiseMin(b).array() - radius, hi = a.cwiseMax(b).array() + radius;
  Key klo, khi;
  if (!coord_to_key(lo, klo) || !coord_to_key(hi, khi))
    throw std::invalid_argument("segment and radius reach outside OctoMap's addressable range");
  const double cells =
      double(khi[0] - klo[0] + 1) * double(khi[1] - klo[1] + 1) * double(khi[2] - klo[2] + 1);
  if (cells > 1e8)
    throw std::invalid_argument("mark_free_segment: the segment's box holds too many cells");
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  // Only cells never observed (and, when clipping, inside the workspace): the vehicle's own volume
  // is evidence of free space where nothing else is known, and must not keep lowering the
  // entropy of observed cells.
  auto markable = [&](const Key& k) {
    const std::int64_t idx = index_of(k);
    if (idx < 0) return !opt_.clip_to_workspace && tree_->search(k) == nullptr;
    return grid_.flag(idx) == CellFlag::Unknown;
  };
  std::vector<Key> keys;
  for (const Key& k : {ka, kb})  // the cells holding the ends, each once
    if (markable(k) && (keys.empty() || keys.front() != k)) keys.push_back(k);
  for (int z = klo[2]; z <= khi[2]; ++z)
    for (int y = klo[1]; y <= khi[1]; ++y)
      for (int x = klo[0]; x <= khi[0]; ++x) {
        const Key k{octomap::key_type(x), octomap::key_type(y), octomap::key_type(z)};
        if (k == ka || k == kb || !markable(k)) continue;
        // the cell touches the swept sphere: box distance from the nearest point of the segment
        const Eigen::Vector3d c = key_to_coord(k);
        const double t = len2 > 0 ? std::clamp((c - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
        const Eigen::Vector3d d = ((a + t * ab - c).cwiseAbs().array() - 0.5 * res_).max(0.0);
        if (d.squaredNorm() <= radius * radius) keys.push_back(k);
      }
  return update_cells(keys, false);
}

std::size_t OccupancyMap::set_unknown_cells(const PointsRef& points, double probability) {
  require_finite(points, "predicted points");
  if (!std::isfinite(probability) || !(probability > 0.0) || !(probability < 1.0))
    throw std::invalid_argument("probability must be in (0, 1), got " + fmt(probability));
  const float l = std::min(std::max(octomap::logodds(probability), clamp_min_log_), clamp_max_log_);
  std::size_t set = 0;
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    Key key;
    if (!tree_->coordToKeyChecked(row_point3d(points.row(r)), key)) continue;
    const std::int64_t idx = index_of(key);
    if (idx < 0 || grid_.flag(idx) != CellFlag::Unknown) continue;
    set_cell(idx, l, CellFlag::Predicted);
    ++set;
  }
  return set;
}

// ---- queries -------------------------------------------------------------------------------

bool OccupancyMap::find_cell(const Eigen::Vector3d& p, CellFlag& flag, float& logodds) const {
  flag = CellFlag::Unknown;
  logodds = 0.0f;
  Key key;
  if (!coord_to_key(p, key)) return false;
  const std::int64_t idx = index_of(key);
  if (idx >= 0) {
    flag = grid_.flag(idx);
    logodds = grid_.logodds(idx);
  } else if (const octomap::OcTreeNode* n = tree_->search(key)) {  // never stale outside
    flag = CellFlag::Observed;
    logodds = n->getLogOdds();
  }
  return flag != CellFlag::Unknown;
}

CellState OccupancyMap::state(const Eigen::Vector3d& p) const {
  CellFlag flag;
  float l;
  if (!find_cell(p, flag, l)) return CellState::Unknown;
  return l >= occ_thres_log_ ? CellState::Occupied : CellState::Free;
}

double OccupancyMap::probability(const Eigen::Vector3d& p) const {
  CellFlag flag;
  float l;
  return find_cell(p, flag, l) ? octomap::probability(l) : 0.5;
}

double OccupancyMap::entropy(const Eigen::Vector3d& p) const {
  CellFlag flag;
  float l;
  find_cell(p, flag, l);
  return cell_entropy(l, flag);
}

bool OccupancyMap::is_predicted(const Eigen::Vector3d& p) const {
  CellFlag flag;
  float l;
  find_cell(p, flag, l);
  return flag == CellFlag::Predicted;
}

namespace {
template <typename Out, typename F>
void map_points(const PointsRef& points, Out& out, const F& f) {
  out.resize(points.rows());
  parallel_chunks(std::size_t(points.rows()), 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      out[Eigen::Index(i)] = f(Eigen::Vector3d(points.row(Eigen::Index(i))));
  });
}
}  // namespace

Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> OccupancyMap::states(const PointsRef& points) const {
  require_finite(points, "query points");
  Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> out;
  map_points(points, out, [&](const Eigen::Vector3d& p) { return std::int8_t(state(p)); });
  return out;
}

Eigen::VectorXd OccupancyMap::probabilities(const PointsRef& points) const {
  require_finite(points, "query points");
  Eigen::VectorXd out;
  map_points(points, out, [&](const Eigen::Vector3d& p) { return probability(p); });
  return out;
}

Eigen::VectorXd OccupancyMap::entropies(const PointsRef& points) const {
  require_finite(points, "query points");
  Eigen::VectorXd out;
  map_points(points, out, [&](const Eigen::Vector3d& p) { return entropy(p); });
  return out;
}

Eigen::Matrix<bool, Eigen::Dynamic, 1> OccupancyMap::predicted(const PointsRef& points) const {
  require_finite(points, "query points");
  Eigen::Matrix<bool, Eigen::Dynamic, 1> out;
  map_points(points, out, [&](const Eigen::Vector3d& p) { return is_predicted(p); });
  return out;
}

Points OccupancyMap::occupied_cells(bool in_order) const {
  // the bricks that hold an occupied cell (a few percent of a large workspace's), then their
  // cells in C order (i fastest), as a scan of every cell would list them
  const GridLayout& layout = grid_.layout();
  const std::uint8_t* occupied = grid_.brick_occupied_data();
  std::vector<std::int64_t> order;  // k, j, i packed, for the C order
  order.reserve(std::size_t(grid_.counts().occupied));
  const auto& d = grid_.dims();
  for (std::size_t brick = 0, nb = layout.num_bricks(); brick < nb; ++brick) {
    if (occupied[brick] == 0) continue;
    for (std::size_t id = brick << 6, e = id + 64; id < e; ++id) {
      int i, j, k;
      if (layout.coords(id, i, j, k) && grid_.state(std::int64_t(id)) == CellState::Occupied)
        order.push_back((std::int64_t(k) * d[1] + j) * d[0] + i);
    }
  }
  if (in_order) std::sort(order.begin(), order.end());
  Points out(Eigen::Index(order.size()), 3);
  for (std::size_t r = 0; r < order.size(); ++r) {
    const std::int64_t c = order[r];
    const int i = int(c % d[0]), j = int(c / d[0] % d[1]), k = int(c / d[0] / d[1]);
    out.row(Eigen::Index(r)) =
        key_to_coord(Key(octomap::key_type(min_key_[0] + i), octomap::key_type(min_key_[1] + j),
                         octomap::key_type(min_key_[2] + k)))
            .transpose();
  }
  return out;
}

std::int64_t OccupancyMap::verify_mirror() const {
  sync_octree();
  std::int64_t bad = 0;
  for (std::int64_t i = 0, n = std::int64_t(grid_.layout().storage_size()); i < n; ++i) {
    int x, y, z;
    if (!grid_.layout().coords(std::size_t(i), x, y, z)) continue;
    const octomap::OcTreeNode* node = tree_->search(key_at(i));
    const CellFlag f = grid_.flag(i);
    if (f == CellFlag::Unknown) {
      bad += node != nullptr;
    } else {
      bad += node == nullptr || node->getLogOdds() != grid_.logodds(i) ||
             std::fabs(grid_.entropy(i) - cell_entropy(grid_.logodds(i), f)) > 1e-6;
    }
  }
  return bad;
}

// ---- files ---------------------------------------------------------------------------------

void OccupancyMap::save(const std::string& path) const {
  const std::string ext = lower_extension(path);
  if (ext != ".ot" && ext != ".bt")
    throw std::invalid_argument("map file '" + path + "': unknown extension '" + ext +
                                "' (use .ot for full probabilities or .bt for free/occupied)");
  sync_octree();
  // OcTree::write(filename) does not check the stream after writing (a full disk left a
  // truncated file and reported success): write through a checked stream instead.
  write_file(path, [&](std::ostream& out) {
    if (ext == ".ot")
      tree_->write(out);
    else
      tree_->writeBinaryConst(out);
  });
}

OccupancyMap OccupancyMap::load(const std::string& path,
                                const std::optional<Eigen::Vector3d>& bounds_min,
                                const std::optional<Eigen::Vector3d>& bounds_max,
                                const OccupancyMapOptions& options) {
  options.validate();
  const std::string ext = lower_extension(path);
  if (ext != ".ot" && ext != ".bt")
    throw std::invalid_argument("map file '" + path + "': unknown extension '" + ext +
                                "' (expected .ot or .bt)");
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw FileNotFound(path);
  const MapFileHeader header = check_map_file(path, ext == ".bt");
  check_resolution(header.res, "map file '" + path + "': its resolution");
  // OctoMap reports progress and errors on std::cerr: keep it for the error message instead.
  struct CerrCapture {
    std::ostringstream text;
    std::streambuf* old = std::cerr.rdbuf(text.rdbuf());
    ~CerrCapture() { std::cerr.rdbuf(old); }
    std::string why() const {
      std::string t = text.str();
      while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.pop_back();
      return t.empty() ? std::string() : " (OctoMap: " + t + ")";
    }
  } cerr_capture;
  std::unique_ptr<octomap::OcTree> tree;
  if (ext == ".ot") {
    std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(path));
    if (!abstract)
      throw std::invalid_argument("map file '" + path + "' is not a readable OctoMap .ot file" +
                                  cerr_capture.why());
    auto* oc = dynamic_cast<octomap::OcTree*>(abstract.get());
    if (!oc)
      throw std::invalid_argument("map file '" + path + "' holds a " + abstract->getTreeType() +
                                  ", not an OcTree");
    abstract.release();
    tree.reset(oc);
  } else {
    tree = std::make_unique<octomap::OcTree>(0.1);
    if (!tree->readBinary(path))
      throw std::invalid_argument("map file '" + path + "' is not a readable OctoMap .bt file" +
                                  cerr_capture.why());
  }
  Eigen::Vector3d bmin, bmax;
  if (!bounds_min || !bounds_max) {
    if (tree->size() == 0)
      throw std::invalid_argument(
          "map file '" + path +
          "' holds no cells: pass bounds_min and bounds_max for the workspace");
    double x, y, z;
    const octomap::OcTree& ct = *tree;
    ct.getMetricMin(x, y, z);
    bmin = Eigen::Vector3d(x, y, z);
    ct.getMetricMax(x, y, z);
    bmax = Eigen::Vector3d(x, y, z);
  }
  if (bounds_min) bmin = *bounds_min;
  if (bounds_max) bmax = *bounds_max;
  return OccupancyMap(std::move(tree), bmin, bmax, options);
}

}  // namespace nbv
