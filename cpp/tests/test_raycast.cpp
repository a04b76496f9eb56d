// Edge cases of the mesh and ray-casting core.
#include "nbv/mesh.hpp"
#include "nbv/raycast.hpp"
#include "nbv/sensors.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>

using nbv::Mesh;
using nbv::Points;

namespace {

Mesh wall(double x) {
  Points v(4, 3);
  v << x, -10, -10, x, 10, -10, x, 10, 10, x, -10, 10;
  nbv::Faces f(2, 3);
  f << 0, 1, 2, 0, 2, 3;
  return Mesh::from_arrays(v, f);
}

}  // namespace

TEST(Mesh, RejectsEmptyAndBadIndices) {
  Points v(3, 3);
  v << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  nbv::Faces none(0, 3);
  EXPECT_THROW(Mesh::from_arrays(v, none), std::invalid_argument);
  nbv::Faces bad(1, 3);
  bad << 0, 1, 3;
  EXPECT_THROW(Mesh::from_arrays(v, bad), std::invalid_argument);
  v(1, 1) = std::numeric_limits<double>::quiet_NaN();
  nbv::Faces ok(1, 3);
  ok << 0, 1, 2;
  EXPECT_THROW(Mesh::from_arrays(v, ok), std::invalid_argument);
}

TEST(Mesh, MissingFileThrowsFileNotFound) {
  EXPECT_THROW(nbv::load_mesh("/nonexistent/never.obj"), nbv::FileNotFound);
}

namespace {
// The message of load_mesh(path)'s std::invalid_argument, or "" when it loads.
std::string load_error(const std::string& path) {
  return nbv_test::error_of(nbv::load_mesh, path, 1.0, 'z');
}

std::string write_obj(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}
}  // namespace

TEST(Mesh, NonFiniteVertexIsRefusedNotMergedAway) {
  // assimp's JoinIdenticalVertices would merge the NaN vertex into another: the loader checks
  // the raw vertices first
  const std::string cube =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv X 1 1\n"
      "f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\n"
      "f 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";
  for (const char* bad : {"nan", "inf", "-inf"}) {
    std::string text = cube;
    text.replace(text.find('X'), 1, bad);
    const std::string path = write_obj("nbv_nan_cube.obj", text);
    EXPECT_NE(load_error(path).find("NaN or infinite"), std::string::npos) << bad;
    std::remove(path.c_str());
  }
  std::string text = cube;
  text.replace(text.find('X'), 1, "1");
  const std::string path = write_obj("nbv_cube.obj", text);
  EXPECT_DOUBLE_EQ(nbv::load_mesh(path).area(), 6.0);
  std::remove(path.c_str());
}

