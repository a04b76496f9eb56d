#include "nbv/workspace_grid.hpp"

#include "nbv/parallel.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace nbv {
namespace {

constexpr double kFixedScale = 1125899906842624.0;  // 2^50: entropy fixed point, units per nat
constexpr double kLn2 = 0.693147180559945309417232121458176568;

/// Binary entropy in nats of p = sigmoid(l), numerically stable for any l.
double binary_entropy_nats(double l) {
  const double a = std::fabs(l);
  const double e = std::exp(-a);
  return std::log1p(e) + a * e / (1.0 + e);
}

}  // namespace

double CellRule::known_entropy_nats(float logodds) const {
  if (clamped_entropy_zero && (logodds <= clamp_min_logodds || logodds >= clamp_max_logodds))
    return 0.0;
  return binary_entropy_nats(double(logodds));
}

double CellRule::entropy(float logodds, CellFlag flag) const {
  if (flag == CellFlag::Unknown) return unit == EntropyUnit::Bits ? 1.0 : kLn2;
  const double nats = known_entropy_nats(logodds);
  return unit == EntropyUnit::Bits ? nats / kLn2 : nats;
}

GridLayout::GridLayout(const std::array<int, 3>& d) : dims(d) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] <= 0) throw std::invalid_argument("grid dimensions must be positive");
    bricks[a] = (d[a] + 3) >> kBrickShift;
  }
}

bool GridLayout::coords(std::size_t id, int& i, int& j, int& k) const {
  const std::size_t in = id & 63;
  const std::array<std::size_t, 3> b = brick_coords(id >> 6);
  i = int(b[0] << 2 | (in & 3));
  j = int(b[1] << 2 | ((in >> 2) & 3));
  k = int(b[2] << 2 | (in >> 4));
  return contains(i, j, k);
}

std::uint64_t BrickStamps::next_id() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

void BrickStamps::touch_all() {
  std::fill(stamps_.begin(), stamps_.end(), epoch_.load(std::memory_order_relaxed));
}

WorkspaceGrid::WorkspaceGrid(const std::array<int, 3>& dims, const CellRule& rule)
    : layout_(dims), rule_(rule), stamps_(layout_.num_bricks()) {
  if (layout_.storage_size() >= (std::size_t(1) << 40))
    throw std::invalid_argument("workspace grid too large");
  // slots: the shared unknown brick and at most one per brick
  pool_logodds_ = ReleasableArray<float>(layout_.storage_size() + 64);
  pool_scored_ = ReleasableArray<float>(layout_.storage_size() + 64);
  pool_flags_ = ReleasableArray<CellFlag>(layout_.storage_size() + 64);
  clear_cells();
  rebuild_derived();
}

WorkspaceGrid::WorkspaceGrid(const WorkspaceGrid& o) { *this = o; }

WorkspaceGrid& WorkspaceGrid::operator=(const WorkspaceGrid& o) {
  if (this == &o) return *this;
  layout_ = o.layout_;
  rule_ = o.rule_;
  brick_live_ = o.brick_live_;
  brick_open_ = o.brick_open_;
  brick_occupied_ = o.brick_occupied_;
  stamps_ = o.stamps_;
  counts_ = o.counts_;
  known_entropy_fixed_ = o.known_entropy_fixed_;
  cache_ = {};
  copy_cells(o);
  return *this;
}

WorkspaceGrid::WorkspaceGrid(WorkspaceGrid&& o) noexcept { *this = std::move(o); }

WorkspaceGrid& WorkspaceGrid::operator=(WorkspaceGrid&& o) noexcept {
  if (this == &o) return *this;
  layout_ = o.layout_;
  rule_ = o.rule_;
  slot_ = std::move(o.slot_);
  used_slots_ = std::exchange(o.used_slots_, 0);
  pool_logodds_ = std::move(o.pool_logodds_);
  pool_scored_ = std::move(o.pool_scored_);
  pool_flags_ = std::move(o.pool_flags_);
  brick_live_ = std::move(o.brick_live_);
  brick_open_ = std::move(o.brick_open_);
  brick_occupied_ = std::move(o.brick_occupied_);
  stamps_ = std::move(o.stamps_);
  counts_ = o.counts_;
  known_entropy_fixed_ = o.known_entropy_fixed_;
  cache_ = o.cache_;
  point_cells();
  o.point_cells();
  return *this;
}

