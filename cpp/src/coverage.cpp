#include "nbv/coverage.hpp"

#include "nbv/huge_pages.hpp"
#include "nbv/parallel.hpp"
#include "view_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

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

/// Occupied (observed or predicted) or predicted: the structure as the map shows it (an unknown
/// cell's entropy is positive, so occupied() holds only for known cells).
bool solid_cell(const GridView& g, std::size_t id) {
  return g.occupied(id) || g.cells.flag_at(id) == CellFlag::Predicted;
}
/// Sorts (key, value) pairs of distinct keys by key, as std::sort would: least significant byte
/// first, through `tmp`, each byte's pass left out where every key has the same one (the bytes
/// above a view's range of cells); std::sort below 256 pairs.
template <class Pair>
void sort_by_key(std::vector<Pair>& a, std::vector<Pair>& tmp) {
  const std::size_t n = a.size();
  if (n < 256) {
    std::sort(a.begin(), a.end(), [](const Pair& x, const Pair& y) { return x.first < y.first; });
    return;
  }
  tmp.resize(n);
  std::uint32_t count[4][256] = {};
  for (const Pair& p : a)
    for (int b = 0; b < 4; ++b) ++count[b][(p.first >> (8 * b)) & 255];
  Pair *from = a.data(), *to = tmp.data();
  for (int b = 0; b < 4; ++b) {
    std::uint32_t* c = count[b];
    const int shift = 8 * b;
    if (c[(from[0].first >> shift) & 255] == n) continue;  // one value of this byte
    std::uint32_t sum = 0;
    for (int v = 0; v < 256; ++v) sum += std::exchange(c[v], sum);
    for (std::size_t i = 0; i < n; ++i) to[c[(from[i].first >> shift) & 255]++] = from[i];
    std::swap(from, to);
  }
  if (from != a.data()) std::copy(from, from + n, a.data());
}

/// Known and not occupied.
bool free_cell(const GridView& g, std::size_t id) {
  return g.cells.flag_at(id) != CellFlag::Unknown && !g.occupied(id);
}

/// Whether a face neighbour of cell c is solid (solid_cell).
bool touches_surface_face(const GridView& g, const int* c) {
  for (int a = 0; a < 3; ++a)
    for (int s = -1; s <= 1; s += 2) {
      int m[3] = {c[0], c[1], c[2]};
      m[a] += s;
      if (!g.contains(m[0], m[1], m[2])) continue;
      if (solid_cell(g, g.layout.id(m[0], m[1], m[2]))) return true;
    }
  return false;
}

/// Whether a brick can hold a surface target: it or a brick beside it (a face) holds a solid
/// cell. A target is a solid cell or an unknown one with a solid face neighbour, which lies in
/// the same brick or the one beside it on that face. Solid cells are the occupied ones, counted
/// per brick, where the map holds no predicted cell; else the written ones stand in for them (a
/// predicted cell is a written one).
bool solid_near(const GridView& g, std::size_t brick) {
  if (g.predicted_cells == 0)
    return g.layout.brick_or_face_neighbour(
        brick, [&](std::size_t b) { return g.brick_occupied[b] != 0; });
  return g.layout.brick_or_face_neighbour(brick,
                                          [&](std::size_t b) { return g.cells.slots[b] != 0; });
}

}  // namespace

SurfaceTargets surface_targets(const GridView& g, const SurfaceTargetOptions& opt) {
  g.validate();
  opt.validate();
  if (!g.observed()) throw std::invalid_argument("surface_targets needs the camera observations");
  const std::array<std::uint32_t, 26> cones = bin_cones(opt.coverage_cone_deg);
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
  // the bricks in blocks of kBlock, each block's targets in brick order
  constexpr std::size_t kBlock = 1024;
  const std::size_t nb = g.layout.num_bricks(), nblocks = (nb + kBlock - 1) / kBlock;
  std::vector<std::vector<Target>> per_block(nblocks);
  parallel_chunks(nblocks, 1, [&](std::size_t blk_begin, std::size_t blk_end) {
    for (std::size_t brick = blk_begin * kBlock, be = std::min(nb, blk_end * kBlock); brick < be;
         ++brick) {
      if (!g.brick_live[brick]) continue;   // neutral cells only: free space
      if (!solid_near(g, brick)) continue;  // no solid cell in it nor on a face: no target
      for (std::size_t id = brick << 6, end = id + 64; id < end; ++id) {
        int c[3];
        if (!g.layout.coords(id, c[0], c[1], c[2])) continue;
        const CellFlag f = g.cells.flag_at(id);
        const bool occ = g.cells.occupied(id);
        TargetKind kind;
        double weight;
        if (f == CellFlag::Observed && occ) {
          if (!opt.observed || g.saturated(id)) continue;
          kind = TargetKind::Observed;
          weight = 1.0;
        } else if (f == CellFlag::Predicted) {
          if (!opt.predicted) continue;
          kind = TargetKind::Predicted;
          weight = 1.0 / (1.0 + std::exp(-double(g.cells.logodds_at(id))));
        } else if (f == CellFlag::Unknown) {
          // a frontier target needs a face neighbour occupied or predicted: most unknown
          // cells have none, and are passed over on their six faces before the 26-neighbour
          // walk below (the same targets)
          if (!opt.frontier || !touches_surface_face(g, c)) continue;
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
          const CellFlag nf = g.cells.flag_at(nid);
          const bool n_occ = g.cells.occupied(nid);
          const bool face = std::abs(off[n][0]) + std::abs(off[n][1]) + std::abs(off[n][2]) == 1;
          const bool n_free = nf == CellFlag::Observed && !n_occ;
          if (kind == TargetKind::Frontier) {
            if (face && solid_cell(g, nid)) touches_surface = true;
            if (n_free) {
              touches_free |= face;
              normal += unit[n];
            }
            continue;
          }
          if (n_occ && nf != CellFlag::Unknown) continue;  // not an open side
          if (kind == TargetKind::Observed && n_free && (g.seen(id) & cones[bins[n]])) continue;
          normal += unit[n];
        }
        if (kind == TargetKind::Frontier && !(touches_surface && touches_free)) continue;
        const double len = normal.norm();
        if (len < 1e-9) continue;  // nothing left to see from any open side
        per_block[brick / kBlock].push_back({id, c[0], c[1], c[2], normal / len, kind, weight});
      }
    }
  });
  std::size_t total = 0;
  for (const auto& v : per_block) total += v.size();
  SurfaceTargets out;
  out.positions.resize(Eigen::Index(total), 3);
  out.normals.resize(Eigen::Index(total), 3);
  out.kind.resize(Eigen::Index(total));
  out.weight.resize(Eigen::Index(total));
  Eigen::Index r = 0;
  for (const auto& v : per_block)
    for (const Target& t : v) {
      out.positions.row(r) = g.center(t.i, t.j, t.k).transpose();
      out.normals.row(r) = t.normal.transpose();
      out.kind[r] = std::int8_t(t.kind);
      out.weight[r] = t.weight;
      ++r;
    }
  return out;
}

