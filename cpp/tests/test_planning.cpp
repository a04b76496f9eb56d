// Edge cases of the planning core: the workspace grid's layout and exact bookkeeping, the ray
// walk, collision checks and A*, tours, set cover and prize-collecting insertion.
#include "nbv/coverage.hpp"
#include "nbv/grid_view.hpp"
#include "nbv/huge_pages.hpp"
#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/surface_observations.hpp"
#include "nbv/tour.hpp"
#include "nbv/tour_plan.hpp"
#include "nbv/views.hpp"
#include "nbv/workspace_grid.hpp"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <vector>

using namespace nbv;

namespace {

CellRule rule() {
  CellRule r;
  r.occupied_logodds = 0.405465f;
  r.clamp_min_logodds = -1.99243f;
  r.clamp_max_logodds = 3.47610f;
  return r;
}

std::vector<std::array<int, 3>> walk(const GridView& g, const Eigen::Vector3d& o,
                                     const Eigen::Vector3d& d, double t) {
  std::vector<std::array<int, 3>> cells;
  walk_ray<false>(g, o, d.normalized(), t, [&](std::size_t, const int* c, double) {
    cells.push_back({c[0], c[1], c[2]});
    return true;
  });
  return cells;
}

/// n points drawn uniformly in the box [0, hi).
Points random_points(std::mt19937& rng, const Eigen::Vector3d& hi, int n) {
  std::uniform_real_distribution<double> ux(0, hi.x()), uy(0, hi.y()), uz(0, hi.z());
  Points p(n, 3);
  for (int r = 0; r < n; ++r) p.row(r) = Eigen::Vector3d(ux(rng), uy(rng), uz(rng)).transpose();
  return p;
}

}  // namespace

TEST(GridLayout, EveryCellHasItsOwnIdAndPaddingHoldsNone) {
  for (const std::array<int, 3> dims : {std::array<int, 3>{1, 1, 1}, {5, 3, 9}, {8, 8, 4}}) {
    const GridLayout L(dims);
    std::set<std::size_t> ids;
    for (int k = 0; k < dims[2]; ++k)
      for (int j = 0; j < dims[1]; ++j)
        for (int i = 0; i < dims[0]; ++i) {
          const std::size_t id = L.id(i, j, k);
          ASSERT_LT(id, L.storage_size());
          int a, b, c;
          ASSERT_TRUE(L.coords(id, a, b, c));
          ASSERT_TRUE(a == i && b == j && c == k);
          ids.insert(id);
        }
    EXPECT_EQ(std::int64_t(ids.size()), L.num_cells());
    std::size_t padding = 0;
    for (std::size_t id = 0; id < L.storage_size(); ++id) {
      int a, b, c;
      padding += !L.coords(id, a, b, c);
    }
    EXPECT_EQ(padding, L.storage_size() - std::size_t(L.num_cells()));
  }
  EXPECT_THROW(GridLayout({0, 2, 2}), std::invalid_argument);
}

TEST(WorkspaceGrid, TotalsCountsAndBricksStayExactUnderRandomUpdates) {
  WorkspaceGrid g({9, 7, 5}, rule());
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> x(0, 8), y(0, 6), z(0, 4), kind(0, 3);
  const float values[] = {-1.99243f, -0.4f, 0.85f, 3.47610f};
  for (int n = 0; n < 3000; ++n) {
    const std::int64_t id = std::int64_t(g.layout().id(x(rng), y(rng), z(rng)));
    const int k = kind(rng);
    g.set(id, values[k], k == 1 && n % 7 == 0 ? CellFlag::Predicted : CellFlag::Observed);
  }
  EXPECT_EQ(g.total_entropy(), g.recompute_total_entropy());  // fixed point: exactly equal
  const CellCounts a = g.counts(), b = g.recompute_counts();
  EXPECT_EQ(a.free, b.free);
  EXPECT_EQ(a.occupied, b.occupied);
  EXPECT_EQ(a.unknown, b.unknown);
  EXPECT_EQ(a.predicted, b.predicted);
  EXPECT_EQ(a.free + a.occupied + a.unknown, g.num_cells());
  // brick summary: a brick is live exactly when a cell in it is not an observed clamped free one
  for (std::size_t brick = 0; brick < g.layout().num_bricks(); ++brick) {
    int live = 0;
    for (std::size_t id = brick << 6; id < (brick + 1) << 6; ++id) {
      int i, j, k;
      if (!g.layout().coords(id, i, j, k)) continue;
      const auto s = std::int64_t(id);
      live += !(g.flag(s) == CellFlag::Observed && g.state(s) == CellState::Free &&
                g.entropy(s) == 0.0f);
    }
    ASSERT_EQ(int(g.brick_live_data()[brick]), live) << brick;
  }
  // ... and counts its open cells (known and not occupied) and its occupied cells
  for (std::size_t brick = 0; brick < g.layout().num_bricks(); ++brick) {
    int open = 0, occupied = 0;
    for (std::size_t id = brick << 6; id < (brick + 1) << 6; ++id) {
      int i, j, k;
      if (!g.layout().coords(id, i, j, k)) continue;
      open += g.state(std::int64_t(id)) == CellState::Free;
      occupied += g.state(std::int64_t(id)) == CellState::Occupied;
    }
    ASSERT_EQ(int(g.brick_open_data()[brick]), open) << brick;
    ASSERT_EQ(int(g.brick_occupied_data()[brick]), occupied) << brick;
  }
}

TEST(WorkspaceGrid, ScoredHoldsEntropyWithOccupancyInItsSign) {
  WorkspaceGrid g({4, 4, 4}, rule());
  const std::int64_t a = std::int64_t(g.layout().id(1, 1, 1)),
                     b = std::int64_t(g.layout().id(2, 1, 1));
  g.set(a, 3.47610f, CellFlag::Observed);  // occupied, clamped: -0.0
  g.set(b, 0.85f, CellFlag::Observed);
  EXPECT_TRUE(std::signbit(g.scored(a)));
  EXPECT_EQ(g.scored(a), 0.0f);
  EXPECT_EQ(g.state(a), CellState::Occupied);
  EXPECT_LT(g.scored(b), 0.0f);
  EXPECT_FLOAT_EQ(-g.scored(b), g.entropy(b));
  const std::int64_t u = std::int64_t(g.layout().id(0, 0, 0));
  EXPECT_FLOAT_EQ(g.scored(u), float(std::log(2.0)));  // unknown: ln 2, not occupied
}

// The grid holds cells only for the bricks written: every other cell reads unknown from the
// shared brick. Values read back exactly after writes, copies and
// moves, and a copy is independent of its source.
TEST(WorkspaceGrid, HoldsCellsOnlyForTheBricksWritten) {
  const std::array<int, 3> dims{37, 21, 13};  // no axis a multiple of 4: padding on 3 faces
  WorkspaceGrid g(dims, rule());
  const GridLayout& L = g.layout();
  EXPECT_EQ(g.allocated_bricks(), 0u);
  const std::size_t empty_bytes = g.bytes();
  // writes into three bricks, one of them holding padding
  std::map<std::int64_t, std::pair<float, CellFlag>> want;
  const std::array<std::array<int, 3>, 5> cells{
      {{1, 1, 1}, {2, 3, 1}, {9, 5, 6}, {36, 20, 12}, {10, 4, 7}}};
  const float values[] = {-1.2f, 0.9f, 3.47610f, -0.4f, 2.0f};
  std::set<std::size_t> bricks;
  for (std::size_t n = 0; n < cells.size(); ++n) {
    const auto& c = cells[n];
    const auto id = std::int64_t(L.id(c[0], c[1], c[2]));
    const CellFlag f = n == 4 ? CellFlag::Predicted : CellFlag::Observed;
    g.set(id, values[n], f);
    want[id] = {values[n], f};
    bricks.insert(std::size_t(id) >> 6);
  }
  EXPECT_EQ(bricks.size(), 3u);
  EXPECT_EQ(g.allocated_bricks(), bricks.size());
  EXPECT_EQ(g.bytes(), empty_bytes + bricks.size() * 64 * 9);
  auto check = [&](const WorkspaceGrid& w) {
    for (int k = 0; k < dims[2]; ++k)
      for (int j = 0; j < dims[1]; ++j)
        for (int i = 0; i < dims[0]; ++i) {
          const auto id = std::int64_t(L.id(i, j, k));
          const auto it = want.find(id);
          if (it == want.end()) {
            ASSERT_EQ(w.flag(id), CellFlag::Unknown);
            ASSERT_EQ(w.logodds(id), 0.0f);
            ASSERT_FLOAT_EQ(w.scored(id), float(std::log(2.0)));
            continue;
          }
          ASSERT_EQ(w.flag(id), it->second.second);
          ASSERT_EQ(w.logodds(id), it->second.first);
          ASSERT_EQ(w.state(id), it->second.first >= rule().occupied_logodds ? CellState::Occupied
                                                                             : CellState::Free);
        }
    const auto pad = std::int64_t(L.id(39, 20, 12));  // past the x face, in (36, 20, 12)'s brick
    int i, j, k;
    EXPECT_FALSE(L.coords(std::size_t(pad), i, j, k));
    EXPECT_EQ(w.flag(pad), CellFlag::Unknown);
    EXPECT_FLOAT_EQ(w.scored(pad), float(std::log(2.0)));
    EXPECT_EQ(w.total_entropy(), w.recompute_total_entropy());
    EXPECT_EQ(w.counts().unknown, w.recompute_counts().unknown);
  };
  check(g);
  WorkspaceGrid copy = g;
  check(copy);
  copy.set(std::int64_t(L.id(30, 2, 2)), 1.0f, CellFlag::Observed);  // the copy's own brick
  EXPECT_EQ(copy.allocated_bricks(), g.allocated_bricks() + 1);
  check(g);
  WorkspaceGrid moved = std::move(g);
  check(moved);
  // a cell set back to unknown reads unknown; its brick keeps its slot
  const auto first = want.begin()->first;
  moved.set(first, 0.0f, CellFlag::Unknown);
  want.erase(first);
  check(moved);
  EXPECT_EQ(moved.allocated_bricks(), bricks.size());
}

