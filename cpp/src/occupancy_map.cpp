#include "nbv/occupancy_map.hpp"

#include "nbv/parallel.hpp"

#include <octomap/AbstractOcTree.h>

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

constexpr int kTreeMaxVal = 32768;                  // OctoMap's tree_max_val at depth 16
constexpr double kFixedScale = 1125899906842624.0;  // 2^50: entropy fixed point, units per nat
constexpr double kLn2 = 0.693147180559945309417232121458176568;
constexpr double kSnap = 1e-6;  // bounds within this many cells of a grid plane snap to it
const Points kNoPoints(0, 3);

std::string fmt_vec(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

/// Binary entropy in nats of p = sigmoid(l), numerically stable for any l.
double binary_entropy_nats(double l) {
  const double a = std::fabs(l);
  const double e = std::exp(-a);
  return std::log1p(e) + a * e / (1.0 + e);
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
  require_finite(hits, "hit points");
  require_finite(free_ends, "free-space ray ends");
  if (std::isnan(max_range) || !(max_range > 0))
    throw std::invalid_argument("max_range must be > 0 (inf = no limit), got " +
                                std::to_string(max_range));
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

OccupancyMap::OccupancyMap(double resolution, const Eigen::Vector3d& bounds_min,
                           const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options)
    : opt_(options) {
  if (!std::isfinite(resolution) || !(resolution > 0))
    throw std::invalid_argument("resolution must be a finite number > 0 (metres), got " +
                                std::to_string(resolution));
  opt_.validate();
  res_ = resolution;
  init_grid(bounds_min, bounds_max);  // validates the bounds before the octree is made
  tree_ = std::make_unique<octomap::OcTree>(resolution);
  apply_tree_params();
  logodds_.assign(std::size_t(num_cells_), 0.0f);
  flags_.assign(std::size_t(num_cells_), CellFlag::Unknown);
  entropy_.assign(std::size_t(num_cells_), mirror_entropy(0.0f, CellFlag::Unknown));
  counts_ = CellCounts{};
  counts_.unknown = num_cells_;
  known_entropy_fixed_ = 0;
}

OccupancyMap::OccupancyMap(std::unique_ptr<octomap::OcTree> tree, const Eigen::Vector3d& bounds_min,
                           const Eigen::Vector3d& bounds_max, const OccupancyMapOptions& options)
    : tree_(std::move(tree)), opt_(options) {
  opt_.validate();
  res_ = tree_->getResolution();
  init_grid(bounds_min, bounds_max);
  apply_tree_params();
  rebuild_mirror_from_tree();
}

OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

void OccupancyMap::init_grid(const Eigen::Vector3d& bmin, const Eigen::Vector3d& bmax) {
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
                                  " exceed OctoMap's addressable range +-" +
                                  std::to_string(range_m) + " m at resolution " +
                                  std::to_string(res_));
    kmin[a] = std::int64_t(std::floor(lo + kSnap));
    kmax[a] = std::int64_t(std::ceil(hi - kSnap));
    if (kmax[a] <= kmin[a]) kmax[a] = kmin[a] + 1;  // a box thinner than a cell: its one cell
    if (kmin[a] + kTreeMaxVal < 0 || kmax[a] + kTreeMaxVal > 2 * kTreeMaxVal)
      throw std::invalid_argument("workspace bounds " + fmt_vec(bmin) + " - " + fmt_vec(bmax) +
                                  " exceed OctoMap's addressable range +-" +
                                  std::to_string(range_m) + " m at resolution " +
                                  std::to_string(res_));
  }
  const std::int64_t nx = kmax[0] - kmin[0], ny = kmax[1] - kmin[1], nz = kmax[2] - kmin[2];
  const double cells = double(nx) * double(ny) * double(nz);
  if (cells > double(kMaxCells))
    throw std::invalid_argument("workspace " + fmt_vec(bmin) + " - " + fmt_vec(bmax) + " at " +
                                std::to_string(res_) + " m holds " + std::to_string(cells) +
                                " cells, more than the limit " + std::to_string(kMaxCells) +
                                " (coarser resolution or smaller bounds)");
  dims_ = {int(nx), int(ny), int(nz)};
  num_cells_ = nx * ny * nz;
  for (int a = 0; a < 3; ++a) min_key_[a] = octomap::key_type(kmin[a] + kTreeMaxVal);
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

// ---- grid ----------------------------------------------------------------------------------

Eigen::Vector3d OccupancyMap::bounds_min() const {
  return Eigen::Vector3d((int(min_key_[0]) - kTreeMaxVal) * res_,
                         (int(min_key_[1]) - kTreeMaxVal) * res_,
                         (int(min_key_[2]) - kTreeMaxVal) * res_);
}

Eigen::Vector3d OccupancyMap::bounds_max() const {
  return Eigen::Vector3d((int(min_key_[0]) + dims_[0] - kTreeMaxVal) * res_,
                         (int(min_key_[1]) + dims_[1] - kTreeMaxVal) * res_,
                         (int(min_key_[2]) + dims_[2] - kTreeMaxVal) * res_);
}

bool OccupancyMap::coord_to_key(const Eigen::Vector3d& p, Key& key) const {
  return tree_->coordToKeyChecked(to_point3d(p), key);
}

Eigen::Vector3d OccupancyMap::key_to_coord(const Key& key) const {
  return Eigen::Vector3d(tree_->keyToCoord(key[0]), tree_->keyToCoord(key[1]),
                         tree_->keyToCoord(key[2]));
}

OccupancyMap::Key OccupancyMap::key_at(std::int64_t index) const {
  const std::int64_t nx = dims_[0], ny = dims_[1];
  const std::int64_t i = index % nx, j = (index / nx) % ny, k = index / (nx * ny);
  return Key(octomap::key_type(min_key_[0] + i), octomap::key_type(min_key_[1] + j),
             octomap::key_type(min_key_[2] + k));
}

// ---- entropy and mirror bookkeeping ---------------------------------------------------------

double OccupancyMap::entropy_nats_of_known(float logodds) const {
  if (opt_.clamped_entropy_zero && (logodds <= clamp_min_log_ || logodds >= clamp_max_log_))
    return 0.0;
  return binary_entropy_nats(double(logodds));
}

double OccupancyMap::cell_entropy(float logodds, CellFlag flag) const {
  const double nats = flag == CellFlag::Unknown ? kLn2 : entropy_nats_of_known(logodds);
  if (opt_.entropy_unit == EntropyUnit::Bits) return flag == CellFlag::Unknown ? 1.0 : nats / kLn2;
  return nats;
}

std::int64_t OccupancyMap::fixed_entropy(float logodds, CellFlag flag) const {
  if (flag == CellFlag::Unknown) return 0;  // unknown cells are counted as unknown * ln 2
  return std::llround(entropy_nats_of_known(logodds) * kFixedScale);
}

void OccupancyMap::set_mirror(std::size_t i, float logodds, CellFlag flag) {
  const CellFlag old_flag = flags_[i];
  const float old_l = logodds_[i];
  if (old_flag == flag && old_l == logodds) return;
  if (old_flag == CellFlag::Unknown) {
    --counts_.unknown;
  } else {
    (old_l >= occ_thres_log_ ? counts_.occupied : counts_.free) -= 1;
    if (old_flag == CellFlag::Predicted) --counts_.predicted;
    known_entropy_fixed_ -= cached_fixed_entropy(old_l);
  }
  if (flag == CellFlag::Unknown) {
    ++counts_.unknown;
    entropy_[i] = mirror_entropy(logodds, flag);
  } else {
    (logodds >= occ_thres_log_ ? counts_.occupied : counts_.free) += 1;
    if (flag == CellFlag::Predicted) ++counts_.predicted;
    const std::int64_t fixed = cached_fixed_entropy(logodds);
    known_entropy_fixed_ += fixed;
    entropy_[i] = entropy_float(fixed);
  }
  flags_[i] = flag;
  logodds_[i] = logodds;
}

float OccupancyMap::entropy_float(std::int64_t fixed) const {
  const double nats = double(fixed) / kFixedScale;
  return float(opt_.entropy_unit == EntropyUnit::Bits ? nats / kLn2 : nats);
}

float OccupancyMap::mirror_entropy(float logodds, CellFlag flag) const {
  if (flag == CellFlag::Unknown) return float(cell_entropy(logodds, flag));
  return entropy_float(fixed_entropy(logodds, flag));
}

std::int64_t OccupancyMap::cached_fixed_entropy(float logodds) {
  std::uint32_t bits;
  std::memcpy(&bits, &logodds, sizeof bits);
  EntropyCacheEntry& e =
      entropy_cache_[(bits ^ (bits >> 13) ^ (bits >> 23)) & (entropy_cache_.size() - 1)];
  if (e.bits != bits) {
    e.bits = bits;
    e.fixed = fixed_entropy(logodds, CellFlag::Observed);
  }
  return e.fixed;
}

double OccupancyMap::total_entropy() const {
  const double known_nats = double(known_entropy_fixed_) / kFixedScale;
  if (opt_.entropy_unit == EntropyUnit::Bits) return double(counts_.unknown) + known_nats / kLn2;
  return double(counts_.unknown) * kLn2 + known_nats;
}

__int128 OccupancyMap::sum_known_entropy_fixed() const {
  const std::size_t n = std::size_t(num_cells_);
  const std::size_t grain = 1 << 16;
  const std::size_t nchunks = (n + grain - 1) / grain;
  std::vector<__int128> sums(nchunks, 0);
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      __int128 s = 0;
      for (std::size_t i = c * grain, e = std::min(n, (c + 1) * grain); i < e; ++i)
        if (flags_[i] != CellFlag::Unknown) s += fixed_entropy(logodds_[i], flags_[i]);
      sums[c] = s;
    }
  });
  __int128 s = 0;
  for (const __int128 v : sums) s += v;  // integers: the same sum in any order
  return s;
}

