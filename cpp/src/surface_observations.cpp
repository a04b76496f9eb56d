#include "nbv/surface_observations.hpp"

#include "nbv/grid_view.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace nbv {

namespace {
// A cell's record of the last scan that hit it (saturation): the scan's number (bits 16-31), its
// hits in the cell (bits 2-15, saturating), whether it saw the cell from a direction bin it had
// not been seen from (kNewSide) and whether it added a square (kAddedSquare).
constexpr std::uint32_t kAddedSquare = 1u, kNewSide = 2u;
constexpr std::uint32_t kHitsMask = std::uint32_t(SurfaceObservations::kMaxSaturationHits);
std::uint32_t scan_of(std::uint32_t record) { return record >> 16; }
std::uint32_t hits_of(std::uint32_t record) { return (record >> 2) & kHitsMask; }
}  // namespace

SurfaceObservations::SurfaceObservations(const OccupancyMap& map, int saturation_hits)
    : res_(map.resolution()),
      min_key_{map.min_key()[0], map.min_key()[1], map.min_key()[2]},
      dims_(map.dims()),
      layout_(map.grid().layout()),
      block_(layout_.num_bricks(), 0u),
      seen_pool_(64, 0u),
      hits_pool_(64, 0u),
      patches_pool_(64, 0u),
      stamps_(layout_.num_bricks()),
      saturation_hits_(saturation_hits),
      scan_pool_(saturation_hits > 0 ? 64 : 0, 0u) {
  if (saturation_hits < 0 || saturation_hits > kMaxSaturationHits)
    throw std::invalid_argument("saturation_hits must be in [0, " +
                                std::to_string(kMaxSaturationHits) + "], got " +
                                std::to_string(saturation_hits));
}

bool SurfaceObservations::matches(const OccupancyMap& map) const {
  return map.resolution() == res_ && map.dims() == dims_ && map.min_key()[0] == min_key_[0] &&
         map.min_key()[1] == min_key_[1] && map.min_key()[2] == min_key_[2];
}

void SurfaceObservations::clear() {
  std::fill(block_.begin(), block_.end(), 0u);
  std::vector<std::uint32_t>(64, 0u).swap(seen_pool_);  // the memory goes back
  std::vector<std::uint16_t>(64, 0u).swap(hits_pool_);
  std::vector<std::uint64_t>(64, 0u).swap(patches_pool_);
  std::vector<std::uint32_t>(saturation_hits_ > 0 ? 64 : 0, 0u).swap(scan_pool_);
  stamps_.touch_all();
}

std::int64_t SurfaceObservations::saturated_cells() const {
  std::int64_t n = 0;
  for (std::size_t i = 64; i < patches_pool_.size(); ++i) n += (patches_pool_[i] & kSaturated) != 0;
  return n;
}

std::int64_t SurfaceObservations::seen_cells() const {
  std::int64_t n = 0;
  for (std::size_t i = 64; i < seen_pool_.size(); ++i) n += seen_pool_[i] != 0;
  return n;
}

std::size_t SurfaceObservations::bytes() const {
  return block_.capacity() * sizeof(std::uint32_t) + seen_pool_.capacity() * sizeof(std::uint32_t) +
         hits_pool_.capacity() * sizeof(std::uint16_t) +
         patches_pool_.capacity() * sizeof(std::uint64_t) +
         scan_pool_.capacity() * sizeof(std::uint32_t);
}

void SurfaceObservations::allocate(const std::vector<std::int64_t>& cells) {
  for (const std::int64_t c : cells) {
    if (c < 0) continue;
    std::uint32_t& b = block_[std::size_t(c) >> 6];
    if (b) continue;
    const std::size_t blocks = seen_pool_.size() / 64;
    if (blocks >= std::numeric_limits<std::uint32_t>::max())
      throw std::length_error("surface observations: more bricks than a 32-bit block index");
    b = std::uint32_t(blocks);
    seen_pool_.resize(seen_pool_.size() + 64, 0u);
    hits_pool_.resize(hits_pool_.size() + 64, std::uint16_t(0));
    patches_pool_.resize(patches_pool_.size() + 64, std::uint64_t(0));
    if (saturation_hits_ > 0) scan_pool_.resize(scan_pool_.size() + 64, 0u);
  }
}

