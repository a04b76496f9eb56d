// The strict PLY reader (nbv/ply.hpp): valid files in every encoding, and hostile ones (truncated
// data or header, counts beyond the file, out-of-range indices) that must throw, never crash.
#include "nbv/common.hpp"
#include "nbv/mesh.hpp"
#include "nbv/ply.hpp"
#include "nbv/raycast.hpp"
#include "nbv/sensors.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace {

const float kV[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};

std::string header(const std::string& fmt, int nv = 4, int nf = 2) {
  return "ply\nformat " + fmt + " 1.0\ncomment test\nelement vertex " + std::to_string(nv) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(nf) + "\nproperty list uchar int vertex_indices\nend_header\n";
}

std::string ascii_square(int bad_index = 3) {
  return header("ascii") + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 " +
         std::to_string(bad_index) + "\n";
}

template <typename T>
void put(std::string& s, T v, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  s.append(b, sizeof(T));
}

std::string binary_square(bool big, int last_index = 3) {
  std::string s = header(big ? "binary_big_endian" : "binary_little_endian");
  for (const auto& v : kV)
    for (float c : v) put(s, c, big);
  const int f[2][3] = {{0, 1, 2}, {0, 2, last_index}};
  for (const auto& t : f) {
    put<std::uint8_t>(s, 3, big);
    for (int i : t) put<std::int32_t>(s, i, big);
  }
  return s;
}

nbv::PlyData parse(const std::string& s, bool faces = true) {
  return nbv::parse_ply(reinterpret_cast<const std::uint8_t*>(s.data()), s.size(), faces);
}

// A mesh's PLY text parsed (for error_of).
nbv::PlyData parse_mesh(const std::string& s) { return parse(s); }

void expect_square(const nbv::PlyData& d) {
  ASSERT_EQ(d.vertices.rows(), 4);
  ASSERT_EQ(d.faces.rows(), 2);
  EXPECT_DOUBLE_EQ(d.vertices(2, 0), 1.0);
  EXPECT_DOUBLE_EQ(d.vertices(2, 1), 1.0);
  EXPECT_EQ(d.faces(1, 2), 3);
}

using nbv_test::error_of;

}  // namespace

TEST(Ply, ReadsAsciiAndBothBinaryEncodings) {
  expect_square(parse(ascii_square()));
  expect_square(parse(binary_square(false)));
  expect_square(parse(binary_square(true)));
}

TEST(Ply, PolygonsBecomeFansAndOtherPropertiesAreSkipped) {
  const std::string s =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty uchar red\n"
      "property float y\nproperty float z\nelement face 1\nproperty uchar flags\n"
      "property list uchar int vertex_indices\nproperty list uchar float tex\nend_header\n"
      "0 9 0 0\n1 9 0 0\n1 9 1 0\n0 9 1 0\n7 4 0 1 2 3 2 0.5 0.5\n";
  const auto d = parse(s);
  ASSERT_EQ(d.faces.rows(), 2);
  EXPECT_DOUBLE_EQ(d.vertices(1, 0), 1.0);
  EXPECT_DOUBLE_EQ(d.vertices(2, 1), 1.0);
  EXPECT_EQ(d.faces(1, 2), 3);
}

using nbv_test::area_of;

TEST(Ply, NonConvexPolygonsAreCutAsTheObjReaderCutsThem) {
  // a dart (area 1.5) and an L-shaped hexagon (area 5), from every start vertex: a fan from the
  // first vertex covered ground outside them (2.5 and 9); faces before the vertices, too
  const std::vector<std::vector<double>> shapes = {{0, 0, 2, 1, 0, 2, 0.5, 1},
                                                   {0, 0, 3, 0, 3, 1, 1, 1, 1, 3, 0, 3}};
  const double areas[2] = {1.5, 5.0};
  for (int s = 0; s < 2; ++s) {
    const std::size_t n = shapes[s].size() / 2;
    for (std::size_t start = 0; start < n; ++start)
      for (bool faces_first : {false, true}) {
        std::string verts, face = std::to_string(n);
        for (std::size_t i = 0; i < n; ++i) {
          verts += std::to_string(shapes[s][2 * i]) + " " + std::to_string(shapes[s][2 * i + 1]) +
                   " 0\n";
          face += " " + std::to_string((start + i) % n);
        }
        const std::string v_el = "element vertex " + std::to_string(n) +
                                 "\nproperty double x\nproperty double y\nproperty double z\n";
        const std::string f_el = "element face 1\nproperty list uchar int vertex_indices\n";
        const std::string text = "ply\nformat ascii 1.0\n" +
                                 (faces_first ? f_el + v_el : v_el + f_el) + "end_header\n" +
                                 (faces_first ? face + "\n" + verts : verts + face + "\n");
        const auto d = parse(text);
        ASSERT_EQ(d.faces.rows(), static_cast<Eigen::Index>(n - 2));
        EXPECT_NEAR(area_of(d), areas[s], 1e-12) << s << " from " << start;
        for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {  // the winding (+z) is kept
          const Eigen::Vector3d p0 = d.vertices.row(d.faces(i, 0)),
                                p1 = d.vertices.row(d.faces(i, 1)),
                                p2 = d.vertices.row(d.faces(i, 2));
          EXPECT_GT((p1 - p0).cross(p2 - p0).z(), 0);
        }
      }
  }
}