TEST(Mesh, FileWithoutAreaFifoAndDeviceAreRefused) {
  const std::string flat = write_obj("nbv_flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
  EXPECT_NE(load_error(flat).find("no area"), std::string::npos);
  std::remove(flat.c_str());
  const std::string fifo = ::testing::TempDir() + "nbv_fifo.obj";
  std::remove(fifo.c_str());
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_NE(load_error(fifo).find("FIFO"), std::string::npos);  // refused, never opened
  std::remove(fifo.c_str());
  EXPECT_NE(load_error("/dev/zero").find("character device"), std::string::npos);
}

TEST(Mesh, ZeroAreaMeshIsRefusedAndCannotBeSampled) {
  Points v(3, 3);
  v << 0, 0, 0, 1, 0, 0, 2, 0, 0;  // collinear: a degenerate triangle
  nbv::Faces f(1, 3);
  f << 0, 1, 2;
  EXPECT_THROW(Mesh::from_arrays(v, f), std::invalid_argument);
  Mesh m;  // built field by field, unchecked
  m.vertices = v;
  m.faces = f;
  EXPECT_DOUBLE_EQ(m.area(), 0.0);
  EXPECT_THROW(m.sample_surface(10, 0), std::invalid_argument);
}

TEST(Raycast, DegenerateTriangleIsNeverHit) {
  Points v(6, 3);
  v << 2, 0, -1, 2, 0, 1, 2, 0, 0,   // zero-area sliver on the ray's path
      5, -1, -1, 5, 1, -1, 5, 0, 1;  // a proper triangle behind it
  nbv::Faces f(2, 3);
  f << 0, 1, 2, 3, 4, 5;
  nbv::RaycastScene scene(Mesh::from_arrays(v, f));
  Points o = Points::Zero(1, 3), d(1, 3);
  d << 1, 0, 0;
  Eigen::VectorXd t;
  Eigen::VectorXi prim;
  scene.intersect(o, d, 0.0, 100.0, t, prim);
  EXPECT_NEAR(t[0], 5.0, 1e-12);
  EXPECT_EQ(prim[0], 1);
}

TEST(Raycast, RayThroughSharedEdgeHitsOnce) {
  // The wall's diagonal edge runs through (x, 0, 0): a ray exactly along it must still hit.
  nbv::RaycastScene scene(wall(3.0));
  Points o = Points::Zero(1, 3), d(1, 3);
  d << 1, 0, 0;
  Eigen::VectorXd t;
  Eigen::VectorXi prim;
  scene.intersect(o, d, 0.0, 100.0, t, prim);
  EXPECT_NEAR(t[0], 3.0, 1e-12);
  EXPECT_GE(prim[0], 0);
}

TEST(Raycast, OriginOnTheSurfaceAndBehind) {
  nbv::RaycastScene scene(wall(3.0));
  Points o(1, 3), d(1, 3);
  o << 4, 0, 0;  // behind the wall, looking away
  d << 1, 0, 0;
  Eigen::VectorXd t;
  Eigen::VectorXi prim;
  scene.intersect(o, d, 0.0, 100.0, t, prim);
  EXPECT_TRUE(std::isinf(t[0]));
  EXPECT_EQ(prim[0], -1);
}

TEST(Sensors, CounterNormalIsStandard) {
  double s = 0, s2 = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double x = nbv::counter_normal(5, 1, static_cast<std::uint64_t>(i));
    s += x;
    s2 += x * x;
  }
  EXPECT_NEAR(s / n, 0.0, 0.01);
  EXPECT_NEAR(s2 / n, 1.0, 0.01);
  EXPECT_EQ(nbv::counter_normal(1, 2, 3), nbv::counter_normal(1, 2, 3));
}

TEST(Sensors, LaserBeamCountForOddResolutions) {
  nbv::LaserScannerOptions o;
  EXPECT_EQ(o.num_beams(), 721);
  o.fov_deg = 270;
  o.resolution_deg = 0.5;
  EXPECT_EQ(o.num_beams(), 541);
  o.fov_deg = 1.0;
  o.resolution_deg = 0.3;  // 0, 0.3, 0.6, 0.9
  EXPECT_EQ(o.num_beams(), 4);
}

TEST(Sensors, CameraTileOrderCoversEveryPixelOnce) {
  auto scene = std::make_shared<nbv::RaycastScene>(wall(4.0));
  nbv::DepthCameraOptions o;
  o.width = 13;  // not a multiple of the 4x4 tile
  o.height = 7;
  nbv::DepthCamera cam(scene, o);
  const nbv::Scan s = cam.scan(Eigen::Isometry3d::Identity());
  ASSERT_EQ(s.hits.rows(), 13 * 7);
  std::vector<int> seen(13 * 7, 0);
  for (Eigen::Index i = 0; i < s.hit_rays.size(); ++i) seen[s.hit_rays[i]]++;
  for (int c : seen) EXPECT_EQ(c, 1);
  for (Eigen::Index i = 0; i < s.hits.rows(); ++i) EXPECT_NEAR(s.hits(i, 0), 4.0, 1e-9);
}

TEST(Raycast, DirectionBeyondSinglePrecisionRangeIsRefused) {
  Points v(3, 3);
  v << 5, -1, -1, 5, 1, -1, 5, 0, 1;
  nbv::Faces f(1, 3);
  f << 0, 1, 2;
  nbv::RaycastScene scene(Mesh::from_arrays(v, f));
  Points o = Points::Zero(1, 3), d(2, 3);
  d << 1, 0, 0, 1e300, 0, 0;  // finite, but Embree aborts on a component beyond ~1.8e18
  Eigen::VectorXd t;
  Eigen::VectorXi prim;
  EXPECT_THROW(scene.intersect(o, d, 0.0, 100.0, t, prim), std::invalid_argument);
  d.row(1) << 0, 0, -nbv::RaycastScene::kMaxDirection;  // the largest taken: no hit behind
  scene.intersect(o, d, 0.0, 100.0, t, prim);
  EXPECT_NEAR(t[0], 5.0, 1e-12);
  EXPECT_EQ(prim[1], -1);
}
