// The camera gimbal (issue 33, part 1): a view is (x, y, z, yaw, pitch), the camera at
// T(x, y, z) Rz(yaw) Ry(pitch) mount, pitch > 0 looking down. Analytic pixels of a pitched
// camera, view scoring of a pitched view against a level one with the pitch in its mount, level
// views bit for bit as before, the memos keeping pitches apart, bad pitches refused.
#include "nbv/coverage.hpp"
#include "nbv/grid_view.hpp"
#include "nbv/mesh.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/raycast.hpp"
#include "nbv/sensors.hpp"
#include "nbv/surface_observations.hpp"
#include "nbv/views.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

using namespace nbv;

namespace {

constexpr double kDeg = M_PI / 180.0;

// A floor: the square z = 0, |x|, |y| <= 100 m, facing up.
std::shared_ptr<const RaycastScene> floor_scene() {
  Points v(4, 3);
  v << -100, -100, 0, 100, -100, 0, 100, 100, 0, -100, 100, 0;
  Faces f(2, 3);
  f << 0, 1, 2, 0, 2, 3;
  return std::make_shared<RaycastScene>(Mesh::from_arrays(v, f));
}

DepthCameraOptions odd_camera() {
  DepthCameraOptions o;
  o.width = 65;  // odd: the optical axis passes through pixel centre (32, 24)
  o.height = 49;
  o.hfov_deg = 60;
  o.vfov_deg = 45;
  o.min_range = 0.1;
  o.max_range = 50;
  return o;
}

// The hit of pixel (u, v) in a scan, or NaN.
Eigen::Vector3d hit_of(const Scan& s, int width, int u, int v) {
  for (Eigen::Index i = 0; i < s.hits.rows(); ++i)
    if (s.hit_rays[i] == v * width + u) return s.hits.row(i).transpose();
  return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
}

}  // namespace

TEST(Gimbal, LevelIsTheYawOnlyTransformBitForBit) {
  const Eigen::Isometry3d mount = mount_transform({0.1, -0.2, 0.3}, 2, 10, -5);
  for (const double pitch : {0.0, -0.0}) {
    const Pose p{1.5, -2.25, 3.0, 0.7, pitch};
    const Eigen::Matrix4d a = gimbal_sensor_transform(p, mount).matrix();
    const Eigen::Matrix4d b = (pose_to_transform(p) * mount).matrix();
    EXPECT_EQ(a, b);  // exact
  }
  // the body does not pitch: pose_to_transform ignores it
  EXPECT_EQ(pose_to_transform({1, 2, 3, 0.4, 0.9}).matrix(),
            pose_to_transform({1, 2, 3, 0.4}).matrix());
}

TEST(Gimbal, PitchTurnsTheOpticalAxisDown) {
  // axis = Rz(yaw) Ry(pitch) x = (cos yaw cos pitch, sin yaw cos pitch, -sin pitch)
  for (const double yaw : {0.0, 0.8, -2.5})
    for (const double pitch : {-60.0, -30.0, 15.0, 45.0, 90.0}) {
      const double p = pitch * kDeg;
      const Eigen::Isometry3d T =
          gimbal_sensor_transform({4, 5, 6, yaw, p}, Eigen::Isometry3d::Identity());
      const Eigen::Vector3d axis = T.linear().col(0);
      EXPECT_NEAR(axis.x(), std::cos(yaw) * std::cos(p), 1e-15);
      EXPECT_NEAR(axis.y(), std::sin(yaw) * std::cos(p), 1e-15);
      EXPECT_NEAR(axis.z(), -std::sin(p), 1e-15);
      EXPECT_EQ(T.translation(), Eigen::Vector3d(4, 5, 6));
    }
  // a mount offset rides the gimbal: 1 m forward, pitched straight down, is 1 m below the body
  const Eigen::Isometry3d T =
      gimbal_sensor_transform({0, 0, 5, 0, M_PI / 2}, mount_transform({1, 0, 0}, 0, 0, 0));
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0, 0, 4)).norm(), 0.0, 1e-15);
  // the gimbal's pitch adds to the mount's: gimbal 20 deg + mount 10 deg = 30 deg down
  const Eigen::Isometry3d U =
      gimbal_sensor_transform({0, 0, 0, 0, 20 * kDeg}, mount_transform({0, 0, 0}, 0, 10, 0));
  EXPECT_NEAR(U.linear().col(0).z(), -std::sin(30 * kDeg), 1e-15);
}