// ---- exploration targets ---------------------------------------------------------------------

namespace {
/// Calls body(brick, i0, j0, k0) for each brick of g's layout that meets the box [lo, hi), in
/// parallel; (i0, j0, k0) is the brick's first cell.
template <typename Body>
void for_bricks_in(const GridView& g, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi,
                   const Body& body) {
  const auto& nb = g.layout.bricks;
  const int b0[3] = {lo[0] >> 2, lo[1] >> 2, lo[2] >> 2};
  const int b1[3] = {(hi[0] + 3) >> 2, (hi[1] + 3) >> 2, (hi[2] + 3) >> 2};
  const std::size_t sx = std::size_t(b1[0] - b0[0]), sy = std::size_t(b1[1] - b0[1]);
  const std::size_t n = sx * sy * std::size_t(b1[2] - b0[2]);
  parallel_chunks(n, 64, [&](std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      const int bi = b0[0] + int(t % sx), bj = b0[1] + int(t / sx % sy),
                bk = b0[2] + int(t / sx / sy);
      const std::size_t brick =
          std::size_t(bi) + std::size_t(nb[0]) * (std::size_t(bj) + std::size_t(nb[1]) * bk);
      body(brick, bi << 2, bj << 2, bk << 2);
    }
  });
}
}  // namespace

bool structure_extent(const GridView& g, Eigen::Vector3i& lo, Eigen::Vector3i& hi) {
  g.validate();
  const Eigen::Vector3i n(g.nx, g.ny, g.nz);
  std::mutex merge;
  Eigen::Vector3i a = n, b = Eigen::Vector3i::Constant(-1);
  for_bricks_in(g, Eigen::Vector3i::Zero(), n, [&](std::size_t brick, int i0, int j0, int k0) {
    if (g.brick_occupied[brick] == 0) {  // the brick's flags say whether any is predicted
      // none where the map holds no predicted cell, nor in a brick never written
      if (g.predicted_cells == 0 || g.cells.slots[brick] == 0) return;
      bool predicted = false;
      for (int c = 0; c < 64; ++c)
        predicted |= g.cells.flag_at(brick << 6 | std::size_t(c)) == CellFlag::Predicted;
      if (!predicted) return;
    }
    Eigen::Vector3i bl = n, bh = Eigen::Vector3i::Constant(-1);
    for (int c = 0; c < 64; ++c) {
      const std::size_t id = brick << 6 | std::size_t(c);
      const Eigen::Vector3i x(i0 + (c & 3), j0 + (c >> 2 & 3), k0 + (c >> 4));
      if (!g.contains(x[0], x[1], x[2]) || !solid_cell(g, id)) continue;
      bl = bl.cwiseMin(x);
      bh = bh.cwiseMax(x);
    }
    if (bh[0] < 0) return;
    std::lock_guard<std::mutex> hold(merge);
    a = a.cwiseMin(bl);
    b = b.cwiseMax(bh);
  });
  if (b[0] < 0) return false;
  lo = (a.array() - 1).max(0).matrix();
  hi = (b.array() + 2).min(n.array()).matrix();
  return true;
}

namespace {
/// The cells of a brick on each of its faces: [axis][0] at the low end, [axis][1] at the high.
constexpr std::array<std::array<std::uint64_t, 2>, 3> face_cells() {
  std::array<std::array<std::uint64_t, 2>, 3> m{};
  for (int c = 0; c < 64; ++c)
    for (int a = 0; a < 3; ++a) {
      const int x = c >> (2 * a) & 3;
      if (x == 0) m[std::size_t(a)][0] |= std::uint64_t(1) << c;
      if (x == 3) m[std::size_t(a)][1] |= std::uint64_t(1) << c;
    }
  return m;
}
constexpr auto kFaceCells = face_cells();
}  // namespace

ExplorationTargets exploration_targets(const GridView& g, Eigen::Vector3i lo, Eigen::Vector3i hi) {
  g.validate();
  const Eigen::Vector3i n(g.nx, g.ny, g.nz);
  lo = lo.cwiseMax(0).cwiseMin(n);
  hi = hi.cwiseMax(lo).cwiseMin(n);
  ExplorationTargets out;
  if ((hi - lo).minCoeff() <= 0) return out;
  struct Found {
    std::int64_t key;  // C order of (i, j, k)
    std::int8_t side[3];
  };
  std::mutex merge;
  std::vector<Found> all;
  for_bricks_in(g, lo, hi, [&](std::size_t brick, int i0, int j0, int k0) {
    // passed over whole: a brick whose cells are all known, or whose cells have no known free
    // face neighbour because neither it nor a brick beside it holds a known free cell
    if (int(g.brick_open[brick]) + g.brick_occupied[brick] == 64) return;
    const std::array<std::size_t, 3> at = {std::size_t(i0 >> 2), std::size_t(j0 >> 2),
                                           std::size_t(k0 >> 2)};
    auto open = [&](std::size_t b) { return g.brick_open[b] != 0; };
    // the cells that can have a known free face neighbour: all of them where the brick holds
    // one; else those on its faces toward a brick that does
    std::uint64_t cells = ~std::uint64_t(0);
    if (!open(brick)) {
      cells = 0;
      g.layout.any_face_neighbour(brick, at, [&](int a, int side, std::size_t b) {
        if (open(b)) cells |= kFaceCells[std::size_t(a)][std::size_t(side)];
        return false;  // every face
      });
      if (!cells) return;
    }
    std::vector<Found> found;
    for (; cells; cells &= cells - 1) {
      const int c = __builtin_ctzll(cells);
      const std::size_t id = brick << 6 | std::size_t(c);
      if (g.cells.flag_at(id) != CellFlag::Unknown) continue;
      const int x[3] = {i0 + (c & 3), j0 + (c >> 2 & 3), k0 + (c >> 4)};
      if (x[0] < lo[0] || x[0] >= hi[0] || x[1] < lo[1] || x[1] >= hi[1] || x[2] < lo[2] ||
          x[2] >= hi[2])
        continue;
      bool near_free = false, near_solid = false;
      std::int8_t side[3] = {0, 0, 0};
      for (int a = 0; a < 3 && !near_solid; ++a)
        for (int s = -1; s <= 1; s += 2) {
          int m[3] = {x[0], x[1], x[2]};
          m[a] += s;
          if (m[a] < lo[a] || m[a] >= hi[a]) continue;
          const std::size_t nid = g.layout.id(m[0], m[1], m[2]);
          if (solid_cell(g, nid)) {
            near_solid = true;
            break;
          }
          if (free_cell(g, nid)) {
            near_free = true;
            side[a] = std::int8_t(side[a] + s);
          }
        }
      if (!near_free || near_solid) continue;
      const std::int64_t key = (std::int64_t(x[0]) * g.ny + x[1]) * g.nz + x[2];
      found.push_back({key, {side[0], side[1], side[2]}});
    }
    if (found.empty()) return;
    std::lock_guard<std::mutex> hold(merge);
    all.insert(all.end(), found.begin(), found.end());
  });
  std::sort(all.begin(), all.end(), [](const Found& a, const Found& b) { return a.key < b.key; });
  out.cells.resize(Eigen::Index(all.size()), 3);
  out.free_sides.resize(Eigen::Index(all.size()), 3);
  for (std::size_t r = 0; r < all.size(); ++r) {
    const std::int64_t key = all[r].key;
    const Eigen::Index row = Eigen::Index(r);
    out.cells(row, 2) = std::int32_t(key % g.nz);
    out.cells(row, 1) = std::int32_t(key / g.nz % g.ny);
    out.cells(row, 0) = std::int32_t(key / g.nz / g.ny);
    for (int a = 0; a < 3; ++a) out.free_sides(row, a) = all[r].side[a];
  }
  return out;
}

