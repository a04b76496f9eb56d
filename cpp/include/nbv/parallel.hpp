// Parallel loops over index ranges, run inside the core's task arena (see set_num_threads).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cstddef>
#include <memory>

namespace nbv {

/// The arena of the core's parallel loops (its size set by set_num_threads). Hold the handle
/// for as long as work runs in it: set_num_threads may replace the arena meanwhile, and the
/// handle keeps the old one alive until the work is done (core_arena()->execute(...) does).
std::shared_ptr<tbb::task_arena> core_arena();

/// Calls body(begin, end) on disjoint chunks covering [0, n), in parallel.
template <typename Body>
void parallel_chunks(std::size_t n, std::size_t grain, const Body& body) {
  if (n == 0) return;
  core_arena()->execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                      [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
  });
}

}  // namespace nbv