void WorkspaceGrid::copy_cells(const WorkspaceGrid& o) {
  slot_ = o.slot_;
  used_slots_ = o.used_slots_;
  const std::size_t n = o.pool_scored_.size(), used = used_slots_ * 64;
  pool_logodds_ = ReleasableArray<float>(n);
  pool_scored_ = ReleasableArray<float>(n);
  pool_flags_ = ReleasableArray<CellFlag>(n);
  if (used) {
    std::copy(o.pool_logodds_.data(), o.pool_logodds_.data() + used, pool_logodds_.data());
    std::copy(o.pool_scored_.data(), o.pool_scored_.data() + used, pool_scored_.data());
    std::copy(o.pool_flags_.data(), o.pool_flags_.data() + used, pool_flags_.data());
  }
  point_cells();
}

void WorkspaceGrid::point_cells() {
  cells_.slots = slot_.data();
  cells_.scored = pool_scored_.data();
  cells_.logodds = pool_logodds_.data();
  cells_.flags = pool_flags_.data();
}

void WorkspaceGrid::clear_cells() {  // every cell unknown, no brick with a slot
  pool_logodds_.release();           // every page zero again: log-odds 0, flags unknown
  pool_scored_.release();
  pool_flags_.release();
  slot_.assign(layout_.num_bricks(), 0u);
  const float unknown = float(rule_.entropy(0.0f, CellFlag::Unknown));
  std::fill(pool_scored_.data(), pool_scored_.data() + 64, unknown);  // slot 0: unknown cells
  used_slots_ = 1;
  point_cells();
}

std::size_t WorkspaceGrid::own_brick(std::size_t brick) {
  std::uint32_t& s = slot_[brick];
  if (s == 0) {
    s = std::uint32_t(used_slots_++);
    std::copy(pool_scored_.data(), pool_scored_.data() + 64, pool_scored_.data() + (s << 6));
  }
  return s;
}

std::size_t WorkspaceGrid::bytes() const {
  const std::size_t per_cell = sizeof(float) * 2 + sizeof(CellFlag);
  const std::size_t per_brick = sizeof(std::uint32_t) * 2 + 3;  // slot, stamp, three counts
  return used_slots_ * 64 * per_cell + layout_.num_bricks() * per_brick;
}

std::int64_t WorkspaceGrid::fixed_entropy_uncached(float logodds) const {
  return std::llround(rule_.known_entropy_nats(logodds) * kFixedScale);
}

std::int64_t WorkspaceGrid::fixed_entropy(float logodds) {
  std::uint32_t bits;
  std::memcpy(&bits, &logodds, sizeof bits);
  CacheEntry& e = cache_[(bits ^ (bits >> 13) ^ (bits >> 23)) & (cache_.size() - 1)];
  if (e.bits != bits) {
    e.bits = bits;
    e.fixed = fixed_entropy_uncached(logodds);
  }
  return e.fixed;
}

float WorkspaceGrid::to_unit(std::int64_t fixed) const {
  const double nats = double(fixed) / kFixedScale;
  return float(rule_.unit == EntropyUnit::Bits ? nats / kLn2 : nats);
}

void WorkspaceGrid::set(std::int64_t idx, float logodds, CellFlag flag) {
  const std::size_t brick = std::size_t(idx) >> 6;
  std::size_t i = cells_.at(std::size_t(idx));
  const CellFlag old_flag = pool_flags_[i];
  const float old_l = pool_logodds_[i];
  if (old_flag == flag && old_l == logodds) return;
  i = own_brick(brick) << 6 | (std::size_t(idx) & 63);
  stamps_.touch(brick);
  if (old_flag == CellFlag::Unknown) {
    --counts_.unknown;
    --brick_live_[brick];
  } else {
    const bool occ = old_l >= rule_.occupied_logodds;
    brick_open_[brick] -= !occ;
    brick_occupied_[brick] -= occ;
    (occ ? counts_.occupied : counts_.free) -= 1;
    if (old_flag == CellFlag::Predicted) --counts_.predicted;
    const std::int64_t fixed = fixed_entropy(old_l);
    known_entropy_fixed_ -= fixed;
    if (live(fixed, old_flag, occ)) --brick_live_[brick];
  }
  if (flag == CellFlag::Unknown) {
    ++counts_.unknown;
    ++brick_live_[brick];
    pool_scored_[i] = float(rule_.entropy(0.0f, CellFlag::Unknown));
    logodds = 0.0f;
  } else {
    const bool occ = logodds >= rule_.occupied_logodds;
    brick_open_[brick] += !occ;
    brick_occupied_[brick] += occ;
    (occ ? counts_.occupied : counts_.free) += 1;
    if (flag == CellFlag::Predicted) ++counts_.predicted;
    const std::int64_t fixed = fixed_entropy(logodds);
    known_entropy_fixed_ += fixed;
    if (live(fixed, flag, occ)) ++brick_live_[brick];
    const float e = to_unit(fixed);
    pool_scored_[i] = occ ? -e : e;
  }
  pool_flags_[i] = flag;
  pool_logodds_[i] = logodds;
}

