#include "nbv/point_cloud.hpp"
#include "nbv/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <random>
#include <string>

namespace nbv {

std::uint64_t draw_hash_seed() {
  try {
    std::random_device rd;
    return std::uint64_t(rd()) << 32 ^ rd();
  } catch (const std::exception&) {  // no entropy source: the clock (at import, never a throw)
    return static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count() *
                                      0x9E3779B97F4A7C15ull);
  }
}
namespace {
// Marks a point dropped by ground removal or cropping (pack_voxel never sets bit 63).
constexpr std::uint64_t kFiltered = kEmptyVoxelKey - 1;
}  // namespace

// ---------------------------------------------------------------------------- VoxelIndex

void VoxelIndex::clear() {
  std::fill(slots_.begin(), slots_.end(), kMissing);
  keys_.clear();
}

std::size_t VoxelIndex::capacity_for(std::size_t n) {
  std::size_t cap = 16;
  while (3 * cap < 4 * n) cap <<= 1;
  return cap;
}

void VoxelIndex::reserve(std::size_t n) {
  if (n > kMaxKeys) throw std::length_error("VoxelIndex: more than 3 * 2^30 keys");
  const std::size_t cap = capacity_for(n);
  if (cap > slots_.size()) rehash(cap);
  // a quarter more when the keys must move: millions of keys grow a little at a time
  if (n > keys_.capacity()) keys_.reserve(std::max(n, keys_.capacity() + keys_.capacity() / 2));
}

void VoxelIndex::shrink_to_fit() {
  keys_.shrink_to_fit();
  const std::size_t cap = capacity_for(keys_.size());
  if (cap < slots_.size()) rehash(cap);
}

void VoxelIndex::rehash(std::size_t capacity) {
  slots_ = HugeVector<std::uint32_t>();  // freed first: the keys alone rebuild the table
  slots_.assign(capacity, kMissing);
  mask_ = capacity - 1;
  for (std::size_t id = 0; id < keys_.size(); ++id) {
    const std::uint64_t h = hash(keys_[id]);
    std::size_t s = h & mask_;
    while (slots_[s] != kMissing) s = (s + 1) & mask_;
    slots_[s] = tag_of(h) | static_cast<std::uint32_t>(id);
  }
}

std::pair<std::uint32_t, bool> VoxelIndex::insert(std::uint64_t key) {
  if (4 * (keys_.size() + 1) > 3 * slots_.size()) reserve(keys_.size() + 1);
  const std::uint64_t h = hash(key);
  const std::uint32_t tag = tag_of(h), low = std::uint32_t(mask_);
  for (std::size_t i = h & mask_;; i = (i + 1) & mask_) {
    const std::uint32_t w = slots_[i];
    if (w == kMissing) {
      const auto fresh = static_cast<std::uint32_t>(keys_.size());
      keys_.push_back(key);
      slots_[i] = tag | fresh;
      return {fresh, true};
    }
    if ((w & ~low) == tag && keys_[w & low] == key) return {w & low, false};
  }
}

// ---------------------------------------------------------------------------- VoxelCentroids

namespace {
/// s += points.row(i), coordinate by coordinate (as Eigen's sum).
inline void accumulate(std::array<double, 3>& s, const PointsRef& points, std::size_t i) {
  const auto r = static_cast<Eigen::Index>(i);
  s[0] += points(r, 0);
  s[1] += points(r, 1);
  s[2] += points(r, 2);
}
}  // namespace

VoxelCentroids::VoxelCentroids(double voxel_size, bool single)
    : size_(voxel_size), inv_(1.0 / voxel_size), single_(single) {
  if (single) require_cell_size(voxel_size, "voxel size");
}

std::size_t VoxelCentroids::add(const PointsRef& points, const std::vector<std::uint64_t>& keys,
                                std::uint64_t skip) {
  if (keys.size() != static_cast<std::size_t>(points.rows()))
    throw std::invalid_argument("VoxelCentroids::add: one key per point");
  return single_ ? add_to(offsets_, points, keys, skip) : add_to(sum_, points, keys, skip);
}