namespace {
constexpr double kMaxNearCells = 5e8;  // a byte a cell: 500 MB at most
}  // namespace

std::vector<std::uint8_t> near_points(const PointsRef& solid, const PointsRef& points,
                                      double within, double resolution) {
  if (!(std::isfinite(within) && within > 0))
    throw std::invalid_argument("within must be a finite distance > 0 metres, got " +
                                std::to_string(within));
  if (!(std::isfinite(resolution) && resolution > 0))
    throw std::invalid_argument("resolution must be > 0 metres, got " + fmt(resolution));
  require_finite(solid, "solid points");
  require_finite(points, "points");
  const Eigen::Index n = points.rows();
  std::vector<std::uint8_t> keep(std::size_t(n), 0);
  if (n == 0 || solid.rows() == 0) return keep;
  const double step = std::max(within / 4.0, resolution);
  Eigen::Vector3d lo;
  std::array<std::int64_t, 3> shape;
  double total = 1;
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::min(solid.col(a).minCoeff(), points.col(a).minCoeff());
    const double hi = std::max(solid.col(a).maxCoeff(), points.col(a).maxCoeff());
    shape[std::size_t(a)] = std::int64_t(std::floor((hi - lo[a]) / step)) + 1;
    total *= double(shape[std::size_t(a)]);
  }
  if (total > kMaxNearCells)
    throw std::invalid_argument(
        "near_points: the points and the solid points span " + std::to_string(std::int64_t(total)) +
        " cells of " + std::to_string(step) + " m, more than " +
        std::to_string(std::int64_t(kMaxNearCells)) + "; give a larger within");
  const auto flat = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return std::size_t((i * shape[1] + j) * shape[2] + k);
  };
  const auto cell_of = [&](const PointsRef& p, Eigen::Index r) {
    std::array<std::int64_t, 3> c;
    for (int a = 0; a < 3; ++a)
      c[std::size_t(a)] = std::int64_t(std::floor((p(r, a) - lo[a]) / step));
    return c;
  };
  std::vector<std::uint8_t> filled(std::size_t(total), 0);
  std::vector<std::array<std::int64_t, 3>> cells;  // the solid cells, each once
  for (Eigen::Index r = 0; r < solid.rows(); ++r) {
    const auto c = cell_of(solid, r);
    std::uint8_t& f = filled[flat(c[0], c[1], c[2])];
    if (!f) cells.push_back(c);
    f = 1;
  }
  // the offsets within reach, their distance summed as scipy sums it (metres, x + y + z)
  const int R = int(std::ceil(within / step));
  std::vector<std::array<int, 3>> ball;
  for (int dx = -R; dx <= R; ++dx)
    for (int dy = -R; dy <= R; ++dy)
      for (int dz = -R; dz <= R; ++dz) {
        const double ex = double(dx) * step, ey = double(dy) * step, ez = double(dz) * step;
        if (std::sqrt(ex * ex + ey * ey + ez * ez) <= within) ball.push_back({dx, dy, dz});
      }
  const auto inside = [&](std::int64_t v, int a) { return v >= 0 && v < shape[std::size_t(a)]; };
  if (std::size_t(n) < cells.size()) {  // round each point: a solid cell in its ball
    parallel_chunks(std::size_t(n), 1024, [&](std::size_t b, std::size_t e) {
      for (std::size_t r = b; r < e; ++r) {
        const auto c = cell_of(points, Eigen::Index(r));
        for (const auto& d : ball) {
          const std::int64_t i = c[0] + d[0], j = c[1] + d[1], k = c[2] + d[2];
          if (inside(i, 0) && inside(j, 1) && inside(k, 2) && filled[flat(i, j, k)]) {
            keep[r] = 1;
            break;
          }
        }
      }
    });
    return keep;
  }
  for (const auto& c : cells)  // round each solid cell: its ball, filled in place
    for (const auto& d : ball) {
      const std::int64_t i = c[0] + d[0], j = c[1] + d[1], k = c[2] + d[2];
      if (inside(i, 0) && inside(j, 1) && inside(k, 2)) filled[flat(i, j, k)] = 1;
    }
  for (Eigen::Index r = 0; r < n; ++r) {
    const auto c = cell_of(points, r);
    keep[std::size_t(r)] = filled[flat(c[0], c[1], c[2])];
  }
  return keep;
}

SurfaceTargets exploration_as_targets(const ExplorationTargets& t, const Eigen::Vector3d& origin,
                                      const Eigen::Vector3i& start, double resolution) {
  std::vector<Eigen::Index> keep;
  std::vector<double> norm;
  for (Eigen::Index r = 0; r < t.free_sides.rows(); ++r) {
    const double x = t.free_sides(r, 0), y = t.free_sides(r, 1), z = t.free_sides(r, 2);
    const double n = std::sqrt(x * x + y * y + z * z);
    if (n > 0) {
      keep.push_back(r);
      norm.push_back(n);
    }
  }
  const auto n = Eigen::Index(keep.size());
  SurfaceTargets out;
  out.positions.resize(n, 3);
  out.normals.resize(n, 3);
  out.kind.setConstant(n, std::int8_t(TargetKind::Exploration));
  out.weight.setOnes(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index r = keep[std::size_t(i)];
    for (int a = 0; a < 3; ++a) {
      const double lo = origin[a] + double(start[a]) * resolution;
      out.positions(i, a) = lo + (double(t.cells(r, a) - start[a]) + 0.5) * resolution;
      out.normals(i, a) = double(t.free_sides(r, a)) / norm[std::size_t(i)];
    }
  }
  return out;
}

// ---- CoverageMemo ----------------------------------------------------------------------------

