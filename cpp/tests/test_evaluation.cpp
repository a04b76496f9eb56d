// Edge cases of the point-cloud and evaluation core: voxel key arithmetic (floor, not
// truncation; packing limits), the voxel index, the surface cloud's centroids, LZF decoding, and
// evaluation of empty / identical clouds and of a mesh's samples drawn again.
#include "nbv/evaluation.hpp"
#include "nbv/point_cloud.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

using namespace nbv;

TEST(VoxelKey, FloorNotTruncationForNegativeCoordinates) {
  const auto a = voxel_index(Eigen::Vector3d(-0.01, 0.0, 0.049), 0.05);
  EXPECT_EQ(a[0], -1);  // truncation would give 0
  EXPECT_EQ(a[1], 0);
  EXPECT_EQ(a[2], 0);
  EXPECT_EQ(voxel_index(Eigen::Vector3d(-0.05, -0.0500001, -1e-300), 0.05)[0], -1);
  EXPECT_EQ(voxel_index(Eigen::Vector3d(-0.05, -0.0500001, -1e-300), 0.05)[1], -2);
  EXPECT_EQ(voxel_index(Eigen::Vector3d(-0.05, -0.0500001, -1e-300), 0.05)[2], -1);
  EXPECT_NE(voxel_key(Eigen::Vector3d(-0.01, 0, 0), 0.02),
            voxel_key(Eigen::Vector3d(0.01, 0, 0), 0.02));
  EXPECT_EQ(voxel_key(Eigen::Vector3d(0.001, 0, 0), 0.02),
            voxel_key(Eigen::Vector3d(0.019, 0, 0), 0.02));
}

TEST(VoxelKey, PackUnpackRoundTripAtTheLimits) {
  const std::int64_t lo = -kVoxelCoordLimit, hi = kVoxelCoordLimit - 1;
  for (std::int64_t x : {lo, std::int64_t(-1), std::int64_t(0), std::int64_t(1), hi})
    for (std::int64_t y : {lo, std::int64_t(-7), hi})
      for (std::int64_t z : {lo, std::int64_t(0), hi}) {
        const std::uint64_t k = pack_voxel(x, y, z);
        EXPECT_NE(k, kEmptyVoxelKey);
        EXPECT_EQ(k >> 63, 0u);
        const auto u = unpack_voxel(k);
        EXPECT_EQ(u[0], x);
        EXPECT_EQ(u[1], y);
        EXPECT_EQ(u[2], z);
      }
  EXPECT_THROW(voxel_index(Eigen::Vector3d(1e9, 0, 0), 0.02), std::invalid_argument);
  EXPECT_EQ(try_voxel_key(1e9, 0, 0, 0.02, 50.0), kEmptyVoxelKey);
  EXPECT_EQ(try_voxel_key(-0.01, 0, 0, 0.02, 50.0), voxel_key(Eigen::Vector3d(-0.01, 0, 0), 0.02));
}

TEST(VoxelKey, FastFloorDivisionEqualsFloorOfTheQuotient) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> U(-50.0, 50.0);
  for (double size : {0.02, 0.05, 0.1, 0.3, 0.5, 1.0 / 3.0}) {
    const double inv = 1.0 / size;
    for (int i = 0; i < 20000; ++i) {
      double v = U(rng);
      if (i % 2) {  // on and next to cell boundaries, where rounding matters
        v = std::round(v / size) * size;
        if (i % 4 == 1) v = std::nextafter(v, i % 8 == 1 ? 1e9 : -1e9);
      }
      ASSERT_EQ(floor_div(v, size, inv), std::floor(v / size)) << v << " / " << size;
    }
  }
  for (double q : {-2.5, -2.0, -0.0, 0.0, 0.5, 3.0, -1e-300, 1e17, -1e17})
    EXPECT_EQ(fast_floor(q), std::floor(q)) << q;
}

