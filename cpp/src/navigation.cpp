#include "nbv/navigation.hpp"

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

namespace nbv {

bool sphere_is_free(const GridView& g, const Eigen::Vector3d& center, double radius) {
  const double r = radius / g.resolution;
  const Eigen::Vector3d q = (center - g.origin) / g.resolution;
  const Eigen::Vector3i lo = (q.array() - r).floor().cast<int>();
  const Eigen::Vector3i hi = (q.array() + r).floor().cast<int>();
  if (lo.x() < 0 || lo.y() < 0 || lo.z() < 0 || hi.x() >= g.nx || hi.y() >= g.ny || hi.z() >= g.nz)
    return false;  // part of the sphere is outside the mapped workspace: unknown
  const double r2 = r * r;
  for (int k = lo.z(); k <= hi.z(); ++k) {
    const double dz = std::max({k - q.z(), 0.0, q.z() - (k + 1)});
    for (int j = lo.y(); j <= hi.y(); ++j) {
      const double dy = std::max({j - q.y(), 0.0, q.y() - (j + 1)});
      for (int i = lo.x(); i <= hi.x(); ++i) {
        const double dx = std::max({i - q.x(), 0.0, q.x() - (i + 1)});
        if (dx * dx + dy * dy + dz * dz > r2) continue;  // the cell does not touch the sphere
        const std::size_t idx = g.index(i, j, k);
        if (g.flags[idx] == CellFlag::Unknown || g.occupied(idx)) return false;
      }
    }
  }
  return true;
}

bool segment_is_free(const GridView& g, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                     double radius) {
  const double len = (b - a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(len / (0.5 * g.resolution))));
  for (int s = 0; s <= steps; ++s)
    if (!sphere_is_free(g, a + (b - a) * (static_cast<double>(s) / steps), radius)) return false;
  return true;
}

std::vector<Eigen::Vector3d> plan_path(const GridView& g, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, double radius,
                                       std::size_t max_expansions) {
  g.validate();
  if (segment_is_free(g, a, b, radius)) return {a, b};
  Eigen::Vector3i ca, cb;
  if (!g.cell_of(a, ca) || !g.cell_of(b, cb)) return {};
  auto center = [&](const Eigen::Vector3i& c) {
    return Eigen::Vector3d(g.origin + (c.cast<double>().array() + 0.5).matrix() * g.resolution);
  };
  std::unordered_map<std::size_t, std::int8_t> free_cache;  // 1 free, 0 blocked
  auto traversable = [&](const Eigen::Vector3i& c) {
    const std::size_t idx = g.index(c);
    auto it = free_cache.find(idx);
    if (it != free_cache.end()) return it->second == 1;
    const bool ok = sphere_is_free(g, center(c), radius);
    free_cache.emplace(idx, ok ? 1 : 0);
    return ok;
  };
  if (!traversable(cb) || !segment_is_free(g, center(cb), b, radius)) return {};
  struct Node {
    double f;
    std::size_t idx;
    bool operator>(const Node& o) const { return f > o.f; }
  };
  std::priority_queue<Node, std::vector<Node>, std::greater<Node>> open;
  std::unordered_map<std::size_t, double> gcost;
  std::unordered_map<std::size_t, std::size_t> parent;
  auto unflat = [&](std::size_t idx) {
    int i, j, k;
    g.layout.coords(idx, i, j, k);
    return Eigen::Vector3i(i, j, k);
  };
  const std::size_t ia = g.index(ca), ib = g.index(cb);
  gcost[ia] = 0.0;
  open.push({(center(ca) - center(cb)).norm(), ia});
  std::size_t expansions = 0;
  bool found = false;
  while (!open.empty() && expansions < max_expansions) {
    const Node cur = open.top();
    open.pop();
    const double gc = gcost[cur.idx];
    if (cur.f > gc + (center(unflat(cur.idx)) - center(cb)).norm() + 1e-9) continue;  // stale
    if (cur.idx == ib) {
      found = true;
      break;
    }
    ++expansions;
    const Eigen::Vector3i c = unflat(cur.idx);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy && !dz) continue;
          const Eigen::Vector3i nb = c + Eigen::Vector3i(dx, dy, dz);
          if (nb.x() < 0 || nb.y() < 0 || nb.z() < 0 || nb.x() >= g.nx || nb.y() >= g.ny ||
              nb.z() >= g.nz)
            continue;
          if (!traversable(nb)) continue;
          const std::size_t ni = g.index(nb);
          const double ng =
              gc + g.resolution * std::sqrt(static_cast<double>(dx * dx + dy * dy + dz * dz));
          auto it = gcost.find(ni);
          if (it != gcost.end() && it->second <= ng) continue;
          gcost[ni] = ng;
          parent[ni] = cur.idx;
          open.push({ng + (center(nb) - center(cb)).norm(), ni});
        }
  }
  if (!found) return {};
  std::vector<Eigen::Vector3d> cells;
  for (std::size_t idx = ib;; idx = parent[idx]) {
    cells.push_back(center(unflat(idx)));
    if (idx == ia) break;
  }
  std::reverse(cells.begin(), cells.end());
  // Path: a -> cell centres -> b, shortened greedily by line of sight.
  std::vector<Eigen::Vector3d> raw;
  raw.push_back(a);
  raw.insert(raw.end(), cells.begin(), cells.end());
  raw.push_back(b);
  std::vector<Eigen::Vector3d> path{raw.front()};
  std::size_t i = 0;
  while (i + 1 < raw.size()) {
    std::size_t j = raw.size() - 1;
    while (j > i + 1 && !segment_is_free(g, raw[i], raw[j], radius)) --j;
    path.push_back(raw[j]);
    i = j;
  }
  return path;
}

double path_length(const std::vector<Eigen::Vector3d>& path) {
  double d = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) d += (path[i] - path[i - 1]).norm();
  return d;
}

}  // namespace nbv
