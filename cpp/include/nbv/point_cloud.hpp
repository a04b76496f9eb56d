// Observed surface points: origin-anchored voxel keys, a voxel index, and the incremental
// voxel-grid filtered cloud that accumulates a mission's sensor hits.
#pragma once

#include "nbv/common.hpp"
#include "nbv/huge_pages.hpp"
#include "nbv/options.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace nbv {

// ---------------------------------------------------------------------------- voxel keys

/// Integer voxel coordinates are limited to [-2^20, 2^20) per axis so that three of them pack
/// into one 64-bit key (21 bits each): +-52 km at 0.05 m, +-21 km at 0.02 m.
constexpr std::int64_t kVoxelCoordLimit = std::int64_t(1) << 20;
/// A key no packed voxel can take (bit 63 is never set by pack_voxel).
constexpr std::uint64_t kEmptyVoxelKey = ~std::uint64_t(0);

/// std::floor without a libm call (the x86-64 baseline has no SSE4.1 roundsd): exact for every
/// finite double.
inline double fast_floor(double q) {
  if (!(std::abs(q) < 4503599627370496.0)) return q;  // |q| >= 2^52: already an integer
  const double t = static_cast<double>(static_cast<std::int64_t>(q));
  return t > q ? t - 1.0 : t;
}

/// floor(v / size), computed with a multiplication by inv = 1 / size and falling back to the
/// exact division only when v * inv is within 1e-9 (relative) of an integer, where the two could
/// round differently. Identical to std::floor(v / size) for every input, about 4x faster.
inline double floor_div(double v, double size, double inv) {
  const double q = v * inv;
  const double c = fast_floor(q);
  const double margin = 1e-9 * (std::abs(q) + 1.0);
  if (q - c < margin || c + 1.0 - q < margin) return std::floor(v / size);
  return c;
}

/// The cell of v on a grid of cell `size` as the evaluation counts cells: floor(v / size), except
/// that a value within 1e-9 (relative) of a cell boundary lies on it and is counted in the cell
/// above. A face on a boundary plane (an axis-aligned face at a multiple of the size, common in
/// modelled structures) then keeps its ground-truth samples and the points reconstructed on it in
/// one cell, whatever the last bits of their coordinates (12.399999999999999 and
/// 12.400000000000002 are both in cell 248 at 0.05 m).
inline double snapped_floor_div(double v, double size, double inv) {
  const double q = v * inv;
  const double c = fast_floor(q);
  // (just above a boundary, or away from one, floor(v * inv): floor(v / size) as floor_div)
  return c + 1.0 - q < 1e-9 * (std::abs(q) + 1.0) ? c + 1.0 : c;
}

/// Cell of `p` on the grid of cell size `size` anchored at the origin: floor(p / size) per axis
/// (floor, not truncation: -0.01 at 0.05 m is cell -1). Throws std::invalid_argument if a
/// coordinate falls outside [-2^20, 2^20) cells (a point too far from the origin for `size`).
inline std::array<std::int64_t, 3> voxel_index(const Eigen::Vector3d& p, double size) {
  std::array<std::int64_t, 3> out{};
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor(p[a] / size);
    if (!(c >= -double(kVoxelCoordLimit) && c < double(kVoxelCoordLimit)))
      throw std::invalid_argument("point coordinate " + fmt(p[a]) +
                                  " is too far from the origin for a grid of cell size " +
                                  fmt(size) + " m (at most 2^20 cells per axis)");
    out[a] = static_cast<std::int64_t>(c);
  }
  return out;
}

/// Packed key of p's cell (as voxel_index), or kEmptyVoxelKey if p is outside the key range.
/// `inv` must be 1 / size.
inline std::uint64_t try_voxel_key(double x, double y, double z, double size, double inv);