TEST(RayWalk, AxisRaysVisitTheirRowAndDiagonalsEveryCrossedCell) {
  OccupancyMap m(1.0, {0, 0, 0}, {10, 10, 10});
  const GridView g = grid_view(m);
  const auto row = walk(g, {0.5, 3.5, 3.5}, {1, 0, 0}, 4.0);
  ASSERT_EQ(row.size(), 5u);  // cells 0..4 (the end at x = 4.5 is inside cell 4)
  for (int i = 0; i < 5; ++i) EXPECT_EQ(row[std::size_t(i)], (std::array<int, 3>{i, 3, 3}));
  const auto diag = walk(g, {0.5, 0.5, 0.5}, {1, 1, 1}, 100.0);  // to the grid's far corner
  EXPECT_EQ(diag.front(), (std::array<int, 3>{0, 0, 0}));
  EXPECT_EQ(diag.back(), (std::array<int, 3>{9, 9, 9}));
  for (std::size_t i = 1; i < diag.size(); ++i) {  // each step moves one cell along one axis
    int moved = 0;
    for (int a = 0; a < 3; ++a) moved += std::abs(diag[i][a] - diag[i - 1][a]);
    EXPECT_EQ(moved, 1);
  }
  EXPECT_TRUE(walk(g, {-5, -5, -5}, {-1, 0, 0}, 100).empty());      // misses the grid
  const auto entering = walk(g, {-3.5, 2.5, 2.5}, {1, 0, 0}, 5.0);  // starts outside
  ASSERT_FALSE(entering.empty());
  EXPECT_EQ(entering.front(), (std::array<int, 3>{0, 2, 2}));
}

TEST(RayWalk, FourLanesMarkTheCellsOfWalkRayUpToTheFirstOccupiedOne) {
  // A grid whose sides are not multiples of a brick, with occupied cells, rays from inside,
  // outside and on cell boundaries, along axes (with -0.0 components), diagonals (exact ties)
  // and at random, with ranges that end inside, on a boundary and past the grid: mark_rays4, in
  // AVX2 lanes and one ray at a time, marks the cells walk_ray<false> enters up to and including
  // each ray's first occupied cell, lists each word it set once, and gives that cell.
  OccupancyMap m(0.5, {-3.0, -2.0, -1.0}, {4.5, 3.5, 2.0});  // 15 x 11 x 6 cells
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-4.0, 5.0), unit(-1.0, 1.0), range(0.0, 12.0);
  std::uniform_real_distribution<double> px(-3.0, 4.5), py(-2.0, 3.5), pz(-1.0, 2.0);
  Points hits(40, 3);
  for (Eigen::Index k = 0; k < hits.rows(); ++k) hits.row(k) << px(rng), py(rng), pz(rng);
  for (int n = 0; n < 3; ++n) m.update_cells(hits, true);
  m.mark_free_segment({-2.5, -1.5, 0.5}, {4.0, 3.0, 0.5}, 0.6);
  const GridView g = grid_view(m);
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> rays;
  const double axis[3] = {-0.0, 0.0, 1.0};
  for (const double ax : axis)
    for (const double ay : axis)
      for (const double az : {-1.0, -0.0, 1.0}) {
        const Eigen::Vector3d d(ax, ay, az);
        if (d.norm() > 0) rays.push_back({{0.25, 0.5, 0.0}, d.normalized()});  // on boundaries
      }
  for (int i = 0; i < 600; ++i) {
    Eigen::Vector3d o(pos(rng), pos(rng), pos(rng) * 0.5), d(unit(rng), unit(rng), unit(rng));
    if (i % 5 == 0) o = (o * 2.0).array().round() / 2.0;  // a cell corner
    if (i % 7 == 0) d[i % 3] = 0.0;
    if (d.norm() < 1e-3) continue;
    rays.push_back({o, d.normalized()});
  }
  const std::size_t words = g.storage_size() / 64, size = 4 * std::size_t(max_ray_cells(g));
  std::vector<std::uint64_t> cells(size), runs(size);
  std::vector<std::uint8_t> ends(std::size_t(max_ray_cells(g)) + 32);
  const MarkBuffer buffer{cells.data(), runs.data(), ends.data()};
  std::size_t walked = 0;
  int crossing = 0, stopped = 0;
  for (std::size_t r0 = 0; r0 < rays.size(); r0 += 4) {
    RayStart starts[4];
    bool active[4];
    std::vector<std::uint64_t> expect(words + 1, 0);
    std::size_t expect_stop[4];
    for (int l = 0; l < 4; ++l) {
      const std::size_t r = std::min(r0 + std::size_t(l), rays.size() - 1);
      const double t_max = l == 3 ? 100.0 : l == 2 ? std::floor(range(rng)) : range(rng);
      const auto& [o, d] = rays[r];
      active[l] = ray_start(g, ray_origin(g, o), d, t_max, starts[l]);
      std::size_t n = 0;
      expect_stop[l] = walk_ray<false>(g, o, d, t_max, [&](std::size_t idx, const int*, double) {
        expect[idx >> 6] |= std::uint64_t(1) << (idx & 63);
        ++n;
        return !g.occupied(idx);
      });
      ASSERT_EQ(active[l], n > 0) << "ray " << r;
      walked += n;
      crossing += n >= 5;
      stopped += expect_stop[l] != kNoCell;
    }
    for (const bool simd : {true, false}) {
      std::vector<std::uint64_t> bits(words + 1, 0);
      std::vector<std::uint32_t> touched(words + 1, 0);
      CellMarks marks{bits.data(), touched.data(), 0};
      std::size_t stop[4] = {0, 0, 0, 0};
      mark_rays4(g, starts, active, marks, buffer, stop, simd);
      for (int l = 0; l < 4; ++l)
        ASSERT_EQ(stop[l], expect_stop[l]) << "ray " << r0 + l << " simd " << simd;
      ASSERT_EQ(bits, expect) << "rays " << r0 << ".. simd " << simd;
      std::vector<std::uint32_t> listed(touched.begin(), touched.begin() + marks.n_touched);
      std::sort(listed.begin(), listed.end());
      ASSERT_EQ(std::adjacent_find(listed.begin(), listed.end()), listed.end());
      for (std::size_t w = 0; w < words; ++w)
        ASSERT_EQ(std::binary_search(listed.begin(), listed.end(), std::uint32_t(w)),
                  expect[w] != 0);
    }
  }
  EXPECT_GT(crossing, 150);  // rays that crossed the grid, not just a corner of it
  EXPECT_GT(walked, 1500u);
  EXPECT_GT(stopped, 40);  // rays that stopped at an occupied cell, and rays that did not
  EXPECT_LT(stopped, int(rays.size()) - 100);
}

TEST(RayWalk, FourLanesStepTheCellsOfWalkRayInItsOrder) {
  // A grid whose sides are not multiples of a brick; rays from inside, outside and on cell
  // boundaries, along axes (with -0.0 components), diagonals (exact ties) and at random, with
  // ranges that end inside, on a boundary and past the grid: step_rays4, in AVX2 lanes and one
  // ray at a time, gives each ray's cells in walk_ray<false>'s order, to the ray's end.
  OccupancyMap m(0.5, {-3.0, -2.0, -1.0}, {4.5, 3.5, 2.0});  // 15 x 11 x 6 cells
  const GridView g = grid_view(m);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(-4.0, 5.0), unit(-1.0, 1.0), range(0.0, 12.0);
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> rays;
  const double axis[3] = {-1.0, -0.0, 1.0};
  for (const double ax : axis)
    for (const double ay : axis)
      for (const double az : axis) {
        const Eigen::Vector3d d(ax, ay, az);
        if (d.norm() > 0) rays.push_back({{0.0, 0.5, 0.0}, d.normalized()});  // a cell corner
      }
  for (int i = 0; i < 800; ++i) {
    Eigen::Vector3d o(pos(rng), pos(rng), pos(rng) * 0.5), d(unit(rng), unit(rng), unit(rng));
    if (i % 5 == 0) o = (o * 2.0).array().round() / 2.0;  // a cell corner
    if (i % 7 == 0) d[i % 3] = 0.0;
    if (i % 11 == 0) d = d.array().sign();  // a diagonal
    if (d.norm() < 1e-3) continue;
    rays.push_back({o, d.normalized()});
  }
  std::vector<std::uint64_t> ids(4 * std::size_t(max_ray_cells(g)));
  std::size_t cells = 0;
  int inactive = 0;
  for (std::size_t r0 = 0; r0 < rays.size(); r0 += 4) {
    RayStart starts[4];
    bool active[4];
    std::vector<std::size_t> expect[4];
    for (int l = 0; l < 4; ++l) {
      const std::size_t r = std::min(r0 + std::size_t(l), rays.size() - 1);
      const double t_max = l == 3 ? 100.0 : l == 2 ? std::floor(range(rng)) : range(rng);
      const auto& [o, d] = rays[r];
      active[l] = ray_start(g, ray_origin(g, o), d, t_max, starts[l]);
      walk_ray<false>(g, o, d, t_max, [&](std::size_t idx, const int*, double) {
        expect[l].push_back(idx);
        return true;
      });
      ASSERT_EQ(active[l], !expect[l].empty()) << "ray " << r;
      cells += expect[l].size();
      inactive += !active[l];
    }
    for (const bool simd : {true, false}) {
      int count[4];
      step_rays4(g, starts, active, ids.data(), count, simd);
      for (int l = 0; l < 4; ++l) {
        std::vector<std::size_t> got;
        for (int j = 0; j < count[l]; ++j) got.push_back(std::size_t(ids[4 * j + l]));
        ASSERT_EQ(got, expect[l]) << "ray " << r0 + l << " simd " << simd;
      }
    }
  }
  EXPECT_GT(cells, 2500u);
  EXPECT_GT(inactive, 20);  // rays that miss the grid, and lanes beside them
}

