// integrate_frame: a camera frame into the map, the camera cloud and the camera observations at
// once gives what the three calls one after the other give, cell for cell and point for point;
// a frame any of them would refuse changes none of them.
#include "nbv/frame_integration.hpp"
#include "nbv/mesh.hpp"
#include "nbv/raycast.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

using namespace nbv;

namespace {

// A room's corner in a 12 x 8 x 6 m box: a floor, two walls and a slanted board, as quads.
std::shared_ptr<const RaycastScene> scene() {
  const std::vector<std::array<Eigen::Vector3d, 4>> quads{
      {{{0, 0, 0.3}, {12, 0, 0.3}, {12, 8, 0.3}, {0, 8, 0.3}}},         // floor
      {{{10.5, 0, 0}, {10.5, 8, 0}, {10.5, 8, 6}, {10.5, 0, 6}}},       // wall across x
      {{{0, 7.5, 0}, {10.5, 7.5, 0}, {10.5, 7.5, 5}, {0, 7.5, 5}}},     // wall across y
      {{{5, 1.5, 0.8}, {7.5, 1.5, 0.8}, {7.5, 5, 2.8}, {5, 5, 2.8}}}};  // slanted board
  Points v(Eigen::Index(4 * quads.size()), 3);
  Faces f(Eigen::Index(2 * quads.size()), 3);
  for (Eigen::Index q = 0; q < Eigen::Index(quads.size()); ++q) {
    for (int c = 0; c < 4; ++c) v.row(4 * q + c) = quads[std::size_t(q)][std::size_t(c)];
    f.row(2 * q) << 4 * q, 4 * q + 1, 4 * q + 2;
    f.row(2 * q + 1) << 4 * q, 4 * q + 2, 4 * q + 3;
  }
  return std::make_shared<RaycastScene>(Mesh::from_arrays(v, f));
}

struct Kept {
  OccupancyMap map{0.2, {0, 0, 0}, {12, 8, 6}};
  SurfaceCloud cloud;
  SurfaceObservations surface{map, 40};
  Kept() {
    SurfaceCloudOptions o;
    o.voxel_size = 0.025;
    o.min_z = 0.5;  // drops the floor's points from the cloud, not from the map
    cloud = SurfaceCloud(o);
  }
};

void expect_same(const Kept& a, const Kept& b) {
  EXPECT_EQ(a.map.total_entropy(), b.map.total_entropy());
  const WorkspaceGrid& ga = a.map.grid();
  const WorkspaceGrid& gb = b.map.grid();
  std::int64_t differ = 0, observed = 0, seen = 0;
  for (std::int64_t i = 0; i < ga.num_cells(); ++i) {
    differ += ga.logodds(i) != gb.logodds(i) || ga.flag(i) != gb.flag(i) ||
              a.surface.seen(i) != b.surface.seen(i) || a.surface.hits(i) != b.surface.hits(i) ||
              a.surface.patches(i) != b.surface.patches(i);
    observed += ga.flag(i) == CellFlag::Observed;
    seen += a.surface.seen(i) != 0;
  }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(observed, 1000);  // the frames reached much of the box...
  EXPECT_GT(seen, 200);       // ...and the camera saw its surfaces
  ASSERT_EQ(a.cloud.size(), b.cloud.size());
  EXPECT_GT(a.cloud.size(), 1000u);
  EXPECT_EQ(a.cloud.points(), b.cloud.points());  // bit for bit, in the same order
  EXPECT_EQ(a.cloud.counts(), b.cloud.counts());
}

}  // namespace

