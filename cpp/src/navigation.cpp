#include "nbv/navigation.hpp"

#include "nbv/parallel.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <queue>
#include <string>
#include <unordered_map>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace nbv {

namespace {

// ---- traversability: is the collision sphere centred on a cell free? ----------------------
//
// sphere_is_free at a cell's centre tests a fixed set of cells around it: offset o touches the
// sphere when sum over axes of max(|o_a| - 1/2, 0)^2 <= (radius / resolution)^2, within a box of
// offsets [-e, e], e = floor(1/2 + r), that must lie inside the grid. Grouped by column (o_x, o_y),
// the touching offsets are a z-range [-h, h]. Where a stencil term or the box edge is within 1e-9
// of the boundary, the rounding of the centre could decide it: there the stencil is not used and
// every cell goes through sphere_is_free.
struct SphereStencil {
  struct Column {
    int dx, dy, h;
  };
  std::vector<Column> columns;
  bool exact = false;

  explicit SphereStencil(double r) {
    auto near_int = [](double x) { return std::abs(x - std::round(x)) < 1e-9; };
    if (near_int(0.5 - r) || near_int(0.5 + r)) return;
    const int extent = int(std::floor(0.5 + r));
    const double r2 = r * r;
    auto f = [](int o) {
      const double d = std::max(std::abs(o) - 0.5, 0.0);
      return d * d;
    };
    for (int dy = -extent; dy <= extent; ++dy)
      for (int dx = -extent; dx <= extent; ++dx) {
        int h = -1;
        for (int dz = 0; dz <= extent; ++dz) {
          const double s = f(dx) + f(dy) + f(dz);
          if (std::abs(s - r2) < 1e-9) return;  // on the boundary: leave it to sphere_is_free
          if (s <= r2) h = dz;
        }
        if (h >= 0) columns.push_back({dx, dy, h});
      }
    exact = true;
  }
  /// The tallest column's h (0 when not exact).
  int height() const {
    int h = 0;
    for (const Column& c : columns) h = std::max(h, c.h);
    return h;
  }
};

// Index of word w (64 cells along x from x = 64 w) of row (j, k), rows of `words` words.
inline std::size_t word_at(int words, int ny, int w, int j, int k) {
  return std::size_t(w) + std::size_t(words) * (std::size_t(j) + std::size_t(ny) * std::size_t(k));
}

// Per-call scratch, reused between calls (thread-local; stamps instead of clearing).
// - What the search knows of each cell, per brick of 64 cells: a brick's block is made on its
//   first touch in the call, so a search pays for the bricks it touches, not for the grid.
// - Blocked cells (unknown or occupied) and traversable cells as bits in words of 64 cells along
//   x, each computed on first use: a traversable word is the complement of the OR, over the
//   stencil's offsets, of the blocked words shifted by the offset, with everything outside the
//   grid blocked (which is sphere_is_free's "the box must lie inside the grid": the stencil
//   reaches the box's extent along each axis). 64 cells cost about what one sphere test did.
// - Per word, the OR of the blocked words of its column within 1 .. H rows above and below it
//   (H the stencil's tallest column), so that a stencil column costs one lookup, not 2 h + 1:
//   a traversable word then takes about 70 lookups at 0.8 m and 0.2 m cells, not about 400.
struct SearchScratch {
  struct Block {
    double g[64];
    std::uint64_t parent[64];
    std::uint64_t has_g, reached;  // bits per cell: g set; reached by the backward flood
  };
  std::vector<std::uint32_t> brick_stamp, brick_block;
  std::deque<Block> blocks;  // a deque: a block's address never moves
  std::size_t used = 0;
  int words = 0;  // words per row along x
  std::vector<std::uint32_t> blocked_stamp, trav_stamp, column_stamp;
  std::vector<std::uint64_t> blocked_bits, trav_bits;
  std::vector<std::uint64_t> column_bits;  // per word, H words: the OR within 1 .. H rows
  int height = 0;                          // H: the levels column_bits holds per word
  int lowest_layer = 0;                    // this call's grid's lowest_path_layer()
  std::uint32_t stamp = 0;