double OccupancyMap::recompute_total_entropy() const {
  const double known_nats = double(sum_known_entropy_fixed()) / kFixedScale;
  const double unknown = double(recompute_counts().unknown);
  if (opt_.entropy_unit == EntropyUnit::Bits) return unknown + known_nats / kLn2;
  return unknown * kLn2 + known_nats;
}

CellCounts OccupancyMap::recompute_counts() const {
  CellCounts c;
  for (std::size_t i = 0, n = std::size_t(num_cells_); i < n; ++i) {
    if (flags_[i] == CellFlag::Unknown) {
      ++c.unknown;
      continue;
    }
    (logodds_[i] >= occ_thres_log_ ? c.occupied : c.free) += 1;
    if (flags_[i] == CellFlag::Predicted) ++c.predicted;
  }
  return c;
}

void OccupancyMap::rebuild_mirror_from_tree() {
  const std::size_t n = std::size_t(num_cells_);
  logodds_.assign(n, 0.0f);
  flags_.assign(n, CellFlag::Unknown);
  const int lo[3] = {min_key_[0], min_key_[1], min_key_[2]};
  const int hi[3] = {lo[0] + dims_[0], lo[1] + dims_[1], lo[2] + dims_[2]};  // exclusive
  const unsigned depth_max = tree_->getTreeDepth();
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
      for (int y = b[1]; y < e[1]; ++y) {
        const std::size_t row =
            std::size_t(z - lo[2]) * std::size_t(dims_[1]) * std::size_t(dims_[0]) +
            std::size_t(y - lo[1]) * std::size_t(dims_[0]);
        for (int x = b[0]; x < e[0]; ++x) {
          logodds_[row + std::size_t(x - lo[0])] = l;
          flags_[row + std::size_t(x - lo[0])] = CellFlag::Observed;
        }
      }
  }
  entropy_.resize(n);
  parallel_chunks(n, 1 << 15, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) entropy_[i] = mirror_entropy(logodds_[i], flags_[i]);
  });
  counts_ = recompute_counts();
  known_entropy_fixed_ = sum_known_entropy_fixed();
}