TEST(VoxelKey, EvaluationCellsPutAValueOnABoundaryInTheCellAbove) {
  // a face on a boundary plane: its coordinates off the plane by a few ulps either way
  const std::vector<std::pair<double, double>> planes = {
      {12.4, 0.05}, {12.4, 0.1}, {-3.0, 0.05}, {-3.0, 0.5}, {0.35, 0.05}, {1000.05, 0.05}};
  for (const auto& [at, size] : planes) {
    const double inv = 1.0 / size, cell = std::round(at / size);
    double v = at;
    for (int k = 0; k < 4; ++k) v = std::nextafter(v, -1e9);
    for (int k = 0; k < 9; ++k, v = std::nextafter(v, 1e9))
      EXPECT_EQ(snapped_floor_div(v, size, inv), cell) << v << " / " << size;
    // truly below (a tenth of a millimetre) or inside a cell: floor
    EXPECT_EQ(snapped_floor_div(at - 1e-4, size, inv), cell - 1.0) << at;
    EXPECT_EQ(snapped_floor_div(at + 0.3 * size, size, inv), cell) << at;
  }
  EXPECT_EQ(try_cell_key(0.0, 12.399999999999999, -2.9999999999999996, 0.05, 20.0),
            pack_voxel(0, 248, -60));
}

TEST(VoxelIndex, IdsInInsertionOrderAcrossRehashes) {
  VoxelIndex m;
  EXPECT_FALSE(m.contains(pack_voxel(0, 0, 0)));
  const auto key = [](std::uint32_t i) { return pack_voxel(i, -static_cast<std::int64_t>(i), 3); };
  for (std::uint32_t i = 0; i < 10000; ++i) {  // many rehashes from 16 slots
    const auto r = m.insert(key(i));
    ASSERT_TRUE(r.second);
    ASSERT_EQ(r.first, i);
  }
  EXPECT_EQ(m.size(), 10000u);
  const auto again = m.insert(key(5));
  EXPECT_FALSE(again.second);
  EXPECT_EQ(again.first, 5u);
  EXPECT_EQ(m.size(), 10000u);
  for (std::uint32_t i = 0; i < 10000; ++i) {
    ASSERT_EQ(m.find(key(i)), i);
    ASSERT_EQ(m.key(i), key(i));
    ASSERT_EQ(m.keys()[i], key(i));
  }
  EXPECT_EQ(m.find(pack_voxel(1, 1, 1)), VoxelIndex::kMissing);
  // reserving far ahead, then shrinking back, keeps every id
  m.reserve(1 << 20);
  const std::size_t big = m.bytes();
  m.shrink_to_fit();
  EXPECT_LT(m.bytes(), big);
  for (std::uint32_t i = 0; i < 10000; i += 7) ASSERT_EQ(m.find(key(i)), i);
  m.clear();
  EXPECT_EQ(m.size(), 0u);
  EXPECT_FALSE(m.contains(key(5)));
  EXPECT_EQ(m.insert(key(7)).first, 0u);  // ids start again
}

TEST(SurfaceCloud, CentroidsInFirstSeenOrderAndGroundRemoval) {
  SurfaceCloudOptions o;
  o.voxel_size = 0.1;
  SurfaceCloud c(o);
  Points p(5, 3);
  p << 0.15, 0.0, 1.0,   // voxel (1, 0, 10)
      -0.01, 0.0, 1.0,   // voxel (-1, 0, 10)
      0.11, 0.02, 1.04,  // voxel (1, 0, 10)
      0.0, 0.0, 0.29,    // ground: dropped
      -0.09, 0.0, 1.0;   // voxel (-1, 0, 10)
  EXPECT_EQ(c.add(p), 2u);
  const Points q = c.points();
  ASSERT_EQ(q.rows(), 2);
  EXPECT_NEAR(q(0, 0), 0.13, 1e-15);
  EXPECT_NEAR(q(0, 2), 1.02, 1e-15);
  EXPECT_NEAR(q(1, 0), -0.05, 1e-15);
  EXPECT_EQ(c.counts()[0], 2);
  EXPECT_EQ(c.num_registered(), 4u);
}