  void begin(const GridView& g) {
    lowest_layer = g.lowest_path_layer();
    const std::size_t bricks = g.storage_size() >> 6;
    words = (g.nx + 63) / 64;
    const std::size_t nw = std::size_t(words) * std::size_t(g.ny) * std::size_t(g.nz);
    if (brick_stamp.size() != bricks || blocked_stamp.size() != nw || ++stamp == 0) {
      brick_stamp.assign(bricks, 0);
      brick_block.assign(bricks, 0);
      blocked_stamp.assign(nw, 0);
      trav_stamp.assign(nw, 0);
      blocked_bits.assign(nw, 0);
      trav_bits.assign(nw, 0);
      column_stamp.assign(nw, 0);
      column_bits.assign(nw * std::size_t(height), 0);
      stamp = 1;
    }
    used = 0;
  }
  /// Holds H levels of column words per word from now on (this call's stencil's tallest column).
  void columns_up_to(int h) {
    if (h <= height) return;
    height = h;
    column_bits.assign(column_stamp.size() * std::size_t(height), 0);
    std::fill(column_stamp.begin(), column_stamp.end(), 0);
  }
  /// After a search: frees the blocks past the first `keep` (a search over much of a large grid
  /// holds hundreds of MB of them). The next search's begin() makes its blocks anew.
  void trim(std::size_t keep) {
    if (blocks.size() <= keep) return;
    blocks.resize(keep);
    blocks.shrink_to_fit();
    used = 0;
#ifdef __GLIBC__
    malloc_trim(0);  // the blocks went back to malloc's lists: hand their pages to the system
#endif
  }
  Block& block(std::size_t idx) {
    const std::size_t b = idx >> 6;
    if (brick_stamp[b] != stamp) {
      brick_stamp[b] = stamp;
      if (used == blocks.size()) blocks.emplace_back();
      Block& k = blocks[used];
      k.has_g = k.reached = 0;
      brick_block[b] = std::uint32_t(used++);
    }
    return blocks[brick_block[b]];
  }
  /// Word w of row (j, k): bit x - 64 w set where cell (x, j, k) is blocked or outside the grid.
  std::uint64_t blocked(const GridView& g, int w, int j, int k) {
    if (w < 0 || w >= words || !g.contains(0, j, k)) return ~std::uint64_t(0);
    const std::size_t at = word_at(words, g.ny, w, j, k);
    if (blocked_stamp[at] != stamp) {
      blocked_stamp[at] = stamp;
      std::uint64_t bits = 0;
      for (int b = 0; b < 64; ++b) {
        const int x = 64 * w + b;
        if (x >= g.nx) {
          bits |= ~std::uint64_t(0) << b;
          break;
        }
        const std::size_t idx = g.index(x, j, k);
        bits |= std::uint64_t(g.blocked(idx)) << b;
      }
      blocked_bits[at] = bits;
    }
    return blocked_bits[at];
  }
  /// Word w of row (j, k), k within the grid: the OR of blocked(w, j, k + dz) over |dz| <= h
  /// (h <= height; h = 0: blocked itself).
  std::uint64_t column(const GridView& g, int w, int j, int k, int h) {
    if (h == 0) return blocked(g, w, j, k);
    if (w < 0 || w >= words || j < 0 || j >= g.ny) return ~std::uint64_t(0);
    const std::size_t at = word_at(words, g.ny, w, j, k);
    std::uint64_t* levels = &column_bits[at * std::size_t(height)];
    if (column_stamp[at] != stamp) {
      column_stamp[at] = stamp;
      std::uint64_t acc = blocked(g, w, j, k);
      for (int d = 1; d <= height; ++d) {
        acc |= blocked(g, w, j, k - d) | blocked(g, w, j, k + d);
        levels[d - 1] = acc;
      }
    }
    return levels[h - 1];
  }
  /// column's bits x0 .. x0 + 63 of row (j, k) (x0 may be negative or past the row: blocked
  /// there).
  std::uint64_t column_from(const GridView& g, int x0, int j, int k, int h) {
    const int w = x0 >> 6, s = x0 & 63;  // arithmetic shift: floor for negative x0
    const std::uint64_t lo = column(g, w, j, k, h);
    if (s == 0) return lo;
    return lo >> s | column(g, w + 1, j, k, h) << (64 - s);
  }
  /// Word w of row (j, k) of cells whose collision sphere (radius) is free, at or above the
  /// grid's lowest path layer.
  std::uint64_t traversable(const GridView& g, const SphereStencil& st, double radius, int w, int j,
                            int k) {
    const std::size_t at = word_at(words, g.ny, w, j, k);
    if (trav_stamp[at] != stamp) {
      trav_stamp[at] = stamp;
      std::uint64_t free = 0;
      if (k < lowest_layer) {
        // below the path floor: no cell of the word is traversable
      } else if (st.exact) {
        std::uint64_t any = 0;
        for (const SphereStencil::Column& c : st.columns) {
          any |= column_from(g, 64 * w + c.dx, j + c.dy, k, c.h);
          if (any == ~std::uint64_t(0)) break;
        }
        free = ~any;
      } else {
        for (int b = 0; b < 64 && 64 * w + b < g.nx; ++b)
          free |= std::uint64_t(sphere_is_free(g, g.center(64 * w + b, j, k), radius)) << b;
      }
      trav_bits[at] = free;
    }
    return trav_bits[at];
  }
};

// The blocks a thread keeps between searches: 4,096 blocks (about 4 MB), the cells of a capped
// plan_path search (200,000 cells) in compact regions and more; a larger search frees the rest.
constexpr std::size_t kKeptBlocks = 4096;

// Out of line: where the search's lambdas named a thread_local, each use looked its address up.
__attribute__((noinline)) SearchScratch& thread_scratch() {
  static thread_local SearchScratch s;
  return s;
}

}  // namespace

