// candidate_rays: what the camera rays of candidate views reach, walked as evaluate_views walks
// them. An analytic wall at a known distance, then agreement with the scoring on random scenes.
#include "nbv/grid_view.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/views.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

using namespace nbv;

namespace {

/// The distinct cells the camera's rays from `view` enter, each ray to its first occupied cell
/// (walk_ray, one ray at a time), with the smallest entry range over the rays.
std::map<std::size_t, double> walked_cells(const GridView& g, const Pose& view,
                                           const ViewCameraModel& camera) {
  const Points dirs = camera.directions();
  const Eigen::Isometry3d T = gimbal_sensor_transform(view, camera.mount);
  std::map<std::size_t, double> cells;
  for (Eigen::Index r = 0; r < dirs.rows(); ++r) {
    const Eigen::Vector3d ds = dirs.row(r).transpose();
    walk_ray<false>(g, T.translation(), T.linear() * ds, camera.max_range / ds.x(),
                    [&](std::size_t idx, const int*, double t) {
                      auto [it, fresh] = cells.emplace(idx, t);
                      if (!fresh) it->second = std::min(it->second, t);
                      return !g.occupied(idx);
                    });
  }
  return cells;
}

// A wall two cells thick filling the workspace's y-z section at x in [6.0, 6.4) m, known free
// space in front of it, unknown behind; a 5 x 5 ray camera at (2.1, 2.1, 2.1) looking along +x.
struct WallScene {
  OccupancyMap map{0.2, {0, 0, 0}, {8, 4, 4}};
  ViewCameraModel camera;
  UtilityOptions utility;
  ValidityOptions validity;
  WallScene() {
    Points wall(2 * 20 * 20, 3);
    Eigen::Index n = 0;
    for (const double x : {6.1, 6.3})
      for (int j = 0; j < 20; ++j)
        for (int k = 0; k < 20; ++k) wall.row(n++) << x, 0.1 + 0.2 * j, 0.1 + 0.2 * k;
    map.update_cells(wall, true);
    map.mark_free_segment({0.5, 2.1, 2.1}, {3.9, 2.1, 2.1}, 1.9);
    camera.rays_x = camera.rays_y = 5;
    camera.hfov_deg = camera.vfov_deg = 60.0;
    camera.max_range = 8.0;
    validity.collision_radius = 0.0;
    validity.blocked_path = "plan";
  }
};

}  // namespace

TEST(CandidateRays, AWallAtAKnownDistanceIsReachedThereAndHeadOn) {
  WallScene s;
  const GridView g = grid_view(s.map);
  const double wall_x = 6.0, eye = 2.1;
  Eigen::Matrix<double, 2, 4, Eigen::RowMajor> cand;
  cand << eye, eye, eye, 0.0,  // looks at the wall
      eye, eye, eye, M_PI;     // looks away: no occupied cell
  const CandidateRays r =
      candidate_rays(g, cand, {eye, eye, eye, 0}, s.camera, s.utility, s.validity);
  ASSERT_EQ(r.size(), 2);
  EXPECT_EQ(r.status[0], std::int8_t(ViewStatus::Valid));
  EXPECT_EQ(r.status[1], std::int8_t(ViewStatus::SeesNoOccupied));
  EXPECT_EQ(r.occupied_seen[0], 25);  // every ray ends at the wall
  EXPECT_EQ(r.occupied_seen[1], 0);
  EXPECT_EQ(r.offsets[0], 0);
  EXPECT_EQ(std::size_t(r.offsets[2]), r.num_cells());
  EXPECT_FALSE(r.observed);
  EXPECT_TRUE(r.seen.empty() && r.hits.empty());

  for (Eigen::Index k = 0; k < 2; ++k) {
    // the distinct cells walked, and the nearest entry of each
    const auto walked = walked_cells(g, view_pose(cand, k), s.camera);
    ASSERT_EQ(r.offsets[k + 1] - r.offsets[k], std::int64_t(walked.size())) << "view " << k;
    std::set<std::int64_t> got;
    for (Eigen::Index i = r.offsets[k]; i < r.offsets[k + 1]; ++i) got.insert(r.index[i]);
    EXPECT_EQ(got.size(), walked.size()) << "cells of a view are distinct";
    for (Eigen::Index i = r.offsets[k]; i < r.offsets[k + 1]; ++i) {
      const Eigen::Vector3d c = r.center(std::size_t(i));
      const std::size_t id = g.index(int(c.x() / 0.2), int(c.y() / 0.2), int(c.z() / 0.2));
      ASSERT_TRUE(walked.count(id));
      EXPECT_EQ(r.range[i], walked.at(id));
      EXPECT_EQ(r.index[i], int(c.x() / 0.2) + 40 * (int(c.y() / 0.2) + 20 * int(c.z() / 0.2)));
    }
  }

  int occupied = 0, head_on = 0, own = 0, unknown = 0;
  for (Eigen::Index i = r.offsets[0]; i < r.offsets[1]; ++i) {
    const Eigen::Vector3d c = r.center(std::size_t(i));
    if (r.range[i] == 0.0) {  // the camera's own cell: free, entered through no face
      ++own;
      EXPECT_TRUE(std::isnan(r.incidence[i]));
      EXPECT_EQ(r.state[i], std::int8_t(CellState::Free));
      EXPECT_NEAR((c - Eigen::Vector3d::Constant(eye)).norm(), 0.0, 1e-9);
      continue;
    }
    EXPECT_GE(r.incidence[i], 0.0);
    EXPECT_LE(r.incidence[i], M_PI / 2);
    if (r.state[i] != std::int8_t(CellState::Occupied)) {
      EXPECT_LT(c.x(), wall_x);
      if (r.state[i] == std::int8_t(CellState::Unknown)) {
        ++unknown;  // beside the free space marked in front of the wall
        EXPECT_EQ(r.probability[i], 0.5);
        EXPECT_EQ(r.logodds[i], 0.0f);
      }
      continue;
    }
    ++occupied;
    EXPECT_NEAR(r.probability[i], 0.7, 1e-6);  // one hit
    EXPECT_NEAR(c.x(), wall_x + 0.1, 1e-9);    // the front layer only
    // every ray meets the wall's face at x = 6 m: range along the ray, incidence from the face's
    // normal (-x, the open face), so range * cos(incidence) is the distance to the wall
    EXPECT_NEAR(r.range[i] * std::cos(r.incidence[i]), wall_x - eye, 1e-9);
    EXPECT_LE(r.range[i], (c - Eigen::Vector3d::Constant(eye)).norm() + 0.2 * std::sqrt(3.0));
    if ((c - Eigen::Vector3d(wall_x + 0.1, eye, eye)).norm() < 1e-9) {
      ++head_on;  // the optical axis
      EXPECT_NEAR(r.range[i], wall_x - eye, 1e-9);
      EXPECT_NEAR(r.incidence[i], 0.0, 1e-12);
    }
  }
  EXPECT_EQ(own, 1);
  EXPECT_EQ(occupied, 25);
  EXPECT_EQ(head_on, 1);
  EXPECT_GT(unknown, 0);
  EXPECT_THROW(candidate_rays(g, Eigen::Matrix<double, 1, 3, Eigen::RowMajor>::Zero(),
                              {eye, eye, eye, 0}, s.camera, s.utility, s.validity),
               std::invalid_argument);
}

