#include "nbv/views.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_map>

namespace nbv {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Amanatides & Woo 3D-DDA over the grid from o along unit d for t in [0, t_max] (metres).
// visit(flat_index) returns false to stop the walk. Cells outside the grid are never visited.
template <typename Visit>
void walk_ray(const DenseGridView& g, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
              double t_max, Visit&& visit) {
  const Eigen::Vector3d pos = (o - g.origin) / g.resolution;  // grid units
  const double tend_g = t_max / g.resolution;
  const int n[3] = {g.nx, g.ny, g.nz};
  double t0 = 0.0, t1 = tend_g;
  for (int a = 0; a < 3; ++a) {  // clip to the grid box [0, n]
    if (d[a] == 0.0) {
      if (pos[a] < 0.0 || pos[a] >= n[a]) return;
      continue;
    }
    double ta = (0.0 - pos[a]) / d[a], tb = (n[a] - pos[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 > t1) return;
  const Eigen::Vector3d p0 = pos + t0 * d;
  int c[3], step[3];
  double t_next[3], t_delta[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = std::clamp(static_cast<int>(std::floor(p0[a])), 0, n[a] - 1);
    if (d[a] > 0) {
      step[a] = 1;
      t_delta[a] = 1.0 / d[a];
      t_next[a] = (c[a] + 1 - pos[a]) / d[a];
    } else if (d[a] < 0) {
      step[a] = -1;
      t_delta[a] = -1.0 / d[a];
      t_next[a] = (c[a] - pos[a]) / d[a];
    } else {
      step[a] = 0;
      t_delta[a] = kInf;
      t_next[a] = kInf;
    }
  }
  for (;;) {
    const std::size_t idx =
        static_cast<std::size_t>(c[0]) +
        static_cast<std::size_t>(g.nx) * (c[1] + static_cast<std::size_t>(g.ny) * c[2]);
    if (!visit(idx, c)) return;
    const int a =
        (t_next[0] < t_next[1]) ? (t_next[0] < t_next[2] ? 0 : 2) : (t_next[1] < t_next[2] ? 1 : 2);
    if (t_next[a] > t1) return;
    c[a] += step[a];
    if (c[a] < 0 || c[a] >= n[a]) return;
    t_next[a] += t_delta[a];
  }
}

// Per-thread set of the cells a view has visited: a bitset over the grid (2 M cells -> 256 KB,
// small enough to stay in the core's L2 cache, unlike a 32-bit stamp per cell), cleared after
// each view through the list of words it touched.
struct VisitedSet {
  std::vector<std::uint64_t> bits;
  std::vector<std::uint32_t> touched;
  void reset(std::size_t n) {
    const std::size_t words = (n + 63) / 64;
    if (bits.size() != words) {
      bits.assign(words, 0);
      touched.clear();
    }
    for (std::uint32_t w : touched) bits[w] = 0;
    touched.clear();
  }
  /// Marks cell i; true if it was not marked yet.
  bool insert(std::size_t i) {
    std::uint64_t& w = bits[i >> 6];
    const std::uint64_t m = std::uint64_t(1) << (i & 63);
    if (w & m) return false;
    if (!w) touched.push_back(static_cast<std::uint32_t>(i >> 6));
    w |= m;
    return true;
  }
};

double logit(double p) { return std::log(p / (1.0 - p)); }

}  // namespace

DenseGridView grid_view(const OccupancyMap& map) {
  static_assert(sizeof(CellFlag) == 1, "the grid view reads flags as bytes");
  DenseGridView g;
  g.resolution = map.resolution();
  g.origin = map.bounds_min();
  g.nx = map.dims()[0];
  g.ny = map.dims()[1];
  g.nz = map.dims()[2];
  g.logodds = map.grid().logodds_data();
  g.known = reinterpret_cast<const std::uint8_t*>(map.grid().flag_data());
  g.scored = map.grid().scored_data();
  g.occupied_logodds = map.grid().rule().occupied_logodds;
  return g;
}

bool DenseGridView::cell_of(const Eigen::Vector3d& p, Eigen::Vector3i& c) const {
  const Eigen::Vector3d q = (p - origin) / resolution;
  c = q.array().floor().cast<int>();
  return c.x() >= 0 && c.y() >= 0 && c.z() >= 0 && c.x() < nx && c.y() < ny && c.z() < nz;
}

void DenseGridView::validate() const {
  if (!(resolution > 0) || nx <= 0 || ny <= 0 || nz <= 0 || !logodds || !known || !scored)
    throw std::invalid_argument("dense grid view is empty or incomplete");
}

ViewCameraModel ViewCameraModel::for_resolution(double hfov_deg, double vfov_deg, double max_range,
                                                double resolution) {
  if (!(resolution > 0)) throw std::invalid_argument("resolution must be positive");
  ViewCameraModel m;
  m.hfov_deg = hfov_deg;
  m.vfov_deg = vfov_deg;
  m.max_range = max_range;
  m.rays_x =
      static_cast<int>(std::ceil(2.0 * max_range * std::tan(hfov_deg * M_PI / 360.0) / resolution));
  m.rays_y =
      static_cast<int>(std::ceil(2.0 * max_range * std::tan(vfov_deg * M_PI / 360.0) / resolution));
  return m;
}

void ViewCameraModel::validate() const {
  if (rays_x <= 0 || rays_y <= 0)
    throw std::invalid_argument("view camera needs at least one ray each way");
  if (!(hfov_deg > 0 && hfov_deg < 180 && vfov_deg > 0 && vfov_deg < 180))
    throw std::invalid_argument("view camera field of view must be in (0, 180) degrees");
  if (!(max_range > 0) || !std::isfinite(max_range))
    throw std::invalid_argument("view camera max_range must be positive");
  if (!mount.matrix().allFinite()) throw std::invalid_argument("view camera mount is not finite");
}

Points ViewCameraModel::directions() const {
  Points d(static_cast<Eigen::Index>(rays_x) * rays_y, 3);
  const double fx = (rays_x / 2.0) / std::tan(hfov_deg * M_PI / 360.0);
  const double fy = (rays_y / 2.0) / std::tan(vfov_deg * M_PI / 360.0);
  for (int v = 0; v < rays_y; ++v)
    for (int u = 0; u < rays_x; ++u)
      d.row(static_cast<Eigen::Index>(v) * rays_x + u) =
          Eigen::Vector3d(1.0, -(u + 0.5 - rays_x / 2.0) / fx, -(v + 0.5 - rays_y / 2.0) / fy)
              .normalized();
  return d;
}

bool sphere_is_free(const DenseGridView& g, const Eigen::Vector3d& center, double radius) {
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
        const std::size_t idx = g.index({i, j, k});
        if (!g.known[idx] || g.logodds[idx] >= g.occupied_logodds) return false;
      }
    }
  }
  return true;
}

