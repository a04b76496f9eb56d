// The workspace grid of an occupancy map: per cell log-odds, flag and entropy, with the total
// entropy and the cell counts kept incrementally and exactly, and a per-brick summary that lets
// ray walks skip empty space.
//
// Layout (GridLayout). Cells are stored in bricks of 4 x 4 x 4 (x fastest within a brick and
// between bricks), so that the cells a ray crosses share cache lines: cell (i, j, k) has the id
// 64 * brick + (i & 3) + 4 (j & 3) + 16 (k & 3), brick = (i >> 2) + bx (j >> 2) + bx by (k >> 2).
// The id space is padded to whole bricks; padding ids hold no cell. The grid knows nothing of
// metres or OctoMap keys: OccupancyMap maps those onto it.
//
// Storage (CellPools). The cells' values are held per brick, and only for the bricks a write has
// reached: a brick table maps each brick to its slot of 64 cells in three pools (log-odds, flag,
// entropy), and every brick never written maps to slot 0, a shared brick of unknown cells. A
// slot is given on a brick's first write and kept. The pools are mappings of the whole id
// space's size whose pages cost memory only once written, so they never move and hold only the
// bricks given out: the memory grows with the space the sensors reached, not with the
// workspace's box (a 100 m plant's map, 1,000 views in: a fifth of its bricks). Padding ids read
// as unknown cells (log-odds 0, flag unknown, the unknown entropy) and count in no total.
//
// Entropy. A cell's entropy follows its CellRule: binary entropy of p = sigmoid(logodds) in nats
// or bits, unknown cells p = 0.5 (ln 2 nats, 1 bit), and with clamped_entropy_zero a cell at a
// clamping threshold counts zero. The total sums every cell's entropy in 2^-50-nat fixed point
// (exact integers: no drift, any order), so total_entropy() is O(1) and equals a full sweep
// (recompute_total_entropy()) exactly.
//
// Bricks. Each brick counts its "live" cells,
// i.e. cells that are not neutral. A neutral cell is an observed free cell of zero entropy (a
// clamped free cell under clamped_entropy_zero): it neither stops a ray nor adds information, so
// walks whose utility ignores such cells skip whole neutral bricks (brick_live == 0). Each also
// counts its open cells (known and not occupied): a collision test passes a brick of 64 of them
// without looking at its cells, and its occupied cells (a ray that ends at its first occupied
// cell reads the cells of a brick with none only to step through them).
//
// Stamps (BrickStamps). Every write stamps its brick with the grid's current epoch, so that a
// reader who took an epoch can tell later which bricks changed since (CoverageMemo).
//
// Thread safety: const members may run concurrently; set/assign must not run concurrently with
// anything else.
#pragma once

#include "nbv/common.hpp"
#include "nbv/huge_pages.hpp"

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <vector>

namespace nbv {

/// Occupancy state of a cell (values as returned by OccupancyMap::state).
enum class CellState : std::int8_t { Unknown = -1, Free = 0, Occupied = 1 };

/// Where a workspace cell's value comes from.
enum class CellFlag : std::uint8_t {
  Unknown = 0,    ///< never observed, not in the octree
  Observed = 1,   ///< integrated from sensor data (or loaded from a file)
  Predicted = 2,  ///< set by symmetry prediction; observations override it
};

enum class EntropyUnit { Nats, Bits };

/// Cell counts over the workspace.
struct CellCounts {
  std::int64_t free = 0, occupied = 0, unknown = 0;
  std::int64_t predicted = 0;  ///< predicted cells (also counted as free or occupied)
};

/// How a cell's log-odds becomes a state and an entropy (thresholds as float log-odds, exactly
/// as the octree holds them).
struct CellRule {
  float occupied_logodds = 0.405465f;  ///< a known cell is occupied when logodds >= this
  float clamp_min_logodds = -1.99243f;
  float clamp_max_logodds = 3.47610f;
  EntropyUnit unit = EntropyUnit::Nats;
  bool clamped_entropy_zero = true;

