// What the camera has seen of each workspace cell: the directions it was seen from, how many
// camera hits fell in it, and where in the cell they fell. The surface utilities and the surface
// targets read it to tell surface that has been observed densely, and from which side, from surface
// that has not.
//
// Directions are the 26 bins of grid_view.hpp's direction_bin (the unit vectors of the cube's
// faces, edges and corners): a hit in cell c seen from sensor origin o marks c as seen from the
// bin of (o - hit). A cell is "covered" for a viewing direction d when it has been seen from a
// bin within a cone around d (UtilityOptions::coverage_cone_deg): the two faces of a thin plate,
// 180 degrees apart, are covered separately; the same face seen again from nearby is not new.
//
// Where the hits fell: the cell is cut into 4 x 4 x 4 patches (a quarter of the resolution on a
// side: 0.05 m in a 0.2 m map, the spacing dense coverage is scored at), and a hit marks its
// patch's square in each of the three projections along the axes (16 bits each: the face of a
// cell seen along an axis is densely sampled when its 16 squares hold hits).
//
// Saturation (with saturation_hits > 0): a camera scan that puts at least saturation_hits hits
// in a cell, none of them in a square that held none before the scan, has found no part of the
// cell's surface its earlier scans had not already sampled: the cell is marked saturated (bit 63
// of patches), and a later scan that adds a square clears the mark. The surface utility credits
// no view for a saturated cell, and surface_targets leaves it out: views are not planned for
// surface whose 0.05 m squares hold every hit the camera lays there.
//
// Storage is sparse, by the grid's bricks of 4 x 4 x 4 cells: a brick gets its 64 records when
// the camera first hits a cell of it, so the record grows with the surface seen, not with the
// workspace box (a 100 m plant's box holds 75 million cells, its surface about 1 % of them).
// Every other brick reads from block 0, a shared block of zeros that is never written.
#pragma once

#include "nbv/common.hpp"
#include "nbv/workspace_grid.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace nbv {

class OccupancyMap;

class SurfaceObservations {
 public:
  /// An empty record over `map`'s workspace grid (same cells, same keys as the map).
  /// saturation_hits: the hits a scan must put in a cell, none in a new square, to mark it
  /// saturated (0: never; see above).
  explicit SurfaceObservations(const OccupancyMap& map, int saturation_hits = 0);
  /// Bit of patches() marking a saturated cell.
  static constexpr std::uint64_t kSaturated = std::uint64_t(1) << 63;
  /// The largest saturation_hits (a scan's hits in a cell are counted in 14 bits).
  static constexpr int kMaxSaturationHits = 0x3fff;

  /// Records one camera scan: hits (N, 3) world-frame points seen from `origin`. Hits outside
  /// the workspace are ignored. Parallel; throws std::invalid_argument for non-finite input.
  /// Returns the number of cells the camera saw for the first time. The first sparse_hits hits
  /// are a coarse frame's (Scan::sparse_hits): recorded like the others, but saturation counts
  /// neither them nor a side only they saw (a coarse resampling of known surface is no evidence
  /// that a cell's surface is sampled whole).
  std::size_t add_scan(const Eigen::Vector3d& origin, const PointsRef& hits,
                       Eigen::Index sparse_hits = 0);
  /// The hits (N, 3) seen from `origin` that would add to the record (read only): those in a
  /// workspace cell not yet seen from a direction bin within cone_deg of theirs (the cell's side
  /// facing the sensor unseen, as the surface utility's cone reads it) or that would mark a
  /// square of the cell no earlier hit marked. Serial: for a few thousand hits (a coarse preview
  /// of a frame). Throws std::invalid_argument for non-finite input.
  std::size_t novel_hits(const Eigen::Vector3d& origin, const PointsRef& hits,
                         double cone_deg) const;
  /// Which of the hits novel_hits counts: 1 per hit that would add to the record, else 0. With
  /// whole_face, also each hit in a cell none of whose three projections has all its 16 squares
  /// marked (no face of its surface sampled whole: a denser scan could add to it).
  std::vector<std::uint8_t> novel_mask(const Eigen::Vector3d& origin, const PointsRef& hits,
                                       double cone_deg, bool whole_face = false) const;
  /// Forgets everything.
  void clear();