TEST(FrameIntegration, TheSameAsTheThreeCallsInTurn) {
  // Noisy frames: the joint flight takes each next frame while it integrates the one before
  // (next_scan), and must draw the same noise in the same order as the serial one.
  DepthCameraOptions co;
  co.width = 160;
  co.height = 120;
  co.noise_k = 0.0025;
  co.seed = 7;
  const auto sc = scene();
  const DepthCamera cam(sc, co), joint_cam(sc, co);
  const std::vector<Pose> poses{Pose{2, 4, 3, 0}, Pose{3, 2, 4, 0.6, 0.5},
                                Pose{4, 6, 3.5, -0.4, 0.2}, Pose{2.5, 4, 3, 0.1},
                                Pose{9, 4, 3, M_PI, 0.3}};
  Kept serial, joint;
  std::size_t new_cells = 0, joint_new_cells = 0;
  Scan next = joint_cam.scan_pose(poses[0]);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Scan s = cam.scan_pose(poses[i]);
    ASSERT_EQ(next.hits, s.hits) << "frame " << i;  // bit for bit, noise included
    ASSERT_EQ(next.free_ends, s.free_ends) << "frame " << i;
    const IntegrationStats st = serial.map.integrate(s);
    const std::size_t voxels = serial.cloud.add(s.hits);
    const std::size_t cells = serial.surface.add_scan(s.origin, s.hits);
    new_cells += cells;
    const bool more = i + 1 < poses.size();
    FrameIntegration f = integrate_frame(
        joint.map, joint.cloud, joint.surface, next, std::numeric_limits<double>::infinity(),
        more ? &joint_cam : nullptr, more ? &poses[i + 1] : nullptr);
    joint_new_cells += f.new_cells;
    EXPECT_EQ(f.map.rays, st.rays);
    EXPECT_EQ(f.map.traced_rays, st.traced_rays);
    EXPECT_EQ(f.map.free_cells, st.free_cells);
    EXPECT_EQ(f.map.occupied_cells, st.occupied_cells);
    EXPECT_EQ(f.cloud_voxels, voxels);
    EXPECT_EQ(f.new_cells, cells);
    ASSERT_EQ(f.next_scan.has_value(), more);
    if (more) next = std::move(*f.next_scan);
  }
  EXPECT_GT(new_cells, 200u);
  EXPECT_EQ(joint_new_cells, new_cells);
  expect_same(serial, joint);
}

TEST(FrameIntegration, ARefusedFrameChangesNothing) {
  DepthCameraOptions co;
  co.width = 80;
  co.height = 60;
  const DepthCamera cam(scene(), co);
  Kept kept;
  integrate_frame(kept.map, kept.cloud, kept.surface, cam.scan_pose(Pose{2, 4, 3, 0}));
  const double entropy = kept.map.total_entropy();
  const std::size_t voxels = kept.cloud.size();
  const std::int64_t seen = kept.surface.seen_cells();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Scan good = cam.scan_pose(Pose{4, 6, 3.5, -0.4, 0.2});
  ASSERT_GT(good.hits.rows(), 10);
  ASSERT_GT(good.free_ends.rows(), 0);
  Scan bad_hit = good, bad_end = good, bad_origin = good, far_origin = good;
  bad_hit.hits(good.hits.rows() - 1, 2) = nan;  // the last hit: the others come first
  bad_end.free_ends(0, 0) = std::numeric_limits<double>::infinity();
  bad_origin.origin.x() = nan;
  far_origin.origin.x() = 1e7;  // beyond OctoMap's addressable range
  const double inf = std::numeric_limits<double>::infinity();
  // beyond the gimbal; not a number; finite but beyond any usable position
  const Pose steep{2, 4, 3, 0, 2.0}, lost{nan, 4, 3, 0}, remote{1e300, 4, 3, 0};
  for (const Scan* s : {&bad_hit, &bad_end, &bad_origin, &far_origin}) {
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, *s), std::invalid_argument);
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, good, 0.0),
                 std::invalid_argument);  // max_range must be > 0
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, good, inf, &cam, &steep),
                 std::invalid_argument);
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, good, inf, &cam, &lost),
                 std::invalid_argument);
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, good, inf, &cam, &remote),
                 std::invalid_argument);
    EXPECT_THROW(integrate_frame(kept.map, kept.cloud, kept.surface, good, inf, &cam, nullptr),
                 std::invalid_argument);  // a camera without a pose
    EXPECT_EQ(kept.map.total_entropy(), entropy);
    EXPECT_EQ(kept.cloud.size(), voxels);
    EXPECT_EQ(kept.surface.seen_cells(), seen);
  }
  EXPECT_GT(integrate_frame(kept.map, kept.cloud, kept.surface, good).new_cells, 0u);
}
