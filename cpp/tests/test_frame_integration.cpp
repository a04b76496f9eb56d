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
#include <map>
#include <memory>
#include <tuple>
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
  Scan bad_hit = good, bad_end = good, bad_origin = good, far_origin = good, far_hit = good,
       far_end = good;
  bad_hit.hits(good.hits.rows() - 1, 2) = nan;  // the last hit: the others come first
  bad_end.free_ends(0, 0) = std::numeric_limits<double>::infinity();
  far_hit.hits(good.hits.rows() - 1, 1) = 1e300;  // finite, infinite in single precision
  far_end.free_ends(good.free_ends.rows() - 1, 0) = -2e9;
  bad_origin.origin.x() = nan;
  far_origin.origin.x() = 1e7;  // beyond OctoMap's addressable range
  const double inf = std::numeric_limits<double>::infinity();
  // beyond the gimbal; not a number; finite but beyond any usable position
  const Pose steep{2, 4, 3, 0, 2.0}, lost{nan, 4, 3, 0}, remote{1e300, 4, 3, 0};
  for (const Scan* s : {&bad_hit, &bad_end, &bad_origin, &far_origin, &far_hit, &far_end}) {
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

namespace {

// The full-resolution scan's point for each of its rays, hits and free ends: pixel -> (point,
// whether a hit).
std::map<int, std::pair<Eigen::Vector3d, bool>> by_pixel(const Scan& s) {
  std::map<int, std::pair<Eigen::Vector3d, bool>> m;
  for (Eigen::Index r = 0; r < s.hits.rows(); ++r)
    m[s.hit_rays[r]] = {s.hits.row(r).transpose(), true};
  for (Eigen::Index r = 0; r < s.free_ends.rows(); ++r)
    m[s.free_rays[r]] = {s.free_ends.row(r).transpose(), false};
  return m;
}

}  // namespace

TEST(FrameRefinement, ScanPixelsCastsTheListedPixelsAsTheWholeScanDoes) {
  DepthCameraOptions co;
  co.width = 96;
  co.height = 72;
  const DepthCamera cam(scene(), co);
  const Eigen::Isometry3d T = gimbal_sensor_transform(Pose{3, 2, 4, 0.6, 0.5}, co.mount);
  const Scan whole = cam.scan(T);
  const auto rays = by_pixel(whole);
  ASSERT_GT(whole.hits.rows(), 1000);
  ASSERT_GT(whole.free_ends.rows(), 100);
  // every third pixel, backwards: the order given is the order returned
  std::vector<int> px;
  for (int p = co.width * co.height - 1; p >= 0; p -= 3) px.push_back(p);
  const Scan some = cam.scan_pixels(T, Eigen::Map<const Eigen::VectorXi>(px.data(), px.size()));
  ASSERT_EQ(some.depth.cols(), Eigen::Index(px.size()));
  Eigen::Index cast = 0;
  for (std::size_t i = 0; i < px.size(); ++i) {
    EXPECT_EQ(some.depth(0, Eigen::Index(i)), whole.depth(px[i] / co.width, px[i] % co.width));
    cast += rays.count(px[i]);
  }
  ASSERT_EQ(some.hits.rows() + some.free_ends.rows(), cast);
  for (const auto& [pts, ids, hit] : {std::tuple{&some.hits, &some.hit_rays, true},
                                      std::tuple{&some.free_ends, &some.free_rays, false}})
    for (Eigen::Index r = 0; r < pts->rows(); ++r) {
      const auto& [p, was_hit] = rays.at((*ids)[r]);
      EXPECT_EQ(was_hit, hit);
      EXPECT_EQ(Eigen::Vector3d(pts->row(r).transpose()), p);
      if (r) EXPECT_LT((*ids)[r], (*ids)[r - 1]);  // in the order listed
    }
  std::vector<int> outside{0, co.width * co.height};
  EXPECT_THROW(cam.scan_pixels(T, Eigen::Map<const Eigen::VectorXi>(outside.data(), 2)),
               std::invalid_argument);
}

TEST(FrameRefinement, FullResolutionWhereNewCoarseWhereKnown) {
  DepthCameraOptions co;
  co.width = 120;
  co.height = 90;
  const auto sc = scene();
  DepthCameraOptions cc = co;
  cc.width = co.width / 3;  // 1 pixel in 3 on each axis
  cc.height = co.height / 3;
  const DepthCamera cam(sc, co), coarse_cam(sc, cc);
  const Pose pose{3, 2, 4, 0.6, 0.5};
  const Scan whole = cam.scan_pose(pose), coarse = coarse_cam.scan_pose(pose);
  Kept kept;
  // Nothing seen yet: every block with a hit, and its neighbours, is cast again, so the frame is
  // the full-resolution one: each of its hits at the same pixel, at the same point.
  const Scan fresh = refine_frame(cam, coarse, pose, kept.surface, 30.0);
  ASSERT_EQ(fresh.depth.rows(), co.height);
  ASSERT_EQ(fresh.depth.cols(), co.width);
  ASSERT_EQ(fresh.hits.rows(), whole.hits.rows());
  const auto rays = by_pixel(whole);
  for (Eigen::Index r = 0; r < fresh.hits.rows(); ++r) {
    const auto& [p, hit] = rays.at(fresh.hit_rays[r]);
    ASSERT_TRUE(hit);
    ASSERT_EQ(Eigen::Vector3d(fresh.hits.row(r).transpose()), p);
  }
  EXPECT_LT(fresh.free_ends.rows(), whole.free_ends.rows());  // far from a hit: coarse
  // A wall filling the view whose every square is recorded as seen from here: nothing a denser
  // frame could add, so the coarse frame stands as it was, its rays renamed to their blocks'
  // first pixels.
  {
    Points v(4, 3);
    v << 10.1, -30, -30, 10.1, 30, -30, 10.1, 30, 30, 10.1, -30, 30;
    Faces f(2, 3);
    f << 0, 1, 2, 0, 2, 3;
    const auto wall = std::make_shared<RaycastScene>(Mesh::from_arrays(v, f));
    const DepthCamera wcam(wall, co), wcoarse_cam(wall, cc);
    const Pose ahead{4, 4, 3, 0};
    const Scan wcoarse = wcoarse_cam.scan_pose(ahead);
    ASSERT_EQ(wcoarse.hits.rows(), cc.width * cc.height);
    Points dense(800 * 600, 3);  // every 1 cm of the wall within the workspace
    for (int i = 0; i < 800; ++i)
      for (int j = 0; j < 600; ++j)
        dense.row(i * 600 + j) << 10.1, 0.005 + 0.01 * i, 0.005 + 0.01 * j;
    Kept seen;
    seen.surface.add_scan(Eigen::Vector3d(4, 4, 3), dense);
    const Scan known = refine_frame(wcam, wcoarse, ahead, seen.surface, 30.0);
    EXPECT_EQ(known.hits, wcoarse.hits);
    EXPECT_EQ(known.free_ends.rows(), 0);
    for (Eigen::Index r = 0; r < known.hits.rows(); ++r) {
      const int pc = wcoarse.hit_rays[r];
      EXPECT_EQ(known.hit_rays[r], (pc / cc.width) * 3 * co.width + (pc % cc.width) * 3);
      EXPECT_EQ(known.depth((pc / cc.width) * 3 + 2, (pc % cc.width) * 3 + 1),
                wcoarse.depth(pc / cc.width, pc % cc.width));
    }
    // one column of squares unmarked: the hits on it, and their neighbours, are cast again
    Kept holed;
    Points part(0, 3);
    std::vector<Eigen::Index> rows;
    for (Eigen::Index r = 0; r < dense.rows(); ++r)
      if (dense(r, 1) < 3.8 || dense(r, 1) > 3.85) rows.push_back(r);
    part.resize(Eigen::Index(rows.size()), 3);
    for (std::size_t i = 0; i < rows.size(); ++i) part.row(Eigen::Index(i)) = dense.row(rows[i]);
    holed.surface.add_scan(Eigen::Vector3d(4, 4, 3), part);
    const Scan around = refine_frame(wcam, wcoarse, ahead, holed.surface, 30.0);
    EXPECT_GT(around.hits.rows(), wcoarse.hits.rows());
    EXPECT_LT(around.hits.rows(), wcam.scan_pose(ahead).hits.rows() / 2);
  }
  kept.surface.add_scan(coarse.origin, coarse.hits);
  // The board seen, not the walls: the walls' blocks are refined, the board's are not.
  Kept board;
  Points on_board(0, 3);
  std::vector<Eigen::Index> rows;
  for (Eigen::Index r = 0; r < whole.hits.rows(); ++r)
    if (whole.hits(r, 2) > 0.9 && whole.hits(r, 0) < 7.4 && whole.hits(r, 0) > 5.1 &&
        whole.hits(r, 1) > 1.6 && whole.hits(r, 1) < 4.9)
      rows.push_back(r);
  on_board.resize(Eigen::Index(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i)
    on_board.row(Eigen::Index(i)) = whole.hits.row(rows[i]);
  ASSERT_GT(on_board.rows(), 500);
  board.surface.add_scan(whole.origin, on_board);
  const Scan part = refine_frame(cam, coarse, pose, board.surface, 30.0);
  EXPECT_GT(part.hits.rows(), coarse.hits.rows());
  EXPECT_LT(part.hits.rows(), whole.hits.rows());
  // bad input: a coarse frame finer than the camera's, rays that do not match the points
  EXPECT_THROW(refine_frame(coarse_cam, whole, pose, kept.surface, 30.0), std::invalid_argument);
  Scan broken = coarse;
  broken.hit_rays[0] = cc.width * cc.height;
  EXPECT_THROW(refine_frame(cam, broken, pose, kept.surface, 30.0), std::invalid_argument);
  broken.hit_rays.resize(1);
  EXPECT_THROW(refine_frame(cam, broken, pose, kept.surface, 30.0), std::invalid_argument);
  EXPECT_THROW(refine_frame(cam, coarse, Pose{3, 2, 4, 0, 2.0}, kept.surface, 30.0),
               std::invalid_argument);  // beyond the gimbal
}

TEST(FrameRefinement, ACoarseFramesKeptHitsDoNotSaturate) {
  // A wall's cells sampled every centimetre, then the same points seen from a new side, once as
  // a dense frame's hits and once as a coarse frame's kept ones (Scan::sparse_hits): both mark
  // the same sides and squares; only the dense hits are evidence that the cells are sampled
  // whole (saturated: no views planned for them).
  Points wall(200 * 200, 3);
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 200; ++j) wall.row(i * 200 + j) << 10.1, 2.005 + 0.01 * i, 2.005 + 0.01 * j;
  Kept dense, sparse;
  for (Kept* k : {&dense, &sparse}) k->surface.add_scan(Eigen::Vector3d(4, 3, 3), wall);
  ASSERT_EQ(dense.surface.saturated_cells(), 0);  // the first scan added every square
  const Eigen::Vector3d aside(6, 9, 3);           // another direction bin
  dense.surface.add_scan(aside, wall);
  sparse.surface.add_scan(aside, wall, wall.rows());
  EXPECT_GT(dense.surface.saturated_cells(), 50);
  EXPECT_EQ(sparse.surface.saturated_cells(), 0);
  std::int64_t differ = 0;
  for (std::int64_t i = 0; i < dense.map.grid().num_cells(); ++i)
    differ += dense.surface.seen(i) != sparse.surface.seen(i) ||
              (dense.surface.patches(i) & ~SurfaceObservations::kSaturated) !=
                  sparse.surface.patches(i) ||
              dense.surface.hits(i) != sparse.surface.hits(i);
  EXPECT_EQ(differ, 0);
  // a refined frame names its kept coarse hits: the leading ones. A wall recorded every
  // centimetre but for one column of squares: the hits on and around that column are refined.
  Points v(4, 3);
  v << 10.1, -30, -30, 10.1, 30, -30, 10.1, 30, 30, 10.1, -30, 30;
  Faces f(2, 3);
  f << 0, 1, 2, 0, 2, 3;
  const auto sc = std::make_shared<RaycastScene>(Mesh::from_arrays(v, f));
  DepthCameraOptions co;
  co.width = 120;
  co.height = 90;
  DepthCameraOptions cc = co;
  cc.width = 40;
  cc.height = 30;
  const DepthCamera cam(sc, co), coarse_cam(sc, cc);
  const Pose pose{4, 4, 3, 0};
  const Scan coarse = coarse_cam.scan_pose(pose);
  EXPECT_EQ(coarse.sparse_hits, 0);
  Points most(0, 3);
  std::vector<Eigen::Index> rows;
  for (int i = 0; i < 800; ++i)
    for (int j = 0; j < 600; ++j)
      if (0.005 + 0.01 * i < 3.8 || 0.005 + 0.01 * i > 3.85) rows.push_back(i * 600 + j);
  most.resize(Eigen::Index(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const Eigen::Index i = rows[k] / 600, j = rows[k] % 600;
    most.row(Eigen::Index(k)) << 10.1, 0.005 + 0.01 * i, 0.005 + 0.01 * j;
  }
  Kept holed;
  holed.surface.add_scan(Eigen::Vector3d(4, 4, 3), most);
  const Scan refined = refine_frame(cam, coarse, pose, holed.surface, 30.0);
  EXPECT_GT(refined.sparse_hits, coarse.hits.rows() / 2);
  EXPECT_LT(refined.sparse_hits, coarse.hits.rows());
  for (Eigen::Index r = 0; r < refined.hits.rows(); ++r) {
    const double y = refined.hits(r, 1);  // kept: away from the column; refined: near it
    if (r < refined.sparse_hits)
      EXPECT_TRUE(y < 3.8 || y >= 4.0) << y;
    else
      EXPECT_TRUE(y > 3.3 && y < 4.5) << y;
  }
}