bool segment_is_free(const DenseGridView& g, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                     double radius) {
  const double len = (b - a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(len / (0.5 * g.resolution))));
  for (int s = 0; s <= steps; ++s)
    if (!sphere_is_free(g, a + (b - a) * (static_cast<double>(s) / steps), radius)) return false;
  return true;
}

namespace {

// Cell readers for the view scoring: the dense mirror (fast) or OctoMap's search per cell (the
// authors' way, kept as the reference the mirror is checked against and the benchmark baseline).
struct MirrorCells {
  const DenseGridView& g;
  // Unknown cells hold log-odds 0 in the mirror, so with an occupancy threshold above p = 0.5
  // (log-odds > 0) they can never read as occupied and the flag need not be read at all.
  bool need_flag = g.occupied_logodds <= 0.0f;
  void read(std::size_t idx, const int*, bool& known, float& logodds, float& entropy) const {
    logodds = g.logodds[idx];
    entropy = std::fabs(g.scored[idx]);
    known = need_flag ? g.known[idx] != 0 : true;
  }
};

struct OctreeCells {
  const OccupancyMap& map;
  const octomap::OcTree& tree;  // map.octree(), brought up to date once before the walks
  void read(std::size_t, const int* c, bool& known, float& logodds, float& entropy) const {
    OccupancyMap::Key key = map.min_key();
    for (int a = 0; a < 3; ++a) key[a] = static_cast<octomap::key_type>(key[a] + c[a]);
    const octomap::OcTreeNode* node = tree.search(key);
    known = node != nullptr;
    logodds = known ? node->getLogOdds() : 0.0f;
    entropy = static_cast<float>(
        map.cell_entropy(logodds, known ? CellFlag::Observed : CellFlag::Unknown));
  }
};

template <typename Cells>
ViewScores score_views(
    const DenseGridView& g, const Cells& cells,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& cand,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity) {
  g.validate();
  camera.validate();
  if (!cand.allFinite())
    throw std::invalid_argument("candidate poses contain NaN or infinite values");
  if (!(validity.collision_radius >= 0))
    throw std::invalid_argument("collision radius must be >= 0");
  const Eigen::Index K = cand.rows();
  ViewScores out;
  out.utility.setConstant(K, -kInf);
  out.gain.setZero(K);
  out.cells_seen.setZero(K);
  out.occupied_seen.setZero(K);
  out.status.setConstant(K, static_cast<std::int8_t>(ViewStatus::Valid));
  const Points dirs = camera.directions();
  const double occ_req = utility.require_occupied_probability > 0
                             ? logit(utility.require_occupied_probability)
                             : -kInf;
  const Eigen::Vector3d here(current.x, current.y, current.z);
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    thread_local VisitedSet visited;
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const Eigen::Vector3d p(cand(k, 0), cand(k, 1), cand(k, 2));
      auto& st = out.status[k];
      if ((p.array() < validity.bounds_min.array()).any() ||
          (p.array() > validity.bounds_max.array()).any()) {
        st = static_cast<std::int8_t>(ViewStatus::OutOfBounds);
        continue;
      }
      if (!sphere_is_free(g, p, validity.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::Collision);
        continue;
      }
      if (validity.check_segment && !segment_is_free(g, here, p, validity.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::PathBlocked);
        continue;
      }
      const Eigen::Isometry3d T =
          pose_to_transform({p.x(), p.y(), p.z(), cand(k, 3)}) * camera.mount;
      const Eigen::Vector3d o = T.translation();
      const Eigen::Matrix3d R = T.linear();
      visited.reset(g.num_cells());
      double gain = 0.0;
      int seen = 0, occ = 0;
      for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
        const Eigen::Vector3d ds = dirs.row(r).transpose();
        const Eigen::Vector3d dw = R * ds;
        walk_ray(g, o, dw, camera.max_range / ds.x(), [&](std::size_t idx, const int* c) {
          bool known;
          float lo, h;
          cells.read(idx, c, known, lo, h);
          if (visited.insert(idx)) {
            gain += h;
            ++seen;
          }
          if (known && lo >= g.occupied_logodds) {
            if (lo > occ_req) ++occ;
            return false;  // the first occupied cell ends the ray (inclusive)
          }
          return true;
        });
      }
      out.gain[k] = gain;
      out.cells_seen[k] = seen;
      out.occupied_seen[k] = occ;
      if (utility.require_occupied && occ == 0) {
        st = static_cast<std::int8_t>(ViewStatus::SeesNoOccupied);
        continue;
      }
      double u = gain;
      if (utility.kind == UtilityOptions::Kind::InformationGainDistance)
        u *= std::exp(-utility.distance_lambda * (p - here).norm());
      out.utility[k] = u;
    }
  });
  return out;
}

}  // namespace