TEST(Navigation, SpheresAndPathsStayInKnownFreeSpace) {
  OccupancyMap m(0.2, {0, 0, 0}, {6, 6, 3});
  // a known free corridor along x at y = 1.5 and one along y at x = 4.5, everything else unknown
  m.mark_free_segment({1, 1.5, 1.5}, {5, 1.5, 1.5}, 1.2);
  m.mark_free_segment({4.5, 1.5, 1.5}, {4.5, 5, 1.5}, 1.2);
  const GridView g = grid_view(m);
  EXPECT_TRUE(sphere_is_free(g, {3, 1.5, 1.5}, 0.6));
  EXPECT_FALSE(sphere_is_free(g, {3, 3.5, 1.5}, 0.6));    // unknown
  EXPECT_FALSE(sphere_is_free(g, {0.1, 1.5, 1.5}, 0.6));  // reaches outside the grid
  EXPECT_FALSE(segment_is_free(g, {2, 1.5, 1.5}, {4.5, 4.5, 1.5}, 0.6));
  const auto path = plan_path(g, {2, 1.5, 1.5}, {4.5, 4.5, 1.5}, 0.6);
  ASSERT_GE(path.size(), 3u);  // around the corner
  for (std::size_t i = 1; i < path.size(); ++i)
    EXPECT_TRUE(segment_is_free(g, path[i - 1], path[i], 0.6));
  EXPECT_GT(path_length(path),
            (Eigen::Vector3d(4.5, 4.5, 1.5) - Eigen::Vector3d(2, 1.5, 1.5)).norm());
  EXPECT_TRUE(plan_path(g, {2, 1.5, 1.5}, {1.5, 4.5, 1.5}, 0.6).empty());  // goal in unknown
}

TEST(Navigation, SphereTestsPassOpenBricksAsTheirCellsWould) {
  // the definition, cell by cell: every cell touching the sphere known and not occupied
  auto brute = [](const GridView& g, const Eigen::Vector3d& c, double radius) {
    const double r = radius / g.resolution;
    const Eigen::Vector3d q = (c - g.origin) / g.resolution;
    const Eigen::Vector3i lo = (q.array() - r).floor().cast<int>();
    const Eigen::Vector3i hi = (q.array() + r).floor().cast<int>();
    if ((lo.array() < 0).any() || hi.x() >= g.nx || hi.y() >= g.ny || hi.z() >= g.nz) return false;
    for (int k = lo.z(); k <= hi.z(); ++k)
      for (int j = lo.y(); j <= hi.y(); ++j)
        for (int i = lo.x(); i <= hi.x(); ++i) {
          const double dx = std::max({i - q.x(), 0.0, q.x() - (i + 1)});
          const double dy = std::max({j - q.y(), 0.0, q.y() - (j + 1)});
          const double dz = std::max({k - q.z(), 0.0, q.z() - (k + 1)});
          if (dx * dx + dy * dy + dz * dz > r * r) continue;
          const std::size_t idx = g.index(i, j, k);
          if (g.cells.flag_at(idx) == CellFlag::Unknown || g.occupied(idx)) return false;
        }
    return true;
  };
  OccupancyMap m(0.2, {0, 0, 0}, {7, 5.4, 3.4});  // 35 x 27 x 17 cells: part bricks at the edges
  m.mark_free_segment({1, 1, 1.7}, {6, 4.4, 1.7}, 1.3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0, 7), uy(0, 5.4), uz(0, 3.4), ur(0, 1.2);
  std::vector<Eigen::Vector3d> hits;  // a few occupied cells inside the free space
  for (int n = 0; n < 12; ++n) hits.emplace_back(ux(rng), uy(rng), uz(rng));
  Points h(Eigen::Index(hits.size()), 3);
  for (std::size_t n = 0; n < hits.size(); ++n) h.row(Eigen::Index(n)) = hits[n];
  m.update_cells(h, true);
  // camera hits in cells the map holds free: with the observations they block the sphere too
  SurfaceObservations seen(m);
  const Points camera_hits = random_points(rng, {7, 5.4, 3.4}, 10);
  seen.add_scan({3.5, 2.7, 1.7}, camera_hits);
  std::set<std::array<int, 3>> hit_cells;
  for (Eigen::Index n = 0; n < camera_hits.rows(); ++n)
    hit_cells.insert({int(std::floor(camera_hits(n, 0) / 0.2)),
                      int(std::floor(camera_hits(n, 1) / 0.2)),
                      int(std::floor(camera_hits(n, 2) / 0.2))});
  const auto near_hit = [&](const Eigen::Vector3d& c, double radius) {
    for (const auto& h : hit_cells) {  // the box distance from the centre to the hit's cell
      double d2 = 0;
      for (int a = 0; a < 3; ++a) {
        const double lo = 0.2 * h[a], d = std::max({lo - c[a], 0.0, c[a] - (lo + 0.2)});
        d2 += d * d;
      }
      if (d2 <= radius * radius) return true;
    }
    return false;
  };
  const GridView g = grid_view(m), observed = grid_view(m, &seen);
  int open = 0, hit_blocked = 0;
  for (int n = 0; n < 20000; ++n) {
    const Eigen::Vector3d c(ux(rng), uy(rng), uz(rng));
    const double r = n % 50 == 0 ? 0.0 : ur(rng);
    const bool expect = brute(g, c, r);
    open += expect;
    ASSERT_EQ(sphere_is_free(g, c, r), expect) << c.transpose() << " r " << r;
    const bool off_hits = expect && !near_hit(c, r);
    hit_blocked += expect && !off_hits;
    ASSERT_EQ(sphere_is_free(observed, c, r), off_hits) << c.transpose() << " r " << r;
  }
  EXPECT_GT(open, 1000);  // both answers are common
  EXPECT_LT(open, 19000);
  EXPECT_GT(hit_blocked, 50);  // free on the map alone, blocked by a camera hit
}

TEST(Exploration, TargetsAndExtentAreTheirDefinitionCellByCell) {
  // the definitions over every cell: unknown, a known free face neighbour and no occupied or
  // predicted one within the box (neighbours outside it count as neither), in C order
  auto solid = [](const GridView& g, std::size_t id) {
    return g.cells.flag_at(id) == CellFlag::Predicted ||
           (g.cells.flag_at(id) != CellFlag::Unknown && g.occupied(id));
  };
  auto brute = [&](const GridView& g, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) {
    std::vector<std::array<int, 6>> out;  // i, j, k and the free sides
    for (int i = lo.x(); i < hi.x(); ++i)
      for (int j = lo.y(); j < hi.y(); ++j)
        for (int k = lo.z(); k < hi.z(); ++k) {
          if (g.cells.flag_at(g.index(i, j, k)) != CellFlag::Unknown) continue;
          std::array<int, 6> t{i, j, k, 0, 0, 0};
          bool near_free = false, near_solid = false;
          for (int a = 0; a < 3; ++a)
            for (int s = -1; s <= 1; s += 2) {
              Eigen::Vector3i c(i, j, k);
              c[a] += s;
              if (c[a] < lo[a] || c[a] >= hi[a]) continue;
              const std::size_t id = g.index(c);
              near_solid |= solid(g, id);
              if (g.cells.flag_at(id) != CellFlag::Unknown && !g.occupied(id)) {
                near_free = true;
                t[3 + a] += s;
              }
            }
          if (near_free && !near_solid) out.push_back(t);
        }
    return out;
  };
  OccupancyMap m(0.2, {0, 0, 0}, {7, 5.4, 3.4});  // 35 x 27 x 17 cells: part bricks at the edges
  std::mt19937 rng(11);
  auto random_points = [&](int n) { return ::random_points(rng, {7, 5.4, 3.4}, n); };
  const GridView empty = grid_view(m);
  Eigen::Vector3i lo, hi;
  EXPECT_FALSE(structure_extent(empty, lo, hi));  // nothing known occupied or predicted
  m.mark_free_segment({1, 1, 1.7}, {6, 4.4, 1.7}, 1.3);
  m.update_cells(random_points(1500), false);
  m.update_cells(random_points(60), true);
  m.set_unknown_cells(random_points(60), 0.6);
  // structure_extent cell by cell: the box of the solid cells grown by one, within the grid
  auto expect_extent = [&](const GridView& v) {
    Eigen::Vector3i elo, ehi, a(v.nx, v.ny, v.nz), b(-1, -1, -1);
    ASSERT_TRUE(structure_extent(v, elo, ehi));
    for (int i = 0; i < v.nx; ++i)
      for (int j = 0; j < v.ny; ++j)
        for (int k = 0; k < v.nz; ++k)
          if (solid(v, v.index(i, j, k))) {
            a = a.cwiseMin(Eigen::Vector3i(i, j, k));
            b = b.cwiseMax(Eigen::Vector3i(i, j, k));
          }
    EXPECT_EQ(elo, (a.array() - 1).max(0).matrix().eval());
    EXPECT_EQ(ehi, (b.array() + 2).min(Eigen::Array3i(v.nx, v.ny, v.nz)).matrix().eval());
  };
  const GridView g = grid_view(m);
  expect_extent(g);
  ASSERT_TRUE(structure_extent(g, lo, hi));
  const std::vector<std::pair<Eigen::Vector3i, Eigen::Vector3i>> boxes = {
      {{0, 0, 0}, {g.nx, g.ny, g.nz}}, {lo, hi}, {{3, 5, 2}, {30, 13, 9}}, {{5, 5, 5}, {5, 9, 9}}};
  std::size_t total = 0;
  for (const auto& [blo, bhi] : boxes) {
    const auto expect = brute(g, blo, bhi);
    const ExplorationTargets t = exploration_targets(g, blo, bhi);
    ASSERT_EQ(std::size_t(t.cells.rows()), expect.size());
    for (std::size_t r = 0; r < expect.size(); ++r)
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(t.cells(Eigen::Index(r), c), expect[r][c]) << r;
        ASSERT_EQ(t.free_sides(Eigen::Index(r), c), expect[r][3 + c]) << r;
      }
    total += expect.size();
  }
  EXPECT_GT(total, 300u);  // the scene has a frontier to find
  // a box beyond the grid is clipped to it: the whole grid's answer
  EXPECT_EQ(exploration_targets(g, {-4, -4, -4}, {99, 99, 99}).cells,
            exploration_targets(g, {0, 0, 0}, {g.nx, g.ny, g.nz}).cells);
  // free space carved in the middle of unknown space, a wall in it: bricks that hold no known
  // free cell border it on every side (their cells on the faces toward it are the frontier)
  OccupancyMap m2(0.2, {0, 0, 0}, {7, 5.4, 3.4});
  m2.mark_free_segment({2.1, 2.3, 1.5}, {4.9, 3.1, 1.9}, 0.9);
  Points wall(40, 3);
  for (int r = 0; r < 40; ++r) wall.row(r) = Eigen::Vector3d(3.5, 1.9 + 0.04 * r, 1.7).transpose();
  m2.update_cells(wall, true);
  const GridView g2 = grid_view(m2);
  ASSERT_EQ(g2.predicted_cells, 0);
  expect_extent(g2);  // the wall's cells grown by one
  for (const auto& [blo, bhi] :
       {std::pair<Eigen::Vector3i, Eigen::Vector3i>{{0, 0, 0}, {g2.nx, g2.ny, g2.nz}},
        {{3, 5, 2}, {30, 13, 9}}}) {
    const auto expect = brute(g2, blo, bhi);
    const ExplorationTargets t = exploration_targets(g2, blo, bhi);
    ASSERT_EQ(std::size_t(t.cells.rows()), expect.size());
    for (std::size_t r = 0; r < expect.size(); ++r)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(t.cells(Eigen::Index(r), c), expect[r][c]) << r;
    EXPECT_GT(expect.size(), 200u);
  }
}