template <class Sum>
std::size_t VoxelCentroids::add_to(GrowArray<Sum>& sums, const PointsRef& points,
                                   const std::vector<std::uint64_t>& keys, std::uint64_t skip) {
  // s += the point (double sums), or its offset from the corner of the voxel of `key` (single)
  const auto accumulate = [&](Sum& s, std::size_t i, std::uint64_t key) {
    if constexpr (std::is_same_v<Sum, std::array<double, 3>>) {
      nbv::accumulate(s, points, i);
    } else {
      const Eigen::Vector3d c = corner(key);
      const auto r = static_cast<Eigen::Index>(i);
      s[0] += static_cast<float>(points(r, 0) - c[0]);
      s[1] += static_cast<float>(points(r, 1) - c[1]);
      s[2] += static_cast<float>(points(r, 2) - c[2]);
    }
  };
  index_.reserve(count_.size() + keys.size() / 8);
  const std::size_t before = count_.size(), n = keys.size();
  const int threads = get_num_threads();
  if (threads < 2 || n < 8192) {
    // Consecutive sensor points often share a voxel: remember the last one.
    std::uint64_t last_key = kEmptyVoxelKey;
    std::uint32_t last = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t k = keys[i];
      if (k == skip) continue;
      if (k != last_key) {
        last = voxel_of(k);
        last_key = k;
      }
      accumulate(sums[last], i, k);
      ++count_[last];
    }
    return count_.size() - before;
  }
  // In parallel, with the serial result: (1) each point's voxel where it exists (lookups only;
  // in a table of millions of voxels most are cache misses), (2) in input order, the voxels first
  // seen here get the next ids, (3) each voxel's points are summed, in input order, by the one
  // task that owns its block of 64 voxels.
  constexpr std::uint32_t kSkipped = VoxelIndex::kMissing - 1;
  constexpr std::size_t kAhead = 16;  // the slot of the point this far ahead is loaded first
  std::vector<std::uint32_t> id(n);
  parallel_chunks(n, 4096, [&](std::size_t b, std::size_t e) {
    std::uint64_t last_key = kEmptyVoxelKey;
    std::uint32_t last = 0;
    for (std::size_t i = b; i < e; ++i) {
      if (i + kAhead < e && keys[i + kAhead] != keys[i + kAhead - 1])
        index_.prefetch(keys[i + kAhead]);
      const std::uint64_t k = keys[i];
      if (k == skip) {
        id[i] = kSkipped;
        continue;
      }
      if (k != last_key) {
        last = index_.find(k);
        last_key = k;
      }
      id[i] = last;
    }
  });
  std::uint64_t last_key = kEmptyVoxelKey;
  std::uint32_t last = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kAhead < n && id[i + kAhead] == VoxelIndex::kMissing &&
        keys[i + kAhead] != keys[i + kAhead - 1])
      index_.prefetch(keys[i + kAhead]);
    if (id[i] != VoxelIndex::kMissing) continue;
    if (keys[i] != last_key) {
      last = voxel_of(keys[i]);
      last_key = keys[i];
    }
    id[i] = last;
  }
  const std::size_t parts = static_cast<std::size_t>(threads);
  parallel_chunks(parts, 1, [&](std::size_t pb, std::size_t pe) {
    for (std::size_t part = pb; part < pe; ++part)
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t v = id[i];
        if (v == kSkipped || (v >> 6) % parts != part) continue;
        accumulate(sums[v], i, keys[i]);
        ++count_[v];
      }
  });
  return count_.size() - before;
}

std::uint32_t VoxelCentroids::voxel_of(std::uint64_t key) {
  const auto r = index_.insert(key);
  if (r.second) {
    if (single_)
      offsets_.push_back({0.0f, 0.0f, 0.0f});
    else
      sum_.push_back({0.0, 0.0, 0.0});
    count_.push_back(0);
  }
  return r.first;
}

Points stack_points(const std::vector<const SurfaceCloud*>& clouds, std::size_t start,
                    std::size_t stop) {
  std::size_t n = 0;
  for (const SurfaceCloud* c : clouds) n += c->size();
  stop = std::min(stop, n);
  start = std::min(start, stop);
  Points out(static_cast<Eigen::Index>(stop - start), 3);
  Eigen::Index row = 0;
  std::size_t first = 0;  // the stacked row of the cloud's first point
  for (const SurfaceCloud* c : clouds) {
    const std::size_t b = std::max(start, first), e = std::min(stop, first + c->size());
    for (std::size_t i = b; i < e; ++i) out.row(row++) = c->point(i - first).transpose();
    first += c->size();
  }
  return out;
}