  /// Entropy in nats of a known cell (the clamping rule applied).
  double known_entropy_nats(float logodds) const;
  /// Entropy in the rule's unit of a cell with this log-odds and flag.
  double entropy(float logodds, CellFlag flag) const;
};

/// Where cell (i, j, k) of a dims[0] x dims[1] x dims[2] grid is stored (see the top).
struct GridLayout {
  static constexpr int kBrickShift = 2;  ///< bricks of 4 x 4 x 4 cells
  std::array<int, 3> dims{0, 0, 0};      ///< cells per axis
  std::array<int, 3> bricks{0, 0, 0};    ///< bricks per axis

  GridLayout() = default;
  explicit GridLayout(const std::array<int, 3>& dims);
  std::size_t id(int i, int j, int k) const {
    return (std::size_t(i >> 2) +
            std::size_t(bricks[0]) *
                (std::size_t(j >> 2) + std::size_t(bricks[1]) * std::size_t(k >> 2)))
               << 6 |
           std::size_t((i & 3) | (j & 3) << 2 | (k & 3) << 4);
  }
  /// The cell of an id; false for a padding id.
  bool coords(std::size_t id, int& i, int& j, int& k) const;
  /// A brick's place among the bricks, per axis.
  std::array<std::size_t, 3> brick_coords(std::size_t brick) const {
    const std::size_t x = brick % std::size_t(bricks[0]), rest = brick / std::size_t(bricks[0]);
    return {x, rest % std::size_t(bricks[1]), rest / std::size_t(bricks[1])};
  }
  /// Calls f(axis, side, b) for each brick b beside brick `brick` on a face (side 0: the low
  /// end of the axis, 1: the high), axis by axis, low side first, until f returns true; returns
  /// whether it did. `at`: the brick's place (brick_coords).
  template <class F>
  bool any_face_neighbour(std::size_t brick, const std::array<std::size_t, 3>& at, F&& f) const {
    std::size_t step = 1;
    for (int a = 0; a < 3; step *= std::size_t(bricks[a]), ++a)
      if ((at[a] > 0 && f(a, 0, brick - step)) ||
          (at[a] + 1 < std::size_t(bricks[a]) && f(a, 1, brick + step)))
        return true;
    return false;
  }
  /// Whether pred(b) holds for a brick b beside brick `brick` on a face; `at`: the brick's place
  /// (brick_coords).
  template <class Pred>
  bool face_neighbour_brick(std::size_t brick, const std::array<std::size_t, 3>& at,
                            Pred&& pred) const {
    return any_face_neighbour(brick, at, [&](int, int, std::size_t b) { return pred(b); });
  }
  /// Whether pred(b) holds for brick b = `brick` or one of the bricks beside it on a face.
  template <class Pred>
  bool brick_or_face_neighbour(std::size_t brick, Pred&& pred) const {
    return pred(brick) || face_neighbour_brick(brick, brick_coords(brick), pred);
  }
  bool contains(int i, int j, int k) const {
    return unsigned(i) < unsigned(dims[0]) && unsigned(j) < unsigned(dims[1]) &&
           unsigned(k) < unsigned(dims[2]);
  }
  std::int64_t num_cells() const { return std::int64_t(dims[0]) * dims[1] * dims[2]; }
  std::size_t storage_size() const { return std::size_t(bricks[0]) * bricks[1] * bricks[2] * 64; }
  std::size_t num_bricks() const { return std::size_t(bricks[0]) * bricks[1] * bricks[2]; }
};

/// Which bricks of a grid's arrays changed, and when: a writer stamps a brick it changes with the
/// current epoch; a reader takes an epoch (take_epoch), after which every write is stamped above
/// it. A brick whose stamp is at most the epoch a reader took has not changed since. Each
/// instance has an id of its own (a copy gets a new one), so that a reader can tell records
/// apart.
class BrickStamps {
 public:
  BrickStamps() = default;
  explicit BrickStamps(std::size_t bricks) : stamps_(bricks, 0u) {}
  BrickStamps(const BrickStamps& o) : stamps_(o.stamps_), epoch_(o.epoch_.load()) {}
  BrickStamps(BrickStamps&& o) noexcept
      : stamps_(std::move(o.stamps_)), epoch_(o.epoch_.load()), id_(o.id_) {}
  BrickStamps& operator=(const BrickStamps& o) {
    stamps_ = o.stamps_;
    epoch_ = o.epoch_.load();
    id_ = next_id();
    return *this;
  }
  BrickStamps& operator=(BrickStamps&& o) noexcept {
    stamps_ = std::move(o.stamps_);
    epoch_ = o.epoch_.load();
    id_ = o.id_;
    return *this;
  }
  /// Brick `b` changed (writers that may run in parallel: the store is atomic).
  void touch(std::size_t b) {
    __atomic_store_n(&stamps_[b], epoch_.load(std::memory_order_relaxed), __ATOMIC_RELAXED);
  }
  void touch_all();
  /// Every write so far is stamped at most the epoch returned, every later one above it.
  std::uint32_t take_epoch() const { return epoch_.fetch_add(1, std::memory_order_relaxed); }
  const std::uint32_t* data() const { return stamps_.data(); }
  std::uint64_t id() const { return id_; }