// ---- integration ---------------------------------------------------------------------------

void OccupancyMap::FreeDeleter::operator()(void* p) const noexcept { std::free(p); }

void OccupancyMap::ensure_scratch() {
  if (stamp_) return;
  stamp_.reset(
      static_cast<std::uint32_t*>(std::calloc(std::size_t(num_cells_), sizeof(std::uint32_t))));
  group_of_.reset(
      static_cast<std::int32_t*>(std::malloc(std::size_t(num_cells_) * sizeof(std::int32_t))));
  if (!stamp_ || !group_of_) throw std::bad_alloc();
  stamp_counter_ = 0;
}

std::uint32_t OccupancyMap::next_stamp(unsigned n) {
  if (stamp_counter_ > std::numeric_limits<std::uint32_t>::max() - n - 1) {
    std::fill(stamp_.get(), stamp_.get() + num_cells_, 0u);
    stamp_counter_ = 0;
  }
  const std::uint32_t first = stamp_counter_ + 1;
  stamp_counter_ += n;
  return first;
}

void OccupancyMap::update_cell(const Key& key, bool hit) {
  const std::int64_t idx = index_of(key);
  octomap::OcTreeNode* node;
  if (idx >= 0 && flags_[std::size_t(idx)] == CellFlag::Predicted) {
    // An observation overrides a prediction: restart from unknown (log-odds 0), then update. On
    // a fresh node OctoMap computes 0 + update, clamped; setNodeValue clamps the same way.
    node = tree_->setNodeValue(key, hit ? hit_log_ : miss_log_, false);
  } else {
    node = tree_->updateNode(key, hit, false);
  }
  if (idx >= 0) set_mirror(std::size_t(idx), node->getLogOdds(), CellFlag::Observed);
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

}  // namespace