CoverageMemo::CoverageMemo(int keep_calls, std::size_t max_bytes)
    : keep_calls_(keep_calls), max_bytes_(max_bytes) {
  if (keep_calls < 1)
    throw std::invalid_argument("CoverageMemo keep_calls must be >= 1, got " +
                                std::to_string(keep_calls));
}

std::size_t CoverageMemo::entry_bytes(const Entry& e, std::size_t elements) {
  return sizeof(e) + (4 + 4) * elements;
}

std::size_t CoverageMemo::bytes() const {
  std::size_t n = 0;
  for (const auto& [k, e] : entries_) n += entry_bytes(e, e.set.capacity());
  return n + 4 * near_grid_.capacity();
}

void CoverageMemo::clear() {
  entries_.clear();
  geometry_.clear();
  grid_id_ = seen_id_ = 0;
  std::vector<std::uint32_t>().swap(near_grid_);  // (made again by the next call's begin)
  seen_stamps_ = nullptr;
}

namespace {
// Per brick, the newest of the stamps of it and its (up to) 26 neighbours: three passes of a
// running maximum over one neighbour along x, y and z.
std::vector<std::uint32_t> newest_nearby(const GridLayout& layout, const std::uint32_t* stamps) {
  const int bx = layout.bricks[0], by = layout.bricks[1], bz = layout.bricks[2];
  const std::size_t n = layout.num_bricks();
  std::vector<std::uint32_t> a(stamps, stamps + n), b(n);
  const std::size_t stride[3] = {1, std::size_t(bx), std::size_t(bx) * std::size_t(by)};
  const int len[3] = {bx, by, bz};
  for (int axis = 0; axis < 3; ++axis) {
    parallel_chunks(n, 4096, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        const int c = int((i / stride[axis]) % std::size_t(len[axis]));
        std::uint32_t m = a[i];
        if (c > 0) m = std::max(m, a[i - stride[axis]]);
        if (c + 1 < len[axis]) m = std::max(m, a[i + stride[axis]]);
        b[i] = m;
      }
    });
    a.swap(b);
  }
  return a;
}
}  // namespace

bool CoverageMemo::begin(const GridView& g, const std::vector<double>& geometry) {
  if (!g.grid_stamps || !g.seen_stamps || g.storage_size() * 2 >= (std::size_t(1) << 32))
    return false;
  if (geometry != geometry_ || g.grid_id != grid_id_ || g.seen_id != seen_id_) {
    entries_.clear();
    geometry_ = geometry;
    grid_id_ = g.grid_id;
    seen_id_ = g.seen_id;
  }
  ++call_;
  // a walk reads the camera observations of the cells it enters only, the map's cells around
  // them too
  near_grid_ = newest_nearby(g.layout, g.grid_stamps);
  seen_stamps_ = g.seen_stamps;
  origin_ = g.origin;
  resolution_ = g.resolution;
  bricks_ = g.layout.bricks;
  return true;
}

const CoverageMemo::Entry* CoverageMemo::find(const Key& key, const Eigen::Isometry3d& sensor,
                                              const ViewCameraModel& camera) const {
  const auto it = entries_.find(key);
  if (it == entries_.end()) return nullptr;
  const Entry& e = it->second;
  return frustum_changed(sensor, camera, e.grid_epoch, e.seen_epoch) ? nullptr : &e;
}

bool CoverageMemo::frustum_changed(const Eigen::Isometry3d& sensor, const ViewCameraModel& camera,
                                   std::uint32_t grid_epoch, std::uint32_t seen_epoch) const {
  // The camera's frustum: depth (x) in [0, max_range], |y| <= x tan(hfov / 2) and
  // |z| <= x tan(vfov / 2) (every ray, ViewCameraModel::directions, lies within), as five
  // planes with inward unit normals through the apex or, the far one, at max_range.
  const Eigen::Vector3d o = sensor.translation();
  const Eigen::Matrix3d R = sensor.linear();
  const double th = std::tan(camera.hfov_deg * M_PI / 360.0);
  const double tv = std::tan(camera.vfov_deg * M_PI / 360.0);
  const double far = camera.max_range;
  const Eigen::Vector3d ax = R.col(0), ay = R.col(1), az = R.col(2);
  const Eigen::Vector3d normal[4] = {
      (th * ax - ay) / std::hypot(th, 1.0), (th * ax + ay) / std::hypot(th, 1.0),
      (tv * ax - az) / std::hypot(tv, 1.0), (tv * ax + az) / std::hypot(tv, 1.0)};
  // a brick meets it if its bounding sphere does (some bricks near an edge also count)
  const double size = 4.0 * resolution_, radius = 0.5 * std::sqrt(3.0) * size;
  Eigen::Vector3d lo = o, hi = o;
  for (const double sy : {-1.0, 1.0})
    for (const double sz : {-1.0, 1.0}) {
      const Eigen::Vector3d corner = o + far * (ax + sy * th * ay + sz * tv * az);
      lo = lo.cwiseMin(corner);
      hi = hi.cwiseMax(corner);
    }
  int first[3], last[3];
  for (int a = 0; a < 3; ++a) {
    first[a] = std::max(0, int(std::floor((lo[a] - radius - origin_[a]) / size)));
    last[a] = std::min(bricks_[a] - 1, int(std::floor((hi[a] + radius - origin_[a]) / size)));
    if (first[a] > last[a]) return false;
  }
  for (int k = first[2]; k <= last[2]; ++k)
    for (int j = first[1]; j <= last[1]; ++j) {
      const std::size_t row =
          std::size_t(bricks_[0]) * (std::size_t(j) + std::size_t(bricks_[1]) * std::size_t(k));
      for (int i = first[0]; i <= last[0]; ++i) {
        const std::size_t b = row + std::size_t(i);
        if (near_grid_[b] <= grid_epoch && seen_stamps_[b] <= seen_epoch) continue;
        const Eigen::Vector3d d = origin_ + size * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) - o;
        const double depth = d.dot(ax);
        if (depth < -radius || depth > far + radius) continue;
        bool inside = true;
        for (const Eigen::Vector3d& n : normal) inside = inside && n.dot(d) >= -radius;
        if (inside) return true;
      }
    }
  return false;
}

namespace {
/// walked[k] (CoverageMemo::end) of a view whose record the memo keeps, of one whose record it
/// would drop at once, and of one left unwalked on its coarse walk (its estimate kept)
constexpr std::uint8_t kRecord = 1, kWalkedOnly = 2, kEstimate = 3;
/// reused[k]: a view answered from its record, or left unwalked on its recorded estimate
constexpr std::uint8_t kFromRecord = 1, kFromEstimate = 2;
}  // namespace