TEST(Exploration, SurfaceTargetsPassOverOnlyBricksWithNoSolidCellNear) {
  // Without a predicted cell, surface_targets looks only at bricks with an occupied cell in
  // them or beside them; it must find every target that looking at every written brick and
  // those beside it finds (the filter of a map that holds predicted cells, forced here by a
  // view that claims one): scattered surface, free space carved round it, the camera's record
  // of some of it, frontier cells on brick faces.
  std::mt19937 rng(23);
  std::size_t total = 0;
  for (int scene = 0; scene < 4; ++scene) {
    OccupancyMap m(0.2, {0, 0, 0}, {7.4, 5.4, 3.4});  // part bricks at the edges
    auto random_points = [&](int n) { return ::random_points(rng, {7.4, 5.4, 3.4}, n); };
    m.mark_free_segment({0.5, 0.5, 1.7}, {6.9, 4.9, 1.7}, 0.6 + 0.3 * scene);
    m.update_cells(random_points(200 + 300 * scene), true);
    m.update_cells(random_points(800), false);
    SurfaceObservations seen(m);
    const Points hits = random_points(300);
    seen.add_scan(Eigen::Vector3d(3.7, 2.7, 1.7), hits);
    const GridView g = grid_view(m, &seen);
    ASSERT_EQ(g.predicted_cells, 0);
    GridView written = g;
    written.predicted_cells = 1;  // the written bricks' filter
    const SurfaceTargetOptions opt;
    const SurfaceTargets a = surface_targets(g, opt), b = surface_targets(written, opt);
    ASSERT_EQ(a.positions, b.positions) << "scene " << scene;
    EXPECT_EQ(a.normals, b.normals);
    EXPECT_EQ(a.kind, b.kind);
    EXPECT_EQ(a.weight, b.weight);
    total += std::size_t(a.kind.rows());
    EXPECT_GT((a.kind.array() == std::int8_t(TargetKind::Frontier)).count(), 0);
  }
  EXPECT_GT(total, 1000u);
}

TEST(Exploration, NearPointsIsTheDistanceBetweenGridCellsByEitherBall) {
  // Brute force: a point's cell against every solid point's cell on the grid of max(within / 4,
  // resolution) spanning both, centre to centre. Fewer points than solid cells (each point's
  // ball) and more (each solid cell's ball).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  const auto random_points = [&](int n) {
    Points p(n, 3);
    for (int r = 0; r < n; ++r)
      for (int a = 0; a < 3; ++a) p(r, a) = u(rng);
    return p;
  };
  bool kept_some = false, dropped_some = false;
  for (const auto& [ns, np] : {std::pair<int, int>{200, 30}, {20, 600}})
    for (const double within : {0.3, 1.0, 2.5}) {
      const double res = 0.2, step = std::max(within / 4.0, res);
      const Points solid = random_points(ns), pts = random_points(np);
      Eigen::Vector3d lo;
      for (int a = 0; a < 3; ++a) lo[a] = std::min(solid.col(a).minCoeff(), pts.col(a).minCoeff());
      const auto cell = [&](const Points& p, int r) {
        return ((p.row(r).transpose() - lo) / step).array().floor().matrix().eval();
      };
      const std::vector<std::uint8_t> keep = near_points(solid, pts, within, res);
      ASSERT_EQ(keep.size(), std::size_t(np));
      int kept = 0;
      for (int r = 0; r < np; ++r) {
        double best = 1e300;
        for (int s = 0; s < ns; ++s)
          best = std::min(best, ((cell(pts, r) - cell(solid, s)) * step).norm());
        EXPECT_EQ(bool(keep[std::size_t(r)]), best <= within)
            << "point " << r << " within " << within;
        kept += keep[std::size_t(r)];
      }
      kept_some = kept_some || kept > 0;
      dropped_some = dropped_some || kept < np;
    }
  EXPECT_TRUE(kept_some && dropped_some);
  EXPECT_EQ(near_points(Points(0, 3), random_points(5), 1.0, 0.2), std::vector<std::uint8_t>(5, 0));
  EXPECT_THROW(near_points(random_points(3), random_points(3), 0.0, 0.2), std::invalid_argument);
}

TEST(SurfaceObservations, NovelHitsAreThoseTheRecordLacks) {
  // A plate of hits at z = 2.03 seen from above, recorded: the same hits are not novel again,
  // nor seen from a little aside (the same side within the cone); seen from below (the other
  // side), in cells never seen, or in a square of a seen cell no hit marked, they are. Hits
  // outside the workspace never are. After any scan is recorded, none of its hits is novel.
  OccupancyMap m(0.2, {0, 0, 0}, {4, 4, 4});
  SurfaceObservations seen(m);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(1.6, 2.4);  // seen along z from above and below
  Points plate(500, 3);
  for (int r = 0; r < 500; ++r) plate.row(r) << u(rng), u(rng), 2.03;
  const Eigen::Vector3d above(2, 2, 3.9), aside(2.4, 1.8, 3.9), below(2, 2, 0.1);
  EXPECT_EQ(seen.novel_hits(above, plate, 75.0), 500u);  // an empty record lacks everything
  seen.add_scan(above, plate);
  EXPECT_EQ(seen.novel_hits(above, plate, 75.0), 0u);
  EXPECT_EQ(seen.novel_hits(aside, plate, 75.0), 0u);
  EXPECT_EQ(seen.novel_hits(below, plate, 75.0), 500u);
  Points beyond = plate;
  beyond.col(2).setConstant(1.03);  // the cells one layer down: never seen
  EXPECT_EQ(seen.novel_hits(above, beyond, 75.0), 500u);
  Points outside = plate;
  outside.col(0).array() += 10.0;
  EXPECT_EQ(seen.novel_hits(above, outside, 75.0), 0u);
  // one cell, one hit in its first quarter on every axis: a hit in the same squares is not
  // novel, one a quarter over along x is (it marks new squares in two projections)
  SurfaceObservations one(m);
  Points a(1, 3), same(1, 3), over(1, 3);
  a << 0.21, 0.21, 0.21;
  same << 0.22, 0.23, 0.24;
  over << 0.27, 0.21, 0.21;
  one.add_scan(above, a);
  EXPECT_EQ(one.novel_hits(above, same, 75.0), 0u);
  EXPECT_EQ(one.novel_hits(above, over, 75.0), 1u);
  for (int scan = 0; scan < 20; ++scan) {
    const Points hits = random_points(rng, {4, 4, 4}, 200);
    const Eigen::Vector3d o = random_points(rng, {4, 4, 4}, 1).row(0).transpose();
    seen.add_scan(o, hits);
    ASSERT_EQ(seen.novel_hits(o, hits, 75.0), 0u) << "scan " << scan;
  }
  Points bad = plate;
  bad(3, 1) = std::nan("");
  EXPECT_THROW(seen.novel_hits(above, bad, 75.0), std::invalid_argument);
}

TEST(Navigation, FastSearchGivesTheReferencePathOnRandomScenes) {
  // Known free tunnels of random radii through unknown space, occupied blobs in them: the fast
  // search must return plan_path_reference's path exactly, reachable or not (and FreeComponent
  // must tell which), for collision
  // radii whose sphere stencil is exact (0.8, 0.35 m) and one on a cell boundary (0.5 m: every
  // cell through sphere_is_free), with the expansion cap biting, and with a path floor (its
  // waypoints between the ends within half a cell of it or above).
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0.5, 15.5), uy(0.5, 7.5), uz(0.5, 4.5), ur(0.6, 1.6);
  int found = 0, unreachable = 0, compared = 0;
  for (int scene = 0; scene < 6; ++scene) {
    OccupancyMap m(0.2, {0, 0, 0}, {16, 8, 5});  // 80 cells along x: two words per row
    std::vector<Eigen::Vector3d> nodes;
    for (int n = 0; n < 7; ++n) nodes.emplace_back(ux(rng), uy(rng), uz(rng));
    for (std::size_t n = 1; n < nodes.size(); ++n)
      if (n % 3 != 0)  // leave some tunnels apart: disconnected free components
        m.mark_free_segment(nodes[n - 1], nodes[n], ur(rng));
    Points blobs(12, 3);
    for (Eigen::Index k = 0; k < blobs.rows(); ++k) blobs.row(k) << ux(rng), uy(rng), uz(rng);
    m.update_cells(blobs, true);
    SurfaceObservations seen(m);  // camera hits beside the tunnels' nodes, in free cells
    Points camera_hits(Eigen::Index(nodes.size()), 3);
    for (std::size_t n = 0; n < nodes.size(); ++n)
      camera_hits.row(Eigen::Index(n)) = (nodes[n] + Eigen::Vector3d(0.5, 0.4, 0.3)).transpose();
    seen.add_scan(nodes[0], camera_hits);
    GridView g = scene % 2 ? grid_view(m, &seen) : grid_view(m);
    if (scene >= 4) g.path_floor = 1.3;
    for (double radius : {0.8, 0.35, 0.5})
      for (std::size_t cap : {std::size_t(200000), std::size_t(300)})
        for (int q = 0; q < 12; ++q) {
          const Eigen::Vector3d a =
              nodes[rng() % nodes.size()] + Eigen::Vector3d(0.05, -0.03, 0.02);
          const Eigen::Vector3d b = nodes[rng() % nodes.size()] + Eigen::Vector3d(-0.04, 0.06, 0.0);
          const auto ref = plan_path_reference(g, a, b, radius, cap);
          const auto fast = plan_path(g, a, b, radius, cap);
          ASSERT_EQ(fast.size(), ref.size()) << "scene " << scene << " radius " << radius;
          for (std::size_t i = 0; i < ref.size(); ++i) EXPECT_EQ(fast[i], ref[i]);
          for (std::size_t i = 1; i + 1 < ref.size(); ++i)
            EXPECT_GE(ref[i].z(), g.path_floor - 0.1 - 1e-9) << "scene " << scene;
          (ref.empty() ? unreachable : found) += 1;
          ++compared;
          if (cap == 200000) {  // the scenes have fewer cells: the cap never bites
            Points t(1, 3);
            t.row(0) = b.transpose();
            EXPECT_EQ(FreeComponent(g, a, radius).contains(g, t)[0] != 0, !ref.empty())
                << "scene " << scene << " radius " << radius;
          }
        }
  }
  EXPECT_EQ(compared, 6 * 3 * 2 * 12);
  EXPECT_GT(found, 40);  // both outcomes are exercised
  EXPECT_GT(unreachable, 40);
}