TEST(Ply, TruncatedDataThrows) {
  const std::string b = binary_square(false);
  for (std::size_t n = b.find("end_header") + 11; n < b.size(); ++n)
    EXPECT_NE(error_of(parse_mesh, b.substr(0, n)), "") << "cut at " << n;
  const std::string a = ascii_square();
  EXPECT_NE(error_of(parse_mesh, a.substr(0, a.size() - 8)).find("truncated"), std::string::npos);
}

TEST(Ply, DataAfterTheDeclaredRecordsThrows) {
  // a header whose counts declare fewer records than the file holds would load part of it
  for (const bool big : {false, true}) {
    std::string b = binary_square(big);
    EXPECT_EQ(error_of(parse_mesh, b + "\n"), "");  // a line end after the data: padding
    b.replace(b.find("element face 2"), 14, "element face 1");
    EXPECT_NE(error_of(parse_mesh, b).find("bytes of data after the last record"),
              std::string::npos);
  }
  std::string a = ascii_square();
  a.replace(a.find("element face 2"), 14, "element face 1");
  EXPECT_NE(error_of(parse_mesh, a).find("after the last record"), std::string::npos);
  // a cloud read stops after its vertices: what follows them is not read, nor checked
  EXPECT_EQ(parse(a, /*faces=*/false).vertices.rows(), 4);
}

TEST(Ply, TruncatedHeaderThrowsAndDoesNotLoop) {
  const std::string b = binary_square(false);
  for (std::size_t n = 0; n < b.find("end_header") + 10; ++n)
    EXPECT_NE(error_of(parse_mesh, b.substr(0, n)), "") << "cut at " << n;
}

TEST(Ply, CountsBeyondTheFileThrowBeforeAllocating) {
  std::string s = header("binary_little_endian", 1000000000, 0);
  s += std::string(100, '\0');
  EXPECT_NE(error_of(parse_mesh, s).find("declares 1000000000"), std::string::npos)
      << error_of(parse_mesh, s);
  std::string a = header("ascii", 2000000000, 2000000000) + "0 0 0\n";
  EXPECT_NE(error_of(parse_mesh, a).find("truncated"), std::string::npos);
  EXPECT_NE(error_of(parse_mesh, header("ascii", 4) + "0 0 0\n1 0 0\n"), "");  // fewer vertex lines
  EXPECT_NE(error_of(parse_mesh,
                     "ply\nformat ascii 1.0\nelement vertex 99999999999999999999\nend_header\n"),
            "");
}

TEST(Ply, OutOfRangeFaceIndexThrows) {
  for (int bad : {4, 1000, -1}) {
    EXPECT_NE(error_of(parse_mesh, ascii_square(bad)).find("out of range"), std::string::npos)
        << bad;
    EXPECT_NE(error_of(parse_mesh, binary_square(false, bad)).find("out of range"),
              std::string::npos);
  }
}