ViewScores evaluate_views(
    const DenseGridView& g,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& cand,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity) {
  return score_views(g, MirrorCells{g}, cand, current, camera, utility, validity);
}

ViewScores evaluate_views_octree(
    const OccupancyMap& map,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>& cand,
    const Pose& current, const ViewCameraModel& camera, const UtilityOptions& utility,
    const ValidityOptions& validity) {
  const DenseGridView g = grid_view(map);
  return score_views(g, OctreeCells{map, map.octree()}, cand, current, camera, utility, validity);
}

double viewable_cells(double hfov_deg, double vfov_deg, double min_range, double max_range,
                      double resolution, bool count_partial) {
  if (!(resolution > 0) || !(max_range > min_range) || !(min_range >= 0))
    throw std::invalid_argument(
        "viewable_cells: need resolution > 0 and 0 <= min_range < max_range");
  const double th = std::tan(hfov_deg * M_PI / 360.0), tv = std::tan(vfov_deg * M_PI / 360.0);
  const double n = min_range, f = max_range, s = resolution;
  const double V = 4.0 * th * tv / 3.0 * (f * f * f - n * n * n);
  if (!count_partial) return V / (s * s * s);
  // Projected areas along x (optical axis), y, z and extents along them, at zero yaw.
  const double Ax = (2 * f * th) * (2 * f * tv);
  const double Ay = (f - n) * (n + f) * tv;
  const double Az = (f - n) * (n + f) * th;
  const double Wx = f - n, Wy = 2 * f * th, Wz = 2 * f * tv;
  return (V + s * (Ax + Ay + Az) + s * s * (Wx + Wy + Wz) + s * s * s) / (s * s * s);
}

std::vector<Eigen::Vector3d> plan_path(const DenseGridView& g, const Eigen::Vector3d& a,
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
    const int i = static_cast<int>(idx % g.nx);
    const int j = static_cast<int>((idx / g.nx) % g.ny);
    const int k = static_cast<int>(idx / (static_cast<std::size_t>(g.nx) * g.ny));
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

}  // namespace nbv