TEST(Navigation, PathsToOneGoalAreWhatASearchFromEachStartFinds) {
  // Random tunnel scenes as above: plan_paths_to's one search from the goal must reach exactly
  // the starts plan_path reaches, each by a cells' path of plan_path's cost (both are cheapest),
  // and return its path from the start to the goal shortened as plan_path shortens (every
  // segment in sight or one step between neighbouring cells), the straight flight where
  // plan_path takes it.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> ux(0.5, 15.5), uy(0.5, 7.5), uz(0.5, 4.5), ur(0.6, 1.6);
  int found = 0, none = 0, straight = 0;
  for (int scene = 0; scene < 6; ++scene) {
    OccupancyMap m(0.2, {0, 0, 0}, {16, 8, 5});
    std::vector<Eigen::Vector3d> nodes;
    for (int n = 0; n < 7; ++n) nodes.emplace_back(ux(rng), uy(rng), uz(rng));
    for (std::size_t n = 1; n < nodes.size(); ++n)
      if (n % 3 != 0) m.mark_free_segment(nodes[n - 1], nodes[n], ur(rng));
    Points blobs(12, 3);
    for (Eigen::Index k = 0; k < blobs.rows(); ++k) blobs.row(k) << ux(rng), uy(rng), uz(rng);
    m.update_cells(blobs, true);
    GridView g = grid_view(m);
    if (scene == 5) g.path_floor = 1.3;  // (both searches read it)
    for (double radius : {0.8, 0.35, 0.5}) {
      const Eigen::Vector3d goal = nodes[rng() % nodes.size()];
      Points starts(30, 3);  // near the nodes (some blocked cells among them), and anywhere
      for (Eigen::Index q = 0; q < starts.rows(); ++q)
        starts.row(q) =
            q % 3
                ? (nodes[rng() % nodes.size()] + Eigen::Vector3d(ux(rng), uy(rng), uz(rng)) * 0.05)
                      .transpose()
                : Eigen::RowVector3d(ux(rng), uy(rng), uz(rng));
      const PathsToGoal all = plan_paths_to(g, starts, goal, radius);
      ASSERT_EQ(all.paths.size(), 30u);
      EXPECT_FALSE(all.capped);
      for (Eigen::Index q = 0; q < starts.rows(); ++q) {
        const Eigen::Vector3d a = starts.row(q).transpose();
        PathSearchStats one;
        const auto ref = plan_path(g, a, goal, radius, 10000000, &one);
        const auto& p = all.paths[std::size_t(q)];
        ASSERT_EQ(p.empty(), ref.empty()) << "scene " << scene << " radius " << radius;
        if (ref.empty()) {
          ++none;
          continue;
        }
        EXPECT_EQ(p.front(), a);
        EXPECT_EQ(p.back(), goal);
        for (std::size_t i = 1; i < p.size(); ++i)  // in sight, or one step of the cells
          EXPECT_TRUE(segment_is_free(g, p[i - 1], p[i], radius) ||
                      (p[i] - p[i - 1]).norm() <= std::sqrt(3.0) * 0.2 + 1e-9)
              << "segment " << i << " of " << p.size() - 1;
        if (ref.size() == 2) {  // the straight flight
          EXPECT_EQ(p.size(), 2u);
          EXPECT_TRUE(std::isnan(all.cells_cost[std::size_t(q)]));
          ++straight;
        } else {
          EXPECT_NEAR(all.cells_cost[std::size_t(q)], one.cost, 1e-9);
          ++found;
        }
      }
    }
  }
  EXPECT_GT(found, 40);  // all three outcomes are exercised
  EXPECT_GT(none, 40);
  EXPECT_GT(straight, 10);
  // a cap of 3 expanded cells stops the search with starts unreached; the goal out of the grid
  // or blocked reaches none but the straight flights
  OccupancyMap m(0.2, {0, 0, 0}, {12, 12, 4});
  m.mark_free_segment({2, 2, 2}, {10, 2, 2}, 1.2);
  m.mark_free_segment({10, 2, 2}, {10, 10, 2}, 1.2);
  const GridView g = grid_view(m);
  Points corner(2, 3);
  corner << 10, 9.5, 2, 2.6, 2, 2;
  const PathsToGoal cut = plan_paths_to(g, corner, {2.5, 2, 2}, 0.35, 3);
  EXPECT_TRUE(cut.capped);
  EXPECT_EQ(cut.expansions, 3u);
  EXPECT_TRUE(cut.paths[0].empty());
  EXPECT_EQ(cut.paths[1].size(), 2u);  // in sight of the goal
  const PathsToGoal whole = plan_paths_to(g, corner, {2.5, 2, 2}, 0.35);
  EXPECT_FALSE(whole.capped);
  EXPECT_GE(whole.paths[0].size(), 3u);
  EXPECT_TRUE(plan_paths_to(g, corner, {30, 2, 2}, 0.35).paths[0].empty());
  EXPECT_TRUE(plan_paths_to(g, corner, {6, 8, 2}, 0.35).paths[0].empty());  // in unknown space
  corner(1, 0) = std::nan("");
  EXPECT_THROW(plan_paths_to(g, corner, {2.5, 2, 2}, 0.35), std::invalid_argument);
}

TEST(Navigation, SearchesAfterALargeOneFindTheSameWays) {
  // A search from the corners of a wide free hall to a goal behind a wall (a door at its far
  // end) touches more bricks than a thread keeps between searches (it frees the rest): the
  // searches after it find what they found before it.
  OccupancyMap m(0.2, {0, 0, 0}, {48, 48, 3});
  for (double y = 1.5; y <= 47; y += 2) m.mark_free_segment({1.5, y, 1.5}, {46.5, y, 1.5}, 1.4);
  Points wall(int(24 / 0.2) * int(3 / 0.2), 3);
  for (Eigen::Index r = 0; r < wall.rows(); ++r)
    wall.row(r) << 24.1, 0.1 + 0.2 * double(r / 15), 0.1 + 0.2 * double(r % 15);
  m.update_cells(wall, true);
  const GridView g = grid_view(m);
  Points small(2, 3), wide(4, 3);
  small << 2, 2, 1.5, 8, 6, 1.5;
  wide << 2, 2, 1.5, 22, 46, 1.5, 2, 46, 1.5, 22, 2, 1.5;
  const Eigen::Vector3d goal(36, 2, 1.5);
  const PathsToGoal before = plan_paths_to(g, small, goal, 0.5);
  PathSearchStats one_before;
  const auto way_before = plan_path(g, {2, 2, 1.5}, goal, 0.5, 10000000, &one_before);
  const PathsToGoal big = plan_paths_to(g, wide, goal, 0.5);
  EXPECT_GT(big.expansions, 64u * 4096u);  // past the blocks kept: the trim is exercised
  for (const auto& p : big.paths) EXPECT_FALSE(p.empty());
  for (int round = 0; round < 2; ++round) {
    const PathsToGoal after = plan_paths_to(g, small, goal, 0.5);
    PathSearchStats one_after;
    const auto way_after = plan_path(g, {2, 2, 1.5}, goal, 0.5, 10000000, &one_after);
    EXPECT_EQ(after.paths, before.paths);
    EXPECT_EQ(after.expansions, before.expansions);
    EXPECT_EQ(way_after, way_before);
    EXPECT_EQ(one_after.cost, one_before.cost);
    EXPECT_FALSE(way_after.empty());
  }
}

TEST(Navigation, AGoalInAClosedPocketCostsThePocketNotTheWholeFreeSpace) {
  // a large known free hall and, apart from it, a small free pocket: the search from the hall
  // ends when the flood from the pocket closes, long before the hall is exhausted
  OccupancyMap m(0.2, {0, 0, 0}, {16, 8, 5});
  m.mark_free_segment({2.5, 4, 2.5}, {9.5, 4, 2.5}, 2.2);    // the hall
  m.mark_free_segment({13.2, 4, 2.5}, {13.6, 4, 2.5}, 1.2);  // the pocket, 1.3 m of unknown apart
  const GridView g = grid_view(m);
  const Eigen::Vector3d a(3, 4.1, 2.5), b(13.4, 4, 2.5);
  PathSearchStats stats;
  EXPECT_TRUE(plan_path(g, a, b, 0.35, 200000, &stats).empty());
  EXPECT_TRUE(stats.flood_ended);
  EXPECT_FALSE(stats.capped);  // a final failure: no longer search can find a way
  EXPECT_LT(stats.expansions, 1024u + stats.flooded + 30);  // the flood's pace: one per expansion
  EXPECT_TRUE(plan_path_reference(g, a, b, 0.35).empty());
  PathSearchStats whole;  // a goal in the hall: found by the search, the flood not needed
  EXPECT_FALSE(plan_path(g, a, {9.2, 4.2, 2.4}, 0.35, 200000, &whole).empty());
  EXPECT_FALSE(whole.flood_ended);
  EXPECT_FALSE(whole.capped);
  // under a cap of 5 expanded cells the goal in the pocket fails before the flood starts: the
  // search was capped, not final
  PathSearchStats pocket;
  EXPECT_TRUE(plan_path(g, a, b, 0.35, 5, &pocket).empty());
  EXPECT_TRUE(pocket.capped);
  EXPECT_FALSE(pocket.flood_ended);
  // exhausting the hall, as the search alone would, costs several times what the flood took
  int hall = 0;
  for (int k = 0; k < g.nz; ++k)
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < 55; ++i) hall += sphere_is_free(g, g.center(i, j, k), 0.35);
  EXPECT_GT(hall, 3 * int(stats.expansions));
}