namespace {
// One search's traversable cells: this thread's scratch begun on g, the collision sphere's
// stencil, and the test of a cell (its bit in its word of 64 cells along x).
struct Traversal {
  const GridView& g;
  double radius;
  SearchScratch& s;
  SphereStencil stencil;
  Traversal(const GridView& grid, double r)
      : g(grid), radius(r), s(thread_scratch()), stencil(r / grid.resolution) {
    s.begin(g);
    s.columns_up_to(stencil.height());
  }
  bool operator()(int i, int j, int k) const {
    return (s.traversable(g, stencil, radius, i >> 6, j, k) >> (i & 63) & 1) != 0;
  }
  /// Whether a search may end at cell c for the point p: c traversable, its centre in sight of p.
  bool ends_at(const Eigen::Vector3i& c, const Eigen::Vector3d& p) const {
    return (*this)(c.x(), c.y(), c.z()) &&
           segment_is_free(g, g.center(c.x(), c.y(), c.z()), p, radius);
  }
};

// An A* queue entry in 16 bytes: f and the cell's (i, j, k) packed 21 bits each (its index and
// its cost are read from the grid and the scratch). A search's queue holds millions of entries
// on a large structure: a third of the bytes of f, g, the index and (i, j, k) each is fewer
// cache misses on every push and pop.
struct QueueNode {
  double f;
  std::uint64_t ijk;
  static constexpr int kBits = 21;
  static constexpr std::uint64_t kMask = (std::uint64_t(1) << kBits) - 1;
  QueueNode(double f_, int i, int j, int k)
      : f(f_), ijk(std::uint64_t(i) | std::uint64_t(j) << kBits | std::uint64_t(k) << 2 * kBits) {}
  int i() const { return int(ijk & kMask); }
  int j() const { return int(ijk >> kBits & kMask); }
  int k() const { return int(ijk >> 2 * kBits); }
  bool operator>(const QueueNode& o) const { return f > o.f; }
};
using OpenQueue = std::priority_queue<QueueNode, std::vector<QueueNode>, std::greater<QueueNode>>;

// A search's queue packs cells in 21 bits an axis (2,097,152 cells: 419 km at 0.2 m).
void require_queue_fits(const GridView& g) {
  const int most = std::max({g.nx, g.ny, g.nz});
  if (most > int(QueueNode::kMask) + 1)
    throw std::invalid_argument("path search: the grid has " + std::to_string(most) +
                                " cells along an axis, more than 2,097,152");
}
}  // namespace