// inline: once a hit in the loops below
inline std::int64_t SurfaceObservations::key_hit(const PointsRef& hits, Eigen::Index row,
                                                 std::uint64_t& patch) const {
  const double rf = 1.0 / res_;  // the map's keys: OctoMap's floor(c / res) of float32 points
  int k[3], q[3];
  for (int a = 0; a < 3; ++a) {
    const double t = rf * double(float(hits(row, a)));
    const double f = std::floor(t);
    if (!(std::fabs(f) < 1e9)) return -1;
    k[a] = int(f) + 32768 - min_key_[a];
    q[a] = std::min(3, int((t - f) * 4.0));  // the quarter of the cell along a
    if (unsigned(k[a]) >= unsigned(dims_[a])) return -1;
  }
  patch = std::uint64_t(1) << (4 * q[1] + q[2]) |       // seen along x
          std::uint64_t(1) << (16 + 4 * q[0] + q[2]) |  // along y
          std::uint64_t(1) << (32 + 4 * q[0] + q[1]);   // along z
  return std::int64_t(layout_.id(k[0], k[1], k[2]));
}

std::size_t SurfaceObservations::novel_hits(const Eigen::Vector3d& origin, const PointsRef& hits,
                                            double cone_deg) const {
  const std::vector<std::uint8_t> mask = novel_mask(origin, hits, cone_deg);
  return std::size_t(std::count(mask.begin(), mask.end(), std::uint8_t(1)));
}

std::vector<std::uint8_t> SurfaceObservations::novel_mask(const Eigen::Vector3d& origin,
                                                          const PointsRef& hits, double cone_deg,
                                                          bool whole_face) const {
  if (!origin.allFinite())
    throw std::invalid_argument("scan origin contains NaN or infinite values");
  require_finite(hits, "hit points");
  const std::array<std::uint32_t, 26> cone = bin_cones(cone_deg);
  std::vector<std::uint8_t> mask(std::size_t(hits.rows()), 0);
  for (Eigen::Index r = 0; r < hits.rows(); ++r) {
    std::uint64_t patch = 0;
    const std::int64_t cell = key_hit(hits, r, patch);
    if (cell < 0) continue;
    const std::size_t at = slot(std::size_t(cell));
    const int bin = direction_bin(origin - hits.row(r).transpose());
    bool novel =
        (seen_pool_[at] & cone[std::size_t(bin)]) == 0 || (patches_pool_[at] & patch) != patch;
    if (!novel && whole_face) {  // no projection of the cell with all its 16 squares marked
      const std::uint64_t p = patches_pool_[at];
      novel = (p & 0xffffu) != 0xffffu && (p >> 16 & 0xffffu) != 0xffffu &&
              (p >> 32 & 0xffffu) != 0xffffu;
    }
    mask[std::size_t(r)] = novel;
  }
  return mask;
}