TEST(CandidateRays, AgreeWithTheScoringOnRandomScenes) {
  // the statuses and occupied rays of evaluate_views, and the ig utility's gain and count from
  // the cells of nonzero entropy, in the cells' order (the walk's: bit for bit)
  OccupancyMap m(0.2, {0, 0, 0}, {12, 8, 6});
  m.mark_free_segment({2, 4, 3}, {8, 4, 3}, 1.5);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0, 12), uy(0, 8), uz(0, 6), u(-1, 1);
  Points hits(80, 3), misses(300, 3);
  for (Eigen::Index i = 0; i < hits.rows(); ++i) hits.row(i) << ux(rng), uy(rng), uz(rng);
  for (Eigen::Index i = 0; i < misses.rows(); ++i)
    misses.row(i) << 5 + 3 * u(rng), 4 + u(rng), 3 + u(rng);
  m.update_cells(hits, true);
  for (int n = 0; n < 6; ++n) m.update_cells(misses, false);
  const GridView g = grid_view(m);
  ViewPoses cand(40, 5);
  for (Eigen::Index k = 0; k < cand.rows(); ++k)
    cand.row(k) << 5 + 4 * u(rng), 4 + 1.5 * u(rng), 3 + 1.5 * u(rng), 3 * u(rng),
        k % 2 ? 0.0 : 0.6 * u(rng);
  ViewCameraModel camera;
  UtilityOptions utility;
  utility.require_occupied_probability = 0.6;
  ValidityOptions validity;
  validity.collision_radius = 0.3;
  validity.bounds_max = Eigen::Vector3d(12, 8, 3.5);
  const Pose here{5, 4, 3, 0};
  for (const std::string path : {"reject", "plan"}) {
    validity.blocked_path = path;
    const ViewScores s = evaluate_views(g, cand, here, camera, utility, validity);
    const CandidateRays r = candidate_rays(g, cand, here, camera, utility, validity);
    EXPECT_EQ(r.status, s.status);
    EXPECT_EQ(r.occupied_seen, s.occupied_seen);
    std::set<int> statuses;
    for (Eigen::Index k = 0; k < cand.rows(); ++k) {
      statuses.insert(r.status[k]);
      const std::int64_t n = r.offsets[k + 1] - r.offsets[k];
      if (r.status[k] != 0 && r.status[k] != std::int8_t(ViewStatus::SeesNoOccupied)) {
        EXPECT_EQ(n, 0) << "an invalid view is not walked";
        continue;
      }
      EXPECT_EQ(std::size_t(n), walked_cells(g, view_pose(cand, k), camera).size());
      double gain = 0.0;
      int cells = 0;
      for (Eigen::Index i = r.offsets[k]; i < r.offsets[k + 1]; ++i) {
        const std::size_t id = m.grid().layout().id(int(r.index[i] % 60), int(r.index[i] / 60 % 40),
                                                    int(r.index[i] / 2400));
        gain += std::fabs(g.cells.scored_at(id));
        cells += g.cells.scored_at(id) != 0.0f;
        EXPECT_EQ(r.logodds[i], g.cells.logodds_at(id));
      }
      EXPECT_EQ(gain, s.gain[k]) << "view " << k;
      EXPECT_EQ(cells, s.cells[k]) << "view " << k;
    }
    EXPECT_GE(statuses.size(), 3u) << "valid and invalid views of several kinds";
  }
}