/// Packs voxel coordinates (each in [-2^20, 2^20)) into a 63-bit key; unpack_voxel inverts it.
inline std::uint64_t pack_voxel(std::int64_t ix, std::int64_t iy, std::int64_t iz) {
  const auto u = [](std::int64_t v) { return static_cast<std::uint64_t>(v + kVoxelCoordLimit); };
  return (u(ix) << 42) | (u(iy) << 21) | u(iz);
}
inline std::array<std::int64_t, 3> unpack_voxel(std::uint64_t key) {
  constexpr std::uint64_t m = (std::uint64_t(1) << 21) - 1;
  return {static_cast<std::int64_t>((key >> 42) & m) - kVoxelCoordLimit,
          static_cast<std::int64_t>((key >> 21) & m) - kVoxelCoordLimit,
          static_cast<std::int64_t>(key & m) - kVoxelCoordLimit};
}
/// pack_voxel of the cells (cx, cy, cz), or kEmptyVoxelKey if one is outside [-2^20, 2^20).
inline std::uint64_t pack_cells(double cx, double cy, double cz) {
  constexpr double lim = static_cast<double>(kVoxelCoordLimit);
  if (!(cx >= -lim && cx < lim && cy >= -lim && cy < lim && cz >= -lim && cz < lim))
    return kEmptyVoxelKey;
  return pack_voxel(static_cast<std::int64_t>(cx), static_cast<std::int64_t>(cy),
                    static_cast<std::int64_t>(cz));
}
inline std::uint64_t try_voxel_key(double x, double y, double z, double size, double inv) {
  return pack_cells(floor_div(x, size, inv), floor_div(y, size, inv), floor_div(z, size, inv));
}

/// try_voxel_key with the evaluation's cells (snapped_floor_div): a value on a cell boundary, up
/// to rounding, in the cell above.
inline std::uint64_t try_cell_key(double x, double y, double z, double size, double inv) {
  return pack_cells(snapped_floor_div(x, size, inv), snapped_floor_div(y, size, inv),
                    snapped_floor_div(z, size, inv));
}

/// pack_voxel(voxel_index(p, size)).
inline std::uint64_t voxel_key(const Eigen::Vector3d& p, double size) {
  const auto i = voxel_index(p, size);
  return pack_voxel(i[0], i[1], i[2]);
}

/// The distinct voxel keys of a set, each with its id: 0, 1, 2, ... in the order the keys were
/// first inserted (the dense position of whatever is kept per voxel beside it). The keys are held
/// once, in id order (keys()); an open-addressing table (linear probing) of 32-bit slots, each an
/// id and some bits of its key's hash (tag_of), finds them, grown at a load factor of 3/4: 13-19
/// bytes a key in all, where a table of (key, value) slots held 16-32 and its users kept the keys a
/// second time. A rehash reads the keys in order and holds the old and new id tables only (4 bytes
/// a slot), not old and new keys. Keys must not be kEmptyVoxelKey; at most 3 * 2^30 keys.
/// A random 64-bit number drawn once a process (std::random_device): the key of VoxelIndex's
/// hash. Which slot a voxel takes never reaches a result (ids are given in insertion order).
std::uint64_t draw_hash_seed();

class VoxelIndex {
 public:
  static constexpr std::uint32_t kMissing = std::numeric_limits<std::uint32_t>::max();
  /// The most keys (their table of 2^32 slots then 3/4 full).
  static constexpr std::size_t kMaxKeys = std::size_t(3) << 30;

  explicit VoxelIndex(std::size_t expected = 0) { reserve(expected); }