Points VoxelCentroids::centroids() const {
  Points out(static_cast<Eigen::Index>(count_.size()), 3);
  for (std::size_t i = 0; i < count_.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = centroid(i).transpose();
  return out;
}

std::size_t VoxelCentroids::bytes() const {
  return index_.bytes() + sum_.capacity() * sizeof(sum_[0]) +
         offsets_.capacity() * sizeof(offsets_[0]) + count_.capacity() * sizeof(count_[0]);
}

void VoxelCentroids::clear() {
  index_ = VoxelIndex();
  sum_.clear();
  sum_.shrink_to_fit();
  offsets_.clear();
  offsets_.shrink_to_fit();
  count_.clear();
  count_.shrink_to_fit();
}

namespace {
void check_voxel_size(double voxel_size) { require_cell_size(voxel_size, "voxel size"); }

/// Adds points to v, each to its voxel of size voxel_size (keys: scratch).
void add_to_voxels(VoxelCentroids& v, const PointsRef& points, double voxel_size,
                   std::vector<std::uint64_t>& keys) {
  keys.resize(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    keys[static_cast<std::size_t>(i)] = voxel_key(points.row(i).transpose(), voxel_size);
  v.add(points, keys);
}
}  // namespace

Points voxelgrid_sampling(const PointsRef& points, double voxel_size) {
  check_voxel_size(voxel_size);
  require_finite(points, "points");
  VoxelCentroids v;
  std::vector<std::uint64_t> keys;
  add_to_voxels(v, points, voxel_size, keys);
  return v.centroids();
}

Points voxelgrid_sampling(const std::vector<const SurfaceCloud*>& clouds, double voxel_size,
                          std::size_t chunk) {
  check_voxel_size(voxel_size);
  chunk = std::max<std::size_t>(chunk, 1);
  std::size_t n = 0;
  for (const SurfaceCloud* c : clouds) n += c->size();
  VoxelCentroids v;
  std::vector<std::uint64_t> keys;
  for (std::size_t start = 0; start < n; start += chunk) {
    const Points part = stack_points(clouds, start, start + chunk);
    add_to_voxels(v, part, voxel_size, keys);
  }
  return v.centroids();
}

// ---------------------------------------------------------------------------- SurfaceCloud

void SurfaceCloudOptions::validate() const {
  require_cell_size(voxel_size, "voxel_size");
  if (std::isnan(min_z) || min_z == std::numeric_limits<double>::infinity())
    throw std::invalid_argument(
        "min_z must be a number of metres or -inf (no ground removal), got " +
        std::to_string(min_z));
  if (crop) {
    if (!crop_min.allFinite() || !crop_max.allFinite())
      throw std::invalid_argument("crop box contains NaN or infinite values");
    if ((crop_max.array() < crop_min.array()).any())
      throw std::invalid_argument("crop box max must be >= min on every axis");
  }
}

SurfaceCloud::SurfaceCloud(const SurfaceCloudOptions& options)
    : opt_((options.validate(), options)), voxels_(opt_.voxel_size, opt_.single_precision) {}

SurfaceCloud::SurfaceCloud(const SurfaceCloud& other)
    : opt_(other.opt_), voxels_(other.voxels_), registered_(other.registered_) {}

SurfaceCloud& SurfaceCloud::operator=(const SurfaceCloud& other) {
  if (this != &other) {
    opt_ = other.opt_;
    voxels_ = other.voxels_;
    registered_ = other.registered_;
    stamp_ = new_stamp();
  }
  return *this;
}

std::uint64_t SurfaceCloud::new_stamp() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

std::vector<std::uint64_t> SurfaceCloud::voxel_keys(const PointsRef& points) const {
  const Eigen::Index n = points.rows();
  const double s = opt_.voxel_size, inv = 1.0 / s;
  // In parallel: keys, kFiltered for filtered-out points, kEmptyVoxelKey out of range.
  std::vector<std::uint64_t> keys(static_cast<std::size_t>(n));
  std::atomic<bool> out_of_range{false}, non_finite{false};
  const auto key_range = [&](std::size_t b, std::size_t e) {
    for (std::size_t j = b; j < e; ++j) {
      const auto i = static_cast<Eigen::Index>(j);
      const double x = points(i, 0), y = points(i, 1), z = points(i, 2);
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) {
        non_finite = true;
        keys[j] = kFiltered;
        continue;
      }
      bool keep = z >= opt_.min_z;
      if (keep && opt_.crop)
        keep = x >= opt_.crop_min.x() && x <= opt_.crop_max.x() && y >= opt_.crop_min.y() &&
               y <= opt_.crop_max.y() && z >= opt_.crop_min.z() && z <= opt_.crop_max.z();
      if (!keep) {
        keys[j] = kFiltered;
        continue;
      }
      keys[j] = try_voxel_key(x, y, z, s, inv);
      if (keys[j] == kEmptyVoxelKey) out_of_range = true;
    }
  };
  if (n > 16384)
    parallel_chunks(static_cast<std::size_t>(n), 8192, key_range);
  else
    key_range(0, static_cast<std::size_t>(n));
  if (non_finite) throw std::invalid_argument("points contains NaN or infinite values");
  if (out_of_range)
    for (Eigen::Index i = 0; i < n; ++i)
      if (keys[static_cast<std::size_t>(i)] == kEmptyVoxelKey)
        voxel_index(points.row(i).transpose(), s);  // throws naming the coordinate
  return keys;
}

std::size_t SurfaceCloud::add_keyed(const PointsRef& points,
                                    const std::vector<std::uint64_t>& keys) {
  const std::size_t added = voxels_.add(points, keys, kFiltered);
  registered_ += static_cast<std::uint64_t>(
      std::count_if(keys.begin(), keys.end(), [](std::uint64_t k) { return k != kFiltered; }));
  return added;
}

Points SurfaceCloud::points() const { return voxels_.centroids(); }

Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1> SurfaceCloud::counts() const {
  const auto& c = voxels_.counts();
  Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1> out(static_cast<Eigen::Index>(c.size()));
  for (std::size_t i = 0; i < c.size(); ++i) out[static_cast<Eigen::Index>(i)] = c[i];
  return out;
}

void SurfaceCloud::clear() {
  voxels_.clear();
  registered_ = 0;
  stamp_ = new_stamp();
}

// ---------------------------------------------------------------------------- LZF

std::vector<std::uint8_t> lzf_decompress(const std::uint8_t* in, std::size_t in_size,
                                         std::size_t out_size) {
  // A back reference emits at most 264 bytes from 2 or 3 input bytes: a larger claim is corrupt
  // (and must not allocate).
  if (out_size / 132 > in_size + 1)
    throw std::invalid_argument("corrupt LZF-compressed data: " + std::to_string(in_size) +
                                " bytes cannot expand to " + std::to_string(out_size));
  std::vector<std::uint8_t> out(out_size);
  std::size_t ip = 0, op = 0;
  const auto corrupt = [] { throw std::invalid_argument("corrupt LZF-compressed data"); };
  while (ip < in_size) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {  // literal run of ctrl + 1 bytes
      const std::size_t len = ctrl + 1;
      if (ip + len > in_size || op + len > out_size) corrupt();
      std::copy(in + ip, in + ip + len, out.begin() + static_cast<std::ptrdiff_t>(op));
      ip += len;
      op += len;
    } else {  // back reference
      std::size_t len = ctrl >> 5;
      std::size_t back = (ctrl & 0x1f) << 8;
      if (len == 7) {
        if (ip >= in_size) corrupt();
        len += in[ip++];
      }
      if (ip >= in_size) corrupt();
      back += in[ip++];
      len += 2;
      if (back + 1 > op || op + len > out_size) corrupt();
      std::size_t ref = op - back - 1;
      for (std::size_t k = 0; k < len; ++k) out[op++] = out[ref++];  // may overlap
    }
  }
  if (op != out_size)
    throw std::invalid_argument("corrupt LZF-compressed data: decompressed " + std::to_string(op) +
                                " bytes, expected " + std::to_string(out_size));
  return out;
}

}  // namespace nbv