TEST(Gimbal, PitchedCameraSeesAFloorPointAtThePredictedPixel) {
  const auto scene = floor_scene();
  const DepthCameraOptions o = odd_camera();
  const DepthCamera cam(scene, o);
  const double h = 4.0;
  // The centre column: a floor point straight ahead at distance x lies atan(h / x) below the
  // horizon, i.e. atan(h / x) - pitch below the optical axis: row v with
  // (v + 0.5 - H / 2) = fy tan(atan(h / x) - pitch).
  for (const double pitch_deg : {10.0, 30.0, 50.0}) {
    const double pitch = pitch_deg * kDeg;
    for (const int v : {5, 24, 40}) {
      const double alpha = std::atan((v + 0.5 - o.height / 2.0) / cam.fy());
      const double x = h / std::tan(pitch + alpha);
      for (const double yaw : {0.0, M_PI / 2}) {
        const Scan s = cam.scan_pose({0, 0, h, yaw, pitch});
        if (pitch + alpha <= 0) {  // the pixel looks above the horizon: no floor
          EXPECT_TRUE(std::isinf(s.depth(v, 32))) << "pitch " << pitch_deg << " row " << v;
          continue;
        }
        const Eigen::Vector3d hit = hit_of(s, o.width, 32, v);
        const Eigen::Vector3d expect(x * std::cos(yaw), x * std::sin(yaw), 0.0);
        EXPECT_NEAR((hit - expect).norm(), 0.0, 1e-9 * x)
            << "pitch " << pitch_deg << " row " << v << " yaw " << yaw;
        // its depth: the distance along the optical axis
        const Eigen::Vector3d axis(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                                   -std::sin(pitch));
        EXPECT_NEAR(s.depth(v, 32), (expect - Eigen::Vector3d(0, 0, h)).dot(axis), 1e-9 * x);
      }
    }
  }
  // Straight down (pitch 90 deg, yaw 0): the sensor's +x is world -z, its +y world +y and its
  // +z (up in the image) world +x. Pixel (u, v) looks along (1, -a, -b) in the sensor frame,
  // a = (u + 0.5 - W/2) / fx, b = (v + 0.5 - H/2) / fy: it sees the floor point (-b h, -a h, 0).
  const Scan down = cam.scan_pose({0, 0, h, 0, M_PI / 2});
  const std::vector<std::pair<int, int>> pixels = {{32, 24}, {0, 0}, {64, 48}, {10, 40}, {50, 3}};
  for (const auto& [u, v] : pixels) {
    const double a = (u + 0.5 - o.width / 2.0) / cam.fx(),
                 b = (v + 0.5 - o.height / 2.0) / cam.fy();
    const Eigen::Vector3d hit = hit_of(down, o.width, u, v);
    EXPECT_NEAR((hit - Eigen::Vector3d(-b * h, -a * h, 0)).norm(), 0.0, 1e-9) << u << "," << v;
    EXPECT_NEAR(down.depth(v, u), h, 1e-9);  // the floor is parallel to the image plane
  }
  // Level, the upper half of the image sees no floor; pitched down 30 deg it sees some of it.
  const Scan level = cam.scan_pose({0, 0, h, 0});
  for (Eigen::Index i = 0; i < level.hits.rows(); ++i)
    ASSERT_GE(level.hit_rays[i] / o.width, o.height / 2);
  const Scan pitched = cam.scan_pose({0, 0, h, 0, 30 * kDeg});
  EXPECT_GT(pitched.hits.rows(), level.hits.rows());
}

TEST(Gimbal, TheLaserKeepsItsFixedMount) {
  const auto scene = floor_scene();
  const LaserScanner laser(scene);  // pitched 10 deg down on the body
  const Scan a = laser.scan_pose({1, 2, 3, 0.5});
  const Scan b = laser.scan_pose({1, 2, 3, 0.5, 60 * kDeg});
  EXPECT_EQ(a.hits, b.hits);
  EXPECT_EQ(a.free_ends, b.free_ends);
}

TEST(Gimbal, BadPitchesAreRefused) {
  const auto scene = floor_scene();
  const DepthCamera cam(scene, odd_camera());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const double bad : {nan, inf, -inf, M_PI / 2 + 1e-9, -2.0, 3.0}) {
    EXPECT_THROW(cam.scan_pose({0, 0, 4, 0, bad}), std::invalid_argument) << bad;
    EXPECT_THROW(require_pitch(bad, "x"), std::invalid_argument) << bad;
    ViewPoses c(1, 5);
    c << 0, 0, 4, 0, bad;
    EXPECT_THROW(check_view_poses(c), std::invalid_argument) << bad;
  }
  EXPECT_NO_THROW(cam.scan_pose({0, 0, 4, 0, M_PI / 2}));
  EXPECT_NO_THROW(cam.scan_pose({0, 0, 4, 0, -M_PI / 2}));
  try {
    require_pitch(2.0, "candidate view 3");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("candidate view 3: pitch"), std::string::npos);
  }
  EXPECT_THROW(check_view_poses(ViewPoses::Zero(2, 3)), std::invalid_argument);
  EXPECT_THROW(check_view_poses(ViewPoses::Zero(2, 6)), std::invalid_argument);
  EXPECT_NO_THROW(check_view_poses(ViewPoses::Zero(2, 4)));
  EXPECT_NO_THROW(check_view_poses(ViewPoses::Zero(2, 5)));
}

