#include "nbv/workspace_grid.hpp"

#include "nbv/parallel.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

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
  const std::size_t brick = id >> 6, in = id & 63;
  const std::size_t bx = brick % std::size_t(bricks[0]), rest = brick / std::size_t(bricks[0]);
  const std::size_t by = rest % std::size_t(bricks[1]), bz = rest / std::size_t(bricks[1]);
  i = int(bx << 2 | (in & 3));
  j = int(by << 2 | ((in >> 2) & 3));
  k = int(bz << 2 | (in >> 4));
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
  logodds_.assign(layout_.storage_size(), 0.0f);
  flags_.assign(layout_.storage_size(), CellFlag::Unknown);
  rebuild_derived();
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
  const std::size_t i = std::size_t(idx);
  const CellFlag old_flag = flags_[i];
  const float old_l = logodds_[i];
  if (old_flag == flag && old_l == logodds) return;
  const std::size_t brick = i >> 6;
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
    scored_[i] = float(rule_.entropy(0.0f, CellFlag::Unknown));
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
    scored_[i] = occ ? -e : e;
  }
  flags_[i] = flag;
  logodds_[i] = logodds;
}

void WorkspaceGrid::assign(std::vector<float> logodds, std::vector<CellFlag> flags) {
  if (logodds.size() != layout_.storage_size() || flags.size() != layout_.storage_size())
    throw std::invalid_argument("WorkspaceGrid::assign: wrong number of cells");
  logodds_ = std::move(logodds);
  flags_ = std::move(flags);
  rebuild_derived();
}

void WorkspaceGrid::rebuild_derived() {
  const std::size_t n = layout_.storage_size();
  scored_.resize(n);
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
      __int128 s = 0;
      int live_cells = 0, open_cells = 0, occupied_cells = 0;
      for (std::size_t id = brick << 6, e = id + 64; id < e; ++id) {
        int i, j, k;
        if (!layout_.coords(id, i, j, k)) {  // padding: no cell
          logodds_[id] = 0.0f;
          flags_[id] = CellFlag::Unknown;
          scored_[id] = 0.0f;
          continue;
        }
        if (flags_[id] == CellFlag::Unknown) {
          logodds_[id] = 0.0f;
          scored_[id] = unknown;
          ++live_cells;
          continue;
        }
        const std::int64_t fixed = fixed_entropy_uncached(logodds_[id]);
        s += fixed;
        const bool occ = logodds_[id] >= rule_.occupied_logodds;
        const float v = to_unit(fixed);
        scored_[id] = occ ? -v : v;
        live_cells += live(fixed, flags_[id], occ);
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
  const std::size_t n = layout_.storage_size();  // padding ids are unknown, 0 in the known sum
  const std::size_t grain = 1 << 16, nchunks = (n + grain - 1) / grain;
  std::vector<__int128> sums(nchunks, 0);
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      __int128 s = 0;
      for (std::size_t i = c * grain, e = std::min(n, (c + 1) * grain); i < e; ++i)
        if (flags_[i] != CellFlag::Unknown) s += fixed_entropy_uncached(logodds_[i]);
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
  c.unknown = layout_.num_cells();  // padding ids are never known
  for (std::size_t i = 0, n = logodds_.size(); i < n; ++i) {
    if (flags_[i] == CellFlag::Unknown) continue;
    --c.unknown;
    (logodds_[i] >= rule_.occupied_logodds ? c.occupied : c.free) += 1;
    if (flags_[i] == CellFlag::Predicted) ++c.predicted;
  }
  return c;
}

}  // namespace nbv