 private:
  static std::uint64_t next_id();
  std::vector<std::uint32_t> stamps_;
  mutable std::atomic<std::uint32_t> epoch_{1};
  std::uint64_t id_ = next_id();
};

/// Read access to a grid's cells by id (see Storage at the top): valid while the grid is alive;
/// pointers stay valid as the grid gives bricks slots, and reads see the slots given so far.
struct CellPools {
  const std::uint32_t* slots = nullptr;  ///< per brick (id >> 6): its slot (0: unknown brick)
  const float* scored = nullptr;         ///< per slot cell: entropy, negated when occupied
  const float* logodds = nullptr;        ///< per slot cell: log-odds (0 for unknown cells)
  const CellFlag* flags = nullptr;       ///< per slot cell: unknown / observed / predicted

  /// Where cell `id`'s values are held in the pools.
  std::size_t at(std::size_t id) const { return std::size_t(slots[id >> 6]) << 6 | (id & 63); }
  /// Cell `id`'s entropy, negated when it is occupied (WorkspaceGrid::scored).
  float scored_at(std::size_t id) const { return scored[at(id)]; }
  float logodds_at(std::size_t id) const { return logodds[at(id)]; }
  CellFlag flag_at(std::size_t id) const { return flags[at(id)]; }
  bool occupied(std::size_t id) const { return std::signbit(scored_at(id)); }
  /// The 64 scored values of a brick, in id order.
  const float* brick_scored(std::size_t brick) const {
    return scored + (std::size_t(slots[brick]) << 6);
  }
  /// The 64 flags of a brick, in id order.
  const CellFlag* brick_flags(std::size_t brick) const {
    return flags + (std::size_t(slots[brick]) << 6);
  }
  explicit operator bool() const { return slots && scored && logodds && flags; }
};

class WorkspaceGrid {
 public:
  static constexpr int kBrickShift = GridLayout::kBrickShift;

  WorkspaceGrid() = default;
  /// A grid of dims[0] x dims[1] x dims[2] unknown cells.
  WorkspaceGrid(const std::array<int, 3>& dims, const CellRule& rule);
  WorkspaceGrid(const WorkspaceGrid& o);
  WorkspaceGrid& operator=(const WorkspaceGrid& o);
  WorkspaceGrid(WorkspaceGrid&& o) noexcept;
  WorkspaceGrid& operator=(WorkspaceGrid&& o) noexcept;

  const GridLayout& layout() const { return layout_; }
  const std::array<int, 3>& dims() const { return layout_.dims; }
  std::int64_t num_cells() const { return layout_.num_cells(); }
  const CellRule& rule() const { return rule_; }