TEST(Gimbal, PoseKeysKeepPitchesApart) {
  EXPECT_NE(pose_key(1, 2, 3, 0.5, 0.2), pose_key(1, 2, 3, 0.5, 0.3));
  EXPECT_NE(pose_key(1, 2, 3, 0.5, 0.2), pose_key(1, 2, 3, 0.5));
  EXPECT_EQ(pose_key(1, 2, 3, 0.5, -0.0), pose_key(1, 2, 3, 0.5, 0.0));  // both level
  EXPECT_EQ(pose_key(1, 2, 3, 0.5), pose_key(Pose{1, 2, 3, 0.5}));
}

namespace {

// A 12 x 8 x 6 m map with a floor, a wall and a block seen by a few camera scans, its camera
// observations, and candidate views around (5, 4, 3).
struct PitchScene {
  OccupancyMap map{0.2, {0, 0, 0}, {12, 8, 6}};
  std::unique_ptr<SurfaceObservations> surface;
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> cand;
  ViewCameraModel camera;
  UtilityOptions utility;
  ValidityOptions validity;

  explicit PitchScene(Eigen::Index n) : cand(n, 4) {
    Points v(12, 3);
    v << 0, 0, 0.3, 12, 0, 0.3, 12, 8, 0.3, 0, 8, 0.3,   // floor
        10.5, 0, 0, 10.5, 8, 0, 10.5, 8, 6, 10.5, 0, 6,  // wall
        6, 2, 1, 8, 2, 1, 8, 6, 2.5, 6, 6, 2.5;          // a slanted block top
    Faces f(6, 3);
    f << 0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7, 8, 9, 10, 8, 10, 11;
    const auto scene = std::make_shared<RaycastScene>(Mesh::from_arrays(v, f));
    DepthCameraOptions co;
    co.width = 80;
    co.height = 60;
    const DepthCamera cam(scene, co);
    surface = std::make_unique<SurfaceObservations>(map);
    for (const Pose& p : {Pose{2, 4, 3, 0}, Pose{3, 2, 4, 0.6, 0.5}, Pose{4, 6, 3.5, -0.4, 0.2}}) {
      const Scan s = cam.scan_pose(p);
      map.integrate(s);
      surface->add_scan(s.origin, s.hits);
    }
    map.mark_free_segment({3, 4, 3}, {7, 4, 3}, 1.2);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    for (Eigen::Index k = 0; k < n; ++k)
      cand.row(k) << 5 + u(rng), 4 + 0.4 * u(rng), 3 + 0.3 * u(rng), 0.8 * u(rng);
    camera.rays_x = 30;
    camera.rays_y = 22;
    camera.mount = mount_transform({0.1, 0, -0.05}, 0, 5, 0);
    utility.require_occupied = false;
    validity.collision_radius = 0.3;
    validity.blocked_path = "plan";
  }
  ViewPoses pitched(double pitch) const {
    ViewPoses c(cand.rows(), 5);
    c.leftCols(4) = cand;
    c.col(4).setConstant(pitch);
    return c;
  }
};

void expect_same(const ViewScores& a, const ViewScores& b, const std::string& what) {
  EXPECT_EQ(a.gain, b.gain) << what;  // bit for bit
  EXPECT_EQ(a.utility, b.utility) << what;
  EXPECT_EQ(a.cells, b.cells) << what;
  EXPECT_EQ(a.occupied_seen, b.occupied_seen) << what;
  EXPECT_EQ(a.status, b.status) << what;
}

void expect_same(const ViewCoverage& a, const ViewCoverage& b, const std::string& what) {
  EXPECT_EQ(a.offsets, b.offsets) << what;
  EXPECT_EQ(a.elements, b.elements) << what;
  EXPECT_EQ(a.weights, b.weights) << what;
  EXPECT_EQ(a.status, b.status) << what;
}

}  // namespace