  /// Bitmask of the direction bins cell `i` (a grid id) has been seen from (0: never seen).
  std::uint32_t seen(std::int64_t i) const { return seen_pool_[slot(std::size_t(i))]; }
  /// Camera hits that fell in cell i (saturating at 65535).
  std::uint16_t hits(std::int64_t i) const { return hits_pool_[slot(std::size_t(i))]; }
  /// Where cell i's hits fell: bits 16 a + 4 u + v (a the axis projected along, u and v the
  /// quarter of the cell along the other two axes in increasing order) set for each square that
  /// holds a hit; bit 63 (kSaturated) for a saturated cell.
  std::uint64_t patches(std::int64_t i) const { return patches_pool_[slot(std::size_t(i))]; }
  /// The storage: per brick (id >> 6) its block, and the blocks of 64 records, cell id & 63 in
  /// block b at b * 64 + (id & 63) (block 0: zeros). Valid until the next add_scan or clear.
  const std::uint32_t* brick_blocks() const { return block_.data(); }
  const std::uint32_t* seen_pool() const { return seen_pool_.data(); }
  const std::uint16_t* hits_pool() const { return hits_pool_.data(); }
  const std::uint64_t* patches_pool() const { return patches_pool_.data(); }
  /// When each brick's records last changed (see BrickStamps).
  const BrickStamps& stamps() const { return stamps_; }
  int saturation_hits() const { return saturation_hits_; }
  /// Cells marked saturated.
  std::int64_t saturated_cells() const;
  /// Cells seen from at least one direction.
  std::int64_t seen_cells() const;
  /// Bricks holding records (hit by the camera at least once since the last clear).
  std::size_t allocated_bricks() const { return seen_pool_.size() / 64 - 1; }
  /// Bytes held by the records (brick table and blocks, capacity included).
  std::size_t bytes() const;

  const std::array<int, 3>& dims() const { return dims_; }
  const GridLayout& layout() const { return layout_; }
  /// True if this record was made for a map of the same workspace grid.
  bool matches(const OccupancyMap& map) const;
  /// The record's reader-writer lock for callers sharing it between threads (the Python
  /// bindings: shared around reads, exclusive around add_scan / clear); never taken inside.
  std::shared_mutex& access_lock() const { return access_.mutex(); }

 private:
  double res_;
  std::array<int, 3> min_key_;  // OctoMap key of cell (0, 0, 0)
  std::array<int, 3> dims_;
  GridLayout layout_;
  std::size_t slot(std::size_t i) const { return std::size_t(block_[i >> 6]) << 6 | (i & 63); }
  /// Hit `row`'s cell (a grid id; -1 outside the workspace) and its squares' bits (`patch`: one
  /// per projection along an axis, see patches).
  inline std::int64_t key_hit(const PointsRef& hits, Eigen::Index row,
                              std::uint64_t& patch) const;  // defined in its .cpp
  /// Gives every brick of `cells` (grid ids, -1 skipped) its block.
  void allocate(const std::vector<std::int64_t>& cells);
  std::vector<std::uint32_t> block_;         // per brick: its block (0: none yet)
  std::vector<std::uint32_t> seen_pool_;     // per block, 64 direction-bin masks
  std::vector<std::uint16_t> hits_pool_;     // per block, 64 hit counts
  std::vector<std::uint64_t> patches_pool_;  // per block, 64 patch masks (see patches)
  BrickStamps stamps_;
  // with saturation_hits: per block, 64 records of the last scan that hit the cell: its number
  // (16 bits), its hits in the cell (14 bits, saturating), whether it saw the cell from a bin
  // it had not been seen from (1 bit) and whether it added a square (1 bit)
  int saturation_hits_ = 0;
  std::uint16_t scan_ = 0;
  std::vector<std::uint32_t> scan_pool_;
  AccessLock access_;
};

}  // namespace nbv