  float logodds(std::int64_t i) const { return cells_.logodds_at(std::size_t(i)); }
  CellFlag flag(std::int64_t i) const { return cells_.flag_at(std::size_t(i)); }
  CellState state(std::int64_t i) const {
    const std::size_t c = cells_.at(std::size_t(i));
    if (cells_.flags[c] == CellFlag::Unknown) return CellState::Unknown;
    return std::signbit(cells_.scored[c]) ? CellState::Occupied : CellState::Free;
  }
  /// Entropy in the rule's unit (the float copy of the value the total sums).
  float entropy(std::int64_t i) const { return std::fabs(cells_.scored_at(std::size_t(i))); }
  /// Entropy, negated when the cell is occupied (the sign bit marks occupancy, also for zero
  /// entropy: -0.0f). One read answers "stop here?" and "how much information?".
  float scored(std::int64_t i) const { return cells_.scored_at(std::size_t(i)); }

  /// Sets cell `id`, keeping the totals, counts and brick summary in sync.
  void set(std::int64_t id, float logodds, CellFlag flag);
  /// Replaces every cell (e.g. from a map file): all unknown, then fill(put) calls
  /// put(id, logodds) once for each observed cell.
  template <class Fill>
  void assign_observed(Fill&& fill) {
    clear_cells();
    fill([this](std::size_t id, float logodds) {
      const std::size_t c = own_brick(id >> 6) << 6 | (id & 63);
      pool_logodds_[c] = logodds;
      pool_flags_[c] = CellFlag::Observed;
    });
    rebuild_derived();
  }

  /// Bricks holding cells of their own: those written since the grid was made or assigned.
  std::size_t allocated_bricks() const { return used_slots_ ? used_slots_ - 1 : 0; }
  /// Bytes the grid holds: its given slots' cells, and its per-brick tables.
  std::size_t bytes() const;

  /// Total entropy in the rule's unit, O(1).
  double total_entropy() const;
  /// The same by a full sweep (equal to total_entropy() exactly).
  double recompute_total_entropy() const;
  CellCounts counts() const { return counts_; }
  CellCounts recompute_counts() const;

  // ---- raw arrays for the ray-walking kernels (valid while the grid is alive) ---------------
  /// The cells by id (scored, log-odds and flags).
  const CellPools& cells() const { return cells_; }
  /// Per brick (id >> 6): the number of live (not neutral) cells.
  const std::uint8_t* brick_live_data() const { return brick_live_.data(); }
  /// Per brick: the number of open cells (known and not occupied; 64: the whole brick).
  const std::uint8_t* brick_open_data() const { return brick_open_.data(); }
  /// Per brick: the number of occupied cells.
  const std::uint8_t* brick_occupied_data() const { return brick_occupied_.data(); }
  /// When each brick's cells last changed (see BrickStamps).
  const BrickStamps& stamps() const { return stamps_; }

 private:
  std::int64_t fixed_entropy(float logodds);  // cached: cells take few distinct values
  std::int64_t fixed_entropy_uncached(float logodds) const;
  float to_unit(std::int64_t fixed) const;
  bool live(std::int64_t fixed, CellFlag flag, bool occupied) const {
    return !(flag == CellFlag::Observed && !occupied && fixed == 0);
  }
  void rebuild_derived();  // scored, counts, totals and bricks from the log-odds and flags
  void clear_cells();      // every cell unknown, no brick with a slot
  std::size_t own_brick(std::size_t brick);  // the brick's slot, given on its first call
  void copy_cells(const WorkspaceGrid& o);
  void point_cells();  // cells_ at this grid's tables

  GridLayout layout_;
  CellRule rule_;
  std::vector<std::uint32_t> slot_;  // per brick
  std::size_t used_slots_ = 0;       // slots given, the shared unknown brick (slot 0) included
  ReleasableArray<float> pool_logodds_, pool_scored_;
  ReleasableArray<CellFlag> pool_flags_;
  CellPools cells_;
  std::vector<std::uint8_t> brick_live_;
  std::vector<std::uint8_t> brick_open_;
  std::vector<std::uint8_t> brick_occupied_;
  BrickStamps stamps_;
  CellCounts counts_;
  __int128 known_entropy_fixed_ = 0;  // sum over known cells, units of 2^-50 nats
  struct CacheEntry {
    std::uint32_t bits = 0xFFFFFFFFu;  // a NaN pattern no cell holds
    std::int64_t fixed = 0;
  };
  std::array<CacheEntry, 1024> cache_{};
};

}  // namespace nbv
