#include "nbv/coverage.hpp"

#include "nbv/parallel.hpp"
#include "view_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <queue>
#include <stdexcept>
#include <unordered_map>

namespace nbv {

void SurfaceTargetOptions::validate() const {
  if (!(coverage_cone_deg >= 0 && coverage_cone_deg <= 180))
    throw std::invalid_argument("coverage_cone_deg must be in [0, 180]");
  if (!(frontier_weight >= 0 && frontier_weight <= 1) || !std::isfinite(frontier_weight))
    throw std::invalid_argument("frontier_weight must be in [0, 1]");
}

namespace {

struct Target {
  std::size_t id;
  int i, j, k;
  Eigen::Vector3d normal;
  TargetKind kind;
  double weight;
};

}  // namespace

SurfaceTargets surface_targets(const GridView& g, const SurfaceTargetOptions& opt) {
  g.validate();
  opt.validate();
  if (!g.seen) throw std::invalid_argument("surface_targets needs the camera observations");
  std::uint32_t cones[26];
  for (int b = 0; b < 26; ++b) cones[b] = bin_cone(b, opt.coverage_cone_deg);
  // the 26 neighbour offsets, their unit directions and direction bins
  int off[26][3];
  Eigen::Vector3d unit[26];
  int bins[26];
  for (int n = 0, m = 0; m < 27; ++m) {
    if (m == 13) continue;
    off[n][0] = m % 3 - 1;
    off[n][1] = (m / 3) % 3 - 1;
    off[n][2] = m / 9 - 1;
    unit[n] = Eigen::Vector3d(off[n][0], off[n][1], off[n][2]).normalized();
    bins[n] = direction_bin(unit[n]);
    ++n;
  }
  const std::size_t nb = g.layout.num_bricks();
  std::vector<std::vector<Target>> per_brick(nb);
  parallel_chunks(nb, 64, [&](std::size_t bb, std::size_t be) {
    for (std::size_t brick = bb; brick < be; ++brick) {
      if (!g.brick_live[brick]) continue;  // neutral cells only: free space
      for (std::size_t id = brick << 6, end = id + 64; id < end; ++id) {
        int c[3];
        if (!g.layout.coords(id, c[0], c[1], c[2])) continue;
        const CellFlag f = g.flags[id];
        const bool occ = std::signbit(g.scored[id]);
        TargetKind kind;
        double weight;
        if (f == CellFlag::Observed && occ) {
          if (!opt.observed) continue;
          kind = TargetKind::Observed;
          weight = 1.0;
        } else if (f == CellFlag::Predicted) {
          if (!opt.predicted) continue;
          kind = TargetKind::Predicted;
          weight = 1.0 / (1.0 + std::exp(-double(g.logodds[id])));
        } else if (f == CellFlag::Unknown) {
          if (!opt.frontier) continue;
          kind = TargetKind::Frontier;
          weight = opt.frontier_weight;
        } else {
          continue;  // observed free
        }
        Eigen::Vector3d normal = Eigen::Vector3d::Zero();
        bool touches_surface = false, touches_free = false;
        for (int n = 0; n < 26; ++n) {
          const int a = c[0] + off[n][0], b = c[1] + off[n][1], d = c[2] + off[n][2];
          if (!g.contains(a, b, d)) continue;
          const std::size_t nid = g.layout.id(a, b, d);
          const CellFlag nf = g.flags[nid];
          const bool n_occ = std::signbit(g.scored[nid]);
          const bool face = std::abs(off[n][0]) + std::abs(off[n][1]) + std::abs(off[n][2]) == 1;
          const bool n_free = nf == CellFlag::Observed && !n_occ;
          if (kind == TargetKind::Frontier) {
            if (face && (n_occ || nf == CellFlag::Predicted)) touches_surface = true;
            if (n_free) {
              touches_free |= face;
              normal += unit[n];
            }
            continue;
          }
          if (n_occ && nf != CellFlag::Unknown) continue;  // not an open side
          if (kind == TargetKind::Observed && n_free && (g.seen[id] & cones[bins[n]])) continue;
          normal += unit[n];
        }
        if (kind == TargetKind::Frontier && !(touches_surface && touches_free)) continue;
        const double len = normal.norm();
        if (len < 1e-9) continue;  // nothing left to see from any open side
        per_brick[brick].push_back({id, c[0], c[1], c[2], normal / len, kind, weight});
      }
    }
  });
  std::size_t total = 0;
  for (const auto& v : per_brick) total += v.size();
  SurfaceTargets out;
  out.positions.resize(Eigen::Index(total), 3);
  out.normals.resize(Eigen::Index(total), 3);
  out.kind.resize(Eigen::Index(total));
  out.weight.resize(Eigen::Index(total));
  Eigen::Index r = 0;
  for (const auto& v : per_brick)
    for (const Target& t : v) {
      out.positions.row(r) = g.center(t.i, t.j, t.k).transpose();
      out.normals.row(r) = t.normal.transpose();
      out.kind[r] = std::int8_t(t.kind);
      out.weight[r] = t.weight;
      ++r;
    }
  return out;
}

ViewCoverage view_coverage(
    const GridView& g,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& cand,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity) {
  g.validate();
  camera.validate();
  utility.validate();
  validity.validate();
  if (!g.seen || !g.hits)
    throw std::invalid_argument("view_coverage needs the camera observations");
  if (!cand.allFinite())
    throw std::invalid_argument("candidate poses contain NaN or infinite values");
  const Eigen::Index K = cand.rows();
  std::vector<std::vector<std::pair<std::int64_t, float>>> sets(static_cast<std::size_t>(K));
  // per cell, lazily: the direction splitting its sides (code 1 + bin index of the side axis,
  // + 27 when the cell has one side only; 0: not computed). Racing threads write the same value.
  std::vector<std::uint8_t> side_axis(g.storage_size(), 0);
  Eigen::Vector3d bin_dir[26];
  for (int b = 0; b < 26; ++b) bin_dir[b] = bin_direction(b);
  auto side_of = [&](std::int64_t cell, int bin) {
    std::uint8_t code = __atomic_load_n(&side_axis[std::size_t(cell)], __ATOMIC_RELAXED);
    if (code == 0) {
      int c[3];
      g.layout.coords(std::size_t(cell), c[0], c[1], c[2]);
      Eigen::Vector3d sum = Eigen::Vector3d::Zero(), spread = Eigen::Vector3d::Zero();
      int open = 0;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            if (!dx && !dy && !dz) continue;
            const int a = c[0] + dx, b = c[1] + dy, e = c[2] + dz;
            if (!g.contains(a, b, e)) continue;
            const std::size_t n = g.layout.id(a, b, e);
            if (std::signbit(g.scored[n]) && g.flags[n] != CellFlag::Unknown) continue;
            const Eigen::Vector3d u = Eigen::Vector3d(dx, dy, dz).normalized();
            sum += u;
            spread += u.cwiseAbs();
            ++open;
          }
      if (open && sum.norm() >= 0.25 * spread.norm()) {
        code = std::uint8_t(1 + 27 + direction_bin(sum));  // one side: the open direction
      } else {
        int axis;
        spread.maxCoeff(&axis);
        code = std::uint8_t(1 + direction_bin(Eigen::Vector3d::Unit(axis)));
      }
      __atomic_store_n(&side_axis[std::size_t(cell)], code, __ATOMIC_RELAXED);
    }
    if (code > 27) return 0;
    return bin_dir[bin].dot(bin_dir[code - 1]) >= 0 ? 0 : 1;
  };
  kernel::Job job{g, cand, current, camera, utility, validity, false, {}};
  job.on_view = [&](Eigen::Index k, const std::vector<utility::Credit>& credits) {
    // (element, weight) sorted by element, each element once with its largest weight in the view
    auto& s = sets[std::size_t(k)];
    s.clear();
    s.reserve(credits.size());
    for (const auto& c : credits) s.emplace_back(c.cell * 2 + side_of(c.cell, c.bin), c.weight);
    std::sort(s.begin(), s.end());
    std::size_t m = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (m && s[m - 1].first == s[i].first)
        s[m - 1].second = s[i].second;  // sorted: the later weight is the larger
      else
        s[m++] = s[i];
    }
    s.resize(m);
  };
  const ViewScores scores = kernel::score<utility::Surface, true>(job, kernel::GridCells{g});
  ViewCoverage out;
  out.status = scores.status;
  out.offsets.resize(K + 1);
  out.offsets[0] = 0;
  for (Eigen::Index k = 0; k < K; ++k)
    out.offsets[k + 1] = out.offsets[k] + std::int64_t(sets[std::size_t(k)].size());
  out.elements.resize(out.offsets[K]);
  out.weights.resize(out.offsets[K]);
  for (Eigen::Index k = 0; k < K; ++k) {
    std::int64_t o = out.offsets[k];
    for (const auto& [e, w] : sets[std::size_t(k)]) {
      out.elements[o] = e;
      out.weights[o] = w;
      ++o;
    }
  }
  return out;
}