bool sphere_is_free(const GridView& g, const Eigen::Vector3d& center, double radius) {
  const double r = radius / g.resolution;
  const Eigen::Vector3d q = (center - g.origin) / g.resolution;
  const Eigen::Vector3i lo = (q.array() - r).floor().cast<int>();
  const Eigen::Vector3i hi = (q.array() + r).floor().cast<int>();
  if (lo.x() < 0 || lo.y() < 0 || lo.z() < 0 || hi.x() >= g.nx || hi.y() >= g.ny || hi.z() >= g.nz)
    return false;  // part of the sphere is outside the mapped workspace: unknown
  const double r2 = r * r;
  // brick by brick: a brick of 64 open cells passes whichever of them touch the sphere
  for (int bk = lo.z() >> 2; bk <= hi.z() >> 2; ++bk)
    for (int bj = lo.y() >> 2; bj <= hi.y() >> 2; ++bj)
      for (int bi = lo.x() >> 2; bi <= hi.x() >> 2; ++bi) {
        if (g.brick_clear(g.index(4 * bi, 4 * bj, 4 * bk) >> 6)) continue;
        for (int k = std::max(lo.z(), 4 * bk); k <= std::min(hi.z(), 4 * bk + 3); ++k) {
          const double dz = std::max({k - q.z(), 0.0, q.z() - (k + 1)});
          for (int j = std::max(lo.y(), 4 * bj); j <= std::min(hi.y(), 4 * bj + 3); ++j) {
            const double dy = std::max({j - q.y(), 0.0, q.y() - (j + 1)});
            for (int i = std::max(lo.x(), 4 * bi); i <= std::min(hi.x(), 4 * bi + 3); ++i) {
              const double dx = std::max({i - q.x(), 0.0, q.x() - (i + 1)});
              if (dx * dx + dy * dy + dz * dz > r2) continue;  // the cell does not touch it
              const std::size_t idx = g.index(i, j, k);
              if (g.blocked(idx)) return false;
            }
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

// Path: a -> cell centres -> b, shortened greedily by line of sight.
static std::vector<Eigen::Vector3d> shortened(const GridView& g, const Eigen::Vector3d& a,
                                              const std::vector<Eigen::Vector3d>& cells,
                                              const Eigen::Vector3d& b, double radius) {
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

std::vector<Eigen::Vector3d> plan_path_reference(const GridView& g, const Eigen::Vector3d& a,
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
  const int lowest_layer = g.lowest_path_layer();
  auto traversable = [&](const Eigen::Vector3i& c) {
    if (c.z() < lowest_layer) return false;
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
  return shortened(g, a, cells, b, radius);
}

std::vector<Eigen::Vector3d> plan_path(const GridView& g, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, double radius,
                                       std::size_t max_expansions, PathSearchStats* stats) {
  if (stats) *stats = {};
  // plan_path_reference step for step (the same cells, costs, queue and order, so the same
  // path), with what it knows of each cell in per-brick blocks instead of hash maps, the
  // collision test 64 cells at a time (SphereStencil, SearchScratch::traversable), and a flood
  // from b beside the search that ends it as soon as b's free component is known not to hold a.
  g.validate();
  if (segment_is_free(g, a, b, radius)) return {a, b};
  Eigen::Vector3i ca, cb;
  if (!g.cell_of(a, ca) || !g.cell_of(b, cb)) return {};
  const Traversal traversable(g, radius);
  SearchScratch& s = traversable.s;
  const std::size_t ia = g.index(ca), ib = g.index(cb);
  if (!traversable.ends_at(cb, b)) return {};
  require_queue_fits(g);
  OpenQueue open;
  const Eigen::Vector3d goal = g.center(cb.x(), cb.y(), cb.z());
  {
    SearchScratch::Block& blk = s.block(ia);
    blk.g[ia & 63] = 0.0;
    blk.has_g |= std::uint64_t(1) << (ia & 63);
  }
  open.push({(g.center(ca.x(), ca.y(), ca.z()) - goal).norm(), ca.x(), ca.y(), ca.z()});
  // the flood from b: breadth first over traversable cells; it proves b unreachable when it
  // runs out without touching a's cell (the search's moves are symmetric)
  constexpr std::size_t kFloodAfter = 1024;  // expansions before the flood starts
  std::vector<std::array<int, 3>> flood{{cb.x(), cb.y(), cb.z()}};
  std::size_t flood_head = 0;
  bool flood_done = ia == ib;
  s.block(ib).reached |= std::uint64_t(1) << (ib & 63);
  std::size_t expansions = 0;
  bool found = false;
  while (!open.empty() && expansions < max_expansions) {
    const QueueNode top = open.top();
    open.pop();
    const int ci = top.i(), cj = top.j(), ck = top.k();
    const std::size_t cidx = g.index(ci, cj, ck);
    const double gc = s.block(cidx).g[cidx & 63];
    if (top.f > gc + (g.center(ci, cj, ck) - goal).norm() + 1e-9) continue;  // stale
    if (cidx == ib) {
      found = true;
      break;
    }
    ++expansions;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy && !dz) continue;
          const int ni = ci + dx, nj = cj + dy, nk = ck + dz;
          if (!g.contains(ni, nj, nk)) continue;
          const std::size_t nidx = g.index(ni, nj, nk);
          if (!traversable(ni, nj, nk)) continue;
          const double ng =
              gc + g.resolution * std::sqrt(static_cast<double>(dx * dx + dy * dy + dz * dz));
          SearchScratch::Block& blk = s.block(nidx);
          const std::uint64_t bit = std::uint64_t(1) << (nidx & 63);
          if ((blk.has_g & bit) && blk.g[nidx & 63] <= ng) continue;
          blk.g[nidx & 63] = ng;
          blk.has_g |= bit;
          blk.parent[nidx & 63] = cidx;
          open.push({ng + (g.center(ni, nj, nk) - goal).norm(), ni, nj, nk});
        }
    if (!flood_done && expansions > kFloodAfter) {  // one step of the flood
      if (flood_head == flood.size()) {             // b's component is closed and lacks a
        if (stats) *stats = {expansions, flood.size(), true};
        return {};
      }
      const std::array<int, 3> c = flood[flood_head++];
      for (int dz = -1; dz <= 1 && !flood_done; ++dz)
        for (int dy = -1; dy <= 1 && !flood_done; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            if (!dx && !dy && !dz) continue;
            const int ni = c[0] + dx, nj = c[1] + dy, nk = c[2] + dz;
            if (!g.contains(ni, nj, nk)) continue;
            const std::size_t nidx = g.index(ni, nj, nk);
            if (nidx == ia) {
              flood_done = true;  // a borders b's component: leave it to the search
              break;
            }
            SearchScratch::Block& blk = s.block(nidx);
            const std::uint64_t bit = std::uint64_t(1) << (nidx & 63);
            if ((blk.reached & bit) || !traversable(ni, nj, nk)) continue;
            blk.reached |= bit;
            flood.push_back({ni, nj, nk});
          }
    }
  }
  if (stats) *stats = {expansions, flood.size(), false, !found && !open.empty()};
  if (!found) return {};
  if (stats) stats->cost = s.block(ib).g[ib & 63];
  std::vector<Eigen::Vector3d> cells;
  for (std::size_t idx = ib;; idx = s.block(idx).parent[idx & 63]) {
    int i, j, k;
    g.layout.coords(idx, i, j, k);
    cells.push_back(g.center(i, j, k));
    if (idx == ia) break;
  }
  std::reverse(cells.begin(), cells.end());
  return shortened(g, a, cells, b, radius);
}

FreeComponent::FreeComponent(const GridView& g, const Eigen::Vector3d& a, double radius)
    : start_(a), radius_(radius) {
  // A flood over words of 64 cells along x: a word's reached bits grow along its row through
  // traversable bits, then reach the 3 x 3 rows about it (26-connectivity: cell x touches x - 1,
  // x, x + 1 of each neighbouring row, across word edges too); a word is queued again whenever
  // it gains bits. The start is seeded as plan_path expands it: its traversable neighbours.
  g.validate();
  SearchScratch& s = thread_scratch();
  s.begin(g);
  const SphereStencil stencil(radius / g.resolution);
  s.columns_up_to(stencil.height());
  words_ = s.words;
  ny_ = g.ny;
  lowest_layer_ = g.lowest_path_layer();
  auto at = [&](int w, int j, int k) { return word_at(words_, ny_, w, j, k); };
  reached_.assign(std::size_t(words_) * std::size_t(g.ny) * std::size_t(g.nz), 0);
  std::vector<std::array<int, 3>> queue;
  std::vector<std::uint8_t> queued(reached_.size(), 0);
  auto add = [&](int w, int j, int k, std::uint64_t bits) {
    if (w < 0 || w >= words_ || !g.contains(0, j, k) || !bits) return;
    const std::size_t i = at(w, j, k);
    const std::uint64_t fresh = bits & s.traversable(g, stencil, radius, w, j, k) & ~reached_[i];
    if (!fresh) return;
    reached_[i] |= fresh;
    if (!queued[i]) {
      queued[i] = 1;
      queue.push_back({w, j, k});
    }
  };
  start_in_grid_ = g.cell_of(a, start_cell_);
  if (start_in_grid_)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int x = start_cell_.x() + dx;
          if ((dx || dy || dz) && x >= 0 && x < g.nx)
            add(x >> 6, start_cell_.y() + dy, start_cell_.z() + dz, std::uint64_t(1) << (x & 63));
        }
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const auto [w, j, k] = queue[head];
    const std::size_t i = at(w, j, k);
    queued[i] = 0;
    const std::uint64_t t = s.traversable(g, stencil, radius, w, j, k);
    std::uint64_t r = reached_[i];
    for (std::uint64_t prev = 0; prev != r;) {  // along the row, within the word
      prev = r;
      r = t & (r | r << 1 | r >> 1);
    }
    reached_[i] = r;
    const std::uint64_t here = r | r << 1 | r >> 1, left = r << 63, right = r >> 63;
    for (int dk = -1; dk <= 1; ++dk)
      for (int dj = -1; dj <= 1; ++dj) {
        if (dj || dk) add(w, j + dj, k + dk, here);
        add(w - 1, j + dj, k + dk, left);
        add(w + 1, j + dj, k + dk, right);
      }
  }
}

std::vector<std::uint8_t> FreeComponent::contains(const GridView& g,
                                                  const PointsRef& targets) const {
  g.validate();
  if (std::size_t(g.nx + 63) / 64 != std::size_t(words_) || g.ny != ny_ ||
      std::size_t(words_) * std::size_t(g.ny) * std::size_t(g.nz) != reached_.size())
    throw std::invalid_argument("FreeComponent::contains: the grid is not the flooded one");
  std::vector<std::uint8_t> out(std::size_t(targets.rows()), 0);
  for (Eigen::Index n = 0; n < targets.rows(); ++n) {
    const Eigen::Vector3d b = targets.row(n).transpose();
    if (segment_is_free(g, start_, b, radius_)) {
      out[std::size_t(n)] = 1;
      continue;
    }
    Eigen::Vector3i cb;
    if (!start_in_grid_ || !g.cell_of(b, cb)) continue;
    const std::size_t i = word_at(words_, ny_, cb.x() >> 6, cb.y(), cb.z());
    const std::uint64_t bit = std::uint64_t(1) << (cb.x() & 63);
    // a reached cell is traversable; the start's own cell is reached only if it is
    const bool in =
        (reached_[i] & bit) || (cb == start_cell_ && cb.z() >= lowest_layer_ &&
                                sphere_is_free(g, g.center(cb.x(), cb.y(), cb.z()), radius_));
    out[std::size_t(n)] = in && segment_is_free(g, g.center(cb.x(), cb.y(), cb.z()), b, radius_);
  }
  return out;
}

PathsToGoal plan_paths_to(const GridView& g, const PointsRef& starts, const Eigen::Vector3d& goal,
                          double radius, std::size_t max_expansions) {
  // plan_path from every start at once: its tests (the straight flight, the goal's cell
  // traversable and in sight of the goal), then its search run backwards, from the goal's cell
  // outwards: a start's cell is reached when the search settles it (a start's cell need not be
  // traversable: it is reached, never passed through, as plan_path leaves it)
  g.validate();
  require_finite(starts, "path starts");
  const std::size_t n = std::size_t(starts.rows());
  PathsToGoal out;
  out.paths.resize(n);
  out.cells_cost.assign(n, std::numeric_limits<double>::quiet_NaN());
  auto start = [&](std::size_t i) { return Eigen::Vector3d(starts.row(Eigen::Index(i))); };
  std::vector<std::uint8_t> direct(n, 0);
  parallel_chunks(n, 8, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) direct[i] = segment_is_free(g, start(i), goal, radius);
  });
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> cell(n, kNone);  // the start's cell, where it is searched
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3i c;
    if (direct[i])
      out.paths[i] = {start(i), goal};
    else if (g.cell_of(start(i), c))
      cell[i] = g.index(c);
  }
  Eigen::Vector3i cb;
  if (!g.cell_of(goal, cb)) return out;
  const Traversal traversable(g, radius);
  SearchScratch& s = traversable.s;
  if (!traversable.ends_at(cb, goal)) return out;
  std::vector<std::size_t> targets;
  for (std::size_t c : cell)
    if (c != kNone) targets.push_back(c);
  std::sort(targets.begin(), targets.end());
  targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
  if (targets.empty()) return out;
  std::vector<std::uint8_t> target_brick(g.storage_size() >> 6, 0);
  for (std::size_t t : targets) target_brick[t >> 6] = 1;
  auto is_target = [&](std::size_t idx) {
    return target_brick[idx >> 6] && std::binary_search(targets.begin(), targets.end(), idx);
  };
  double step[27];
  for (int d = 0; d < 27; ++d) {
    const int dx = d % 3 - 1, dy = d / 3 % 3 - 1, dz = d / 9 - 1;
    step[d] = g.resolution * std::sqrt(double(dx * dx + dy * dy + dz * dz));
  }
  // A* towards the box of the starts' cells: the distance to a box never drops by more than a
  // move costs (a consistent heuristic), so a cell's cost is final when it leaves the queue, as
  // in Dijkstra's search; for one start it is plan_path's search backwards
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (std::size_t t : targets) {
    int x, y, z;
    g.layout.coords(t, x, y, z);
    lo = lo.cwiseMin(g.center(x, y, z));
    hi = hi.cwiseMax(g.center(x, y, z));
  }
  auto h = [&](int i, int j, int k) {
    const Eigen::Vector3d p = g.center(i, j, k);
    return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm();
  };
  require_queue_fits(g);
  OpenQueue open;  // a cell's first entry out of the queue holds its least cost (h is its own)
  const std::size_t ib = g.index(cb);
  {
    SearchScratch::Block& blk = s.block(ib);
    blk.g[ib & 63] = 0.0;
    blk.parent[ib & 63] = ib;
    blk.has_g |= std::uint64_t(1) << (ib & 63);
  }
  open.push({h(cb.x(), cb.y(), cb.z()), cb.x(), cb.y(), cb.z()});
  std::size_t remaining = targets.size();
  while (!open.empty() && remaining) {
    const QueueNode top = open.top();
    open.pop();
    const int ci = top.i(), cj = top.j(), ck = top.k();
    const std::size_t cidx = g.index(ci, cj, ck);
    SearchScratch::Block& here = s.block(cidx);
    const std::uint64_t cur_bit = std::uint64_t(1) << (cidx & 63);
    if (here.reached & cur_bit) continue;  // settled before: a stale entry
    here.reached |= cur_bit;               // settled: its cost is final
    if (is_target(cidx) && --remaining == 0) break;
    if (!traversable(ci, cj, ck)) continue;  // a start's cell: an end, not a way
    if (max_expansions && out.expansions == max_expansions) {
      out.capped = true;
      break;
    }
    ++out.expansions;
    const double gc = here.g[cidx & 63];
    for (int d = 0; d < 27; ++d) {
      if (d == 13) continue;  // the cell itself
      const int ni = ci + d % 3 - 1, nj = cj + d / 3 % 3 - 1, nk = ck + d / 9 - 1;
      if (!g.contains(ni, nj, nk)) continue;
      const std::size_t nidx = g.index(ni, nj, nk);
      if (!traversable(ni, nj, nk) && !is_target(nidx)) continue;
      SearchScratch::Block& blk = s.block(nidx);
      const std::uint64_t bit = std::uint64_t(1) << (nidx & 63);
      const double ng = gc + step[d];
      if ((blk.reached & bit) || ((blk.has_g & bit) && blk.g[nidx & 63] <= ng)) continue;
      blk.g[nidx & 63] = ng;
      blk.has_g |= bit;
      blk.parent[nidx & 63] = cidx;
      open.push({ng + h(ni, nj, nk), ni, nj, nk});
    }
  }
  // the settled starts' cells back to the goal's, read here from this thread's scratch (no
  // other thread touches it), then shortened in parallel as plan_path shortens
  auto settled = [&](std::size_t idx) -> const SearchScratch::Block* {
    const std::size_t b = idx >> 6;
    if (s.brick_stamp[b] != s.stamp) return nullptr;
    const SearchScratch::Block& blk = s.blocks[s.brick_block[b]];
    return (blk.reached >> (idx & 63) & 1) ? &blk : nullptr;
  };
  std::vector<std::vector<Eigen::Vector3d>> chains(n);
  for (std::size_t i = 0; i < n; ++i) {
    const SearchScratch::Block* blk = cell[i] == kNone ? nullptr : settled(cell[i]);
    if (!blk) continue;
    for (std::size_t idx = cell[i];; idx = settled(idx)->parent[idx & 63]) {
      int x, y, z;
      g.layout.coords(idx, x, y, z);
      chains[i].push_back(g.center(x, y, z));
      if (idx == ib) break;
    }
    out.cells_cost[i] = blk->g[cell[i] & 63];
  }
  s.trim(kKeptBlocks);  // the chains are read: the search's blocks are not needed any more
  parallel_chunks(n, 4, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      if (!chains[i].empty()) {
        out.paths[i] = shortened(g, start(i), chains[i], goal, radius);
        std::vector<Eigen::Vector3d>().swap(chains[i]);
      }
  });
  return out;
}

double path_length(const std::vector<Eigen::Vector3d>& path) {
  double d = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) d += (path[i] - path[i - 1]).norm();
  return d;
}

}  // namespace nbv
