// The view-scoring kernel shared by evaluate_views and view_coverage (internal to the core):
// validity, then every ray of each valid candidate through the grid, each cell handed to the
// utility policy in order.
#pragma once

#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "nbv/views.hpp"
#include "utilities/registry.hpp"

#include <cmath>
#include <functional>
#include <limits>

namespace nbv::kernel {

constexpr double kInf = std::numeric_limits<double>::infinity();

using Candidates = Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>;

inline double logit(double p) { return std::log(p / (1.0 - p)); }

// Cell readers: the workspace grid (fast), or OctoMap's search per cell (the authors' way, kept
// as the reference the grid is checked against and as the benchmark baseline).
struct GridCells {
  const GridView& g;
  float scored(std::size_t idx, const int*) const { return g.scored[idx]; }
  float logodds(std::size_t idx, const int*) const { return g.logodds[idx]; }
  CellFlag flag(std::size_t idx, const int*) const { return g.flags[idx]; }
};

struct OctreeCells {
  const OccupancyMap& map;
  const octomap::OcTree& tree;  // map.octree(), brought up to date once before the walks
  const octomap::OcTreeNode* node(const int* c) const {
    OccupancyMap::Key key = map.min_key();
    for (int a = 0; a < 3; ++a) key[a] = static_cast<octomap::key_type>(key[a] + c[a]);
    return tree.search(key);
  }
  float scored(std::size_t, const int* c) const {
    const octomap::OcTreeNode* n = node(c);
    if (!n) return float(map.cell_entropy(0.0f, CellFlag::Unknown));
    const float l = n->getLogOdds();
    const float e = float(map.cell_entropy(l, CellFlag::Observed));
    return l >= map.grid().rule().occupied_logodds ? -e : e;
  }
  float logodds(std::size_t, const int* c) const {
    const octomap::OcTreeNode* n = node(c);
    return n ? n->getLogOdds() : 0.0f;
  }
  // files and the octree keep no predictions: the grid's flag tells them apart
  CellFlag flag(std::size_t idx, const int* c) const {
    return node(c) ? map.grid().flag(std::int64_t(idx)) : CellFlag::Unknown;
  }
};

struct Job {
  const GridView& grid;
  Candidates cand;
  const Pose& current;
  const ViewCameraModel& camera;
  const UtilityOptions& utility;
  const ValidityOptions& validity;
  bool distance_weight;
  /// If set, called after each valid view with what its utility credited (Surface records).
  std::function<void(Eigen::Index, const std::vector<utility::Credit>&)> on_view;
};

// One kernel for every utility: validity, then the rays of each valid candidate through the
// grid, each cell handed to the utility in order.
template <class Utility, bool kSkip, class Cells>
ViewScores score(const Job& job, const Cells& cells) {
  const GridView& g = job.grid;
  const Eigen::Index K = job.cand.rows();
  ViewScores out;
  out.utility.setConstant(K, -kInf);
  out.gain.setZero(K);
  out.cells.setZero(K);
  out.occupied_seen.setZero(K);
  out.status.setConstant(K, static_cast<std::int8_t>(ViewStatus::Valid));
  const Points dirs = job.camera.directions();
  const double occ_req = job.utility.require_occupied_probability > 0
                             ? logit(job.utility.require_occupied_probability)
                             : -kInf;
  std::uint32_t cones[26];
  for (int b = 0; b < 26; ++b) cones[b] = bin_cone(b, job.utility.coverage_cone_deg);
  const Eigen::Vector3d here(job.current.x, job.current.y, job.current.z);
  const ValidityOptions& v = job.validity;
  const bool check_segment = v.blocked_path == "reject";
  parallel_chunks(static_cast<std::size_t>(K), 1, [&](std::size_t b, std::size_t e) {
    thread_local utility::VisitedSet visited;
    thread_local std::vector<utility::Credit> credits;
    for (std::size_t kk = b; kk < e; ++kk) {
      const auto k = static_cast<Eigen::Index>(kk);
      const Eigen::Vector3d p(job.cand(k, 0), job.cand(k, 1), job.cand(k, 2));
      auto& st = out.status[k];
      if ((p.array() < v.bounds_min.array()).any() || (p.array() > v.bounds_max.array()).any()) {
        st = static_cast<std::int8_t>(ViewStatus::OutOfBounds);
        continue;
      }
      if (!sphere_is_free(g, p, v.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::Collision);
        continue;
      }
      if (check_segment && !segment_is_free(g, here, p, v.collision_radius)) {
        st = static_cast<std::int8_t>(ViewStatus::PathBlocked);
        continue;
      }
      const Eigen::Isometry3d T =
          pose_to_transform({p.x(), p.y(), p.z(), job.cand(k, 3)}) * job.camera.mount;
      const Eigen::Vector3d o = T.translation();
      const Eigen::Matrix3d R = T.linear();
      visited.reset(g.storage_size());
      credits.clear();
      utility::ViewContext ctx{g, job.utility, visited, cones, job.on_view ? &credits : nullptr};
      Utility u(ctx);
      int occ = 0;
      for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
        const Eigen::Vector3d ds = dirs.row(r).transpose();
        const Eigen::Vector3d dw = R * ds;
        u.begin_ray(dw);
        bool ray_occ = false;
        walk_ray<kSkip>(g, o, dw, job.camera.max_range / ds.x(),
                        [&](std::size_t idx, const int* c, double t) {
                          const float s = cells.scored(idx, c);
                          if (!ray_occ && std::signbit(s)) {  // the ray's first occupied cell
                            ray_occ = true;
                            if (cells.logodds(idx, c) > occ_req) ++occ;
                          }
                          return u.visit(cells, idx, c, t, s);
                        });
      }
      if (job.on_view) job.on_view(k, credits);
      out.gain[k] = u.gain();
      out.cells[k] = u.cells();
      out.occupied_seen[k] = occ;
      if (job.utility.require_occupied && occ == 0) {
        st = static_cast<std::int8_t>(ViewStatus::SeesNoOccupied);
        continue;
      }
      double value = u.gain();
      if (job.distance_weight) value *= std::exp(-job.utility.distance_lambda * (p - here).norm());
      out.utility[k] = value;
    }
  });
  return out;
}

}  // namespace nbv::kernel