void CoverageMemo::end(const std::vector<Key>& keys, std::vector<Entry>& fresh,
                       const std::vector<std::uint8_t>& walked,
                       const std::vector<std::uint8_t>& reused) {
  for (std::size_t k = 0; k < keys.size(); ++k) {
    // an estimate that held, its view then walked, is replaced without being stale
    const bool from_estimate = reused[k] == kFromEstimate;
    if (walked[k] == kRecord || walked[k] == kEstimate) {
      fresh[k].used = call_;
      const auto it = entries_.find(keys[k]);
      if (it != entries_.end()) {
        stats_.stale += !from_estimate;
        it->second = std::move(fresh[k]);
      } else {
        entries_.emplace(keys[k], std::move(fresh[k]));
      }
      stats_.walked += walked[k] == kRecord;
    } else if (walked[k] == kWalkedOnly) {  // its record dropped for max_bytes, and an older one
      stats_.stale += entries_.erase(keys[k]) && !from_estimate;
      ++stats_.walked;
      ++stats_.evicted;
    } else if (reused[k]) {
      entries_.find(keys[k])->second.used = call_;
      ++(from_estimate ? stats_.estimated : stats_.reused);
    }
  }
  for (auto it = entries_.begin(); it != entries_.end();)
    it = it->second.used > call_ - keep_calls_ ? std::next(it) : entries_.erase(it);
  std::size_t held = bytes();
  if (held <= max_bytes_) return;
  // over max_bytes: the records used longest ago go first, then the largest
  std::vector<decltype(entries_)::iterator> order;
  order.reserve(entries_.size());
  for (auto it = entries_.begin(); it != entries_.end(); ++it) order.push_back(it);
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    if (a->second.used != b->second.used) return a->second.used < b->second.used;
    return a->second.set.size() > b->second.set.size();
  });
  for (const auto& it : order) {
    if (held <= max_bytes_) break;
    held -= entry_bytes(it->second, it->second.set.capacity());
    entries_.erase(it);
    ++stats_.evicted;
  }
}

// ---- view_coverage ---------------------------------------------------------------------------

namespace {

/// From this many coverage elements, view_coverage hands the heap back as it copies the sets.
constexpr std::int64_t kTrimElements = 16'000'000;

/// Marks the walked views whose records the memo could not keep (kWalkedOnly), and frees their
/// brick lists, so that their copies are never made: while this call's records alone exceed the
/// memo's max_bytes, the largest, as its eviction would drop them (older records go first).
void keep_within(const CoverageMemo& memo, std::vector<CoverageMemo::Entry>& fresh,
                 std::vector<std::uint8_t>& walked,
                 const std::vector<std::vector<std::pair<std::uint32_t, float>>>& sets) {
  std::vector<std::pair<std::size_t, std::size_t>> bytes;  // (a record's bytes, view)
  std::size_t sum = 0;
  for (std::size_t k = 0; k < walked.size(); ++k) {
    if (walked[k] != kRecord) continue;
    const std::size_t b = CoverageMemo::entry_bytes(fresh[k], sets[k].size());
    bytes.push_back({b, k});
    sum += b;
  }
  if (sum <= memo.max_bytes()) return;
  std::sort(bytes.begin(), bytes.end(), std::greater<>());
  for (const auto& [b, k] : bytes) {
    if (sum <= memo.max_bytes()) break;
    sum -= b;
    walked[k] = kWalkedOnly;
    fresh[k] = CoverageMemo::Entry();
  }
}

}  // namespace