void WorkspaceGrid::rebuild_derived() {
  brick_live_.assign(layout_.num_bricks(), 0);
  brick_open_.assign(layout_.num_bricks(), 0);
  brick_occupied_.assign(layout_.num_bricks(), 0);
  stamps_.touch_all();
  const float unknown = float(rule_.entropy(0.0f, CellFlag::Unknown));
  // per brick: fixed-point sums (integers: the same total in any order and thread count)
  const std::size_t nb = layout_.num_bricks();
  std::vector<__int128> sums(nb, 0);
  parallel_chunks(nb, 256, [&](std::size_t bb, std::size_t be) {
    for (std::size_t brick = bb; brick < be; ++brick) {
      if (slot_[brick] == 0) {  // the shared brick: unknown cells (and padding)
        int cells = 0;
        for (std::size_t id = brick << 6, e = id + 64; id < e; ++id) {
          int i, j, k;
          cells += layout_.coords(id, i, j, k);
        }
        brick_live_[brick] = std::uint8_t(cells);
        continue;
      }
      __int128 s = 0;
      int live_cells = 0, open_cells = 0, occupied_cells = 0;
      for (std::size_t id = brick << 6, e = id + 64; id < e; ++id) {
        const std::size_t c = cells_.at(id);
        int i, j, k;
        const bool cell = layout_.coords(id, i, j, k);  // padding: no cell, read as unknown
        if (!cell || pool_flags_[c] == CellFlag::Unknown) {
          pool_logodds_[c] = 0.0f;
          pool_flags_[c] = CellFlag::Unknown;
          pool_scored_[c] = unknown;
          live_cells += cell;
          continue;
        }
        const std::int64_t fixed = fixed_entropy_uncached(pool_logodds_[c]);
        s += fixed;
        const bool occ = pool_logodds_[c] >= rule_.occupied_logodds;
        const float v = to_unit(fixed);
        pool_scored_[c] = occ ? -v : v;
        live_cells += live(fixed, pool_flags_[c], occ);
        open_cells += !occ;
        occupied_cells += occ;
      }
      sums[brick] = s;
      brick_live_[brick] = std::uint8_t(live_cells);
      brick_open_[brick] = std::uint8_t(open_cells);
      brick_occupied_[brick] = std::uint8_t(occupied_cells);
    }
  });
  known_entropy_fixed_ = 0;
  for (const __int128 v : sums) known_entropy_fixed_ += v;
  counts_ = recompute_counts();
}

double WorkspaceGrid::total_entropy() const {
  const double known_nats = double(known_entropy_fixed_) / kFixedScale;
  if (rule_.unit == EntropyUnit::Bits) return double(counts_.unknown) + known_nats / kLn2;
  return double(counts_.unknown) * kLn2 + known_nats;
}

double WorkspaceGrid::recompute_total_entropy() const {
  // the given slots' cells (padding and the shared brick's cells are unknown: 0 in the sum)
  const std::size_t n = used_slots_ * 64;
  const std::size_t grain = 1 << 16, nchunks = (n + grain - 1) / grain;
  std::vector<__int128> sums(nchunks, 0);
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      __int128 s = 0;
      for (std::size_t i = c * grain, e = std::min(n, (c + 1) * grain); i < e; ++i)
        if (pool_flags_[i] != CellFlag::Unknown) s += fixed_entropy_uncached(pool_logodds_[i]);
      sums[c] = s;
    }
  });
  __int128 total = 0;
  for (const __int128 v : sums) total += v;
  const double known_nats = double(total) / kFixedScale;
  const double unknown = double(recompute_counts().unknown);
  if (rule_.unit == EntropyUnit::Bits) return unknown + known_nats / kLn2;
  return unknown * kLn2 + known_nats;
}

CellCounts WorkspaceGrid::recompute_counts() const {
  CellCounts c;
  c.unknown = layout_.num_cells();  // padding and the shared brick's cells are never known
  for (std::size_t i = 0, n = used_slots_ * 64; i < n; ++i) {
    if (pool_flags_[i] == CellFlag::Unknown) continue;
    --c.unknown;
    (pool_logodds_[i] >= rule_.occupied_logodds ? c.occupied : c.free) += 1;
    if (pool_flags_[i] == CellFlag::Predicted) ++c.predicted;
  }
  return c;
}

}  // namespace nbv
