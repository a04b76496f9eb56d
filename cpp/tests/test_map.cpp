// Edge cases of the occupancy map: key arithmetic, ray traversal, workspace bookkeeping, and the
// fast integration path against OctoMap's own code.
#include "nbv/occupancy_map.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <set>
#include <vector>

using nbv::CellFlag;
using nbv::CellState;
using nbv::OccupancyMap;
using nbv::OccupancyMapOptions;
using nbv::Points;
using Key = OccupancyMap::Key;

namespace {

Points rows(std::initializer_list<std::array<double, 3>> pts) {
  Points p(Eigen::Index(pts.size()), 3);
  Eigen::Index r = 0;
  for (const auto& a : pts) p.row(r++) << a[0], a[1], a[2];
  return p;
}

const Points kNone(0, 3);

std::vector<Key> octomap_ray(const octomap::OcTree& t, const octomap::point3d& a,
                             const octomap::point3d& b) {
  octomap::KeyRay ray;
  EXPECT_TRUE(t.computeRayKeys(a, b, ray));
  return std::vector<Key>(ray.begin(), ray.end());
}

std::vector<Key> our_ray(const octomap::OcTree& t, const octomap::point3d& a,
                         const octomap::point3d& b) {
  std::vector<Key> out;
  EXPECT_TRUE(OccupancyMap::walk_ray_keys(t, a, b, [&](const Key& k) { out.push_back(k); }));
  return out;
}

}  // namespace

TEST(MapKeys, NegativeCoordinatesFollowOctomapFloat32Rule) {
  OccupancyMap m(0.2, {-2, -2, -2}, {2, 2, 2});
  Key k;
  ASSERT_TRUE(m.coord_to_key({-0.1, 0.1, -0.3}, k));
  EXPECT_EQ(k, Key(32767, 32768, 32766));
  // float(-0.2) is slightly below -0.2: OctoMap files it one cell lower than floor(-0.2 / 0.2)
  ASSERT_TRUE(m.coord_to_key({-0.2, 0.2, 0.0}, k));
  EXPECT_EQ(k, m.octree().coordToKey(octomap::point3d(-0.2f, 0.2f, 0.0f)));
  EXPECT_EQ(int(k[0]), 32768 - 2);
  EXPECT_EQ(int(k[1]), 32768 + 1);
  // random points: identical to OctoMap's coordToKey of the float point
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-30.0, 30.0);
  for (int i = 0; i < 10000; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    ASSERT_TRUE(m.coord_to_key(p, k));
    EXPECT_EQ(k, m.octree().coordToKey(octomap::point3d(float(p.x()), float(p.y()), float(p.z()))));
  }
  EXPECT_FALSE(m.coord_to_key({1e6, 0, 0}, k));  // beyond +-32768 cells
  const Eigen::Vector3d c = m.key_to_coord(Key(32767, 32768, 32766));
  EXPECT_NEAR(c.x(), -0.1, 1e-12);
  EXPECT_NEAR(c.y(), 0.1, 1e-12);
  EXPECT_NEAR(c.z(), -0.3, 1e-12);
}

TEST(MapKeys, WorkspaceIndexAtBoundsEdges) {
  OccupancyMap m(0.2, {-1, -2, 0}, {1, 2, 0.6});
  EXPECT_EQ(m.dims()[0], 10);
  EXPECT_EQ(m.dims()[1], 20);
  EXPECT_EQ(m.dims()[2], 3);
  EXPECT_EQ(m.num_cells(), 600);
  const Key lo = m.min_key();
  EXPECT_EQ(lo, Key(32768 - 5, 32768 - 10, 32768));
  EXPECT_EQ(m.index_of(lo), 0);
  const Key hi(lo[0] + 9, lo[1] + 19, lo[2] + 2);
  EXPECT_EQ(m.index_of(hi), std::int64_t(m.grid().layout().id(9, 19, 2)));
  for (int a = 0; a < 3; ++a) {
    Key below = lo, above = hi;
    below[a] -= 1;
    above[a] += 1;
    EXPECT_FALSE(m.in_workspace(below));
    EXPECT_EQ(m.index_of(below), -1);
    EXPECT_FALSE(m.in_workspace(above));
  }
  // every cell has its own id, and key_at inverts index_of
  std::set<std::int64_t> ids;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 10; ++i) {
        const Key key(lo[0] + i, lo[1] + j, lo[2] + k);
        const std::int64_t id = m.index_of(key);
        ASSERT_GE(id, 0);
        ASSERT_LT(std::size_t(id), m.grid().layout().storage_size());
        ASSERT_EQ(m.key_at(id), key);
        ids.insert(id);
      }
  EXPECT_EQ(ids.size(), 600u);
  // bricks of 4 x 4 x 4, x fastest: neighbours along x within a brick are adjacent ids
  EXPECT_EQ(m.index_of(Key(lo[0] + 1, lo[1], lo[2])), 1);
  EXPECT_EQ(m.index_of(Key(lo[0], lo[1] + 1, lo[2])), 4);
  EXPECT_EQ(m.index_of(Key(lo[0], lo[1], lo[2] + 1)), 16);
  EXPECT_EQ(m.index_of(Key(lo[0] + 4, lo[1], lo[2])), 64);
  EXPECT_NEAR(m.bounds_min().x(), -1.0, 1e-12);
  EXPECT_NEAR(m.bounds_max().z(), 0.6, 1e-12);
}