CoverSelection select_cover(const ViewCoverage& cov, double min_gain, int max_views) {
  const Eigen::Index K = cov.offsets.size() - 1;
  if (K < 0) throw std::invalid_argument("coverage has no offsets");
  CoverSelection out;
  std::unordered_map<std::int64_t, float> covered;  // element -> weight already covered
  auto gain_of = [&](Eigen::Index k) {
    double g = 0.0;
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      auto it = covered.find(cov.elements[o]);
      const float have = it == covered.end() ? 0.0f : it->second;
      g += std::max(0.0f, cov.weights[o] - have);
    }
    return g;
  };
  // lazy greedy: a view's gain only shrinks as others are chosen, so a stale upper bound that
  // still tops the queue after recomputation is the true best
  using Entry = std::pair<double, Eigen::Index>;
  auto cmp = [](const Entry& a, const Entry& b) {
    return a.first < b.first || (a.first == b.first && a.second > b.second);
  };
  std::priority_queue<Entry, std::vector<Entry>, decltype(cmp)> queue(cmp);
  for (Eigen::Index k = 0; k < K; ++k)
    if (cov.status[k] == 0) queue.push({gain_of(k), k});
  while (!queue.empty() && int(out.views.size()) < max_views) {
    auto [bound, k] = queue.top();
    queue.pop();
    const double g = gain_of(k);
    if (!queue.empty() && g < queue.top().first) {
      queue.push({g, k});
      continue;
    }
    if (g < min_gain) break;
    out.views.push_back(int(k));
    out.gains.push_back(g);
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      float& have = covered[cov.elements[o]];
      have = std::max(have, cov.weights[o]);
    }
  }
  return out;
}

