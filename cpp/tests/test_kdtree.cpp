// The shared nearest-neighbour index and voxel-centroid downsampling (nbv/kdtree.hpp,
// nbv/point_cloud.hpp) against brute force.
#include "nbv/kdtree.hpp"
#include "nbv/point_cloud.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>

using namespace nbv;

TEST(KdTree, MatchesBruteForce) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> N(0.0, 1.0);
  Points t(2000, 3), q(300, 3);
  for (Eigen::Index i = 0; i < t.rows(); ++i) t.row(i) << N(rng), N(rng), 0.1 * N(rng);
  t.bottomRows(100).setConstant(0.25);  // duplicates
  for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << 3 * N(rng), 3 * N(rng), 3 * N(rng);
  const KdTree tree(t, 4);
  Eigen::Index hint = -1;
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    const double best = (t.rowwise() - q.row(i)).rowwise().squaredNorm().minCoeff();
    const auto r = tree.nearest(q.row(i).transpose(), hint);
    ASSERT_GE(r.first, 0);
    EXPECT_DOUBLE_EQ(r.second, best);
    EXPECT_DOUBLE_EQ((t.row(r.first) - q.row(i)).squaredNorm(), best);
    hint = (i % 3) ? r.first : (i * 7) % t.rows();  // a good or an arbitrary hint
  }
  EXPECT_TRUE(tree.points().isApprox(t));
}

TEST(KdTree, EmptyAndSinglePoint) {
  const KdTree empty(Points(0, 3));
  EXPECT_EQ(empty.nearest(Eigen::Vector3d::Zero()).first, -1);
  EXPECT_TRUE(std::isinf(empty.nearest(Eigen::Vector3d::Zero()).second));
  Points one(1, 3);
  one << 1, 2, 3;
  const KdTree single(one);
  EXPECT_EQ(single.nearest(Eigen::Vector3d::Zero()).first, 0);
  EXPECT_DOUBLE_EQ(single.nearest(Eigen::Vector3d::Zero()).second, 14.0);
}

TEST(KdTree, PointsGivenOneAtATimeMakeTheSameTree) {
  // the points of two blocks read in place, as the evaluation reads several clouds
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> U(-2.0, 2.0);
  Points t(777, 3);
  for (Eigen::Index i = 0; i < t.rows(); ++i) t.row(i) << U(rng), U(rng), U(rng);
  const Eigen::Index split = 300;
  const KdTree whole(t, 5);
  const Points a = t.topRows(split), b = t.bottomRows(t.rows() - split);
  const KdTree parts(
      std::size_t(t.rows()),
      [&](std::size_t i) -> Eigen::Vector3d {
        const Eigen::Index r = Eigen::Index(i);
        return r < split ? a.row(r).transpose() : b.row(r - split).transpose();
      },
      5);
  ASSERT_EQ(parts.size(), whole.size());
  for (std::size_t k = 0; k < whole.size(); ++k) {
    ASSERT_EQ(parts.id_at(k), whole.id_at(k));
    ASSERT_EQ(parts.point_at(k), whole.point_at(k));
  }
  EXPECT_EQ(parts.points(), t);
  const auto nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(KdTree(3, [&](std::size_t i) { return Eigen::Vector3d(0, i == 1 ? nan : 0, 0); }),
               std::invalid_argument);
}