  std::size_t size() const { return keys_.size(); }
  /// The keys in id order: keys()[id] is the key of id.
  const GrowArray<std::uint64_t>& keys() const { return keys_; }
  std::uint64_t key(std::uint32_t id) const { return keys_[id]; }
  /// Bytes held (the id table and the keys).
  std::size_t bytes() const {
    return slots_.capacity() * sizeof(std::uint32_t) + keys_.capacity() * sizeof(std::uint64_t);
  }
  void clear();
  /// Makes room for `n` keys without rehashing.
  void reserve(std::size_t n);
  /// Gives back the keys' spare room and the table's beyond what size() needs.
  void shrink_to_fit();
  /// The id of `key`, or kMissing.
  std::uint32_t find(std::uint64_t key) const {
    if (slots_.empty()) return kMissing;
    const std::uint64_t h = hash(key);
    const std::uint32_t tag = tag_of(h), low = std::uint32_t(mask_);
    for (std::size_t i = h & mask_;; i = (i + 1) & mask_) {
      const std::uint32_t w = slots_[i];
      if (w == kMissing) return kMissing;
      if ((w & ~low) == tag && keys_[w & low] == key) return w & low;
    }
  }
  bool contains(std::uint64_t key) const { return find(key) != kMissing; }
  /// Starts loading the table slot where a find or insert of `key` begins (a hint: in a table of
  /// millions of voxels that slot is a cache miss; asked for ahead of time, the probe waits less).
  void prefetch(std::uint64_t key) const {
    if (!slots_.empty()) __builtin_prefetch(slots_.data() + (hash(key) & mask_));
  }
  /// The id of `key`, the next one (size()) if it was absent; and whether it was inserted.
  std::pair<std::uint32_t, bool> insert(std::uint64_t key);

 private:
  static std::uint64_t hash(std::uint64_t key) {
    // keyed by a seed drawn per process: a cloud crafted so that its voxels' keys collide under
    // a fixed hash (it is invertible) would make every insert probe them all
    key ^= kHashSeed;
    key ^= key >> 33;  // murmur3 finaliser
    key *= 0xff51afd7ed558ccdull;
    key ^= key >> 33;
    key *= 0xc4ceb9fe1a85ec53ull;
    key ^= key >> 33;
    return key;
  }
  /// A slot holds an id in its low bits (those of mask_: ids stay below the table's size) and,
  /// in the bits above them, the same bits of the key's hash (from its upper half, not those
  /// that chose the slot): most probes past other keys end without reading their keys.
  std::uint32_t tag_of(std::uint64_t h) const {
    return std::uint32_t(h >> 32) & ~std::uint32_t(mask_);
  }
  /// The table's size for n keys: a power of two at least 4/3 n (16 at least).
  static std::size_t capacity_for(std::size_t n);
  void rehash(std::size_t capacity);

  static inline const std::uint64_t kHashSeed = draw_hash_seed();
  // Tables of millions of voxels: huge pages spare a page fault per 4 KiB as they grow.
  HugeVector<std::uint32_t> slots_;  ///< tag | id, or kMissing
  GrowArray<std::uint64_t> keys_;    ///< by id
  std::size_t mask_ = 0;
};

// ---------------------------------------------------------------------------- voxel centroids

/// Voxel-grid downsampling by centroids, incrementally (the one implementation behind
/// SurfaceCloud and voxelgrid_sampling; small_gicp's voxelgrid_sampling is the model). Each voxel
/// keeps the running sum and count of the points added to it: 28 bytes a voxel, the sums of the
/// coordinates in double precision. With `single`, the sums are of the points' offsets from the
/// voxel's lowest corner, in single precision (PCL's VoxelGrid sums in single precision too): 16
/// bytes a voxel, and a centroid is the mean of its points to within 1e-6 of the voxel's size
/// with tens of points and 1e-5 with 200,000 (a GoogleTest), and always inside the voxel (floor(c /
/// size) is the voxel's coordinate), so a face on a voxel boundary keeps its centroids in its
/// voxels. Centroids come out in the order
/// their voxels were first seen, so the result is deterministic for a given sequence of points.
class VoxelCentroids {
 public:
  VoxelCentroids() = default;
  /// single: sums in single precision, for keys of a grid of cell voxel_size (m, > 0).
  VoxelCentroids(double voxel_size, bool single);
  /// Adds points[i] to the voxel keys[i] (packed keys, e.g. try_voxel_key); points whose key is
  /// `skip` are left out. Returns the number of new voxels.
  std::size_t add(const PointsRef& points, const std::vector<std::uint64_t>& keys,
                  std::uint64_t skip = kEmptyVoxelKey);
  /// (K, 3) centroids in voxel creation order.
  Points centroids() const;
  /// Centroid of voxel i (the row centroids() holds).
  Eigen::Vector3d centroid(std::size_t i) const {
    const double n = static_cast<double>(count_[i]);
    if (!single_) return Eigen::Vector3d(sum_[i][0], sum_[i][1], sum_[i][2]) / n;
    const auto v = unpack_voxel(index_.keys()[i]);
    Eigen::Vector3d out;
    for (int a = 0; a < 3; ++a)
      out[a] = into_voxel(double(v[a]) * size_ + double(offsets_[i][a]) / n, v[a]);
    return out;
  }
  /// (K,) number of points in each voxel.
  const GrowArray<std::uint32_t>& counts() const { return count_; }
  std::size_t size() const { return count_.size(); }
  /// Bytes held (the voxel index, the sums and the counts).
  std::size_t bytes() const;
  void clear();

