// Observed surface points: origin-anchored voxel keys, a voxel hash table, and the incremental
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

/// Cell of `p` on the grid of cell size `size` anchored at the origin: floor(p / size) per axis
/// (floor, not truncation: -0.01 at 0.05 m is cell -1). Throws std::invalid_argument if a
/// coordinate falls outside [-2^20, 2^20) cells (a point too far from the origin for `size`).
inline std::array<std::int64_t, 3> voxel_index(const Eigen::Vector3d& p, double size) {
  std::array<std::int64_t, 3> out{};
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor(p[a] / size);
    if (!(c >= -double(kVoxelCoordLimit) && c < double(kVoxelCoordLimit)))
      throw std::invalid_argument("point coordinate " + std::to_string(p[a]) +
                                  " is too far from the origin for a grid of cell size " +
                                  std::to_string(size) + " m (at most 2^20 cells per axis)");
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
inline std::uint64_t try_voxel_key(double x, double y, double z, double size, double inv) {
  constexpr double lim = static_cast<double>(kVoxelCoordLimit);
  const double cx = floor_div(x, size, inv), cy = floor_div(y, size, inv),
               cz = floor_div(z, size, inv);
  if (!(cx >= -lim && cx < lim && cy >= -lim && cy < lim && cz >= -lim && cz < lim))
    return kEmptyVoxelKey;
  return pack_voxel(static_cast<std::int64_t>(cx), static_cast<std::int64_t>(cy),
                    static_cast<std::int64_t>(cz));
}

/// pack_voxel(voxel_index(p, size)).
inline std::uint64_t voxel_key(const Eigen::Vector3d& p, double size) {
  const auto i = voxel_index(p, size);
  return pack_voxel(i[0], i[1], i[2]);
}

/// Open-addressing (linear probing) hash map from packed voxel keys to 32-bit values. Grows at a
/// load factor of 3/4 (12 bytes a slot: 16-32 bytes an entry; at 1/2 a 100 m plant's 19 M-voxel
/// camera cloud held a 64 M-slot, 800 MB table). Much faster than std::unordered_map for this use
/// (no node allocation, one cache line per probe). Keys must not be kEmptyVoxelKey.
class VoxelHashMap {
 public:
  static constexpr std::uint32_t kMissing = std::numeric_limits<std::uint32_t>::max();

  explicit VoxelHashMap(std::size_t expected = 0) { reserve(expected); }

  std::size_t size() const { return size_; }
  /// Bytes held by the table.
  std::size_t bytes() const {
    return keys_.capacity() * sizeof(std::uint64_t) + values_.capacity() * sizeof(std::uint32_t);
  }
  void clear();
  /// Makes room for `n` entries without rehashing.
  void reserve(std::size_t n);
  /// The value stored for `key`, or kMissing.
  std::uint32_t find(std::uint64_t key) const {
    if (keys_.empty()) return kMissing;
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      const std::uint64_t k = keys_[i];
      if (k == key) return values_[i];
      if (k == kEmptyVoxelKey) return kMissing;
    }
  }
  bool contains(std::uint64_t key) const { return find(key) != kMissing; }
  /// Inserts (key, value) if the key is absent. Returns the stored value and whether it inserted.
  std::pair<std::uint32_t, bool> insert(std::uint64_t key, std::uint32_t value);

 private:
  std::size_t slot(std::uint64_t key) const {
    key ^= key >> 33;  // murmur3 finaliser
    key *= 0xff51afd7ed558ccdull;
    key ^= key >> 33;
    key *= 0xc4ceb9fe1a85ec53ull;
    key ^= key >> 33;
    return static_cast<std::size_t>(key) & mask_;
  }
  void rehash(std::size_t capacity);

  // Tables of millions of voxels: huge pages spare a page fault per 4 KiB as they grow.
  HugeVector<std::uint64_t> keys_;
  HugeVector<std::uint32_t> values_;
  std::size_t mask_ = 0, size_ = 0;
};

// ---------------------------------------------------------------------------- voxel centroids

/// Voxel-grid downsampling by centroids, incrementally (the one implementation behind
/// SurfaceCloud and voxelgrid_sampling; small_gicp's voxelgrid_sampling is the model). Each voxel
/// keeps the running sum and count of the points added to it; centroids come out in the order
/// their voxels were first seen, so the result is deterministic for a given sequence of points.
class VoxelCentroids {
 public:
  /// Adds points[i] to the voxel keys[i] (packed keys, e.g. try_voxel_key); points whose key is
  /// `skip` are left out. Returns the number of new voxels.
  std::size_t add(const PointsRef& points, const std::vector<std::uint64_t>& keys,
                  std::uint64_t skip = kEmptyVoxelKey);
  /// (K, 3) centroids in voxel creation order.
  Points centroids() const;
  /// Centroid of voxel i (the row centroids() holds).
  Eigen::Vector3d centroid(std::size_t i) const { return sum_[i] / static_cast<double>(count_[i]); }
  /// (K,) number of points in each voxel.
  const HugeVector<std::uint32_t>& counts() const { return count_; }
  std::size_t size() const { return count_.size(); }
  void clear();

 private:
  /// The voxel of `key`, made (empty, with the next id) if it is new.
  std::uint32_t voxel_of(std::uint64_t key);

  VoxelHashMap index_;
  HugeVector<Eigen::Vector3d> sum_;
  HugeVector<std::uint32_t> count_;
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
  std::size_t add(const PointsRef& points);
  /// (K, 3) voxel centroids in voxel creation order.
  Points points() const;
  /// Voxel i's centroid (row i of points(), without building the array).
  Eigen::Vector3d point(std::size_t i) const { return voxels_.centroid(i); }
  /// (K,) number of registered points that fell in each voxel.
  Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1> counts() const;
  std::size_t size() const { return voxels_.size(); }
  /// Total number of points registered (after ground removal and cropping).
  std::uint64_t num_registered() const { return registered_; }
  /// Number of points registered in each voxel (creation order): a voxel's centroid changes
  /// exactly when its count does.
  const HugeVector<std::uint32_t>& voxel_counts() const { return voxels_.counts(); }
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

// ---------------------------------------------------------------------------- file helpers

/// Decompresses an LZF block (the codec of PCD "binary_compressed" files, liblzf format) into
/// exactly `out_size` bytes. Throws std::invalid_argument on corrupt input.
std::vector<std::uint8_t> lzf_decompress(const std::uint8_t* in, std::size_t in_size,
                                         std::size_t out_size);

}  // namespace nbv