TEST(Gimbal, APitchedViewScoresAsALevelViewWithThePitchInItsMount) {
  const PitchScene s(12);
  const GridView g = grid_view(s.map, s.surface.get());
  const Pose here{5, 4, 3, 0};
  for (const char* name : {"ig", "surface", "unobserved_voxel", "average_entropy"}) {
    UtilityOptions u = s.utility;
    u.name = name;
    for (const double pitch_deg : {-30.0, -7.5, 20.0, 45.0, 90.0}) {
      const double pitch = pitch_deg * kDeg;
      ViewCameraModel level = s.camera;
      level.mount = gimbal_mount(pitch, s.camera.mount);
      const ViewScores a = evaluate_views(g, s.pitched(pitch), here, s.camera, u, s.validity);
      const ViewScores b = evaluate_views(g, s.cand, here, level, u, s.validity);
      expect_same(a, b, std::string(name) + " " + std::to_string(pitch_deg));
      EXPECT_GT((a.gain.array() > 0).count(), 0) << name;
    }
  }
  // and the coverage sets of the tours
  for (const double pitch_deg : {-20.0, 35.0, 80.0}) {
    const double pitch = pitch_deg * kDeg;
    ViewCameraModel level = s.camera;
    level.mount = gimbal_mount(pitch, s.camera.mount);
    const ViewCoverage a =
        view_coverage(g, s.pitched(pitch), here, s.camera, s.utility, s.validity);
    const ViewCoverage b = view_coverage(g, s.cand, here, level, s.utility, s.validity);
    expect_same(a, b, "coverage " + std::to_string(pitch_deg));
    EXPECT_GT(a.elements.size(), 0);
  }
  // a pitch changes what a view sees
  const ViewScores level = evaluate_views(g, s.cand, here, s.camera, s.utility, s.validity);
  const ViewScores down =
      evaluate_views(g, s.pitched(45 * kDeg), here, s.camera, s.utility, s.validity);
  EXPECT_NE(level.gain, down.gain);
}

TEST(Gimbal, FourColumnsArePitchZeroBitForBit) {
  const PitchScene s(10);
  const GridView g = grid_view(s.map, s.surface.get());
  const Pose here{5, 4, 3, 0};
  for (const char* name : {"ig", "surface"}) {
    UtilityOptions u = s.utility;
    u.name = name;
    for (const double zero : {0.0, -0.0}) {
      ViewMemo m4, m5;
      for (int round = 0; round < 2; ++round) {  // walked, then replayed from the memos
        const ViewScores a = evaluate_views(g, s.cand, here, s.camera, u, s.validity, &m4);
        const ViewScores b = evaluate_views(g, s.pitched(zero), here, s.camera, u, s.validity, &m5);
        expect_same(a, b, name);
      }
      const ViewScores octree4 =
          evaluate_views_octree(s.map, s.cand, here, s.camera, u, s.validity, s.surface.get());
      const ViewScores octree5 = evaluate_views_octree(s.map, s.pitched(zero), here, s.camera, u,
                                                       s.validity, s.surface.get());
      expect_same(octree4, octree5, std::string(name) + " octree");
    }
  }
  CoverageMemo c4, c5;
  for (int round = 0; round < 2; ++round)
    expect_same(view_coverage(g, s.cand, here, s.camera, s.utility, s.validity, &c4),
                view_coverage(g, s.pitched(0.0), here, s.camera, s.utility, s.validity, &c5),
                "coverage");
  EXPECT_GT(c5.stats().reused, 0);
}

TEST(Gimbal, TheMemosKeepPitchesApart) {
  const PitchScene s(8);
  const GridView g = grid_view(s.map, s.surface.get());
  const Pose here{5, 4, 3, 0};
  const double pitches[] = {0.0, 30 * kDeg, -20 * kDeg, 30 * kDeg, 0.0};
  ViewMemo memo(8);
  CoverageMemo cover(8);
  for (const double p : pitches) {
    // the same positions and yaws at another pitch: never answered from the other's record
    expect_same(evaluate_views(g, s.pitched(p), here, s.camera, s.utility, s.validity, &memo),
                evaluate_views(g, s.pitched(p), here, s.camera, s.utility, s.validity),
                "ig " + std::to_string(p));
    expect_same(view_coverage(g, s.pitched(p), here, s.camera, s.utility, s.validity, &cover),
                view_coverage(g, s.pitched(p), here, s.camera, s.utility, s.validity),
                "coverage " + std::to_string(p));
  }
  const auto valid =
      (evaluate_views(g, s.cand, here, s.camera, s.utility, s.validity).status.array() == 0)
          .count();
  EXPECT_EQ(memo.entries(), std::size_t(3 * valid));  // three pitches, each its own entries
  EXPECT_EQ(memo.stats().reused, 2 * valid);          // the two repeated pitches
  EXPECT_EQ(cover.stats().reused, 2 * valid);
}