TEST(Navigation, OnlyASearchStoppedByItsCapIsNotFinal) {
  // an L-shaped corridor: the goal round its corner takes A* well over 5 expanded cells
  OccupancyMap m(0.2, {0, 0, 0}, {12, 12, 4});
  m.mark_free_segment({2, 2, 2}, {10, 2, 2}, 1.2);
  m.mark_free_segment({10, 2, 2}, {10, 10, 2}, 1.2);
  const GridView g = grid_view(m);
  const Eigen::Vector3d a(2.5, 2, 2), b(10, 9.5, 2);
  PathSearchStats cut, whole, beyond;
  EXPECT_TRUE(plan_path(g, a, b, 0.35, 5, &cut).empty());
  EXPECT_TRUE(cut.capped);
  EXPECT_EQ(cut.expansions, 5u);
  EXPECT_FALSE(plan_path(g, a, b, 0.35, 200000, &whole).empty());
  EXPECT_FALSE(whole.capped);
  EXPECT_GT(whole.expansions, 5u);
  // a goal in unknown space past the corridor's end: no path however long the search
  EXPECT_TRUE(plan_path(g, a, {10, 11.8, 2}, 0.35, 200000, &beyond).empty());
  EXPECT_FALSE(beyond.capped);
}

TEST(Tour, IsAPermutationNoLongerThanNearestNeighbourAndEmptyForNoPoints) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-10, 10);
  Points pts(40, 3);
  for (Eigen::Index i = 0; i < 40; ++i) pts.row(i) << u(rng), u(rng), u(rng);
  const Eigen::Vector3d start(12, 0, 0);
  const Tour nn = solve_tour(pts, start, false), best = solve_tour(pts, start, true);
  std::vector<int> sorted = best.order;
  std::sort(sorted.begin(), sorted.end());
  std::vector<int> all(40);
  std::iota(all.begin(), all.end(), 0);
  EXPECT_EQ(sorted, all);
  EXPECT_LE(best.length, nn.length + 1e-9);
  EXPECT_TRUE(solve_tour(Points(0, 3), start).order.empty());
  EXPECT_EQ(solve_tour(Points(0, 3), start).length, 0.0);
}

namespace {

ViewCoverage coverage(const std::vector<std::vector<std::int32_t>>& sets) {
  ViewCoverage c;
  c.offsets.resize(Eigen::Index(sets.size() + 1));
  c.offsets[0] = 0;
  std::vector<std::int32_t> el;
  for (std::size_t k = 0; k < sets.size(); ++k) {
    el.insert(el.end(), sets[k].begin(), sets[k].end());
    c.offsets[Eigen::Index(k + 1)] = std::int64_t(el.size());
  }
  c.elements = Eigen::Map<Eigen::Matrix<std::int32_t, Eigen::Dynamic, 1>>(el.data(),
                                                                          Eigen::Index(el.size()));
  c.weights = Eigen::VectorXf::Ones(Eigen::Index(el.size()));
  c.status = Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1>::Zero(Eigen::Index(sets.size()));
  return c;
}

}  // namespace