std::size_t SurfaceObservations::add_scan(const Eigen::Vector3d& origin, const PointsRef& hits,
                                          Eigen::Index sparse_hits) {
  if (!origin.allFinite())
    throw std::invalid_argument("scan origin contains NaN or infinite values");
  require_finite(hits, "hit points");
  const std::size_t n = std::size_t(hits.rows());
  // the hits' cells (grid ids, -1 outside the workspace) and patch bits, in parallel; then their
  // bricks' blocks
  std::vector<std::int64_t> cells(n, -1);
  std::vector<std::uint64_t> patch(n, 0);
  const std::size_t chunk = 8192;
  parallel_chunks((n + chunk - 1) / chunk, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t r = cb * chunk, e = std::min(n, ce * chunk); r < e; ++r)
      cells[r] = key_hit(hits, Eigen::Index(r), patch[r]);
  });
  allocate(cells);
  const bool saturating = saturation_hits_ > 0;
  if (saturating && ++scan_ == 0) scan_ = 1;  // 0: no scan yet
  const std::uint32_t scan = scan_;
  std::atomic<std::size_t> gained{0};
  const std::size_t nchunks = (n + chunk - 1) / chunk;
  std::vector<std::vector<std::size_t>> touched(saturating ? nchunks : 0);  // slots, per chunk
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    std::size_t local_gained = 0;
    for (std::size_t c = cb; c < ce; ++c) {
      // consecutive hits (neighbouring pixels) mostly share a cell and a bin: flush per run
      std::int64_t run_cell = -1;
      // run_dense_*: the run's hits from sparse_hits on, the only ones saturation counts
      std::uint32_t run_bits = 0, run_hits = 0, run_dense_bits = 0, run_dense_hits = 0;
      std::uint64_t run_patches = 0;
      auto flush = [&] {
        if (run_cell < 0) return;
        stamps_.touch(std::size_t(run_cell) >> 6);
        const std::size_t at = slot(std::size_t(run_cell));
        std::uint32_t* s = &seen_pool_[at];
        const std::uint32_t before = __atomic_load_n(s, __ATOMIC_RELAXED);
        const bool new_side = (before & run_bits) != run_bits;
        if (new_side && __atomic_fetch_or(s, run_bits, __ATOMIC_RELAXED) == 0)
          ++local_gained;  // seen by the camera for the first time
        std::uint64_t* p = &patches_pool_[at];
        const bool added = (__atomic_load_n(p, __ATOMIC_RELAXED) & run_patches) != run_patches;
        if (added) __atomic_fetch_or(p, run_patches, __ATOMIC_RELAXED);
        if (saturating) {  // this scan's hits in the cell, and whether a run added a square
          std::uint32_t* r = &scan_pool_[at];
          std::uint32_t cur = __atomic_load_n(r, __ATOMIC_RELAXED), next;
          const bool dense_new_side = (before & run_dense_bits) != run_dense_bits;
          const std::uint32_t flags =
              (added ? kAddedSquare : 0u) | (dense_new_side ? kNewSide : 0u);
          do {
            const bool same = scan_of(cur) == scan;
            const std::uint32_t now =
                std::min(kHitsMask, (same ? hits_of(cur) : 0u) + run_dense_hits);
            next = scan << 16 | now << 2 | (same ? cur & (kAddedSquare | kNewSide) : 0u) | flags;
          } while (!__atomic_compare_exchange_n(r, &cur, next, false, __ATOMIC_RELAXED,
                                                __ATOMIC_RELAXED));
          touched[c].push_back(at);
        }
        std::uint16_t* h = &hits_pool_[at];
        std::uint16_t cur = __atomic_load_n(h, __ATOMIC_RELAXED);
        while (cur != 65535) {
          const std::uint16_t next = std::uint16_t(std::min<std::uint32_t>(65535u, cur + run_hits));
          if (__atomic_compare_exchange_n(h, &cur, next, false, __ATOMIC_RELAXED, __ATOMIC_RELAXED))
            break;
        }
      };
      for (std::size_t r = c * chunk, e = std::min(n, (c + 1) * chunk); r < e; ++r) {
        const std::int64_t cell = cells[r];
        if (cell < 0) continue;
        const Eigen::Index row = Eigen::Index(r);
        const Eigen::Vector3d to_sensor = origin - hits.row(row).transpose();
        const std::uint32_t bit = std::uint32_t(1) << direction_bin(to_sensor);
        if (cell != run_cell) {
          flush();
          run_cell = cell;
          run_bits = 0;
          run_hits = 0;
          run_dense_bits = 0;
          run_dense_hits = 0;
          run_patches = 0;
        }
        run_bits |= bit;
        run_patches |= patch[r];
        ++run_hits;
        if (row >= sparse_hits) {
          run_dense_bits |= bit;
          ++run_dense_hits;
        }
      }
      flush();
    }
    gained += local_gained;
  });
  // the cells this scan hit: saturated if it saw them from a direction bin they had not been seen
  // from, put saturation_hits hits there and no run added a square; no longer if a run added one
  // (the same marks in any order of the runs)
  const std::uint32_t need = std::uint32_t(saturation_hits_);
  for (const auto& slots : touched)
    for (const std::size_t at : slots) {
      const std::uint32_t r = scan_pool_[at];
      if (r & kAddedSquare)
        patches_pool_[at] &= ~kSaturated;
      else if ((r & kNewSide) && hits_of(r) >= need)
        patches_pool_[at] |= kSaturated;
    }
  return gained.load();
}

}  // namespace nbv
