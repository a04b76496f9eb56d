// The core's shared thread pool: set_num_threads while other threads run parallel loops.
#include "nbv/common.hpp"
#include "nbv/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <thread>
#include <vector>

using namespace nbv;

TEST(ThreadPool, SetNumThreadsWhileLoopsRunKeepsTheirArenaAlive) {
  std::atomic<bool> stop{false};
  std::atomic<long> loops{0};
  std::vector<std::thread> workers;
  for (int w = 0; w < 2; ++w)
    workers.emplace_back([&] {
      while (!stop) {
        std::vector<int> out(20000, 0);
        parallel_chunks(out.size(), 64, [&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i) out[i] = int(i % 7);
        });
        for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], int(i % 7));
        ++loops;
      }
    });
  // replace the arena over and over while the loops run, until they have run 200 times
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; loops < 200 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20);
       ++k)
    set_num_threads(1 + k % 3);
  stop = true;
  for (auto& t : workers) t.join();
  set_num_threads(0);
  EXPECT_GE(loops.load(), 200);
  EXPECT_GE(get_num_threads(), 1);
}

// The coordinate checks test coordinates in pairs, then a scalar tail: a bad value anywhere (the
// first pair, the last odd coordinate, a row of a strided view) is found, the bound itself passes.
TEST(CoordinateChecks, FindABadValueAtEveryPositionContiguousOrStrided) {
  const double bad[] = {std::numeric_limits<double>::quiet_NaN(),
                        std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity(), 2 * kMaxCoordinate};
  for (const Eigen::Index rows : {1, 2, 3, 1025, 1100}) {
    Points p = Points::Constant(rows, 3, 1.0);
    p(0, 0) = kMaxCoordinate;  // at the bound: usable
    p(rows - 1, 2) = -kMaxCoordinate;
    EXPECT_NO_THROW(require_coordinates(p, "points"));
    EXPECT_NO_THROW(require_finite(p, "points"));
    for (const Eigen::Index at : {Eigen::Index(0), rows / 2, rows - 1})
      for (int c = 0; c < 3; ++c)
        for (const double b : bad) {
          Points q = p;
          q(at, c) = b;
          EXPECT_THROW(require_coordinates(q, "points"), std::invalid_argument) << at << " " << c;
          if (!std::isfinite(b))
            EXPECT_THROW(require_finite(q, "points"), std::invalid_argument);
          else
            EXPECT_NO_THROW(require_finite(q, "points"));
        }
  }
  // rows of a wider array (outer stride 6): only the three columns viewed are checked
  Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor> wide =
      Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>::Constant(50, 6, 1.0);
  wide.col(4).setConstant(std::numeric_limits<double>::quiet_NaN());
  const PointsRef view(wide.leftCols<3>());
  ASSERT_EQ(view.outerStride(), 6);  // a view, not a copy
  EXPECT_NO_THROW(require_coordinates(view, "points"));
  wide(31, 1) = std::numeric_limits<double>::quiet_NaN();
  const PointsRef bad_view(wide.leftCols<3>());
  EXPECT_THROW(require_finite(bad_view, "points"), std::invalid_argument);
}