 private:
  template <class Sum>
  std::size_t add_to(GrowArray<Sum>& sums, const PointsRef& points,
                     const std::vector<std::uint64_t>& keys, std::uint64_t skip);
  /// The voxel of `key`, made (empty, with the next id) if it is new.
  std::uint32_t voxel_of(std::uint64_t key);
  /// x moved to the nearest coordinate of voxel coordinate k (floor(x / size) == k) if it is
  /// outside: a mean of offsets just under the voxel's size, summed in single precision, can round
  /// up to it (float(0.025) > 0.025), which would put the centroid in the next voxel.
  double into_voxel(double x, std::int64_t k) const {
    const double q = floor_div(x, size_, inv_);
    if (q == double(k)) return x;
    const bool above = q > double(k);
    double b = double(above ? k + 1 : k) * size_;  // the boundary, within an ulp or two
    const double toward = above ? -HUGE_VAL : HUGE_VAL;
    while (floor_div(b, size_, inv_) != double(k)) b = std::nextafter(b, toward);
    return b;
  }
  /// The lowest corner of the voxel of `key`.
  Eigen::Vector3d corner(std::uint64_t key) const {
    const auto v = unpack_voxel(key);
    return {double(v[0]) * size_, double(v[1]) * size_, double(v[2]) * size_};
  }

  double size_ = 0.0;                     ///< the voxel size, m (single precision only)
  double inv_ = 0.0;                      ///< 1 / size_
  bool single_ = false;                   ///< the sums are offsets_, else sum_
  VoxelIndex index_;                      ///< voxel key -> id (the position in the sums and count_)
  GrowArray<std::array<double, 3>> sum_;  ///< per voxel: the sum of its points
  GrowArray<std::array<float, 3>>
      offsets_;                     ///< per voxel: the sum of their offsets from its corner
  GrowArray<std::uint32_t> count_;  ///< per voxel: its number of points
};

/// Voxel-grid centroids of points (N, 3): one point per cell floor(p / voxel_size) (grid anchored
/// at the origin), in the order the cells are first seen. Throws std::invalid_argument for a
/// non-positive voxel size, non-finite points or a point too far from the origin for the grid.
Points voxelgrid_sampling(const PointsRef& points, double voxel_size);

// ---------------------------------------------------------------------------- surface cloud

#define NBV_SURFACE_CLOUD_OPTIONS(X)                                                            \
  X(double, voxel_size, 0.02,                                                                   \
    "voxel-grid cell, m: one point (the centroid) per cell; the authors used 0.02 for the "     \
    "RGB-D camera's cloud and 0.1 for the laser's profile cloud")                               \
  X(bool, single_precision, false,                                                              \
    "voxel sums in single precision, as offsets from the voxel's corner: 16 bytes a voxel "     \
    "instead of 28, each centroid within 1e-5 of the voxel size of its points' mean")           \
  X(double, min_z, 0.3,                                                                         \
    "ground removal, m (world z): points below are not registered; -inf disables it (authors: " \
    "0.3)")                                                                                     \
  X(bool, crop, false, "register only points inside the crop box [crop_min, crop_max]")         \
  X(Eigen::Vector3d, crop_min, Eigen::Vector3d::Zero(), "crop box minimum corner, m (world)")   \
  X(Eigen::Vector3d, crop_max, Eigen::Vector3d::Zero(), "crop box maximum corner, m (world)")

struct SurfaceCloudOptions {
  NBV_SURFACE_CLOUD_OPTIONS(NBV_DECLARE_OPTION)

