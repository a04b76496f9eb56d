#include "nbv/workspace_grid.hpp"

#include "nbv/parallel.hpp"

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

WorkspaceGrid::WorkspaceGrid(const std::array<int, 3>& dims, const CellRule& rule)
    : dims_(dims), rule_(rule) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0) throw std::invalid_argument("workspace grid dimensions must be positive");
    brick_dims_[a] = (dims[a] + (1 << kBrickShift) - 1) >> kBrickShift;
  }
  const std::size_t n = std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(dims[2]);
  if (n >= (std::size_t(1) << 32)) throw std::invalid_argument("workspace grid too large");
  div_nx_ = Divider(std::uint32_t(dims[0]));
  div_ny_ = Divider(std::uint32_t(dims[1]));
  logodds_.assign(n, 0.0f);
  flags_.assign(n, CellFlag::Unknown);
  rebuild_derived();
}

std::int64_t WorkspaceGrid::brick_of(std::int64_t i) const {
  // cell indices are < 2^32 (OccupancyMap::kMaxCells): one exact multiply per division
  const std::uint32_t yz = div_nx_(std::uint32_t(i)), z = div_ny_(yz);
  const std::int64_t x = i - std::int64_t(yz) * dims_[0], y = yz - std::int64_t(z) * dims_[1];
  return (x >> kBrickShift) +
         std::int64_t(brick_dims_[0]) *
             ((y >> kBrickShift) + std::int64_t(brick_dims_[1]) * (z >> kBrickShift));
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
  const std::size_t brick = std::size_t(brick_of(idx));
  if (old_flag == CellFlag::Unknown) {
    --counts_.unknown;
    --brick_live_[brick];
  } else {
    const bool occ = old_l >= rule_.occupied_logodds;
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
  if (logodds.size() != logodds_.size() || flags.size() != flags_.size())
    throw std::invalid_argument("WorkspaceGrid::assign: wrong number of cells");
  logodds_ = std::move(logodds);
  flags_ = std::move(flags);
  rebuild_derived();
}

void WorkspaceGrid::rebuild_derived() {
  const std::size_t n = logodds_.size();
  scored_.resize(n);
  const float unknown = float(rule_.entropy(0.0f, CellFlag::Unknown));
  // per-chunk fixed-point sums: integers, so the same total in any order and any thread count
  const std::size_t grain = 1 << 16, nchunks = (n + grain - 1) / grain;
  std::vector<__int128> sums(nchunks, 0);
  parallel_chunks(nchunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      __int128 s = 0;
      for (std::size_t i = c * grain, e = std::min(n, (c + 1) * grain); i < e; ++i) {
        if (flags_[i] == CellFlag::Unknown) {
          logodds_[i] = 0.0f;
          scored_[i] = unknown;
          continue;
        }
        const std::int64_t fixed = fixed_entropy_uncached(logodds_[i]);
        s += fixed;
        const float v = to_unit(fixed);
        scored_[i] = logodds_[i] >= rule_.occupied_logodds ? -v : v;
      }
      sums[c] = s;
    }
  });
  known_entropy_fixed_ = 0;
  for (const __int128 v : sums) known_entropy_fixed_ += v;
  counts_ = recompute_counts();
  brick_live_.assign(std::size_t(brick_dims_[0]) * brick_dims_[1] * brick_dims_[2], 0);
  for (std::size_t i = 0; i < n; ++i) {
    const bool occ = std::signbit(scored_[i]);
    if (flags_[i] == CellFlag::Unknown || live(scored_[i] == 0.0f ? 0 : 1, flags_[i], occ))
      ++brick_live_[std::size_t(brick_of(std::int64_t(i)))];
  }
}

double WorkspaceGrid::total_entropy() const {
  const double known_nats = double(known_entropy_fixed_) / kFixedScale;
  if (rule_.unit == EntropyUnit::Bits) return double(counts_.unknown) + known_nats / kLn2;
  return double(counts_.unknown) * kLn2 + known_nats;
}

double WorkspaceGrid::recompute_total_entropy() const {
  const std::size_t n = logodds_.size();
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
  for (std::size_t i = 0, n = logodds_.size(); i < n; ++i) {
    if (flags_[i] == CellFlag::Unknown) {
      ++c.unknown;
      continue;
    }
    (logodds_[i] >= rule_.occupied_logodds ? c.occupied : c.free) += 1;
    if (flags_[i] == CellFlag::Predicted) ++c.predicted;
  }
  return c;
}

}  // namespace nbv