TEST(Cover, GreedyAndPrizeCollectingInsertion) {
  // views along x: 0 at 1 m covers {1,2,3}, 1 at 2 m {3,4}, 2 at 50 m {5,6,7,8}
  const ViewCoverage cov = coverage({{1, 2, 3}, {3, 4}, {5, 6, 7, 8}});
  const CoverSelection g = select_cover(cov, 0.5, 10);
  EXPECT_EQ(g.views, (std::vector<int>{2, 0, 1}));
  EXPECT_EQ(g.gains, (std::vector<double>{4, 3, 1}));
  Points pos(3, 3);
  pos << 1, 0, 0, 2, 0, 0, 50, 0, 0;
  // 0.05 per metre: the far view pays (4 - 0.05 * 48 > 0); 0.2 per metre: it does not
  const CoverSelection cheap = select_tour(cov, pos, Eigen::Vector3d::Zero(), 0.05, 0.5, 10);
  EXPECT_EQ(cheap.views, (std::vector<int>{0, 1, 2}));  // in tour order
  const CoverSelection dear = select_tour(cov, pos, Eigen::Vector3d::Zero(), 0.2, 0.5, 10);
  EXPECT_EQ(dear.views, (std::vector<int>{0, 1}));
  EXPECT_EQ(dear.gains, (std::vector<double>{3, 1}));
  EXPECT_THROW(select_tour(cov, Points(2, 3), Eigen::Vector3d::Zero(), 0.1, 0.5, 10),
               std::invalid_argument);
  // the first view's transit free: the far view (the best gain) enters first, the near ones on
  // the way to it at no extra length; judging the transit is left to the caller
  const CoverSelection free = select_tour(cov, pos, Eigen::Vector3d::Zero(), 0.2, 0.5, 10, false);
  EXPECT_EQ(free.views, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(free.gains, (std::vector<double>{3, 1, 4}));
}

TEST(Cover, AFarClusterFormsOnlyWithoutChargingItsTransit) {
  // five views 1 m apart, 50 m away, 6 new elements each: none pays 0.45 x 50 m alone
  const ViewCoverage cov = coverage({{0, 1, 2, 3, 4, 5},
                                     {6, 7, 8, 9, 10, 11},
                                     {12, 13, 14, 15, 16, 17},
                                     {18, 19, 20, 21, 22, 23},
                                     {24, 25, 26, 27, 28, 29}});
  Points pos(5, 3);
  for (int i = 0; i < 5; ++i) pos.row(i) << 50.0 + i, 0, 0;
  EXPECT_TRUE(select_tour(cov, pos, Eigen::Vector3d::Zero(), 0.45, 0.5, 10).views.empty());
  const CoverSelection all = select_tour(cov, pos, Eigen::Vector3d::Zero(), 0.45, 0.5, 10, false);
  EXPECT_EQ(all.views, (std::vector<int>{0, 1, 2, 3, 4}));
}

TEST(TourPlan, TheFarClusterIsFlownWhenItPaysAsAWholeAndReportedUnpaidWhenNot) {
  // five views 1 m apart, 50 m away: 6 (then 4) m^2 each, against 0.45 m^2 a metre
  for (const int n : {6, 4}) {
    std::vector<std::vector<std::int32_t>> sets;
    for (int v = 0; v < 5; ++v) {
      sets.emplace_back();
      for (int e = 0; e < n; ++e) sets.back().push_back(v * n + e);
    }
    const ViewCoverage cov = coverage(sets);
    Points pos(5, 3);
    for (int i = 0; i < 5; ++i) pos.row(i) << 50.0 + i, 0, 0;
    TourPlanOptions o;
    o.rate = 0.45;
    o.min_gain = 1.2;
    const TourPlan plan = plan_tour(cov, pos, Eigen::Vector3d::Zero(), o);
    if (n == 6) {  // 30 m^2 for 54 m: the free-transit tour, worth 30 - 0.45 x 54
      EXPECT_EQ(plan.flight(), (std::vector<int>{0, 1, 2, 3, 4}));
      EXPECT_NEAR(plan.length, 54.0, 1e-12);
      EXPECT_NEAR(plan.value, 30.0 - 0.45 * 54.0, 1e-12);
      EXPECT_EQ(plan.unpaid, 0);
    } else {  // 20 m^2 for 54 m: no view is kept; the five views adding 4 m^2 were unpaid
      EXPECT_TRUE(plan.order.empty());
      EXPECT_EQ(plan.value, 0.0);
      EXPECT_EQ(plan.unpaid, 5);
      EXPECT_EQ(plan.unpaid_area, 20.0);
    }
  }
}

TEST(TourPlan, PrizeCollectionDropsTheDetourThatDoesNotPayAndRejectsBadInput) {
  Points pts(4, 3);
  pts << 1, 0, 0, 2, 0, 0, 2, 10, 0, 3, 0, 0;  // view 2: a 20 m detour for 3 m^2
  const std::vector<double> gains{5, 5, 3, 5};
  const Eigen::Vector3d start = Eigen::Vector3d::Zero();
  EXPECT_EQ(prize_collect(start, pts, gains, {0, 1, 2, 3}, 1.0), (std::vector<int>{0, 1, 3}));
  EXPECT_EQ(prize_collect(start, pts, gains, {0, 1, 2, 3}, 0.1), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_THROW(prize_collect(start, pts, {1, 2}, {0, 1}, 1.0), std::invalid_argument);
  EXPECT_THROW(prize_collect(start, pts, gains, {0, 4}, 1.0), std::invalid_argument);
  TourPlanOptions bad;
  bad.cell_area = 0.0;
  const ViewCoverage cov = coverage({{1}, {2}, {3}, {4}});
  EXPECT_THROW(plan_tour(cov, pts, start, bad), std::invalid_argument);
  EXPECT_THROW(plan_tour(cov, Points(3, 3), start, TourPlanOptions{}), std::invalid_argument);
}

namespace {

// select_tour as first written: every candidate's insertion cost into the whole tour at every
// step, candidates in index order. The pruned, ordered search must choose exactly the same.
CoverSelection reference_select_tour(const ViewCoverage& cov, const Points& pos,
                                     const Eigen::Vector3d& start, double rate, double min_gain,
                                     int max_views, bool charge_transit) {
  const Eigen::Index K = cov.offsets.size() - 1;
  std::vector<double> gain(std::size_t(K), 0.0);
  std::map<std::int64_t, std::vector<std::pair<std::int64_t, Eigen::Index>>> holders;
  for (Eigen::Index k = 0; k < K; ++k) {
    if (cov.status[k] != 0) continue;
    for (std::int64_t o = cov.offsets[k]; o < cov.offsets[k + 1]; ++o) {
      holders[cov.elements[o]].push_back({o, k});
      gain[std::size_t(k)] += cov.weights[o];
    }
  }
  std::map<std::int64_t, float> covered;
  std::vector<Eigen::Vector3d> stops{start};
  std::vector<int> ids{-1}, inserted;
  std::vector<char> taken(std::size_t(K), 0);
  std::vector<double> gains;
  while (int(inserted.size()) < max_views) {
    const std::size_t n = stops.size();
    int best = -1;
    double best_value = 0.0;
    std::size_t best_at = 0;
    for (Eigen::Index k = 0; k < K; ++k) {
      if (cov.status[k] != 0 || taken[std::size_t(k)] || gain[std::size_t(k)] < min_gain) continue;
      const Eigen::Vector3d q = pos.row(k).transpose();
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
      const double value = gain[std::size_t(k)] - rate * cost;
      if (value > best_value) {
        best_value = value;
        best = int(k);
        best_at = at;
      }
    }
    if (best < 0) break;
    stops.insert(stops.begin() + std::ptrdiff_t(best_at), Eigen::Vector3d(pos.row(best)));
    ids.insert(ids.begin() + std::ptrdiff_t(best_at), best);
    taken[std::size_t(best)] = 1;
    inserted.push_back(best);
    gains.push_back(gain[std::size_t(best)]);
    for (std::int64_t o = cov.offsets[best]; o < cov.offsets[best + 1]; ++o) {
      float& have = covered[cov.elements[o]];
      const float now = std::max(have, cov.weights[o]);
      for (const auto& [oo, holder] : holders[cov.elements[o]]) {
        const float w = cov.weights[oo];
        gain[std::size_t(holder)] -= std::max(0.0f, w - have) - std::max(0.0f, w - now);
      }
      have = now;
    }
  }
  CoverSelection out;
  std::map<int, double> gain_of;
  for (std::size_t i = 0; i < inserted.size(); ++i) gain_of[inserted[i]] = gains[i];
  for (std::size_t i = 1; i < ids.size(); ++i) {
    out.views.push_back(ids[i]);
    out.gains.push_back(gain_of[ids[i]]);
  }
  return out;
}

}  // namespace

TEST(Cover, PrizeCollectingInsertionChoosesAsTheExhaustiveSearch) {
  // random scenes, some on an integer lattice with equal weights (ties in gain, in insertion
  // cost and in value), some with invalid candidates; the views, their order and gains agree
  std::mt19937 rng(11);
  for (int scene = 0; scene < 600; ++scene) {
    const int K = 1 + int(rng() % 60), E = 1 + int(rng() % 80);
    const bool lattice = scene % 2 == 0;
    std::uniform_real_distribution<double> coord(-20.0, 20.0), weight(0.05, 1.0);
    std::vector<std::vector<std::int32_t>> sets(static_cast<std::size_t>(K));
    for (auto& set : sets) {
      const int m = int(rng() % 12);
      for (int i = 0; i < m; ++i) set.push_back(std::int32_t(rng() % std::uint32_t(E)));
      std::sort(set.begin(), set.end());
      set.erase(std::unique(set.begin(), set.end()), set.end());
    }
    ViewCoverage cov = coverage(sets);
    for (Eigen::Index i = 0; i < cov.weights.size(); ++i)
      cov.weights[i] = lattice ? 1.0f : float(weight(rng));
    for (Eigen::Index k = 0; k < K; ++k)
      if (rng() % 10 == 0) cov.status[k] = 2;
    Points pos(K, 3);
    for (Eigen::Index k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a) pos(k, a) = lattice ? double(int(rng() % 3)) : coord(rng);
    const Eigen::Vector3d start = lattice ? Eigen::Vector3d(2, 2, 0) : Eigen::Vector3d(0, 0, 0);
    const double rate = lattice ? 0.25 * double(rng() % 4) : 0.3 * weight(rng);
    const double min_gain = double(rng() % 3);
    for (const bool charge : {true, false}) {
      const CoverSelection a = select_tour(cov, pos, start, rate, min_gain, 1000, charge);
      const CoverSelection b = reference_select_tour(cov, pos, start, rate, min_gain, 1000, charge);
      ASSERT_EQ(a.views, b.views) << "scene " << scene << " charge " << charge;
      ASSERT_EQ(a.gains, b.gains) << "scene " << scene << " charge " << charge;
    }
  }
}

TEST(Cover, PrizeCollectingInsertionOverManyWideElementsChoosesAsTheExhaustiveSearch) {
  // elements spread over 2^30 values and 10^5 memberships: too sparse a range for the ranks'
  // bitmap, so they are ranked by the sorted distinct elements; ranked densely instead (the same
  // elements, one apart, below zero), the bitmap ranks them, and the choice is the same
  std::mt19937 rng(5);
  std::vector<std::int32_t> pool(4000);
  for (auto& e : pool) e = std::int32_t(rng() % (std::uint32_t(1) << 30));
  const int K = 400;
  std::vector<std::vector<std::int32_t>> sets(K);
  for (auto& set : sets) {
    for (int i = 0; i < 250; ++i) set.push_back(pool[rng() % pool.size()]);
    std::sort(set.begin(), set.end());
    set.erase(std::unique(set.begin(), set.end()), set.end());
  }
  ViewCoverage cov = coverage(sets);
  std::uniform_real_distribution<double> coord(-30.0, 30.0), weight(0.05, 1.0);
  for (Eigen::Index i = 0; i < cov.weights.size(); ++i) cov.weights[i] = float(weight(rng));
  ASSERT_GT(cov.elements.size(), 90000);
  Points pos(K, 3);
  for (Eigen::Index k = 0; k < K; ++k)
    for (int a = 0; a < 3; ++a) pos(k, a) = coord(rng);
  const Eigen::Vector3d start(0, 0, 0);
  for (const bool charge : {true, false}) {
    const CoverSelection a = select_tour(cov, pos, start, 0.5, 5.0, 1000, charge);
    const CoverSelection b = reference_select_tour(cov, pos, start, 0.5, 5.0, 1000, charge);
    ASSERT_GT(a.views.size(), 10u);
    ASSERT_EQ(a.views, b.views) << "charge " << charge;
    ASSERT_EQ(a.gains, b.gains) << "charge " << charge;
    ViewCoverage dense = cov;
    std::vector<std::int32_t> sorted(pool);
    std::sort(sorted.begin(), sorted.end());
    for (Eigen::Index i = 0; i < dense.elements.size(); ++i)
      dense.elements[i] = std::int32_t(
          std::lower_bound(sorted.begin(), sorted.end(), cov.elements[i]) - sorted.begin() - 9000);
    const CoverSelection c = select_tour(dense, pos, start, 0.5, 5.0, 1000, charge);
    ASSERT_EQ(a.views, c.views) << "charge " << charge;
    ASSERT_EQ(a.gains, c.gains) << "charge " << charge;
    ViewCoverage extreme = cov;  // the widest range an element can span
    extreme.elements[0] = std::numeric_limits<std::int32_t>::min();
    extreme.elements[extreme.elements.size() - 1] = std::numeric_limits<std::int32_t>::max();
    const CoverSelection d = select_tour(extreme, pos, start, 0.5, 5.0, 1000, charge);
    const CoverSelection e = reference_select_tour(extreme, pos, start, 0.5, 5.0, 1000, charge);
    ASSERT_EQ(d.views, e.views) << "charge " << charge;
    ASSERT_EQ(d.gains, e.gains) << "charge " << charge;
  }
}

TEST(HugeVector, LargeBuffersAreHugePageAlignedAndHoldTheirValues) {
  // past the threshold: 2 MiB aligned (what madvise needs); below it: an ordinary allocation
  HugeVector<std::uint64_t> big(HugePageAllocator<std::uint64_t>::kMin / 8 + 12345);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % HugePageAllocator<char>::kHuge, 0u);
  std::iota(big.begin(), big.end(), std::uint64_t(7));
  big.push_back(1);  // reallocation copies into a new huge buffer
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % HugePageAllocator<char>::kHuge, 0u);
  for (std::size_t i = 0; i + 1 < big.size(); ++i) ASSERT_EQ(big[i], i + 7);
  HugeVector<int> small(100, 3);
  EXPECT_EQ(std::accumulate(small.begin(), small.end(), 0), 300);
}

TEST(GrowArray, GrowsInPlaceAcrossTheMappingThresholdAndKeepsItsValues) {
  GrowArray<std::uint32_t> a;
  for (std::uint32_t i = 0; i < (3u << 20); ++i) a.push_back(i * 3);  // heap, then a mapping
  ASSERT_EQ(a.size(), std::size_t(3) << 20);
  EXPECT_GE(a.capacity(), a.size());
  for (std::size_t i = 0; i < a.size(); i += 997) ASSERT_EQ(a[i], i * 3);
  EXPECT_EQ(a.back(), ((3u << 20) - 1) * 3);
  GrowArray<std::uint32_t> b = a;  // a copy of its own
  b[5] = 1;
  EXPECT_EQ(a[5], 15u);
  a.resize(10);  // shrinking keeps the first elements; growing again zeroes the new ones
  a.shrink_to_fit();
  EXPECT_EQ(a.size(), 10u);
  EXPECT_EQ(a[9], 27u);
  a.resize(2000000);
  EXPECT_EQ(a[9], 27u);
  EXPECT_EQ(a[10], 0u);
  EXPECT_EQ(a[1999999], 0u);
  GrowArray<std::uint32_t> c = std::move(b);
  EXPECT_EQ(c.size(), std::size_t(3) << 20);
  EXPECT_EQ(c[5], 1u);
  EXPECT_TRUE(b.empty());  // NOLINT: moved-from is empty
  c.assign(a.begin(), a.begin() + 12);
  EXPECT_EQ(c.size(), 12u);
  EXPECT_EQ(c[11], 0u);
  EXPECT_EQ(c[9], 27u);
  c.clear();
  c.shrink_to_fit();
  EXPECT_EQ(c.capacity(), 0u);
}

TEST(ReleasableArray, ReadsZeroAfterReleaseAndMoves) {
  ReleasableArray<std::uint32_t> a(3 << 20);  // 12 MiB: many pages
  ASSERT_TRUE(a);
  EXPECT_EQ(a[0], 0u);
  EXPECT_EQ(a[a.size() - 1], 0u);
  for (std::size_t i = 0; i < a.size(); i += 1000) a[i] = std::uint32_t(i + 1);
  for (std::size_t i = 0; i < a.size(); i += 1000) ASSERT_EQ(a[i], i + 1);
  // resident pages (mincore): those written, and none once released
  const auto resident = [](const ReleasableArray<std::uint32_t>& x) {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    std::vector<unsigned char> in((x.size() * 4 + page - 1) / page);
    EXPECT_EQ(mincore(x.data(), x.size() * 4, in.data()), 0);
    return std::count_if(in.begin(), in.end(), [](unsigned char c) { return c & 1; });
  };
  EXPECT_GE(resident(a), 3000);  // 12 MiB written every 4 KB: every 4 KiB page
  ReleasableArray<std::uint32_t> b(std::move(a));
  EXPECT_FALSE(a);
  EXPECT_EQ(b[1000], 1001u);
  b.release();
  EXPECT_EQ(resident(b), 0);
  for (std::size_t i = 0; i < b.size(); i += 1000) ASSERT_EQ(b[i], 0u);
  b[5] = 9;
  a = std::move(b);
  EXPECT_EQ(a[5], 9u);
  EXPECT_EQ(a.size(), std::size_t(3) << 20);
  EXPECT_FALSE(ReleasableArray<int>(0));
}