void OccupancyMap::apply_updates(const std::vector<Key>& misses, const std::vector<Key>& hits) {
  // Same leaf values as one updateNode(key, hit/miss, lazy_eval = false) per cell; faster: the
  // mirror answers OctoMap's early-abort search and supplies the current value (setNodeValue of
  // value + update, clamped as updateNodeLogOdds clamps), cells are visited in tree order, and
  // inner nodes are pruned / updated once per batch instead of once per cell.
  struct Update {
    std::uint64_t code;
    Key key;
    float value;  // new value (workspace cells) or update (cells outside the workspace)
    std::int64_t idx;
  };
  std::vector<Update> ups;
  ups.reserve(misses.size() + hits.size());
  auto add = [&](const Key& key, bool hit) {
    const float update = hit ? hit_log_ : miss_log_;
    const std::int64_t idx = index_of(key);
    float value = update;  // unknown, or predicted (an observation restarts it from log-odds 0)
    if (idx >= 0 && flags_[std::size_t(idx)] == CellFlag::Observed) {
      const float l = logodds_[std::size_t(idx)];
      if (hit ? l >= clamp_max_log_ : l <= clamp_min_log_) return;  // OctoMap's early abort
      value = l + update;  // OctoMap's addValue on the leaf, whose value the mirror holds
    }
    ups.push_back(Update{tree_order(key), key, value, idx});
  };
  for (const Key& k : misses) add(k, false);
  for (const Key& k : hits) add(k, true);
  if (ups.empty()) return;
  std::sort(ups.begin(), ups.end(),
            [](const Update& a, const Update& b) { return a.code < b.code; });
  for (const Update& u : ups) {
    if (u.idx >= 0) {
      const octomap::OcTreeNode* node = tree_->setNodeValue(u.key, u.value, true);
      set_mirror(std::size_t(u.idx), node->getLogOdds(), CellFlag::Observed);
    } else {
      tree_->updateNode(u.key, u.value, true);
    }
  }
  std::vector<std::uint64_t> codes(ups.size());
  for (std::size_t i = 0; i < ups.size(); ++i) codes[i] = ups[i].code;
  fix_inner_nodes(*tree_, tree_->getRoot(), 0, codes.data(), 0, codes.size());
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

IntegrationStats OccupancyMap::integrate(const Scan& scan, double max_range) {
  return integrate(scan.origin, scan.hits, scan.free_ends, max_range);
}

IntegrationStats OccupancyMap::integrate(const Eigen::Vector3d& origin, const PointsRef& hits,
                                         const PointsRef& free_ends, double max_range) {
  // points are checked for NaN/inf inside the parallel pass below (before anything changes)
  check_integrate_args(origin, PointsRef(kNoPoints), PointsRef(kNoPoints), max_range);
  const octomap::point3d o = to_point3d(origin);
  Key okey;
  if (!tree_->coordToKeyChecked(o, okey))
    throw std::invalid_argument("sensor origin " + fmt_vec(origin) +
                                " is outside OctoMap's addressable range");
  const std::size_t nh = std::size_t(hits.rows()), nf = std::size_t(free_ends.rows()), n = nh + nf;
  IntegrationStats stats;
  stats.rays = n;
  if (n == 0) return stats;
  const bool cut = std::isfinite(max_range);

  // 1. Per ray (parallel over fixed chunks): its end point (cut at max_range as OctoMap does),
  //    the end cell's key (OctoMap's coordToKeyChecked: floor(resolution_factor * c) + 32768)
  //    and the sub-cell of the end point. Consecutive rays ending in the same sub-cell
  //    (neighbouring pixels) are merged on the fly into one candidate.
  const bool dedup = opt_.deduplicate_end_points;
  const bool clip = opt_.clip_to_workspace;
  const int k = dedup ? opt_.end_point_subdivision : 1;
  const double rf = 1.0 / res_;  // OctoMap's resolution_factor
  const double kd = k, inv_k = 1.0 / k;
  enum : std::uint8_t { kHitFlag = 1, kFreeEndFlag = 2 };
  struct Cand {
    octomap::point3d rep;  // representative end point: the one nearest the sub-cell centre
    float d2;              // its squared distance to the sub-cell centre (cell units)
    Key key;               // end cell
    std::uint16_t sub;     // sub-cell index within the end cell
    std::uint8_t flags;    // some ray of the group is a hit / a free end in range
  };
  const std::size_t chunk1 = 4096, nchunks1 = (n + chunk1 - 1) / chunk1;
  std::vector<std::vector<Cand>> cands(nchunks1);
  std::atomic<int> non_finite{0};  // 1: a hit, 2: a free end is NaN or infinite
  const octomap::OcTree& tree = *tree_;
  parallel_chunks(nchunks1, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::vector<Cand>& out = cands[c];
      out.reserve(dedup ? 1024 : chunk1);
      for (std::size_t r = c * chunk1, e = std::min(n, (c + 1) * chunk1); r < e; ++r) {
        const bool is_hit = r < nh;
        const auto row = is_hit ? hits.row(Eigen::Index(r)) : free_ends.row(Eigen::Index(r - nh));
        if (!(std::isfinite(row(0)) && std::isfinite(row(1)) && std::isfinite(row(2)))) {
          non_finite.store(is_hit ? 1 : 2, std::memory_order_relaxed);
          continue;
        }
        octomap::point3d p = row_point3d(row);
        std::uint8_t flag = is_hit ? kHitFlag : kFreeEndFlag;
        if (cut && (p - o).norm() > max_range) {  // OctoMap's maxrange rule (computeUpdate)
          const octomap::point3d dir = (p - o).normalized();
          p = o + dir * float(max_range);
          flag = 0;  // the ray clears the cells before its cut end, nothing else
        }
        Key key;
        int sub = 0;
        double d2 = 0;
        bool inside = true;
        for (int a = 2; a >= 0; --a) {
          const double t = rf * double(p(a));
          if (!(std::fabs(t) < 1e9)) {
            inside = false;
            break;
          }
          int fl = int(t);
          fl -= double(fl) > t;  // floor, without a libm call
          const int kv = fl + kTreeMaxVal;
          if (kv < 0 || kv >= 2 * kTreeMaxVal) {
            inside = false;
            break;
          }
          key[a] = octomap::key_type(kv);
          const double frac = t - fl;  // position within the cell, [0, 1)
          const int sa = std::min(k - 1, int(frac * kd));
          const double dc = frac - (sa + 0.5) * inv_k;
          d2 += dc * dc;
          sub = sub * k + sa;
        }
        if (!inside) continue;  // OctoMap skips rays whose end it cannot address
        if (dedup && !out.empty() && out.back().key == key && out.back().sub == sub) {
          Cand& cd = out.back();
          if (float(d2) < cd.d2) {
            cd.d2 = float(d2);
            cd.rep = p;
          }
          cd.flags |= flag;
        } else {
          out.push_back(Cand{p, float(d2), key, std::uint16_t(sub), flag});
        }
      }
    }
  });

  if (const int bad = non_finite.load())
    throw std::invalid_argument(bad == 1 ? "hit points contain NaN or infinite values"
                                         : "free-space ray ends contain NaN or infinite values");

  // 2. Group candidates by end sub-cell (serial, in ray order): cells through the stamp array
  //    (workspace) or a hash map (outside), kk group slots per cell.
  ensure_scratch();
  const std::uint32_t s_group = next_stamp(3), s_free = s_group + 1, s_occ = s_group + 2;
  const int kk = k * k * k;
  std::vector<Cand> groups;
  std::vector<std::int32_t> slots;  // kk group slots per end cell (-1: none yet)
  std::unordered_map<Key, std::int32_t, KeyHash> outside_cells;
  {
    std::size_t nc = 0;
    for (const auto& v : cands) nc += v.size();
    groups.reserve(dedup ? std::min<std::size_t>(nc, 1 << 16) : nc);
  }
  for (const auto& chunk_cands : cands) {
    for (const Cand& cd : chunk_cands) {
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
      Cand& gr = groups[std::size_t(slot)];
      if (cd.d2 < gr.d2) {
        gr.d2 = cd.d2;
        gr.rep = cd.rep;
      }
      gr.flags |= cd.flags;
    }
  }
  cands.clear();
  cands.shrink_to_fit();
  stats.traced_rays = groups.size();

  // 3. End cells: hits first (a cell hit in this scan is never also a miss), then free ends.
  std::vector<Key> occ, fr;
  std::unordered_set<Key, KeyHash> occ_out, free_out;
  for (const Cand& gr : groups) {
    if (!(gr.flags & kHitFlag)) continue;
    const std::int64_t idx = index_of(gr.key);
    if (idx >= 0) {
      if (stamp_[std::size_t(idx)] != s_occ) {
        stamp_[std::size_t(idx)] = s_occ;
        occ.push_back(gr.key);
      }
    } else if (!clip && occ_out.insert(gr.key).second) {
      occ.push_back(gr.key);
    }
  }
  std::vector<Key> outside_free;
  for (const Cand& gr : groups) {
    if (!(gr.flags & kFreeEndFlag) || (gr.flags & kHitFlag)) continue;
    const std::int64_t idx = index_of(gr.key);
    if (idx < 0) {
      if (!clip) outside_free.push_back(gr.key);
    } else if (stamp_[std::size_t(idx)] != s_occ && stamp_[std::size_t(idx)] != s_free) {
      stamp_[std::size_t(idx)] = s_free;
      fr.push_back(gr.key);
    }
  }

  // 4. Walk one ray per group (parallel over fixed chunks). A workspace cell is claimed for this
  //    scan's misses by the first walker that stamps it (atomic; cells hit in this scan keep
  //    their stamp); cells outside the workspace are merged afterwards through hash sets.
  const std::size_t ng = groups.size();
  const std::size_t grain = 32;
  const std::size_t nchunks = (ng + grain - 1) / grain;
  std::vector<std::vector<Key>> chunk_free(nchunks), chunk_out(nchunks);
  std::uint32_t* const stamps = stamp_.get();
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::vector<Key>& out = chunk_free[c];
      std::vector<Key>& out_outside = chunk_out[c];
      out.reserve(grain * 16);
      for (std::size_t g = c * grain, e = std::min(ng, (c + 1) * grain); g < e; ++g)
        walk_ray_keys(tree, o, groups[g].rep, [&](const Key& key) {
          const std::int64_t idx = index_of(key);
          if (idx < 0) {
            if (!clip) out_outside.push_back(key);
            return;
          }
          std::uint32_t* st = stamps + idx;
          std::uint32_t cur = __atomic_load_n(st, __ATOMIC_RELAXED);
          while (cur != s_occ && cur != s_free) {
            if (__atomic_compare_exchange_n(st, &cur, s_free, false, __ATOMIC_RELAXED,
                                            __ATOMIC_RELAXED)) {
              out.push_back(key);
              break;
            }
          }
        });
    }
  });
  {
    std::size_t total = fr.size();
    for (const auto& v : chunk_free) total += v.size();
    fr.reserve(total);
  }
  for (const auto& v : chunk_free) fr.insert(fr.end(), v.begin(), v.end());
  for (const Key& key : outside_free)
    if (!occ_out.count(key) && free_out.insert(key).second) fr.push_back(key);
  for (const auto& v : chunk_out)
    for (const Key& key : v)
      if (!occ_out.count(key) && free_out.insert(key).second) fr.push_back(key);

  // 5. Update the octree and the mirror, each cell once.
  apply_updates(fr, occ);
  stats.free_cells = fr.size();
  stats.occupied_cells = occ.size();
  return stats;
}