CoverSelection select_tour(const ViewCoverage& cov, const PointsRef& positions,
                           const Eigen::Vector3d& start, double rate, double min_gain,
                           int max_views, bool charge_transit) {
  const Eigen::Index K = cov.offsets.size() - 1;
  if (K < 0 || positions.rows() != K)
    throw std::invalid_argument("select_tour: one position per candidate of the coverage");
  require_finite(positions, "candidate positions");
  if (!start.allFinite()) throw std::invalid_argument("select_tour: start is not finite");
  if (!(rate >= 0) || !std::isfinite(rate)) throw std::invalid_argument("rate must be >= 0");
  // every candidate's current gain, and the candidates each element belongs to (inverse CSR:
  // the distinct elements sorted, each with its holders in candidate order)
  std::vector<double> gain(static_cast<std::size_t>(K), 0.0);
  // (offset into cov, candidate) of every valid candidate's elements
  std::vector<std::pair<std::int64_t, Eigen::Index>> entries;
  for (Eigen::Index k = 0; k < K; ++k) {
    if (cov.status[k] != 0) continue;
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      entries.emplace_back(o, k);
      gain[std::size_t(k)] += cov.weights[o];
    }
  }
  std::stable_sort(entries.begin(), entries.end(), [&](const auto& a, const auto& b) {
    return cov.elements[a.first] < cov.elements[b.first];
  });
  std::vector<std::int64_t> keys;     // distinct elements, ascending
  std::vector<std::size_t> first{0};  // holders of keys[i]: entries[first[i], first[i + 1])
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const std::int64_t e = cov.elements[entries[i].first];
    if (keys.empty() || keys.back() != e) {
      if (!keys.empty()) first.push_back(i);
      keys.push_back(e);
    }
  }
  first.push_back(entries.size());
  std::vector<float> covered(keys.size(), 0.0f);  // per distinct element: weight covered
  std::vector<Eigen::Vector3d> stops{start};      // the open tour: start, then the chosen views
  std::vector<int> ids{-1};
  // best insertion cost of each candidate into the current tour (recomputed after each insert)
  std::vector<double> ins(static_cast<std::size_t>(K)), pos(static_cast<std::size_t>(K));
  std::vector<char> taken(static_cast<std::size_t>(K), 0);
  std::vector<int> inserted;  // view ids in insertion order
  auto p = [&](Eigen::Index k) { return Eigen::Vector3d(positions.row(k).transpose()); };
  CoverSelection out;
  while (int(out.views.size()) < max_views) {
    const std::size_t n = stops.size();
    int best = -1;
    double best_value = 0.0;
    for (Eigen::Index k = 0; k < K; ++k) {
      if (cov.status[k] != 0 || taken[std::size_t(k)] || gain[std::size_t(k)] < min_gain) continue;
      const Eigen::Vector3d q = p(k);
      // appended at the end (the first view, without charge_transit, for free)
      double cost = n == 1 && !charge_transit ? 0.0 : (q - stops[n - 1]).norm();
      std::size_t at = n;
      for (std::size_t i = 0; i + 1 < n; ++i) {
        const double c =
            (q - stops[i]).norm() + (q - stops[i + 1]).norm() - (stops[i + 1] - stops[i]).norm();
        if (c < cost) {
          cost = c;
          at = i + 1;
        }
      }
      ins[std::size_t(k)] = cost;
      pos[std::size_t(k)] = double(at);
      const double value = gain[std::size_t(k)] - rate * cost;
      if (value > best_value) {
        best_value = value;
        best = int(k);
      }
    }
    if (best < 0) break;
    const std::size_t at = std::size_t(pos[std::size_t(best)]);
    stops.insert(stops.begin() + std::ptrdiff_t(at), p(best));
    ids.insert(ids.begin() + std::ptrdiff_t(at), best);
    taken[std::size_t(best)] = 1;
    inserted.push_back(best);
    out.gains.push_back(gain[std::size_t(best)]);
    // the chosen view's elements are covered now: every holder's gain shrinks accordingly
    for (std::int64_t o = cov.offsets[best]; o < cov.offsets[best + 1]; ++o) {
      const std::size_t e =
          std::size_t(std::lower_bound(keys.begin(), keys.end(), cov.elements[o]) - keys.begin());
      float& have = covered[e];
      const float now = std::max(have, cov.weights[o]);
      if (now == have) continue;
      for (std::size_t i = first[e]; i < first[e + 1]; ++i) {
        const float w = cov.weights[entries[i].first];
        gain[std::size_t(entries[i].second)] -= std::max(0.0f, w - have) - std::max(0.0f, w - now);
      }
      have = now;
    }
  }
  // out.gains follows the insertion order; report the views in tour order with their gains
  std::unordered_map<int, double> gain_of;
  for (std::size_t i = 0; i < inserted.size(); ++i) gain_of[inserted[i]] = out.gains[i];
  out.gains.clear();
  for (std::size_t i = 1; i < ids.size(); ++i) {
    out.views.push_back(ids[i]);
    out.gains.push_back(gain_of[ids[i]]);
  }
  return out;
}

}  // namespace nbv