ViewCoverage view_coverage(const GridView& g, const ViewPosesRef& cand, const Pose& current,
                           const ViewCameraModel& camera, const UtilityOptions& utility,
                           const ValidityOptions& validity, CoverageMemo* memo, double min_gain,
                           int coarse_stride, bool pool_unknown, double coarse_margin) {
  if (!std::isfinite(min_gain)) throw std::invalid_argument("view_coverage: min_gain not finite");
  if (coarse_stride < 0) throw std::invalid_argument("view_coverage: coarse_stride below 0");
  if (!(coarse_margin > 0.0) || !std::isfinite(coarse_margin))
    throw std::invalid_argument("view_coverage: coarse_margin must be finite and > 0");
  g.validate();
  camera.validate();
  utility.validate();
  validity.validate();
  if (!g.observed()) throw std::invalid_argument("view_coverage needs the camera observations");
  check_view_poses(cand);
  const Eigen::Index K = cand.rows();
  // elements cell * 2 + side, then the pooled bricks', fit 31 bits (OccupancyMap holds at most
  // 400 M cells): 8 bytes per element while the sets are gathered, the largest transient of a
  // plan on a large structure
  if (g.storage_size() * 2 + (g.storage_size() >> 6) >= (std::size_t(1) << 31))
    throw std::invalid_argument("view_coverage: the grid holds too many cells");
  std::vector<std::vector<std::pair<std::uint32_t, float>>> sets(static_cast<std::size_t>(K));
  // per cell, lazily: the direction splitting its sides (code 1 + bin index of the side axis,
  // + 27 when the cell has one side only; 0: not computed). Racing threads write the same value.
  // Zero pages until written: it costs memory for the cells the walks reach, not the grid's.
  const ReleasableArray<std::uint8_t> side_axis(g.storage_size());
  Eigen::Vector3d bin_dir[26];
  for (int b = 0; b < 26; ++b) bin_dir[b] = bin_direction(b);
  Eigen::Vector3d unit[27];  // towards neighbour (dx, dy, dz): [dx + 1 + 3 (dy + 1) + 9 (dz + 1)]
  for (int i = 0; i < 27; ++i) {
    const Eigen::Vector3d v(i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1);
    unit[i] = i == 13 ? v : v.normalized();
  }
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
            if (g.cells.occupied(n) && g.cells.flag_at(n) != CellFlag::Unknown) continue;
            const Eigen::Vector3d& u = unit[dx + 1 + 3 * (dy + 1) + 9 * (dz + 1)];
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
  // the memo: which candidates it answers, what the walked ones leave in it
  std::vector<CoverageMemo::Key> keys;
  std::vector<CoverageMemo::Entry> fresh;
  std::vector<std::uint8_t> walked, reused;
  if (memo) {
    std::vector<double> geometry = kernel::memo_geometry(job);
    const UtilityOptions& u = utility;
    geometry.insert(geometry.end(),
                    {double(u.require_occupied), u.require_occupied_probability, u.min_visibility,
                     u.frontier_prior, u.unknown_prior, u.coverage_cone_deg, u.dense_spacing,
                     u.max_incidence_deg, double(u.incidence_min_patches), camera.pixel_pitch_deg,
                     double(pool_unknown)});
    if (!memo->begin(g, geometry)) memo = nullptr;
  }
  if (memo) {
    keys.resize(std::size_t(K));
    fresh.resize(std::size_t(K));
    walked.assign(std::size_t(K), 0);
    reused.assign(std::size_t(K), 0);
    for (Eigen::Index k = 0; k < K; ++k) keys[std::size_t(k)] = pose_key(view_pose(cand, k));
    job.replay_view = [&](Eigen::Index k, double& gain, int& cells, int& occupied) {
      const CoverageMemo::Entry* e = memo->find(
          keys[std::size_t(k)], gimbal_sensor_transform(view_pose(cand, k), camera.mount), camera);
      if (!e) return int(kernel::kUnknown);
      if (e->coarse_stride) {  // an estimate: of use to this call's prune at the same stride
        if (!job.pruned || e->coarse_stride != job.coarse_stride) return int(kernel::kUnknown);
        gain = e->gain;
        reused[std::size_t(k)] = kFromEstimate;
        return int(kernel::kEstimated);
      }
      auto& s = sets[std::size_t(k)];
      s = e->set;
      gain = e->gain;
      cells = e->cells;
      occupied = e->occupied;
      reused[std::size_t(k)] = kFromRecord;
      return int(kernel::kReplayed);
    };
  }
  job.on_view = [&](Eigen::Index k, const std::vector<utility::Credit>& credits) {
    // (element, weight) sorted by element: the surface utility credits a cell once in a view,
    // and a cell is one element (of the side it was first seen from)
    if (memo) {  // the view's record: its set (below), gain and counts (after the walks)
      CoverageMemo::Entry& e = fresh[std::size_t(k)];
      e.grid_epoch = g.grid_epoch;
      e.seen_epoch = g.seen_epoch;
      walked[std::size_t(k)] = kRecord;
    }
    auto& s = sets[std::size_t(k)];
    s.resize(credits.size());
    for (std::size_t i = 0; i < s.size(); ++i) {
      const utility::Credit& c = credits[i];
      if (pool_unknown && c.prior)  // GridLayout: a brick's 64 cells are consecutive ids
        s[i] = {pooled_element(g, std::size_t(c.cell) >> 6), c.weight};
      else
        s[i] = {std::uint32_t(c.cell * 2 + side_of(c.cell, c.bin)), c.weight};
    }
    thread_local std::vector<std::pair<std::uint32_t, float>> tmp;
    sort_by_key(s, tmp);
    if (pool_unknown) {  // a pooled brick's credits summed into one element
      std::size_t n = 0;
      for (std::size_t i = 0; i < s.size(); ++i) {
        if (n && s[n - 1].first == s[i].first)
          s[n - 1].second += s[i].second;
        else
          s[n++] = s[i];
      }
      s.resize(n);
      s.shrink_to_fit();
    }
  };
  std::vector<std::uint8_t> pruned;
  if (min_gain > 0.0 && coarse_stride > 0) {
    job.prune_below = min_gain * coarse_margin;
    job.coarse_stride = coarse_stride;
    job.pruned = &pruned;
  }
  const ViewScores scores = kernel::score<utility::Surface, true>(job, kernel::PackedCells(g));
  if (memo)  // the views left unwalked on a coarse walk of this call: their estimates
    for (std::size_t k = 0; k < pruned.size(); ++k) {
      if (!pruned[k] || reused[k] == kFromEstimate) continue;
      CoverageMemo::Entry& e = fresh[k];
      e.gain = scores.gain[Eigen::Index(k)];
      e.coarse_stride = coarse_stride;
      e.grid_epoch = g.grid_epoch;
      e.seen_epoch = g.seen_epoch;
      walked[k] = kEstimate;
    }
  ViewCoverage out;
  if (pool_unknown) {
    out.pooled_from = pooled_element(g, 0);
    out.pool_cap = 64.0 * utility.unknown_prior;
  }
  out.status = scores.status;
  out.pruned.setZero(K);
  for (std::size_t k = 0; k < pruned.size(); ++k) out.pruned[Eigen::Index(k)] = pruned[k];
  out.gain = scores.gain;
  // the sets handed out: a valid candidate's when its weights sum to min_gain (summed as
  // select_tours sums them, in the set's order), none otherwise
  std::vector<std::uint8_t> held(std::size_t(K), 1);
  if (min_gain > 0.0)
    for (Eigen::Index k = 0; k < K; ++k) {
      double sum = 0.0;
      for (const auto& [e, w] : sets[std::size_t(k)]) sum += w;
      held[std::size_t(k)] = sum >= min_gain;
    }
  auto size_of = [&](Eigen::Index k) {
    return held[std::size_t(k)] ? std::int64_t(sets[std::size_t(k)].size()) : std::int64_t(0);
  };
  out.offsets.resize(K + 1);
  out.offsets[0] = 0;
  for (Eigen::Index k = 0; k < K; ++k) out.offsets[k + 1] = out.offsets[k] + size_of(k);
  if (memo) keep_within(*memo, fresh, walked, sets);
  // The sets are copied into the arrays one by one, each then freed or moved into its memo
  // record; on a large plan the heap they leave goes back every eighth of the elements, so the
  // sets and their copy are not all held at once (a 100 m plant's plans: 30-50 M).
  const std::int64_t total = out.offsets[K], trim_every = total / 8;
  const bool trim = total >= kTrimElements;
  std::int64_t next_trim = trim_every;
  out.elements.resize(total);
  out.weights.resize(total);
  for (Eigen::Index k = 0; k < K; ++k) {
    auto& s = sets[std::size_t(k)];
    std::int64_t o = out.offsets[k];
    if (held[std::size_t(k)])
      for (const auto& [e, w] : s) {
        out.elements[o] = std::int32_t(e);
        out.weights[o] = w;
        ++o;
      }
    if (memo && walked[std::size_t(k)] == kRecord) {  // the set moves into its record
      CoverageMemo::Entry& e = fresh[std::size_t(k)];
      e.set = std::move(s);
      e.gain = scores.gain[k];
      e.cells = scores.cells[k];
      e.occupied = scores.occupied_seen[k];
    }
    std::vector<std::pair<std::uint32_t, float>>().swap(s);  // its memory back (if not moved)
    if (trim && o >= next_trim) {
      release_free_memory();
      next_trim += trim_every;
    }
  }
  if (memo) memo->end(keys, fresh, walked, reused);
  if (trim) release_free_memory();
  return out;
}

namespace {

/// What an element of weight w still adds when `have` of it is covered, and what is covered
/// once it is taken: a cell's the most weight it was taken with; a pooled brick's (elements
/// from pooled_from on) the share of its cap, the views' cells in it spread at random.
struct Saturation {
  explicit Saturation(const CoverageRef& cov)
      : from(cov.pooled_from), inv_cap(cov.pool_cap > 0.0 ? float(1.0 / cov.pool_cap) : 0.0f) {}
  float left(std::int64_t e, float w, float have) const {
    return e >= from ? w * (1.0f - have) : std::max(0.0f, w - have);
  }
  float after(std::int64_t e, float w, float have) const {
    return e >= from ? have + std::min(1.0f, w * inv_cap) * (1.0f - have) : std::max(have, w);
  }
  std::int64_t from;
  float inv_cap;
};

}  // namespace