TEST(KdTree, BatchQueriesMatchBruteForce) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-5.0, 5.0);
  Points t(3000, 3), q(5000, 3);
  for (Eigen::Index i = 0; i < t.rows(); ++i) t.row(i) << U(rng), U(rng), 0.2 * U(rng);
  for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << 1.5 * U(rng), 1.5 * U(rng), U(rng);
  const KdTree tree(t);
  const auto [idx, dist] = tree.nearest_each(q);
  ASSERT_EQ(idx.size(), q.rows());
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    const double best = std::sqrt((t.rowwise() - q.row(i)).rowwise().squaredNorm().minCoeff());
    ASSERT_GE(idx[i], 0);
    EXPECT_DOUBLE_EQ(dist[i], best);
    EXPECT_TRUE(tree.point(idx[i]).isApprox(t.row(idx[i]).transpose()));
  }
  const Eigen::VectorXd d = nearest_distances(t, q);
  EXPECT_TRUE(d.isApprox(dist));
  const auto [none, inf] = KdTree(Points(0, 3)).nearest_each(q);
  EXPECT_EQ(none.maxCoeff(), -1);
  EXPECT_TRUE(std::isinf(inf.minCoeff()));
}

TEST(VoxelgridSampling, CentroidsPerCellInFirstSeenOrder) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> U(-2.0, 2.0);
  Points p(4000, 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) p.row(i) << U(rng), U(rng), U(rng);
  const double leaf = 0.5;
  // Brute force: cells in order of first occurrence, centroid of each.
  std::map<std::tuple<long, long, long>, std::size_t> slot;
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const auto key =
        std::make_tuple(long(std::floor(p(i, 0) / leaf)), long(std::floor(p(i, 1) / leaf)),
                        long(std::floor(p(i, 2) / leaf)));
    auto [it, inserted] = slot.emplace(key, sum.size());
    if (inserted) {
      sum.emplace_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    sum[it->second] += p.row(i).transpose();
    ++count[it->second];
  }
  const Points v = voxelgrid_sampling(p, leaf);
  ASSERT_EQ(v.rows(), static_cast<Eigen::Index>(sum.size()));
  for (std::size_t k = 0; k < sum.size(); ++k)
    EXPECT_TRUE(v.row(static_cast<Eigen::Index>(k)).transpose().isApprox(sum[k] / count[k]));
  // The surface cloud is the same downsampling, fed incrementally.
  SurfaceCloudOptions o;
  o.voxel_size = leaf;
  o.min_z = -std::numeric_limits<double>::infinity();
  SurfaceCloud cloud(o);
  cloud.add(p.topRows(1000));
  cloud.add(p.bottomRows(3000));
  EXPECT_EQ(cloud.points(), v);  // bit for bit
}

namespace {
/// A cloud of voxel `size` without ground removal, its sums in single precision.
SurfaceCloudOptions single_precision_options(double size) {
  SurfaceCloudOptions o;
  o.voxel_size = size;
  o.min_z = -std::numeric_limits<double>::infinity();
  o.single_precision = true;
  return o;
}
}  // namespace

// Sums in single precision (SurfaceCloudOptions::single_precision): a voxel far from the origin
// with 200,000 points has the mean of its points within 1e-5 of the voxel's size, and a cloud of
// random points (about 60 a voxel) every centroid within 1e-6 of it, in the same voxels and order
// as with double sums.
TEST(VoxelCentroids, SinglePrecisionSumsGiveTheMeansWithinTheirBound) {
  const double size = 0.02;
  const Eigen::Vector3d corner(1234.0 * size, -5678.0 * size, 91.0 * size);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 0.999 * size);
  Points p(200000, 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    p.row(i) = (corner + Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng))).transpose();
  SurfaceCloudOptions o = single_precision_options(size);
  SurfaceCloud one(o);
  one.add(p);
  ASSERT_EQ(one.size(), 1u);
  const Eigen::RowVector3d mean = p.colwise().mean();
  EXPECT_LT((one.points().row(0) - mean).cwiseAbs().maxCoeff(), 1e-5 * size);

  std::uniform_real_distribution<double> w(-2.0, 2.0);
  Points q(30000, 3);
  for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << w(rng), w(rng), w(rng);
  o.voxel_size = 0.5;
  SurfaceCloud single(o);
  single.add(q.topRows(10000));
  single.add(q.bottomRows(20000));  // the parallel registration on 2 threads and more
  const Points exact = voxelgrid_sampling(q, 0.5);
  ASSERT_EQ(single.points().rows(), exact.rows());
  EXPECT_LT((single.points() - exact).cwiseAbs().maxCoeff(), 1e-6 * 0.5);
  EXPECT_GT((single.points() - exact).cwiseAbs().maxCoeff(), 0.0);  // not the double sums
  o.single_precision = false;
  SurfaceCloud twice(o);
  twice.add(q);
  EXPECT_LT(single.bytes() * 10, twice.bytes() * 7);  // 16 bytes a voxel against 28, and the index
}