IntegrationStats OccupancyMap::integrate_exact(const Eigen::Vector3d& origin, const PointsRef& hits,
                                               const PointsRef& free_ends, double max_range) {
  check_integrate_args(origin, hits, free_ends, max_range);
  const octomap::point3d o = to_point3d(origin);
  Key okey;
  if (!tree_->coordToKeyChecked(o, okey))
    throw std::invalid_argument("sensor origin " + fmt_vec(origin) +
                                " is outside OctoMap's addressable range");
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
    throw std::invalid_argument("radius must be finite and >= 0, got " + std::to_string(radius));
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
    return flags_[std::size_t(idx)] == CellFlag::Unknown;
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
    throw std::invalid_argument("probability must be in (0, 1), got " +
                                std::to_string(probability));
  const float l = octomap::logodds(probability);
  std::size_t set = 0;
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    Key key;
    if (!tree_->coordToKeyChecked(row_point3d(points.row(r)), key)) continue;
    const std::int64_t idx = index_of(key);
    if (idx < 0 || flags_[std::size_t(idx)] != CellFlag::Unknown) continue;
    octomap::OcTreeNode* node = tree_->setNodeValue(key, l, false);
    set_mirror(std::size_t(idx), node->getLogOdds(), CellFlag::Predicted);
    ++set;
  }
  return set;
}