TEST(Ply, BadHeadersThrow) {
  EXPECT_NE(error_of(parse_mesh, "").find("not a PLY"), std::string::npos);
  EXPECT_NE(error_of(parse_mesh, "plyx\n").find("not a PLY"), std::string::npos);
  EXPECT_NE(error_of(parse_mesh, "ply\nend_header\n").find("format"), std::string::npos);
  EXPECT_NE(error_of(parse_mesh, "ply\nformat ascii 1.0\nproperty float x\nend_header\n"), "");
  EXPECT_NE(error_of(parse_mesh,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
            "");
  EXPECT_NE(error_of(parse_mesh, "ply\nformat weird 1.0\nend_header\n"), "");
  EXPECT_NE(error_of(parse_mesh,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                     "property float y\nend_header\n1 2\n")
                .find("no 'z'"),
            std::string::npos);
  std::string nonascii = ascii_square();
  nonascii[5] = '\xff';
  EXPECT_NE(error_of(parse_mesh, nonascii), "");
}

TEST(Ply, AnAsciiRecordIsOneLine) {
  const auto error = [](const std::string& text) { return error_of([&] { parse(text); }); };
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string face = "element face 1\nproperty list uchar int vertex_indices\n";
  // a face line one value short ran onto the next line: the triangle (1, 2, 3) of the wrong
  // vertices, loaded without a word
  EXPECT_NE(error("ply\nformat ascii 1.0\nelement vertex 5\n" + xyz + face + "end_header\n" +
                  "0 0 0\n1 0 0\n0 1 0\n5 5 5\n9 9 9\n3 1 2\n3 0 1 2\n")
                .find("element 'face', record 0: fewer values than its properties"),
            std::string::npos);
  // normals declared and not written: every vertex took the next one's values
  EXPECT_NE(error("ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
                  "property float nx\nproperty float ny\nproperty float nz\nelement face 3\n"
                  "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n" +
                  "3 0 1 2\n3 0 1 2\n3 0 1 2\n")
                .find("element 'vertex', record 0: fewer values"),
            std::string::npos);
  // a vertex line holding more values than the properties
  EXPECT_NE(error(header("ascii", 4, 1) + "0 0 0\n1 0 0 7\n1 1 0\n0 1 0\n3 0 1 2\n")
                .find("element 'vertex', record 1: more values"),
            std::string::npos);
  // trailing blanks, CRLF, CR alone and blank lines between records stay fine
  for (const std::string body : {std::string("0 0 0 \r\n1 0 0\t\r\n\n1 1 0\n0 1 0\n3 0 1 2  \n"),
                                 std::string("0 0 0\r1 0 0\r1 1 0\r0 1 0\r3 0 1 2\r")}) {
    const auto d = parse(header("ascii", 4, 1) + body);
    EXPECT_EQ(d.faces.rows(), 1);
    EXPECT_DOUBLE_EQ(d.vertices(2, 1), 1.0);
  }
}

TEST(Ply, CloudReadStopsAfterTheVertices) {
  const std::string s = binary_square(false);
  const std::string cut = s.substr(0, s.size() - 5);  // faces truncated, vertices whole
  const auto d = parse(cut, /*faces=*/false);
  EXPECT_EQ(d.vertices.rows(), 4);
  EXPECT_EQ(d.faces.rows(), 0);
}

TEST(Ply, LoadMeshReadsPlyThroughTheStrictReader) {
  const std::string path = ::testing::TempDir() + "nbv_ply_test.ply";
  {
    std::ofstream f(path, std::ios::binary);
    f << ascii_square(7);
  }
  const std::string e = error_of(nbv::load_mesh, path, 1.0, 'z');
  EXPECT_NE(e.find("nbv_ply_test.ply"), std::string::npos) << e;
  EXPECT_NE(e.find("out of range"), std::string::npos) << e;
  {  // a face's vertex with a NaN coordinate: the loader's check for every format
    std::ofstream f(path, std::ios::binary);
    std::string text = ascii_square();
    f << text.replace(text.find("1 1 0\n"), 5, "1 nan 0");
  }
  EXPECT_NE(error_of(nbv::load_mesh, path, 1.0, 'z')
                .find("1 vertices of its faces have a NaN or infinite coordinate (vertex 2 is (1, "
                      "nan, 0))"),
            std::string::npos);
  {
    std::ofstream f(path, std::ios::binary);
    f << binary_square(true);
  }
  const nbv::Mesh m = nbv::load_mesh(path, 2.0, 'y');
  EXPECT_EQ(m.faces.rows(), 2);
  EXPECT_DOUBLE_EQ(m.vertices(2, 0), 2.0);  // x scaled
  EXPECT_DOUBLE_EQ(m.vertices(2, 2), 2.0);  // file y became z
  std::remove(path.c_str());
}

TEST(Hostile, UnrepresentablePosesThrow) {
  nbv::Points v(3, 3);
  v << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  nbv::Faces f(1, 3);
  f << 0, 1, 2;
  auto scene = std::make_shared<nbv::RaycastScene>(nbv::Mesh::from_arrays(v, f));
  nbv::DepthCamera cam(scene);
  nbv::LaserScanner laser(scene);
  for (double x : {2e18, -1e10, std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(cam.scan_pose(nbv::Pose{x, 0, 4, 0}), std::invalid_argument);
    EXPECT_THROW(laser.scan_pose(nbv::Pose{0, x, 4, 0}), std::invalid_argument);
    nbv::Points o(1, 3), d(1, 3);
    o << 0, 0, x;
    d << 0, 0, -1;
    Eigen::VectorXd t;
    Eigen::VectorXi prim;
    EXPECT_THROW(scene->intersect(o, d, 0, 100, t, prim), std::invalid_argument);
  }
}

TEST(Hostile, DerivedRayCountsAreBounded) {
  nbv::LaserScannerOptions o;
  for (double r : {1e-9, 1e-7, 1e-300}) {
    o.resolution_deg = r;
    EXPECT_NE(error_of(&nbv::LaserScannerOptions::validate, o).find("resolution_deg"),
              std::string::npos)
        << r;
  }
  nbv::DepthCameraOptions c;
  c.width = 100000;
  c.height = 100000;
  EXPECT_THROW(c.validate(), std::invalid_argument);
}
