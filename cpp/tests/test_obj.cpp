// nbvkit's OBJ reader (nbv/obj.hpp): double precision, index forms, ignored statements, used
// vertices only, triangulation of convex and non-convex polygons, and bad files that must throw
// naming the line. tests/test_mesh.py checks what load_mesh makes of it (the file named).
#include "nbv/obj.hpp"
#include "nbv/polygon.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace {

nbv::ObjData parse(const std::string& s) { return nbv::parse_obj(s.data(), s.size()); }

using nbv_test::area_of;

using nbv_test::error_of;

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
  EXPECT_NEAR(area_of(d), 4.0 + 3.0, 1e-12);
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {  // the polygons' winding (+z) is kept
    const Eigen::Vector3d p0 = d.vertices.row(d.faces(i, 0)), p1 = d.vertices.row(d.faces(i, 1)),
                          p2 = d.vertices.row(d.faces(i, 2));
    EXPECT_GT((p1 - p0).cross(p2 - p0).z(), 0) << i;
  }
  // a concave quad (an arrowhead): the fan from its first vertex would cover the notch
  const auto q = parse("v 0 0 0\nv 2 1 0\nv 4 0 0\nv 2 3 0\nf 1 2 3 4\n");
  EXPECT_NEAR(area_of(q), 4.0, 1e-12);  // 6 (the hull triangle) - 2 (the notch)
}

TEST(Obj, AByteOrderMarkIsNotPartOfTheFirstStatement) {
  // "\xEF\xBB\xBFv" read as a statement of its own dropped vertex 1 and moved every index
  const auto d = parse("\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n");
  ASSERT_EQ(d.vertices.rows(), 3);
  EXPECT_NEAR(area_of(d), 0.5, 1e-12);
  EXPECT_EQ(d.vertices.maxCoeff(), 1.0);
}