// ---- queries -------------------------------------------------------------------------------

namespace {
struct Lookup {
  bool known = false;
  float logodds = 0;
  CellFlag flag = CellFlag::Unknown;
};

Lookup lookup(const OccupancyMap& m, const Eigen::Vector3d& p) {
  Lookup out;
  Key key;
  if (!m.coord_to_key(p, key)) return out;
  const std::int64_t idx = m.index_of(key);
  if (idx >= 0) {
    out.flag = m.flag_at(idx);
    out.known = out.flag != CellFlag::Unknown;
    out.logodds = m.logodds_at(idx);
  } else if (const octomap::OcTreeNode* n = m.octree().search(key)) {
    out.known = true;
    out.flag = CellFlag::Observed;
    out.logodds = n->getLogOdds();
  }
  return out;
}
}  // namespace

CellState OccupancyMap::state(const Eigen::Vector3d& p) const {
  const Lookup c = lookup(*this, p);
  if (!c.known) return CellState::Unknown;
  return c.logodds >= occ_thres_log_ ? CellState::Occupied : CellState::Free;
}

double OccupancyMap::probability(const Eigen::Vector3d& p) const {
  const Lookup c = lookup(*this, p);
  return c.known ? octomap::probability(c.logodds) : 0.5;
}

double OccupancyMap::entropy(const Eigen::Vector3d& p) const {
  const Lookup c = lookup(*this, p);
  return cell_entropy(c.logodds, c.known ? c.flag : CellFlag::Unknown);
}