  void validate() const;
};
/// A cloud of observed surface points with an incremental voxel-grid filter.
///
/// Each voxel (cell = floor(p / voxel_size), anchored at the origin) holds the running centroid
/// of every registered point that fell in it, so the result equals PCL's VoxelGrid over the
/// union of everything added. Points are kept in the order their voxels were first seen, so the
/// output is deterministic for a given sequence of add() calls.
class SurfaceCloud {
 public:
  explicit SurfaceCloud(const SurfaceCloudOptions& options = {});
  // A copy is a new cloud: it takes a new stamp (see stamp()). (No move operations: a move
  // copies, so the moved-from cloud keeps its points and its stamp.)
  SurfaceCloud(const SurfaceCloud& other);
  SurfaceCloud& operator=(const SurfaceCloud& other);

  const SurfaceCloudOptions& options() const { return opt_; }
  /// Registers points (N, 3), world frame. Returns the number of new voxels they created.
  /// Throws std::invalid_argument (nothing registered) if any point is NaN or infinite.
  std::size_t add(const PointsRef& points) { return add_keyed(points, voxel_keys(points)); }
  /// add's two steps: each point's voxel key (a marker where ground removal or the crop drops
  /// it), checked (throws std::invalid_argument for a NaN, infinite or out-of-range point)...
  std::vector<std::uint64_t> voxel_keys(const PointsRef& points) const;
  /// ...and the points registered under those keys (what voxel_keys returned for them).
  std::size_t add_keyed(const PointsRef& points, const std::vector<std::uint64_t>& keys);
  /// (K, 3) voxel centroids in voxel creation order.
  Points points() const;
  /// Voxel i's centroid (row i of points(), without building the array).
  Eigen::Vector3d point(std::size_t i) const { return voxels_.centroid(i); }
  /// (K,) number of registered points that fell in each voxel.
  Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1> counts() const;
  std::size_t size() const { return voxels_.size(); }
  /// Bytes held (the voxel index, sums and counts).
  std::size_t bytes() const { return voxels_.bytes(); }
  /// Total number of points registered (after ground removal and cropping).
  std::uint64_t num_registered() const { return registered_; }
  /// Number of points registered in each voxel (creation order): a voxel's centroid changes
  /// exactly when its count does.
  const GrowArray<std::uint32_t>& voxel_counts() const { return voxels_.counts(); }
  /// An id unique to this cloud's history in the process: it changes when the cloud is cleared
  /// (and a copy has its own), so between two equal stamps the cloud only grew by add().
  std::uint64_t stamp() const { return stamp_; }
  void clear();

 private:
  static std::uint64_t new_stamp();
  SurfaceCloudOptions opt_;
  VoxelCentroids voxels_;
  std::uint64_t registered_ = 0;
  std::uint64_t stamp_ = new_stamp();
};

/// (sum of sizes, 3): the clouds' points one cloud after the other (each in voxel creation
/// order), in one array: the same as stacking their points(), without a copy per cloud. With
/// [start, stop), only those rows of the stack (clamped to it): a large cloud a part at a time.
Points stack_points(const std::vector<const SurfaceCloud*>& clouds, std::size_t start = 0,
                    std::size_t stop = std::numeric_limits<std::size_t>::max());

/// voxelgrid_sampling(stack_points(clouds), voxel_size), the same centroids in the same order,
/// reading the clouds `chunk` points at a time instead of holding their stack (a 100 m
/// structure's 26 M points: 0.6 GB).
Points voxelgrid_sampling(const std::vector<const SurfaceCloud*>& clouds, double voxel_size,
                          std::size_t chunk = std::size_t(1) << 20);

// ---------------------------------------------------------------------------- file helpers

/// Decompresses an LZF block (the codec of PCD "binary_compressed" files, liblzf format) into
/// exactly `out_size` bytes. Throws std::invalid_argument on corrupt input.
std::vector<std::uint8_t> lzf_decompress(const std::uint8_t* in, std::size_t in_size,
                                         std::size_t out_size);

}  // namespace nbv