// Candidate views around (5, 4, 3) m in a 12 x 8 x 6 m map, and the options the view tests
// share (every valid view scored, paths planned).
struct ViewScene {
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> cand;
  ViewCameraModel camera;
  UtilityOptions utility;
  ValidityOptions validity;
  ViewScene(std::mt19937& rng, Eigen::Index n) : cand(n, 4) {
    std::uniform_real_distribution<double> u(-1, 1);
    for (Eigen::Index k = 0; k < n; ++k)
      cand.row(k) << 5 + 2 * u(rng), 4 + 0.5 * u(rng), 3 + 0.5 * u(rng), 3 * u(rng);
    utility.require_occupied = false;
    validity.collision_radius = 0.3;
    validity.blocked_path = "plan";
  }
};

TEST(Views, TheMemoOfWalksScoresAsWalkingAgain) {
  OccupancyMap m(0.2, {0, 0, 0}, {12, 8, 6});
  m.mark_free_segment({2, 4, 3}, {8, 4, 3}, 1.5);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(0, 12), uy(0, 8), uz(0, 6);
  ViewScene v(rng, 10);
  v.utility.require_occupied_probability = 0.6;
  const auto& [cand, camera, utility, validity] = v;
  ViewMemo memo;
  for (int round = 0; round < 12; ++round) {
    Points p(20, 3);  // hits and misses scattered over the workspace
    for (Eigen::Index r = 0; r < p.rows(); ++r) p.row(r) << ux(rng), uy(rng), uz(rng);
    for (int n = 0; n <= round % 3; ++n) m.update_cells(p, round % 4 != 0);
    const GridView g = grid_view(m);
    const ViewScores a = evaluate_views(g, cand, {5, 4, 3, 0}, camera, utility, validity, &memo);
    const ViewScores b = evaluate_views(g, cand, {5, 4, 3, 0}, camera, utility, validity);
    EXPECT_EQ(a.gain, b.gain);  // bit for bit
    EXPECT_EQ(a.utility, b.utility);
    EXPECT_EQ(a.cells, b.cells);
    EXPECT_EQ(a.occupied_seen, b.occupied_seen);
    EXPECT_EQ(a.status, b.status);
  }
  EXPECT_GT(memo.stats().reused, 0);
  EXPECT_GT(memo.stats().stale, 0);
  EXPECT_EQ(memo.entries(), std::size_t(cand.rows()));
  EXPECT_THROW(ViewMemo(0), std::invalid_argument);
}

// The paper's information gain as walk_ray walks it: each view's rays in order, each to its
// first occupied cell, the entropies of the distinct nonzero cells summed in the order the
// rays first reach them.
double gain_in_walk_order(const GridView& g, const Eigen::Vector4d& view,
                          const ViewCameraModel& camera, int& cells) {
  const Points dirs = camera.directions();
  const Eigen::Isometry3d T =
      pose_to_transform({view[0], view[1], view[2], view[3]}) * camera.mount;
  std::vector<bool> seen(g.storage_size(), false);
  double sum = 0.0;
  cells = 0;
  for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
    const Eigen::Vector3d ds = dirs.row(r).transpose();
    walk_ray<false>(g, T.translation(), T.linear() * ds, camera.max_range / ds.x(),
                    [&](std::size_t idx, const int*, double) {
                      const float s = g.cells.scored_at(idx);
                      if (!seen[idx] && s != 0.0f) {
                        sum += std::fabs(s);
                        ++cells;
                      }
                      seen[idx] = true;
                      return !std::signbit(s);
                    });
  }
  return sum;
}

TEST(Views, TheInformationGainIsTheSumInTheWalksOrderBitForBit) {
  // Views scored four rays at a time, their marks summed in the set's order, give the sum in
  // the walk's order to the last bit: on a map of the usual entropies (the sum is exact in any
  // order) and on one whose free cells fall far below 2^-8 nats (walked again in order).
  for (const bool tiny : {false, true}) {
    OccupancyMapOptions o;
    if (tiny) {  // free cells of about 3e-11 nats: a sum's order shows in its last bits
      o.prob_miss = 0.05;
      o.clamp_min = 1e-12;
      o.clamped_entropy_zero = false;
    }
    OccupancyMap m(0.2, {0, 0, 0}, {12, 8, 6}, o);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> ux(0, 12), uy(0, 8), uz(0, 6), u(-1, 1);
    m.mark_free_segment({2, 4, 3}, {8, 4, 3}, 1.5);
    Points hits(60, 3), misses(400, 3);
    for (Eigen::Index r = 0; r < hits.rows(); ++r) hits.row(r) << ux(rng), uy(rng), uz(rng);
    for (Eigen::Index r = 0; r < misses.rows(); ++r)
      misses.row(r) << 2 + 6 * (u(rng) + 1) / 2, 4 + u(rng), 3 + u(rng);
    for (int n = 0; n < 2; ++n) m.update_cells(hits, true);
    for (int n = 0; n < 30; ++n) m.update_cells(misses, false);
    const GridView g = grid_view(m);
    int below = 0;  // cells of nonzero entropy below 2^-8
    for (std::size_t i = 0; i < g.storage_size(); ++i)
      below += g.cells.scored_at(i) != 0.0f && std::fabs(g.cells.scored_at(i)) < 0.00390625f;
    EXPECT_EQ(below > 0, tiny);
    const ViewScene v(rng, 12);
    const auto& [cand, camera, utility, validity] = v;
    ViewMemo memo;
    for (ViewMemo* with : {static_cast<ViewMemo*>(nullptr), &memo}) {
      const ViewScores a = evaluate_views(g, cand, {5, 4, 3, 0}, camera, utility, validity, with);
      int valid = 0;
      for (Eigen::Index k = 0; k < cand.rows(); ++k) {
        if (a.status[k] != 0) continue;
        ++valid;
        int cells = 0;
        const double expect = gain_in_walk_order(g, cand.row(k).transpose(), camera, cells);
        EXPECT_EQ(a.gain[k], expect) << "view " << k << " tiny " << tiny;  // bit for bit
        EXPECT_EQ(a.cells[k], cells) << "view " << k << " tiny " << tiny;
      }
      EXPECT_GE(valid, 8);
    }
  }
}

TEST(Views, MarkedCellsSumInLanesAsOneAtATime) {
  // sum_marked in AVX2 lanes and one cell at a time: the same gain, count and verdict, on words
  // of random cells and entropies (neutral bricks skipped), and false for an entropy below 2^-8
  OccupancyMap m(0.2, {0, 0, 0}, {6, 6, 4});
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> ux(0, 6), uy(0, 6), uz(0, 4);
  Points p(300, 3);
  for (Eigen::Index r = 0; r < p.rows(); ++r) p.row(r) << ux(rng), uy(rng), uz(rng);
  m.update_cells(p, true);
  m.update_cells(p.topRows(150), false);
  m.mark_free_segment({1, 1, 2}, {5, 5, 2}, 1.0);
  const GridView g = grid_view(m);
  const std::size_t words = g.storage_size() / 64;
  std::vector<std::uint64_t> bits(words + 1, 0);
  std::vector<std::uint32_t> listed;
  for (std::size_t w = 0; w < words; w += 1 + rng() % 3) {
    bits[w] = (std::uint64_t(rng()) << 32 | rng()) & (std::uint64_t(rng()) << 32 | rng());
    if (bits[w]) listed.push_back(std::uint32_t(w));
  }
  double gain[2];
  int cells[2];
  bool exact[2];
  for (const bool simd : {true, false})
    exact[simd] =
        sum_marked(g, listed.data(), listed.size(), bits.data(), gain[simd], cells[simd], simd);
  EXPECT_TRUE(exact[0] && exact[1]);
  EXPECT_EQ(gain[0], gain[1]);
  EXPECT_EQ(cells[0], cells[1]);
  EXPECT_GT(cells[0], 1000);
  // one tiny entropy among them: neither sum is taken
  OccupancyMapOptions o;
  o.clamp_min = 1e-5;
  o.clamped_entropy_zero = false;
  OccupancyMap t(0.2, {0, 0, 0}, {6, 6, 4}, o);
  for (int n = 0; n < 30; ++n) t.update_cells(p.topRows(1), false);
  const GridView h = grid_view(t);
  std::vector<std::uint64_t> all(h.storage_size() / 64 + 1, ~std::uint64_t(0));
  std::vector<std::uint32_t> every(h.storage_size() / 64);
  std::iota(every.begin(), every.end(), 0u);
  for (const bool simd : {true, false})
    EXPECT_FALSE(sum_marked(h, every.data(), every.size(), all.data(), gain[0], cells[0], simd));
}

TEST(Views, OptionsRejectBadValuesWithTheirName) {
  UtilityOptions u;
  u.name = "nope";
  EXPECT_THROW(u.validate(), std::invalid_argument);
  u.name = "surface";
  u.frontier_prior = 1.5;
  try {
    u.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frontier_prior"), std::string::npos);
  }
  ValidityOptions v;
  v.blocked_path = "teleport";
  EXPECT_THROW(v.validate(), std::invalid_argument);
  ViewCameraModel c;
  c.rays_x = 0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  EXPECT_EQ(view_status_names().size(), 5u);
  const auto names = utility_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "ig"), names.end());
}

TEST(Views, DirectionBinsAreTheCubesDirectionsAndConesAreSymmetric) {
  for (int b = 0; b < 26; ++b) {
    EXPECT_EQ(direction_bin(bin_direction(b)), b);
    EXPECT_TRUE(bin_cone(b, 0.0) & (1u << b));
    for (int c = 0; c < 26; ++c)
      EXPECT_EQ(bool(bin_cone(b, 75.0) & (1u << c)), bool(bin_cone(c, 75.0) & (1u << b)));
  }
  EXPECT_EQ(bin_cone(0, 180.0), (1u << 26) - 1);
}