bool OccupancyMap::is_predicted(const Eigen::Vector3d& p) const {
  const Lookup c = lookup(*this, p);
  return c.flag == CellFlag::Predicted;
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

Points OccupancyMap::occupied_cells() const {
  std::vector<std::int64_t> idx;
  idx.reserve(std::size_t(counts_.occupied));
  for (std::int64_t i = 0; i < num_cells_; ++i)
    if (state_at(i) == CellState::Occupied) idx.push_back(i);
  Points out(Eigen::Index(idx.size()), 3);
  for (std::size_t r = 0; r < idx.size(); ++r)
    out.row(Eigen::Index(r)) = key_to_coord(key_at(idx[r])).transpose();
  return out;
}

std::int64_t OccupancyMap::verify_mirror() const {
  std::int64_t bad = 0;
  for (std::int64_t i = 0; i < num_cells_; ++i) {
    const octomap::OcTreeNode* node = tree_->search(key_at(i));
    const CellFlag f = flags_[std::size_t(i)];
    if (f == CellFlag::Unknown) {
      bad += node != nullptr;
    } else {
      bad += node == nullptr || node->getLogOdds() != logodds_[std::size_t(i)] ||
             entropy_[std::size_t(i)] != mirror_entropy(logodds_[std::size_t(i)], f);
    }
  }
  return bad;
}

// ---- files ---------------------------------------------------------------------------------

void OccupancyMap::save(const std::string& path) const {
  const std::string ext = lower_extension(path);
  bool ok;
  if (ext == ".ot")
    ok = tree_->write(path);
  else if (ext == ".bt")
    ok = tree_->writeBinaryConst(path);
  else
    throw std::invalid_argument("map file '" + path + "': unknown extension '" + ext +
                                "' (use .ot for full probabilities or .bt for free/occupied)");
  if (!ok) throw std::runtime_error("could not write map file '" + path + "'");
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
  if (std::filesystem::is_directory(path, ec))
    throw std::invalid_argument("map file '" + path + "' is a directory");
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