// A face just under a voxel boundary (a mesh face at a whole metre, hit with rounding below it)
// at 0.025 m: the offsets, each just under the voxel's size, sum in single precision to more than
// n times it (float(0.025) > 0.025); the centroid still lies in its own voxel, so re-filtering
// the cloud gives the same voxels, on either side of the origin.
TEST(VoxelCentroids, SinglePrecisionCentroidsStayInTheirVoxels) {
  const double size = 0.025;
  Points p(4000, 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const double x = (i % 2 ? 4.0 : -3.0) - 1e-12 * double(1 + i % 7);
    p.row(i) << x, 0.01 * double(i % 200), 0.5 + 0.01 * double(i / 200);
  }
  SurfaceCloud single(single_precision_options(size));
  single.add(p);
  const Points c = single.points();
  for (Eigen::Index i = 0; i < c.rows(); ++i) {
    const double x = c(i, 0);
    EXPECT_EQ(std::floor(x / size), x > 0 ? 159.0 : -121.0) << x;
  }
  EXPECT_EQ(voxelgrid_sampling(c, size).rows(), c.rows());
}

TEST(VoxelgridSampling, OfCloudsReadAChunkAtATimeEqualsOfTheirStack) {
  // Two clouds (double and single precision sums) thinned a chunk at a time, with chunks that
  // end inside either cloud: the centroids of their stack, bit for bit, in the same order.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  Points p(4000, 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) p.row(i) << u(rng), u(rng), u(rng);
  SurfaceCloudOptions o;
  o.voxel_size = 0.05;
  o.min_z = -std::numeric_limits<double>::infinity();
  SurfaceCloud a(o), b(single_precision_options(0.02));
  a.add(p.topRows(2500));
  b.add(p.bottomRows(1500));
  const std::vector<const SurfaceCloud*> both = {&a, &b};
  const Points stacked = voxelgrid_sampling(stack_points(both), 0.4);
  ASSERT_GT(stacked.rows(), 100);
  for (std::size_t chunk :
       {std::size_t(1), std::size_t(7), std::size_t(2500), std::size_t(1) << 20})
    EXPECT_EQ(voxelgrid_sampling(both, 0.4, chunk), stacked) << chunk;
  EXPECT_EQ(voxelgrid_sampling(std::vector<const SurfaceCloud*>{}, 0.4).rows(), 0);
  EXPECT_THROW(voxelgrid_sampling(both, 0.0), std::invalid_argument);
}

TEST(VoxelgridSampling, EdgeCases) {
  EXPECT_EQ(voxelgrid_sampling(Points(0, 3), 0.1).rows(), 0);
  Points one(1, 3);
  one << -0.01, 0.0, 1e-3;
  EXPECT_EQ(voxelgrid_sampling(one, 0.1), one);
  EXPECT_THROW(voxelgrid_sampling(one, 0.0), std::invalid_argument);
  EXPECT_THROW(voxelgrid_sampling(one, std::nan("")), std::invalid_argument);
  one(0, 0) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(voxelgrid_sampling(one, 0.1), std::invalid_argument);
  // Points on both sides of a cell boundary stay apart (floor, not truncation).
  Points two(2, 3);
  two << -0.01, 0, 0, 0.01, 0, 0;
  EXPECT_EQ(voxelgrid_sampling(two, 0.1).rows(), 2);
}
