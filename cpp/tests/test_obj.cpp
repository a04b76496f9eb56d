// nbvkit's OBJ reader (nbv/obj.hpp): double precision, index forms, triangulation of convex and
// non-convex polygons, and bad files that must throw naming the line.
#include "nbv/obj.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace {

nbv::ObjData parse(const std::string& s) { return nbv::parse_obj(s.data(), s.size()); }

double area(const nbv::ObjData& d) {
  double a = 0;
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {
    const Eigen::Vector3d p0 = d.vertices.row(d.faces(i, 0)), p1 = d.vertices.row(d.faces(i, 1)),
                          p2 = d.vertices.row(d.faces(i, 2));
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

std::string error_of(const std::string& s) {
  try {
    parse(s);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Obj, KeepsDoublePrecision) {
  const auto d = parse(
      "v 500000.3 5000000.3 100.7\nv 500001.3 5000000.3 100.7\n"
      "v 500000.3 5000001.3 100.7\nf 1 2 3\n");
  ASSERT_EQ(d.vertices.rows(), 3);
  EXPECT_EQ(d.vertices(0, 1), 5000000.3);  // float32 would give 5000000.5
  EXPECT_EQ(d.vertices(0, 0), 500000.3);
}

TEST(Obj, IndexFormsAndPolygons) {
  // a quad with v/vt/vn and negative indices, then a non-convex L-shaped hexagon (area 3)
  const auto d = parse(
      "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nvt 0 0\nvn 0 0 1\nf -4/1/1 -3/1/1 -2//1 -1/1\n"
      "v 0 0 5\nv 2 0 5\nv 2 1 5\nv 1 1 5\nv 1 2 5\nv 0 2 5\nf 5 6 7 8 9 10\n");
  EXPECT_EQ(d.faces.rows(), 2 + 4);
  EXPECT_NEAR(area(d), 4.0 + 3.0, 1e-12);
  // a concave quad (an arrowhead): the fan from its first vertex would cover the notch
  const auto q = parse("v 0 0 0\nv 2 1 0\nv 4 0 0\nv 2 3 0\nf 1 2 3 4\n");
  EXPECT_NEAR(area(q), 4.0, 1e-12);  // 6 (the hull triangle) - 2 (the notch)
}

TEST(Obj, BadFilesNameTheLine) {
  EXPECT_NE(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").find("line 4"), std::string::npos);
  EXPECT_NE(error_of("v 0 0 0\nv 1 x 0\n").find("line 2"), std::string::npos);
  EXPECT_NE(error_of("v 0 0 0\nf -2 1 1\n").find("before the first vertex"), std::string::npos);
  EXPECT_NE(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").find("index 0"), std::string::npos);
  EXPECT_NE(error_of("v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").find("NaN or infinite"),
            std::string::npos);
  // a non-convex polygon of too many vertices (a comb): refused, not left to a slow clipper
  std::string comb;
  const int teeth = static_cast<int>(nbv::kObjMaxEarClipVertices);
  for (int i = 0; i < teeth; ++i)
    comb += "v " + std::to_string(i) + " " + (i % 2 ? "1" : "3") + " 0\n";
  comb += "v " + std::to_string(teeth - 1) + " 0 0\nv 0 0 0\nf";
  for (int i = 1; i <= teeth + 2; ++i) comb += " " + std::to_string(i);
  EXPECT_NE(error_of(comb + "\n").find("non-convex polygon"), std::string::npos);
}

}  // namespace