TEST(MapKeys, RejectsBadGrids) {
  EXPECT_THROW(OccupancyMap(0.0, {0, 0, 0}, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(OccupancyMap(-1.0, {0, 0, 0}, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(OccupancyMap(NAN, {0, 0, 0}, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(OccupancyMap(0.2, {0, 0, 0}, {1, 0, 1}), std::invalid_argument);
  EXPECT_THROW(OccupancyMap(0.2, {0, 0, NAN}, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(OccupancyMap(0.2, {-7000, 0, 0}, {0, 1, 1}),
               std::invalid_argument);  // > 32768 cells
  EXPECT_THROW(OccupancyMap(0.01, {-20, -20, 0}, {20, 20, 10}),
               std::invalid_argument);  // 1.6e10 cells
  OccupancyMapOptions o;
  o.prob_miss = 0.7;
  EXPECT_THROW(OccupancyMap(0.2, {0, 0, 0}, {1, 1, 1}, o), std::invalid_argument);
}

TEST(MapRays, WalkerMatchesComputeRayKeys) {
  octomap::OcTree t(0.2);
  std::vector<std::pair<octomap::point3d, octomap::point3d>> rays = {
      {{0, 0, 0}, {3, 0, 0}},                        // along +x, starting on a cell corner
      {{0.1f, 0.1f, 0.1f}, {0.1f, 0.1f, -3.1f}},     // along -z through cell centres
      {{0, 0, 0}, {1, 1, 1}},                        // through cell corners
      {{0, 0, 0}, {-1, -1, 0}},                      // through edges, negative side
      {{0.05f, 0.05f, 0.05f}, {0.15f, 0.1f, 0.1f}},  // same cell: empty ray
      {{0.19f, 0, 0}, {0.21f, 0, 0}},                // adjacent cells
      {{-5.3f, 2.2f, 1.0f}, {7.9f, -3.3f, 4.4f}},
      {{0, 0, 0}, {400.0f, 300.0f, -50.0f}},  // long ray
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-10.f, 10.f);
  std::uniform_int_distribution<int> grid(-40, 40);
  for (int i = 0; i < 3000; ++i)
    rays.push_back({{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}});
  for (int i = 0; i < 1000; ++i)  // ends on cell boundaries (multiples of the resolution)
    rays.push_back({{grid(rng) * 0.2f, grid(rng) * 0.2f, grid(rng) * 0.2f},
                    {grid(rng) * 0.2f, grid(rng) * 0.2f, grid(rng) * 0.2f}});
  for (const auto& r : rays)
    ASSERT_EQ(our_ray(t, r.first, r.second), octomap_ray(t, r.first, r.second));
  // out of range: false, nothing emitted, like computeRayKeys
  int emitted = 0;
  EXPECT_FALSE(
      OccupancyMap::walk_ray_keys(t, {0, 0, 0}, {1e5f, 0, 0}, [&](const Key&) { ++emitted; }));
  EXPECT_EQ(emitted, 0);
}

TEST(MapRays, AxisRayMarksFreeThenOccupied) {
  OccupancyMap m(0.2, {-1, -1, -1}, {5, 1, 1});
  m.integrate(Eigen::Vector3d(0.1, 0.1, 0.1), rows({{3.1, 0.1, 0.1}}), kNone);
  for (int i = 0; i < 15; ++i) EXPECT_EQ(m.state({0.1 + 0.2 * i, 0.1, 0.1}), CellState::Free) << i;
  EXPECT_EQ(m.state({3.1, 0.1, 0.1}), CellState::Occupied);
  EXPECT_EQ(m.state({3.3, 0.1, 0.1}), CellState::Unknown);
  EXPECT_EQ(m.state({0.1, 0.5, 0.1}), CellState::Unknown);
  EXPECT_EQ(m.counts().free, 15);
  EXPECT_EQ(m.counts().occupied, 1);
}

TEST(MapRays, CornerRayAgreesWithExactPath) {
  OccupancyMapOptions all;
  all.deduplicate_end_points = false;
  OccupancyMap fast(0.2, {-2, -2, -2}, {2, 2, 2}, all), exact(0.2, {-2, -2, -2}, {2, 2, 2});
  const Points ends = rows({{1, 1, 1}, {-1, 1, 0.6}, {1.2, -1.2, -1.2}});
  fast.integrate(Eigen::Vector3d::Zero(), ends, kNone);
  exact.integrate_exact(Eigen::Vector3d::Zero(), ends, kNone);
  EXPECT_TRUE(fast.octree() == exact.octree());
  for (std::size_t i = 0; i < fast.grid().layout().storage_size(); ++i)
    ASSERT_EQ(fast.grid().logodds(std::int64_t(i)), exact.grid().logodds(std::int64_t(i)));
}

TEST(MapWorkspace, CellsOutsideAreInTheOctreeButNotCounted) {
  OccupancyMapOptions unclipped;
  unclipped.clip_to_workspace = false;  // the default clips; this test is about the octree outside
  OccupancyMap m(0.2, {0, 0, 0}, {2, 2, 2}, unclipped);
  const double h0 = m.total_entropy();
  EXPECT_DOUBLE_EQ(h0, 1000 * std::log(2.0));
  // a ray entirely below the workspace
  m.integrate(Eigen::Vector3d(0.5, 0.5, -3.0), rows({{1.5, 1.5, -1.0}}), rows({{0.5, 1.5, -2.0}}));
  EXPECT_EQ(m.counts().unknown, 1000);
  EXPECT_EQ(m.total_entropy(), h0);
  EXPECT_GT(m.octree().size(), 0u);
  EXPECT_EQ(m.state({1.5, 1.5, -1.0}), CellState::Occupied);
  EXPECT_EQ(m.state({0.5, 1.5, -2.0}), CellState::Free);
  // a ray that crosses the workspace: only the cells inside count
  m.integrate(Eigen::Vector3d(-1.9, 1.1, 1.1), rows({{3.9, 1.1, 1.1}}), kNone);
  EXPECT_EQ(m.counts().free, 10);
  EXPECT_EQ(m.counts().occupied, 0);
  EXPECT_EQ(m.state({3.9, 1.1, 1.1}), CellState::Occupied);
  EXPECT_EQ(m.total_entropy(), m.recompute_total_entropy());
  EXPECT_EQ(m.verify_mirror(), 0);
}

TEST(MapWorkspace, ClippedMapsKeepNothingOutside) {
  OccupancyMap m(0.2, {0, 0, 0}, {2, 2, 2});  // clip_to_workspace is the default
  ASSERT_TRUE(m.options().clip_to_workspace);
  m.integrate(Eigen::Vector3d(0.5, 0.5, -3.0), rows({{1.5, 1.5, -1.0}}), rows({{0.5, 1.5, -2.0}}));
  EXPECT_EQ(m.octree().size(), 0u);
  m.integrate(Eigen::Vector3d(-1.9, 1.1, 1.1), rows({{3.9, 1.1, 1.1}}), kNone);
  EXPECT_EQ(m.counts().free, 10);
  EXPECT_EQ(m.state({3.9, 1.1, 1.1}), CellState::Unknown);
  EXPECT_EQ(m.state({-1.5, 1.1, 1.1}), CellState::Unknown);
}

TEST(MapWorkspace, ClippedRaysEndWhereTheyLeaveAndTheGridIsTheSame) {
  // A clipped map ends a ray's walk where it leaves the workspace (from an origin inside; from
  // outside it walks on). Inside, its cells must be those of an unclipped map, which walks on.
  OccupancyMapOptions unclipped;
  unclipped.clip_to_workspace = false;
  OccupancyMap clipped(0.2, {-2, -2, 0}, {2, 2, 1.6}),
      full(0.2, {-2, -2, 0}, {2, 2, 1.6}, unclipped);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int s = 0; s < 40; ++s) {
    const double far = s % 4 == 3 ? 3.0 : 1.0;  // every 4th origin outside the workspace
    const Eigen::Vector3d o(1.8 * far * u(rng), 1.8 * u(rng), 0.8 + 0.7 * u(rng));
    Points hits(200, 3), free_ends(200, 3);
    for (Eigen::Index r = 0; r < hits.rows(); ++r)
      hits.row(r) << 3 * u(rng), 3 * u(rng), 2 * u(rng);
    for (Eigen::Index r = 0; r < free_ends.rows(); ++r)
      free_ends.row(r) = o.transpose() + 6.0 * Eigen::RowVector3d(u(rng), u(rng), u(rng));
    clipped.integrate(o, hits, free_ends, s % 2 ? 3.0 : std::numeric_limits<double>::infinity());
    full.integrate(o, hits, free_ends, s % 2 ? 3.0 : std::numeric_limits<double>::infinity());
  }
  ASSERT_GT(clipped.counts().free, 100);
  for (std::size_t i = 0; i < clipped.grid().layout().storage_size(); ++i) {
    ASSERT_EQ(clipped.grid().logodds(std::int64_t(i)), full.grid().logodds(std::int64_t(i))) << i;
    ASSERT_EQ(clipped.grid().flag(std::int64_t(i)), full.grid().flag(std::int64_t(i))) << i;
  }
  EXPECT_EQ(clipped.total_entropy(), full.total_entropy());
}

TEST(MapUpdate, BatchedUpdateBuildsTheSameOctreeAsUpdateNode) {
  // Many overlapping scans, clamping and pruning included: the fast path's batched tree update
  // (lazy updates in tree order, inner nodes fixed once) must give a structurally identical octree.
  OccupancyMapOptions all, unclipped;
  all.deduplicate_end_points = false;
  all.clip_to_workspace = unclipped.clip_to_workspace = false;  // cells outside the grid too
  OccupancyMap fast(0.2, {-3, -3, -3}, {3, 3, 3}, all),
      exact(0.2, {-3, -3, -3}, {3, 3, 3}, unclipped);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 2.0);
  for (int s = 0; s < 30; ++s) {
    const Eigen::Vector3d o(g(rng) * 0.3, g(rng) * 0.3, g(rng) * 0.3);
    Points hits(300, 3), free_ends(100, 3);
    for (Eigen::Index r = 0; r < hits.rows(); ++r) hits.row(r) << g(rng), g(rng), g(rng);
    for (Eigen::Index r = 0; r < free_ends.rows(); ++r)
      free_ends.row(r) << 2 * g(rng), 2 * g(rng), 2 * g(rng);
    const double max_range = s % 2 ? 4.0 : std::numeric_limits<double>::infinity();
    fast.integrate(o, hits, free_ends, max_range);
    exact.integrate_exact(o, hits, free_ends, max_range);
    ASSERT_TRUE(fast.octree() == exact.octree()) << "scan " << s;
  }
  EXPECT_EQ(fast.total_entropy(), exact.total_entropy());
  EXPECT_EQ(fast.verify_mirror(), 0);
  // pruning happened (free space far from the hits clamps into coarse leaves)
  std::size_t coarse = 0;
  for (auto it = fast.octree().begin_leafs(); it != fast.octree().end_leafs(); ++it)
    coarse += it.getDepth() < 16;
  EXPECT_GT(coarse, 0u);
}

TEST(MapKeys, EndCellsFourAtATimeAreOneAtATimesToTheBit) {
  // integrate's first step finds the end points' cells four rays at a time (AVX2 where the CPU
  // has it): keys, sub-cells, distances and states must be those found one ray at a time, on
  // points on cell and sub-cell boundaries, at +-0, beyond OctoMap's addressable range, beyond a
  // float, not finite, in rows 4 doubles apart, a count not a multiple of four, k = 1 to 4.
  std::mt19937 rng(17);
  std::normal_distribution<double> g(0.0, 20.0);
  std::uniform_int_distribution<int> cell(-400, 400), pick(0, 11);
  const std::size_t n = 4099;
  std::vector<double> rows(4 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      double& c = rows[4 * i + std::size_t(a)];
      switch (pick(rng)) {
        case 0:
          c = cell(rng) * 0.2;
          break;  // cell boundaries (0.2 m cells)
        case 1:
          c = cell(rng) * 0.05;
          break;  // sub-cell boundaries, k = 2 and 4
        case 2:
          c = i % 2 ? -0.0 : 0.0;
          break;
        case 3:
          c = (i % 2 ? -1 : 1) * 6553.7;
          break;  // just beyond the addressable range
        case 4:
          c = i % 3 ? 1e39 : -1e300;
          break;  // beyond a float
        case 5:
          c = i % 5 ? std::numeric_limits<double>::quiet_NaN() : -INFINITY;
          break;
        default:
          c = g(rng);
      }
    }
  for (int k = 1; k <= 4; ++k) {
    std::vector<std::int32_t> key[2], sub[2];
    std::vector<double> d2[2];
    std::vector<std::uint8_t> state[2];
    for (int simd = 0; simd < 2; ++simd) {
      key[simd].assign(3 * n, -7);
      sub[simd].assign(n, -7);
      d2[simd].assign(n, -1.0);
      state[simd].assign(n, 9);
      const nbv::detail::EndCellBlock out{
          {key[simd].data(), key[simd].data() + n, key[simd].data() + 2 * n},
          sub[simd].data(),
          d2[simd].data(),
          state[simd].data()};
      nbv::detail::end_cells(rows.data(), 4, n, 1.0 / 0.2, k, out, simd == 1);
    }
    std::size_t kinds[3] = {0, 0, 0};
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(state[0][i], state[1][i]) << "k " << k << " row " << i;
      ASSERT_LE(state[0][i], 2);
      ++kinds[state[0][i]];
      if (state[0][i] != 1) continue;  // keys of rays that are skipped are not read
      for (int a = 0; a < 3; ++a) ASSERT_EQ(key[0][a * n + i], key[1][a * n + i]) << i;
      ASSERT_EQ(sub[0][i], sub[1][i]) << i;
      ASSERT_LT(sub[0][i], k * k * k);
      ASSERT_EQ(std::memcmp(&d2[0][i], &d2[1][i], sizeof(double)), 0) << i;
    }
    EXPECT_GT(kinds[0], 100u);  // every state is exercised
    EXPECT_GT(kinds[1], 1000u);
    EXPECT_GT(kinds[2], 100u);
  }
}

TEST(MapUpdate, ACutNoRayReachesBuildsTheSameMap) {
  // With a range cut the end points go through the cut first (in float, as OctoMap's
  // computeUpdate), then the same key step: a cut no ray reaches must build the same map as no
  // cut, over more rays than a chunk holds (4,096, the hits ending inside a chunk), with points
  // on cell boundaries and beyond OctoMap's addressable range, rows 4 doubles apart.
  OccupancyMapOptions unclipped;
  unclipped.clip_to_workspace = false;
  OccupancyMap no_cut(0.2, {-3, -3, -3}, {3, 3, 3}, unclipped),
      cut(0.2, {-3, -3, -3}, {3, 3, 3}, unclipped);
  std::mt19937 rng(19);
  std::normal_distribution<double> g(0.0, 2.0);
  std::uniform_int_distribution<int> cell(-40, 40), pick(0, 9);
  for (int s = 0; s < 12; ++s) {
    const Eigen::Vector3d o(g(rng) * 0.3, g(rng) * 0.3, g(rng) * 0.3);
    const Eigen::Index nh = 5003 + s, nf = 1499 + 2 * s;
    Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> wide(nh, 4);
    Points free_ends(nf, 3);
    auto point = [&](Eigen::Index r) {
      Eigen::RowVector3d p(g(rng), g(rng), g(rng));
      const int kind = pick(rng);
      if (kind == 0) p << cell(rng) * 0.2, cell(rng) * 0.1, cell(rng) * 0.05;  // boundaries
      if (kind == 1 && r % 7 == 0) p(r % 3) = (r % 2 ? -1 : 1) * 7000.0;       // not addressable
      return p;
    };
    for (Eigen::Index r = 0; r < nh; ++r) wide.row(r) << point(r), 99.0;
    for (Eigen::Index r = 0; r < nf; ++r) free_ends.row(r) = point(r);
    const nbv::PointsRef hits(wide.leftCols<3>());  // rows 4 doubles apart
    ASSERT_EQ(hits.outerStride(), 4);
    const auto a = no_cut.integrate(o, hits, free_ends, std::numeric_limits<double>::infinity());
    const auto b = cut.integrate(o, hits, free_ends, 1e8);
    ASSERT_EQ(a.traced_rays, b.traced_rays) << "scan " << s;
    ASSERT_EQ(a.free_cells, b.free_cells) << "scan " << s;
    ASSERT_EQ(a.occupied_cells, b.occupied_cells) << "scan " << s;
    ASSERT_TRUE(no_cut.octree() == cut.octree()) << "scan " << s;
  }
  EXPECT_EQ(no_cut.total_entropy(), cut.total_entropy());
  // a non-finite end point is refused either way, naming the array it is in
  Points bad = rows({{1, 1, 1}, {1, 2, 1}, {1, 3, 1}, {1, 4, 1}, {1, 5, 1}});
  bad(3, 1) = std::numeric_limits<double>::quiet_NaN();
  for (double max_range : {std::numeric_limits<double>::infinity(), 1e8}) {
    try {
      cut.integrate({0, 0, 0}, kNone, bad, max_range);
      FAIL() << "a NaN free end was integrated";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("free-space ray ends"), std::string::npos);
    }
  }
}

TEST(MapUpdate, PredictionIsDiscardedByObservation) {
  OccupancyMap m(0.2, {-1, -1, -1}, {3, 1, 1});
  EXPECT_EQ(m.set_unknown_cells(rows({{1.1, 0.1, 0.1}, {1.15, 0.15, 0.1}, {2.1, 0.1, 0.1}}), 0.6),
            2u);
  const std::int64_t i1 = m.index_of(m.octree().coordToKey(octomap::point3d(1.1f, 0.1f, 0.1f)));
  EXPECT_EQ(m.grid().flag(i1), CellFlag::Predicted);
  EXPECT_EQ(m.grid().state(i1), CellState::Occupied);  // 0.6 >= threshold 0.6
  EXPECT_EQ(m.counts().predicted, 2);
  m.integrate(Eigen::Vector3d(0.1, 0.1, 0.1), rows({{2.1, 0.1, 0.1}}), kNone);
  EXPECT_EQ(m.grid().flag(i1), CellFlag::Observed);
  EXPECT_FLOAT_EQ(m.grid().logodds(i1), octomap::logodds(0.4));  // restarted from unknown, one miss
  EXPECT_FLOAT_EQ(float(m.probability({2.1, 0.1, 0.1})),
                  float(octomap::probability(octomap::logodds(0.7))));
  EXPECT_EQ(m.counts().predicted, 0);
  EXPECT_EQ(m.verify_mirror(), 0);
}

TEST(MapFiles, RoundTripExpandsCoarseLeaves) {
  OccupancyMap m(0.2, {-3, -3, -3}, {3, 3, 3});
  Points hits(41 * 41, 3);  // a wall of hits at x = 2.5: the space in front clamps free and prunes
  for (int i = 0; i < 41; ++i)
    for (int j = 0; j < 41; ++j) hits.row(i * 41 + j) << 2.5, -1.0 + 0.05 * i, -1.0 + 0.05 * j;
  for (int i = 0; i < 8; ++i)
    m.integrate(Eigen::Vector3d(-2.5, 0.3, 0.1), hits, rows({{-2.5, 2.9, 0.1}}));
  std::size_t coarse = 0;
  for (auto it = m.octree().begin_leafs(); it != m.octree().end_leafs(); ++it)
    coarse += it.getDepth() < 16;
  ASSERT_GT(coarse, 0u);
  const auto dir = std::filesystem::temp_directory_path() / "nbv_test_map";
  std::filesystem::create_directories(dir);
  for (const char* name : {"m.ot", "m.bt"}) {
    const std::string p = (dir / name).string();
    m.save(p);
    OccupancyMap r = OccupancyMap::load(p, Eigen::Vector3d(-3, -3, -3), Eigen::Vector3d(3, 3, 3));
    EXPECT_EQ(r.verify_mirror(), 0) << name;
    for (std::size_t i = 0; i < m.grid().layout().storage_size(); ++i)
      ASSERT_EQ(r.grid().state(std::int64_t(i)), m.grid().state(std::int64_t(i))) << name;
    EXPECT_EQ(r.counts().free, m.counts().free);
  }
  EXPECT_THROW(OccupancyMap::load((dir / "absent.ot").string()), nbv::FileNotFound);
  EXPECT_THROW(m.save((dir / "m.txt").string()), std::invalid_argument);
  // a write that fails (here: no such folder; a full disk the same way) throws, leaving nothing
  try {
    m.save((dir / "absent" / "m.ot").string());
    ADD_FAILURE() << "save into a missing folder did not throw";
  } catch (const nbv::FileWriteError& e) {
    EXPECT_EQ(e.error(), ENOENT);
  }
  // a failed save leaves an existing file as it was
  const std::string p = (dir / "m.ot").string();
  const auto size = std::filesystem::file_size(p);
  EXPECT_THROW(m.save(p + "/x.ot"), nbv::FileWriteError);
  EXPECT_EQ(std::filesystem::file_size(p), size);
  std::filesystem::remove_all(dir);
}

TEST(MapUpdate, ExactPathEqualsInsertPointCloud) {
  // With hits only (and no predictions), integrate_exact builds the very octree that
  // octomap::OcTree::insertPointCloud builds, with and without maxrange.
  OccupancyMap m(0.2, {-4, -4, -4}, {4, 4, 4});
  octomap::OcTree plain(0.2);
  // the map's sensor model; a bare OcTree clamps at log-odds -2 / 3.5 (p 0.1192 / 0.971), the
  // map (like octomap_server, the authors' setup) at 0.12 / 0.97
  plain.setProbHit(0.7);
  plain.setProbMiss(0.4);
  plain.setClampingThresMin(0.12);
  plain.setClampingThresMax(0.97);
  plain.setOccupancyThres(0.6);
  std::mt19937 rng(9);
  std::normal_distribution<double> g(0.0, 3.0);
  for (int s = 0; s < 10; ++s) {
    const Eigen::Vector3d o(g(rng) * 0.2, g(rng) * 0.2, g(rng) * 0.2);
    Points hits(500, 3);
    octomap::Pointcloud cloud;
    for (Eigen::Index r = 0; r < hits.rows(); ++r) {
      hits.row(r) << g(rng), g(rng), g(rng);
      cloud.push_back(float(hits(r, 0)), float(hits(r, 1)), float(hits(r, 2)));
    }
    const double max_range = s % 2 ? 5.0 : -1.0;
    m.integrate_exact(o, hits, kNone,
                      max_range > 0 ? max_range : std::numeric_limits<double>::infinity());
    plain.insertPointCloud(cloud, octomap::point3d(float(o.x()), float(o.y()), float(o.z())),
                           max_range);
    ASSERT_TRUE(m.octree() == plain) << "scan " << s;
  }
  EXPECT_EQ(m.verify_mirror(), 0);
}

// Every change of a cell stamps its brick above the epoch a reader took before it; a write that
// changes nothing, and the other bricks, keep their stamps. A copy is another record (new id).
TEST(BrickStamps, AWriteStampsItsBrickAboveTheReadersEpoch) {
  nbv::WorkspaceGrid w({8, 8, 8}, nbv::CellRule{});
  const nbv::BrickStamps& st = w.stamps();
  const std::uint32_t e = st.take_epoch();
  for (std::size_t b = 0; b < w.layout().num_bricks(); ++b) EXPECT_LE(st.data()[b], e);
  const std::size_t id = w.layout().id(5, 1, 6);  // brick (1, 0, 1)
  w.set(std::int64_t(id), -1.0f, CellFlag::Observed);
  for (std::size_t b = 0; b < w.layout().num_bricks(); ++b)
    EXPECT_EQ(st.data()[b] > e, b == id >> 6) << "brick " << b;
  const std::uint32_t e2 = st.take_epoch();
  EXPECT_GT(e2, e);
  w.set(std::int64_t(id), -1.0f, CellFlag::Observed);  // the same value: no change
  EXPECT_LE(st.data()[id >> 6], e2);
  const nbv::WorkspaceGrid copy = w;
  EXPECT_NE(copy.stamps().id(), w.stamps().id());
}