TEST(SurfaceCloud, ThreadsDoNotChangeTheCentroidsOrTheirOrder) {
  // Frames large enough for the parallel registration, with runs of equal voxels, new voxels
  // scattered among old ones, and ground points: 1 thread and 2 give the same bits.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Points> frames;
  for (int f = 0; f < 6; ++f) {
    Points p(40000, 3);
    for (Eigen::Index i = 0; i < p.rows(); ++i) {
      const double t = (f + 1) * 0.3 * u(rng);
      p.row(i) << t + 0.001 * (i % 7), 0.5 * u(rng), 0.2 + 0.5 * std::abs(u(rng));
    }
    frames.push_back(p);
  }
  const int threads = get_num_threads();
  const auto fly = [&](int n) {
    set_num_threads(n);
    SurfaceCloud c;
    std::vector<std::size_t> added;
    for (const Points& p : frames) added.push_back(c.add(p));
    set_num_threads(threads);
    return std::make_tuple(c.points(), c.counts(), added);
  };
  const auto [p1, n1, a1] = fly(1);
  const auto [p2, n2, a2] = fly(2);
  EXPECT_EQ(a1, a2);
  ASSERT_EQ(p1.rows(), p2.rows());
  EXPECT_TRUE((p1.array() == p2.array()).all());  // bit for bit, in the same order
  EXPECT_TRUE((n1.array() == n2.array()).all());
}

TEST(SurfaceCloud, NonFiniteInputChangesNothing) {
  SurfaceCloud c;
  Points p(2, 3);
  p << 1, 1, 1, 1, std::numeric_limits<double>::quiet_NaN(), 1;
  EXPECT_THROW(c.add(p), std::invalid_argument);
  EXPECT_EQ(c.size(), 0u);
  SurfaceCloudOptions bad;
  bad.voxel_size = 0;
  EXPECT_THROW(SurfaceCloud{bad}, std::invalid_argument);
  bad.voxel_size = -1;
  EXPECT_THROW(SurfaceCloud{bad}, std::invalid_argument);
}

TEST(Lzf, DecodesLiteralsAndOverlappingBackReferences) {
  // "abc" as a literal run, then a back reference of 6 bytes at distance 3: "abcabcabc".
  const std::uint8_t in[] = {2, 'a', 'b', 'c', (6 - 2) << 5, 2};
  const auto out = lzf_decompress(in, sizeof(in), 9);
  EXPECT_EQ(std::string(out.begin(), out.end()), "abcabcabc");
  EXPECT_THROW(lzf_decompress(in, sizeof(in), 8), std::invalid_argument);   // too long
  EXPECT_THROW(lzf_decompress(in, sizeof(in), 10), std::invalid_argument);  // too short
  const std::uint8_t bad[] = {0xe0, 0xff, 0xff};  // reference before start
  EXPECT_THROW(lzf_decompress(bad, sizeof(bad), 4), std::invalid_argument);
}