TEST(Obj, OtherStatementsAreIgnoredAndOnlyUsedVerticesKept) {
  // comments, materials, groups, texture and normal lines, w and colours after x y z, a line
  // continued by a backslash, lines and points (faces of fewer than three vertices)
  const auto d = parse(
      "# comment\nmtllib none.mtl\no square\nv 0 0 0 1\nv 2 0 0 1 0.5 0.5 0.5\nv 2 2 0\n"
      "v 0 \\\n 2 0\nvt 0 0\nvn 0 0 1\nusemtl x\ns off\n"
      "f -4/1/1 -3/1/1 -2/1/1 -1/1/1  # a quad, relative indices\nl 1 2\nf 1 2\np 3\n");
  EXPECT_EQ(d.faces.rows(), 2);
  EXPECT_NEAR(area_of(d), 4.0, 1e-12);
  // a forward reference; the unused vertex is dropped, the others keep their file order
  const auto f = parse("f 2 3 4\nv 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  Eigen::Matrix3d expected;
  expected << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  EXPECT_EQ(f.vertices, expected);
}

TEST(Obj, NonFiniteCoordinatesAreLeftToTheLoader) {
  // load_mesh checks the vertices of faces for every format (test_raycast.cpp)
  const auto d = parse("v inf 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 3\n");
  ASSERT_EQ(d.vertices.rows(), 3);  // the unused NaN vertex is dropped
  EXPECT_TRUE(std::isinf(d.vertices(0, 0)));
}

TEST(Obj, KeptVerticesKeepTheirNumberInTheFile) {  // for the loader's messages
  const auto d = parse("v 9 9 9\nv 0 0 0\nv 1 0 0\nv 7 7 7\nv 0 1 0\nf 2 3 5\n");
  ASSERT_EQ(d.vertices.rows(), 3);
  EXPECT_EQ(d.file_number, (std::vector<std::int64_t>{2, 3, 5}));
}

TEST(Obj, BadFilesNameTheLine) {
  EXPECT_EQ(error_of(parse, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"),
            "line 4: face vertex index 4 is out of range: the file has 3 vertices");
  EXPECT_EQ(error_of(parse, "v 0 0 0\nv 1 zero 0\n"),
            "line 2: vertex coordinate 'zero' is not a number");
  EXPECT_NE(error_of(parse, "v 0 0\n").find("line 1: a vertex needs three coordinates"),
            std::string::npos);
  EXPECT_NE(error_of(parse, "v 0 0 0\nf -2 1 1\n").find("before the first vertex"),
            std::string::npos);
  EXPECT_NE(error_of(parse, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").find("index 0"),
            std::string::npos);
  EXPECT_NE(
      error_of(parse, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n").find("'x' does not start with an"),
      std::string::npos);
  EXPECT_NE(
      error_of(parse, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 99999999999\n").find("out of range"),
      std::string::npos);
  // a non-convex polygon of too many vertices (a comb): refused, not left to a slow clipper
  std::string comb;
  const int teeth = static_cast<int>(nbv::kMaxEarClipVertices);
  for (int i = 0; i < teeth; ++i)
    comb += "v " + std::to_string(i) + " " + (i % 2 ? "1" : "3") + " 0\n";
  comb += "v " + std::to_string(teeth - 1) + " 0 0\nv 0 0 0\nf";
  for (int i = 1; i <= teeth + 2; ++i) comb += " " + std::to_string(i);
  EXPECT_NE(error_of(parse, comb + "\n").find("non-convex polygon"), std::string::npos);
}

}  // namespace

namespace {
nbv::ObjData parse_off(const std::string& s) { return nbv::parse_off(s.data(), s.size()); }
}  // namespace

TEST(Off, ReadsPolygonsCommentsColoursAndVariants) {
  // a unit square as a quad (0-based indices), a face colour, comments, blank lines, a triangle
  // with a point face beside it (ignored); then the same as COFF with vertex colours
  const std::string off =
      "OFF\n# a comment\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n\n0 0 7.25\n"
      "4 0 1 2 3 255 0 0\n1 4\n3 0 1 4  # the last face\n";
  const auto d = parse_off(off);
  EXPECT_EQ(d.faces.rows(), 2 + 1);
  EXPECT_NEAR(area_of(d), 1.0 + 0.5 * 7.25, 1e-12);
  EXPECT_EQ(d.file_number.front(), 0);  // OFF counts vertices from 0
  const auto c = parse_off("COFF 3 1 0\n0 0 0 1 1 1 1\n2 0 0 1 1 1 1\n0 2 0 1 1 1 1\n3 0 1 2\n");
  EXPECT_NEAR(area_of(c), 2.0, 1e-12);
}

TEST(Off, BadFilesThrowNamingTheLine) {
  const auto err = [](const std::string& s) { return error_of(parse_off, s); };
  const std::string head = "OFF\n3 1 0\n0 0 0\n1 0 1\n0 1 1\n";
  EXPECT_EQ(err(head + "3 0 1 2\n"), "");
  // assimp's OFF reader clamped an index past the last vertex, and read -7 as 0
  EXPECT_NE(err(head + "3 0 1 9\n").find("line 6: face vertex index 9 is out of range"),
            std::string::npos);
  EXPECT_NE(err(head + "3 0 1 -7\n").find("index -7 is out of range"), std::string::npos);
  EXPECT_NE(err(head + "3 0 1\n").find("a face of 3 vertices lists 2 indices"), std::string::npos);
  EXPECT_NE(err(head).find("ends after 0 of its 1 faces"), std::string::npos);
  EXPECT_NE(err(head + "3 0 1 2\n3 0 1 2\n").find("more data after the 1 faces"),
            std::string::npos);
  EXPECT_NE(err("OFF\n3 1\n0 0 0\n1 0 x\n0 1 1\n3 0 1 2\n").find("line 4: vertex coordinate 'x'"),
            std::string::npos);
  EXPECT_NE(err("PLY\n3 1 0\n").find("not an OFF header"), std::string::npos);
  EXPECT_NE(err("4OFF\n3 1 0\n").find("not an OFF header"), std::string::npos);
  EXPECT_NE(err("OFF BINARY\n").find("binary OFF"), std::string::npos);
  EXPECT_NE(err("OFF\n99999999 1 0\n").find("more than the file's"), std::string::npos);
  EXPECT_NE(err("").find("no OFF header"), std::string::npos);
}
