// The core's shared thread pool: set_num_threads while other threads run parallel loops.
#include "nbv/common.hpp"
#include "nbv/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
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