TEST(Evaluation, OptionsRejectDuplicateAndNonPositiveGrids) {
  EvaluationOptions o;
  EXPECT_NO_THROW(o.validate());
  o.resolutions = {0.1, 0.5, 0.1};
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = EvaluationOptions{};
  o.taus = {0.05, 0.05};
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = EvaluationOptions{};
  o.resolutions = {0.0};
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

TEST(Evaluation, EmptyCloudScoresZeroWithoutChamfer) {
  Points gt(3, 3);
  gt << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  const EvaluationResult r = evaluate_points(gt, Points(0, 3));
  EXPECT_EQ(r.n_points, 0);
  EXPECT_FALSE(r.has_chamfer);
  for (double v : r.coverage) EXPECT_EQ(v, 0.0);
  for (double v : r.precision) EXPECT_EQ(v, 0.0);
  for (double v : r.fscore) EXPECT_EQ(v, 0.0);
  EXPECT_EQ(r.gt_cells[0], 3);
}

TEST(Evaluation, AMeshsSamplesDrawnAgainAreThoseOfTheConstruction) {
  // a box of 12 triangles: its copy is far smaller than its samples, so the Evaluator keeps the
  // mesh and draws the samples again; every figure must be that of the samples held as points
  Points v(8, 3);
  for (int i = 0; i < 8; ++i)
    v.row(i) << (i & 1 ? 2.0 : -1.0), (i & 2 ? 1.5 : 0.25), (i & 4 ? 3.0 : 0.5);
  Faces f(12, 3);
  f << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1,
      3, 5, 3, 7, 5;
  const Mesh box = Mesh::from_arrays(v, f);
  EvaluationOptions o;
  o.gt_density = 2000;
  o.seed = 7;
  Evaluator from_mesh(box, o);
  const Points samples = box.sample_surface(from_mesh.num_gt_points(), 7);
  ASSERT_GT(samples.rows(), 1000);
  Evaluator from_points(samples, o);
  EXPECT_TRUE(from_mesh.gt_points() == samples);
  std::vector<std::uint8_t> mask(samples.rows());
  for (std::size_t k = 0; k < mask.size(); ++k) mask[k] = samples(Eigen::Index(k), 2) > 1.0;
  from_mesh.set_observable(mask);
  from_points.set_observable(mask);
  const Points cloud = samples.topRows(samples.rows() / 3).array() + 0.01;
  const EvaluationResult a = from_mesh.evaluate(cloud), b = from_points.evaluate(cloud);
  EXPECT_EQ(a.coverage, b.coverage);
  EXPECT_EQ(a.area_coverage, b.area_coverage);
  EXPECT_EQ(a.coverage_observable, b.coverage_observable);
  EXPECT_EQ(a.completeness, b.completeness);
  EXPECT_EQ(a.accuracy, b.accuracy);
  EXPECT_TRUE(from_mesh.gt_points() == samples);  // now from the distances' tree
}

TEST(Evaluation, IdenticalCloudsScoreOneAndNegativeCellsCount) {
  Points gt(4, 3);
  gt << -0.01, -0.01, -0.01, 0.01, 0.01, 0.01, -0.26, 0.3, 2.0, 5.0, -5.0, -0.001;
  const EvaluationResult r = evaluate_points(gt, gt);
  ASSERT_TRUE(r.has_chamfer);
  EXPECT_EQ(r.chamfer, 0.0);
  for (double v : r.coverage) EXPECT_EQ(v, 1.0);
  for (double v : r.accuracy) EXPECT_EQ(v, 1.0);
  // -0.01 and 0.01 are in cells -1 and 0 at every resolution (the origin is a cell corner);
  // truncation toward zero would put both in cell 0 and count 3 cells.
  EXPECT_EQ(r.gt_cells[0], 4);  // 0.05 m
  EXPECT_EQ(r.gt_cells[2], 4);  // 0.5 m
}

TEST(Evaluation, ACloudScoredInPartsHasTheFiguresOfOneTreeAndOfBruteForce) {
  // Ground truth on a plane patch; a cloud over part of it with outliers, so that some samples'
  // nearest point lies in another part than their neighbours' (parts are in input order).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Points gt(3000, 3), cloud(1000, 3);
  for (Eigen::Index i = 0; i < gt.rows(); ++i) gt.row(i) << 2 * U(rng), 2 * U(rng), 0.0;
  for (Eigen::Index i = 0; i < cloud.rows(); ++i)
    cloud.row(i) << 1.3 * U(rng), 2 * U(rng), (i % 7 == 0 ? 0.3 : 0.02) * U(rng);
  EvaluationOptions whole, parts;
  parts.part_points = 97;  // 11 parts, the last one short
  const EvaluationResult a = evaluate_points(gt, cloud, whole);
  const EvaluationResult b = evaluate_points(gt, cloud, parts);
  EXPECT_EQ(a.completeness, b.completeness);
  EXPECT_EQ(a.accuracy, b.accuracy);
  EXPECT_EQ(a.coverage, b.coverage);
  EXPECT_EQ(a.area_coverage, b.area_coverage);
  EXPECT_EQ(a.mean_gt_to_cloud, b.mean_gt_to_cloud);  // summed in the ground truth's order
  EXPECT_NEAR(a.mean_cloud_to_gt, b.mean_cloud_to_gt, 1e-14);
  // brute force: the mean distance each way, and completeness at the first tau
  double gt_sum = 0, cloud_sum = 0;
  std::int64_t within = 0;
  for (Eigen::Index i = 0; i < gt.rows(); ++i) {
    double best = 1e300;
    for (Eigen::Index j = 0; j < cloud.rows(); ++j)
      best = std::min(best, (gt.row(i) - cloud.row(j)).norm());
    gt_sum += best;
    within += best <= parts.taus[0];
  }
  for (Eigen::Index j = 0; j < cloud.rows(); ++j) {
    double best = 1e300;
    for (Eigen::Index i = 0; i < gt.rows(); ++i)
      best = std::min(best, (gt.row(i) - cloud.row(j)).norm());
    cloud_sum += best;
  }
  EXPECT_NEAR(b.mean_gt_to_cloud, gt_sum / gt.rows(), 1e-12);
  EXPECT_NEAR(b.mean_cloud_to_gt, cloud_sum / cloud.rows(), 1e-12);
  EXPECT_EQ(b.completeness[0], double(within) / gt.rows());
  EXPECT_GT(b.completeness[0], 0.3);  // the cloud covers part of the patch only
  EXPECT_LT(b.completeness[0], 0.9);
  parts.part_points = 0;
  EXPECT_THROW(evaluate_points(gt, cloud, parts), std::invalid_argument);
}

TEST(Evaluation, BadInput) {
  Points gt(1, 3);
  gt << 0, 0, 0;
  EXPECT_THROW(evaluate_points(Points(0, 3), gt), std::invalid_argument);
  EvaluationOptions o;
  o.resolutions = {0.05, 0.0};
  EXPECT_THROW(evaluate_points(gt, gt, o), std::invalid_argument);
  o = EvaluationOptions{};
  o.taus = {-1};
  EXPECT_THROW(evaluate_points(gt, gt, o), std::invalid_argument);
  Points nan = gt;
  nan(0, 1) = std::numeric_limits<double>::infinity();
  try {
    evaluate_points(gt, nan);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cloud"), std::string::npos);
  }
}

TEST(CoverageTracker, EqualsACountFromScratchAsCloudsGrowMoveAndAreCleared) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.03);
  Points gt(4000, 3);
  for (Eigen::Index i = 0; i < gt.rows(); ++i) gt.row(i) << u(rng), u(rng), 0.25 * u(rng);
  Evaluator ev(gt);
  CoverageTracker tracker(ev);
  SurfaceCloudOptions fine, coarse;
  fine.voxel_size = 0.02;
  coarse.voxel_size = 0.1;
  fine.min_z = coarse.min_z = -10.0;
  SurfaceCloud a(fine), b(coarse);
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(gt.rows()));
  for (int step = 0; step < 16; ++step) {
    Points p(1500, 3);
    for (Eigen::Index i = 0; i < p.rows(); ++i)
      p.row(i) = gt.row(static_cast<Eigen::Index>(rng() % 4000)) +
                 Eigen::RowVector3d(noise(rng), noise(rng), noise(rng));
    (step % 3 ? a : b).add(p);
    if (step == 6) a.clear();
    if (step == 8) b = SurfaceCloud(b);  // a copy: another stamp, the same points
    if (step == 10) {
      for (auto& m : mask) m = rng() % 3 != 0;
      ev.set_observable(mask);
    }
    const std::vector<const SurfaceCloud*> clouds = step == 12
                                                        ? std::vector<const SurfaceCloud*>{&b}
                                                        : std::vector<const SurfaceCloud*>{&a, &b};
    const EvaluationResult got = tracker.update(clouds), want = ev.evaluate_cells(clouds);
    EXPECT_EQ(got.n_points, want.n_points) << step;
    EXPECT_EQ(got.covered_cells, want.covered_cells) << step;
    EXPECT_EQ(got.cloud_cells, want.cloud_cells) << step;
    EXPECT_EQ(got.coverage, want.coverage) << step;
    EXPECT_EQ(got.area_coverage, want.area_coverage) << step;
    EXPECT_EQ(got.precision, want.precision) << step;
    EXPECT_EQ(got.covered_observable_cells, want.covered_observable_cells) << step;
    EXPECT_EQ(got.area_coverage_observable, want.area_coverage_observable) << step;
    EXPECT_EQ(got.area_coverage_observable_cells, want.area_coverage_observable_cells) << step;
  }
}