CoverSelection select_cover(const CoverageRef& cov, double min_gain, int max_views) {
  const Eigen::Index K = cov.offsets.size() - 1;
  if (K < 0) throw std::invalid_argument("coverage has no offsets");
  CoverSelection out;
  const Saturation sat(cov);
  std::unordered_map<std::int64_t, float> covered;  // element -> weight (share) covered
  auto gain_of = [&](Eigen::Index k) {
    double g = 0.0;
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      auto it = covered.find(cov.elements[o]);
      const float have = it == covered.end() ? 0.0f : it->second;
      g += sat.left(cov.elements[o], cov.weights[o], have);
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
      have = sat.after(cov.elements[o], cov.weights[o], have);
    }
  }
  return out;
}

namespace {

/// The distinct elements of a coverage, ranked 0, 1, ... in ascending order: a bitmap over
/// their range with a running count per 64-bit word (a bit and a half per value in the range),
/// or, where the range is too sparse for that to be cheaper than the elements themselves, the
/// distinct elements sorted.
class ElementRanks {
 public:
  template <typename Held>
  ElementRanks(const CoverageRef& cov, Held held, std::size_t n, std::int64_t lo, std::int64_t hi)
      : lo_(lo) {
    const std::uint64_t span = std::uint64_t(hi) - std::uint64_t(lo);  // the range's size - 1
    if (n && span / 8 < 4 * n + 4096) {
      bits_.assign(std::size_t(span / 64 + 1), 0);
      held([&](Eigen::Index, std::int64_t o) {
        const std::uint64_t v = std::uint64_t(cov.elements[o]) - std::uint64_t(lo);
        bits_[v >> 6] |= std::uint64_t(1) << (v & 63);
      });
      before_.resize(bits_.size());
      std::uint32_t sum = 0;
      for (std::size_t w = 0; w < bits_.size(); ++w) {
        before_[w] = sum;
        sum += std::uint32_t(__builtin_popcountll(bits_[w]));
      }
      size_ = sum;
    } else {
      keys_.reserve(n);
      held([&](Eigen::Index, std::int64_t o) { keys_.push_back(cov.elements[o]); });
      std::sort(keys_.begin(), keys_.end());
      keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
      keys_.shrink_to_fit();
      size_ = keys_.size();
    }
  }
  std::size_t size() const { return size_; }
  /// The rank of an element that the coverage holds.
  std::size_t operator()(std::int64_t e) const {
    if (bits_.empty())
      return std::size_t(std::lower_bound(keys_.begin(), keys_.end(), e) - keys_.begin());
    const std::uint64_t v = std::uint64_t(e) - std::uint64_t(lo_);
    const std::uint64_t below = bits_[v >> 6] & ((std::uint64_t(1) << (v & 63)) - 1);
    return before_[v >> 6] + std::size_t(__builtin_popcountll(below));
  }

 private:
  std::int64_t lo_;
  std::vector<std::uint64_t> bits_;
  std::vector<std::uint32_t> before_;
  std::vector<std::int64_t> keys_;
  std::size_t size_ = 0;
};

/// The inverse of a coverage: per distinct element (by rank), its holders in candidate order,
/// each with the weight it gives the element, side by side for the updates to read in one pass;
/// by a counting sort on the rank (8 bytes per element held, 4 per distinct element).
struct Holders {
  struct Holder {
    std::int32_t candidate;
    float weight;
  };
  std::vector<std::uint32_t> first;  ///< holders of rank r: of[first[r], first[r + 1])
  HugeVector<Holder> of;
};

template <typename Held>
Holders holders_of(const CoverageRef& cov, Held held, std::size_t n, const ElementRanks& rank) {
  Holders h;
  h.first.assign(rank.size() + 1, 0);
  held([&](Eigen::Index, std::int64_t o) { ++h.first[rank(cov.elements[o]) + 1]; });
  for (std::size_t r = 0; r < rank.size(); ++r) h.first[r + 1] += h.first[r];
  h.of.resize(n);
  // place each holder at its rank's cursor (first[r], advanced), then shift the cursors back
  held([&](Eigen::Index k, std::int64_t o) {
    h.of[h.first[rank(cov.elements[o])]++] = {std::int32_t(k), cov.weights[o]};
  });
  for (std::size_t r = rank.size(); r > 0; --r) h.first[r] = h.first[r - 1];
  h.first[0] = 0;
  return h;
}

/// One prize-collecting insertion tour over a coverage's inverse (select_tour), from the
/// candidates' gains with nothing covered.
CoverSelection insertion_tour(const CoverageRef& cov, const PointsRef& positions,
                              const Eigen::Vector3d& start, double rate, double min_gain,
                              int max_views, bool charge_transit, const ElementRanks& rank,
                              const Holders& holders, const std::vector<double>& gain0) {
  const Eigen::Index K = cov.offsets.size() - 1;
  const std::vector<std::uint32_t>& first = holders.first;
  const HugeVector<Holders::Holder>& hold = holders.of;
  std::vector<double> gain = gain0;
  const Saturation sat(cov);
  std::vector<float> covered(rank.size(), 0.0f);  // per distinct element: weight (share) covered
  std::vector<Eigen::Vector3d> stops{start};      // the open tour: start, then the chosen views
  std::vector<int> ids{-1};
  std::vector<int> inserted;  // view ids in insertion order
  auto p = [&](Eigen::Index k) { return Eigen::Vector3d(positions.row(k).transpose()); };
  // Per candidate still in play, its cheapest insertion into the current tour, kept up to date
  // as the tour grows instead of searched again: the cost of appending it after the last stop
  // and its cheapest leg (the cost of going through it between the leg's two stops, the first
  // leg of least cost). Inserting a view changes one leg into two (or adds one at the end), so
  // a candidate only compares the new legs with its cheapest, and searches all legs again only
  // when its cheapest leg was the one replaced. Each cost is the same expression, so the same
  // number, as the exhaustive search over every leg at every step would compute.
  constexpr int kNoLeg = std::numeric_limits<int>::max();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<Eigen::Index> alive;  // valid, not taken, gain >= min_gain (gains only shrink)
  for (Eigen::Index k = 0; k < K; ++k)
    if (cov.status[k] == 0 && gain[std::size_t(k)] >= min_gain) alive.push_back(k);
  std::vector<double> append(static_cast<std::size_t>(K)), leg_cost(static_cast<std::size_t>(K));
  std::vector<int> leg_of(static_cast<std::size_t>(K), kNoLeg);
  for (const Eigen::Index k : alive) {
    append[std::size_t(k)] = charge_transit ? (p(k) - start).norm() : 0.0;
    leg_cost[std::size_t(k)] = kInf;
  }
  std::vector<double> leg;                                // leg[i]: from stops[i] to stops[i + 1]
  auto consider = [&](Eigen::Index k, double c, int i) {  // leg i at cost c: the cheaper, first
    double& best = leg_cost[std::size_t(k)];
    int& at = leg_of[std::size_t(k)];
    if (c < best || (c == best && i < at)) {
      best = c;
      at = i;
    }
  };
  auto through = [&](const Eigen::Vector3d& q, std::size_t i) {  // cost of q on leg i
    return (q - stops[i]).norm() + (q - stops[i + 1]).norm() - leg[i];
  };
  CoverSelection out;
  while (int(out.views.size()) < max_views) {
    const std::size_t n = stops.size();
    // the best value (> 0), ties to the lower index, over the candidates still in play; the
    // cheapest insertion: appended, unless a leg is strictly cheaper
    int best = -1;
    double best_value = 0.0;
    std::size_t best_at = 0;
    std::size_t m = 0;
    for (const Eigen::Index k : alive) {
      const std::size_t kk = std::size_t(k);
      if (gain[kk] < min_gain) continue;  // for good
      alive[m++] = k;
      const bool on_leg = leg_cost[kk] < append[kk];
      const double value = gain[kk] - rate * (on_leg ? leg_cost[kk] : append[kk]);
      if (value > best_value) {  // alive is in index order: ties keep the lower index
        best_value = value;
        best = int(k);
        best_at = on_leg ? std::size_t(leg_of[kk]) + 1 : n;
      }
    }
    alive.resize(m);
    if (best < 0) break;
    const std::size_t at = best_at;
    const Eigen::Vector3d x = p(best);
    stops.insert(stops.begin() + std::ptrdiff_t(at), x);
    ids.insert(ids.begin() + std::ptrdiff_t(at), best);
    leg.resize(n);
    for (std::size_t i = 0; i < n; ++i) leg[i] = (stops[i + 1] - stops[i]).norm();
    inserted.push_back(best);
    out.gains.push_back(gain[std::size_t(best)]);
    alive.erase(std::find(alive.begin(), alive.end(), Eigen::Index(best)));
    for (const Eigen::Index k : alive) {
      const std::size_t kk = std::size_t(k);
      const Eigen::Vector3d q = p(k);
      if (at == n) {  // appended: a new last leg, and appending now follows x
        consider(k, through(q, n - 1), int(n - 1));
        append[kk] = (q - x).norm();
        continue;
      }
      // leg at - 1 became legs at - 1 and at; the legs after it moved up by one
      int& li = leg_of[kk];
      if (li == int(at) - 1) {
        leg_cost[kk] = kInf;
        li = kNoLeg;
        for (std::size_t i = 0; i < n; ++i) consider(k, through(q, i), int(i));
        continue;
      }
      if (li != kNoLeg && li > int(at) - 1) ++li;
      consider(k, through(q, at - 1), int(at) - 1);
      consider(k, through(q, at), int(at));
    }
    // the chosen view's elements are covered now: every holder's gain shrinks accordingly
    for (std::int64_t o = cov.offsets[best]; o < cov.offsets[best + 1]; ++o) {
      const std::int64_t el = cov.elements[o];
      const std::size_t e = rank(el);
      float& have = covered[e];
      const float now = sat.after(el, cov.weights[o], have);
      if (now == have) continue;
      for (std::size_t i = first[e]; i < first[e + 1]; ++i) {
        const float w = hold[i].weight;
        gain[std::size_t(hold[i].candidate)] -= sat.left(el, w, have) - sat.left(el, w, now);
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

}  // namespace

std::vector<CoverSelection> select_tours(const CoverageRef& cov, const PointsRef& positions,
                                         const Eigen::Vector3d& start, double rate, double min_gain,
                                         int max_views, const std::vector<bool>& charges) {
  const Eigen::Index K = cov.offsets.size() - 1;
  if (K < 0 || positions.rows() != K)
    throw std::invalid_argument("select_tour: one position per candidate of the coverage");
  require_finite(positions, "candidate positions");
  if (!start.allFinite()) throw std::invalid_argument("select_tour: start is not finite");
  if (!(rate >= 0) || !std::isfinite(rate)) throw std::invalid_argument("rate must be >= 0");
  if (K > std::numeric_limits<std::int32_t>::max())
    throw std::invalid_argument("select_tour: too many candidates");
  // every candidate's gain with nothing covered, and the candidates each element belongs to
  // (inverse CSR: the distinct elements by rank, each with its holders in candidate order).
  // Gains only shrink as views are chosen, so a candidate below min_gain at the start is never
  // chosen and its gain never read: the inverse holds only the others (at a high gain level a
  // few hundred of a plan's tens of thousands; the same tours, in a fraction of the memory)
  std::vector<double> gain0(static_cast<std::size_t>(K), 0.0);
  const std::int64_t total = K ? cov.offsets[K] : 0;
  if (std::uint64_t(total) > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("select_tour: over 2^32 coverage elements; plan fewer candidates");
  for (Eigen::Index k = 0; k < K; ++k)
    if (cov.status[k] == 0)
      for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o)
        gain0[std::size_t(k)] += cov.weights[o];
  auto in_play = [&](Eigen::Index k) {
    return cov.status[k] == 0 && gain0[std::size_t(k)] >= min_gain;
  };
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(),  // the held elements' range
      hi = std::numeric_limits<std::int64_t>::min();
  std::size_t held = 0;
  for (Eigen::Index k = 0; k < K; ++k) {
    if (!in_play(k)) continue;
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      lo = std::min(lo, std::int64_t(cov.elements[o]));
      hi = std::max(hi, std::int64_t(cov.elements[o]));
    }
    held += std::size_t(cov.offsets[k + 1] - cov.offsets[k]);
  }
  auto each_held = [&](auto&& f) {  // the candidates in play and their offsets, ascending
    for (Eigen::Index k = 0; k < K; ++k)
      if (in_play(k))
        for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) f(k, o);
  };
  const ElementRanks rank(cov, each_held, held, lo, hi);
  const Holders holders = holders_of(cov, each_held, held, rank);
  // the tours read the inverse and write only their own state: one task each
  std::vector<CoverSelection> tours(charges.size());
  parallel_chunks(charges.size(), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      tours[i] = insertion_tour(cov, positions, start, rate, min_gain, max_views, charges[i], rank,
                                holders, gain0);
  });
  return tours;
}

CoverSelection select_tour(const CoverageRef& cov, const PointsRef& positions,
                           const Eigen::Vector3d& start, double rate, double min_gain,
                           int max_views, bool charge_transit) {
  return select_tours(cov, positions, start, rate, min_gain, max_views, {charge_transit})[0];
}
}  // namespace nbv
