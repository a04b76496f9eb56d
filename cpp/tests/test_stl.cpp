// nbvkit's STL reader (nbv/stl.hpp): binary and ASCII files of known area and volume (the signed
// volume checks the winding), ASCII spellings assimp refused (case, a blank first line, CR line
// ends, a BOM), facets of more than three vertices, vertex merging, double precision, and bad
// files that must throw naming the line or the sizes.
#include "nbv/common.hpp"
#include "nbv/polygon.hpp"
#include "nbv/stl.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using nbv_test::area_of;
using nbv_test::error_of;
using nbv_test::volume_of;

using Triangle = std::array<double, 9>;  // x y z of three vertices

// The unit cube [0, 1]^3 as 12 triangles, each wound counter-clockwise seen from outside.
std::vector<Triangle> unit_cube() {
  const double quads[6][12] = {
      {0, 0, 0, 0, 1, 0, 1, 1, 0, 1, 0, 0},  // z = 0
      {0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1},  // z = 1
      {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1},  // y = 0
      {0, 1, 0, 0, 1, 1, 1, 1, 1, 1, 1, 0},  // y = 1
      {0, 0, 0, 0, 0, 1, 0, 1, 1, 0, 1, 0},  // x = 0
      {1, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1},  // x = 1
  };
  std::vector<Triangle> out;
  for (const auto& q : quads)
    for (int t = 0; t < 2; ++t) {  // (0, 1, 2) and (0, 2, 3)
      const int c[3] = {0, 1 + t, 2 + t};
      Triangle tri;
      for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 3; ++k) tri[3 * v + k] = q[3 * c[v] + k];
      out.push_back(tri);
    }
  return out;
}

std::vector<Triangle> reversed(std::vector<Triangle> tris) {
  for (auto& t : tris)
    for (int k = 0; k < 3; ++k) std::swap(t[3 + k], t[6 + k]);
  return tris;
}

void put_u32(std::string& s, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

void put_f32(std::string& s, float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  put_u32(s, u);
}

// A binary STL of `tris` (normals left 0: the reader ignores them) with an 80-byte header that
// starts with `header`.
std::string binary_stl(const std::vector<Triangle>& tris, const std::string& header = "binary") {
  std::string s = header.substr(0, 80);
  s.resize(80, ' ');
  put_u32(s, static_cast<std::uint32_t>(tris.size()));
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) put_f32(s, 0.0f);
    for (double c : t) put_f32(s, static_cast<float>(c));
    s.append(2, '\0');
  }
  return s;
}

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// An ASCII STL solid of `tris` (normals 0 0 0: the reader ignores them).
std::string ascii_stl(const std::vector<Triangle>& tris, const std::string& name = "cube") {
  std::string s = "solid " + name + "\n";
  for (const auto& t : tris) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int v = 0; v < 3; ++v)
      s += "      vertex " + num(t[3 * v]) + " " + num(t[3 * v + 1]) + " " + num(t[3 * v + 2]) +
           "\n";
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid " + name + "\n";
}

nbv::StlData parse(const std::string& s) {
  return nbv::parse_stl(reinterpret_cast<const std::uint8_t*>(s.data()), s.size());
}

// A unit cube as the reader must give it: 12 triangles over 8 merged vertices, area 6, volume 1
// (the winding kept: outwards).
void expect_cube(const nbv::StlData& d) {
  EXPECT_EQ(d.faces.rows(), 12);
  EXPECT_EQ(d.vertices.rows(), 8);
  EXPECT_NEAR(area_of(d), 6.0, 1e-12);
  EXPECT_NEAR(volume_of(d), 1.0, 1e-12);
}

// Each triangle's normal points along +z.
void expect_facing_up(const nbv::StlData& d) {
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {
    const Eigen::Vector3d p0 = d.vertices.row(d.faces(i, 0)), p1 = d.vertices.row(d.faces(i, 1)),
                          p2 = d.vertices.row(d.faces(i, 2));
    EXPECT_GT((p1 - p0).cross(p2 - p0).z(), 0) << i;
  }
}

}  // namespace

TEST(Stl, BinaryCube) {
  const auto d = parse(binary_stl(unit_cube()));
  EXPECT_TRUE(d.binary);
  expect_cube(d);
  const auto r = parse(binary_stl(reversed(unit_cube())));  // inside out: the winding is kept
  EXPECT_NEAR(volume_of(r), -1.0, 1e-12);
  EXPECT_NEAR(area_of(r), 6.0, 1e-12);
}

TEST(Stl, AsciiCube) {
  const auto d = parse(ascii_stl(unit_cube()));
  EXPECT_FALSE(d.binary);
  expect_cube(d);
  EXPECT_NEAR(volume_of(parse(ascii_stl(reversed(unit_cube())))), -1.0, 1e-12);
  // the facet normal is ignored: a cube with every normal pointing the wrong way stays outwards
  std::string text = ascii_stl(unit_cube());
  for (std::size_t at = 0; (at = text.find("normal 0 0 0", at)) != std::string::npos;)
    text.replace(at, 12, "normal 0 0 -1");
  EXPECT_NEAR(volume_of(parse(text)), 1.0, 1e-12);
}

TEST(Stl, AsciiSpellingsAssimpRefused) {
  const std::string text = ascii_stl(unit_cube());
  std::string upper = text;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  std::string mixed = text;
  for (std::size_t i = 0; i < mixed.size(); i += 2)
    mixed[i] = static_cast<char>(std::toupper(static_cast<unsigned char>(mixed[i])));
  const auto line_ends = [&](const std::string& eol) {  // every LF replaced by eol
    std::string s;
    for (char c : text) s += c == '\n' ? eol : std::string(1, c);
    return s;
  };
  std::string tabs = text;
  for (char& c : tabs)
    if (c == ' ') c = '\t';
  std::string one_line = text;  // every token on one line but the solid's name
  for (std::size_t i = one_line.find('\n') + 1; i < one_line.size(); ++i)
    if (one_line[i] == '\n') one_line[i] = ' ';
  std::string all_on_one_line = text;  // the name too: it ends at the first facet
  for (char& c : all_on_one_line)
    if (c == '\n') c = ' ';
  const std::vector<std::pair<const char*, std::string>> cases = {
      {"upper case", upper},
      {"mixed case", mixed},
      {"blank lines first", "\n\n  \r\n" + text},
      {"CRLF", line_ends("\r\n")},
      {"lone CR", line_ends("\r")},
      {"BOM", "\xEF\xBB\xBF" + text},
      {"BOM and blank line", "\xEF\xBB\xBF\n" + text},
      {"tabs", tabs},
      {"one line", one_line},
      {"all on one line", all_on_one_line},
      {"two solids on one line", "solid a endsolid a " + all_on_one_line},
      {"NUL padding after endsolid", text + std::string(37, '\0')},
      {"NUL padding and spaces", text + std::string(5, '\0') + " \n" + std::string(3, '\0')},
      {"no final newline", text.substr(0, text.size() - 1)},
      {"no names",
       "solid\n" + text.substr(text.find('\n') + 1, text.rfind("endsolid") - text.find('\n') - 1) +
           "endsolid"},
  };
  for (const auto& [what, s] : cases) {
    SCOPED_TRACE(what);
    const auto d = parse(s);
    EXPECT_FALSE(d.binary);
    expect_cube(d);
  }
}

TEST(Stl, MergingIsTheSameWhateverTheTablesSeed) {
  // each table draws its own hash seed (a fixed hash let a crafted file make merging quadratic):
  // the merged vertices and faces do not depend on it
  std::vector<Triangle> tris;
  for (int i = 0; i < 3000; ++i) {
    const double x = i % 50, y = i / 50;
    tris.push_back({x, y, 0, x + 1, y, 0, x, y + 1, 0});
  }
  const auto a = parse(binary_stl(tris)), b = parse(binary_stl(tris));
  EXPECT_EQ(a.vertices.rows(), 3000 + 60 + 50);  // the 50 x 60 corners, x = 50 and y = 60
  EXPECT_TRUE(a.vertices == b.vertices);
  EXPECT_TRUE(a.faces == b.faces);
}

TEST(Stl, LineNumbersCountEveryKindOfLineEnd) {
  // the bad number is on line 4 whether lines end in LF, CRLF or a lone CR
  for (const std::string eol : {"\n", "\r\n", "\r"}) {
    const std::string s =
        "solid x" + eol + "facet normal 0 0 1" + eol + "outer loop" + eol + "vertex 0 0 zero" + eol;
    EXPECT_EQ(error_of(parse, s), "line 4: vertex coordinate 'zero' is not a number");
  }
}

TEST(Stl, BinaryWhoseHeaderStartsWithSolid) {
  // many exporters write "solid" into a binary header: the size 84 + 50 N decides
  for (const std::string header : {"solid cube", "SOLID", "solid\n  facet normal"}) {
    const auto d = parse(binary_stl(unit_cube(), header));
    EXPECT_TRUE(d.binary) << header;
    expect_cube(d);
  }
}

TEST(Stl, BinarySizeDisagreeingWithTheCountIsRefused) {
  const std::string b = binary_stl(unit_cube());  // 12 facets, 684 bytes
  ASSERT_EQ(b.size(), 684u);
  EXPECT_EQ(error_of(parse, b.substr(0, 600)),
            "neither binary nor ASCII STL: as binary STL it is truncated (its header declares 12 "
            "facets, 84 + 50 x 12 = 684 bytes, but the file has 600 bytes); as ASCII STL it does "
            "not start with 'solid'");
  EXPECT_EQ(error_of(parse, b + std::string(10, '\0')),
            "neither binary nor ASCII STL: as binary STL it holds more bytes than its 12 facets "
            "(its header declares 12 facets, 84 + 50 x 12 = 684 bytes, but the file has 694 "
            "bytes); as ASCII STL it does not start with 'solid'");
  // a count whose 84 + 50 N overflows 32 bits
  std::string huge = b;
  huge.replace(80, 4, "\xff\xff\xff\xff");
  EXPECT_NE(error_of(parse, huge)
                .find("declares 4294967295 facets, 84 + 50 x 4294967295 = "
                      "214748364834 bytes, but the file has 684 bytes"),
            std::string::npos);
  // shorter than a header
  EXPECT_EQ(error_of(parse, std::string(40, '\0')),
            "neither binary nor ASCII STL: as binary STL it is too short (40 bytes, fewer than the "
            "84 of the header and facet count); as ASCII STL it does not start with 'solid'");
  EXPECT_NE(error_of(parse, "").find("too short (0 bytes"), std::string::npos);
  EXPECT_NE(error_of(parse, "solidworks\n").find("does not start with 'solid'"), std::string::npos);
  // a truncated binary STL whose header starts with "solid": read as ASCII, refused naming both
  const std::string s = binary_stl(unit_cube(), "solid cube").substr(0, 600);
  const std::string e = error_of(parse, s);
  EXPECT_EQ(e.rfind("line 1: expected 'facet' or 'endsolid', found ", 0), 0u) << e;
  EXPECT_NE(e.find("holds binary bytes: as binary STL it is truncated (its header declares 12 "
                   "facets, 84 + 50 x 12 = 684 bytes, but the file has 600 bytes)"),
            std::string::npos)
      << e;
}

TEST(Stl, PolygonFacetsAreTriangulatedKeepingTheirWinding) {
  // a dart (arrowhead, area 4: the fan from its first vertex would cover 6) and an L-shaped
  // hexagon (area 3), from every start vertex, wound counter-clockwise about +z
  const std::vector<std::vector<double>> shapes = {{0, 0, 2, 1, 4, 0, 2, 3},
                                                   {0, 0, 2, 0, 2, 1, 1, 1, 1, 2, 0, 2}};
  const double areas[2] = {4.0, 3.0};
  for (int s = 0; s < 2; ++s) {
    const std::size_t n = shapes[s].size() / 2;
    for (std::size_t start = 0; start < n; ++start) {
      std::string text = "solid polygon\nfacet normal 0 0 1\nouter loop\n";
      for (std::size_t i = 0; i < n; ++i) {
        const std::size_t v = (start + i) % n;
        text += "vertex " + num(shapes[s][2 * v]) + " " + num(shapes[s][2 * v + 1]) + " 7\n";
      }
      text += "endloop\nendfacet\nendsolid polygon\n";
      const auto d = parse(text);
      SCOPED_TRACE(std::to_string(s) + " from " + std::to_string(start));
      EXPECT_EQ(d.faces.rows(), static_cast<Eigen::Index>(n - 2));
      EXPECT_EQ(d.vertices.rows(), static_cast<Eigen::Index>(n));
      EXPECT_NEAR(area_of(d), areas[s], 1e-12);
      expect_facing_up(d);
    }
  }
}

TEST(Stl, BadAsciiFilesNameTheLine) {
  const std::string head = "solid x\nfacet normal 0 0 1\nouter loop\n";
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n"),
            "line 2: facet 1 has 2 vertices (a facet needs at least 3)");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n" +
                                "facet normal 0 0 1\nouter loop\nendloop\nendfacet\nendsolid\n"),
            "line 9: facet 2 has 0 vertices (a facet needs at least 3)");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0,5 0\n"),
            "line 5: vertex coordinate '0,5' is not a number");
  EXPECT_EQ(error_of(parse, "solid x\nfacet normal 0 up 1\n"),
            "line 2: facet normal component 'up' is not a number");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0\nvertex 1 0 0\n"),
            "line 5: vertex coordinate 'vertex' is not a number");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"),
            "line 8: expected 'facet' or 'endsolid', found the end of the file");  // no endsolid
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"),
            "line 7: expected 'endfacet', found the end of the file");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendfacet\n"),
            "line 7: expected 'vertex' or 'endloop', found 'endfacet'");
  EXPECT_EQ(error_of(parse, head + "vertex 0 0"),
            "line 4: expected a vertex coordinate, found the end of the file");
  EXPECT_EQ(error_of(parse, "solid x\nfacet 0 0 1\n"),
            "line 2: expected 'normal' after 'facet', found '0'");
  EXPECT_EQ(error_of(parse, "solid x\nfacet normal 0 0 1\nouter\nvertex 0 0 0\n"),
            "line 4: expected 'loop' after 'outer', found 'vertex'");
  EXPECT_EQ(error_of(parse, "solid x\nfacets normal 0 0 1\n"),
            "line 2: expected 'facet' or 'endsolid', found 'facets'");
  EXPECT_EQ(error_of(parse, "solid x\n"),
            "line 1: expected 'facet' or 'endsolid', found the end of the file");
  // text after the last endsolid
  EXPECT_EQ(error_of(parse, ascii_stl(unit_cube()) + "\n\nthe end\n"),
            "line 89: expected 'solid' or the end of the file after 'endsolid', found 'the'");
  // a non-convex facet of too many vertices (a comb): refused, not left to a slow clipper
  std::string comb = "solid comb\nfacet normal 0 0 1\nouter loop\n";
  const int teeth = static_cast<int>(nbv::kMaxEarClipVertices);
  for (int i = 0; i < teeth; ++i)
    comb += "vertex " + std::to_string(i) + " " + (i % 2 ? "1" : "3") + " 0\n";
  comb += "vertex " + std::to_string(teeth - 1) + " 0 0\nvertex 0 0 0\nendloop\nendfacet\n";
  EXPECT_NE(error_of(parse, comb + "endsolid\n").find("line 2: facet 1: a non-convex polygon of "),
            std::string::npos);
}

TEST(Stl, SeveralSolidsInOneFile) {
  std::vector<Triangle> cube = unit_cube(), lower(cube.begin(), cube.begin() + 6),
                        upper(cube.begin() + 6, cube.end());
  const auto d =
      parse(ascii_stl(lower, "first part") + "\n" + ascii_stl(upper, "") + ascii_stl({}, "empty"));
  expect_cube(d);  // the halves' shared vertices merged across the solids
}

TEST(Stl, AsciiKeepsDoublePrecision) {
  const auto d = parse(
      "solid geo\nfacet normal 0 0 1\nouter loop\nvertex 500000.3 5000000.3 100.7\n"
      "vertex 500001.3 5000000.3 100.7\nvertex +500000.3 5000001.3 1.007e2\nendloop\nendfacet\n"
      "endsolid geo\n");
  ASSERT_EQ(d.vertices.rows(), 3);
  EXPECT_EQ(d.vertices(0, 1), 5000000.3);  // float32 would give 5000000.5
  EXPECT_EQ(d.vertices(0, 0), 500000.3);
  EXPECT_EQ(d.vertices(2, 0), 500000.3);
  EXPECT_EQ(d.vertices(2, 2), 100.7);
}

TEST(Stl, IdenticalVerticesAreMergedInOrderOfFirstUse) {
  const auto d = parse(binary_stl(unit_cube()));
  ASSERT_EQ(d.vertices.rows(), 8);
  // every corner of the cube once
  for (Eigen::Index i = 0; i < 8; ++i)
    for (Eigen::Index j = i + 1; j < 8; ++j) EXPECT_NE(d.vertices.row(i), d.vertices.row(j));
  // first use: the first triangle's three corners, in order
  EXPECT_EQ(d.faces.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(Eigen::RowVector3d(d.vertices.row(1)), Eigen::RowVector3d(0, 1, 0));
  // -0.0 and 0.0 are one vertex: two triangles sharing an edge written with both signs
  const auto z = parse(
      "solid z\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
      "endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex -0.0 1 -0\nvertex 1 -0 0\n"
      "vertex 1 1 0\nendloop\nendfacet\nendsolid\n");
  EXPECT_EQ(z.vertices.rows(), 4);
  EXPECT_EQ(z.faces(1, 0), 2);
  EXPECT_EQ(z.faces(1, 1), 1);
  // NaN positions are never merged: each stays a vertex of its own
  const auto n = parse(
      "solid n\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\nvertex nan 0 0\n"
      "endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\n"
      "vertex inf 0 0\nendloop\nendfacet\nendsolid\n");
  EXPECT_EQ(n.vertices.rows(), 5);
  EXPECT_EQ(n.faces.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(n.faces.row(1), Eigen::RowVector3i(3, 1, 4));
  EXPECT_TRUE(std::isnan(n.vertices(3, 0)));
  EXPECT_TRUE(std::isinf(n.vertices(4, 0)));
  // the same in binary
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto b =
      parse(binary_stl({{nan, 0, 0, 1, 0, 0, 0, 1, 0}, {nan, 0, 0, -0.0, 1, 0, 1, 0, 0}}));
  EXPECT_EQ(b.vertices.rows(), 4);
  EXPECT_EQ(b.faces.row(1), Eigen::RowVector3i(3, 2, 1));
}

TEST(Stl, ZeroFacets) {
  for (const std::string& s :
       {binary_stl({}), binary_stl({}, "solid empty"), std::string("solid empty\nendsolid empty\n"),
        std::string("solid")}) {
    if (s == "solid") {  // a solid never ended
      EXPECT_NE(error_of(parse, s).find("found the end of the file"), std::string::npos);
      continue;
    }
    const auto d = parse(s);
    EXPECT_EQ(d.faces.rows(), 0);
    EXPECT_EQ(d.faces.cols(), 3);
    EXPECT_EQ(d.vertices.rows(), 0);
    EXPECT_EQ(d.vertices.cols(), 3);
  }
}

TEST(Stl, LargeBinaryFile) {
  // 200,000 facets (10 MB): a 100 x 1000 grid of unit squares
  std::vector<Triangle> tris;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 1000; ++j) {
      const double x = i, y = j;
      tris.push_back({x, y, 0, x + 1, y, 0, x + 1, y + 1, 0});
      tris.push_back({x, y, 0, x + 1, y + 1, 0, x, y + 1, 0});
    }
  const auto d = parse(binary_stl(tris));
  EXPECT_EQ(d.faces.rows(), 200000);
  EXPECT_EQ(d.vertices.rows(), 101 * 1001);
  EXPECT_NEAR(area_of(d), 100000.0, 1e-6);
  expect_facing_up(d);
}

TEST(Stl, ReadStlNamesTheFile) {
  EXPECT_THROW(nbv::read_stl("/nonexistent/never.stl"), nbv::FileNotFound);
  const std::string path = ::testing::TempDir() + "nbv_stl_test.stl";
  {
    std::ofstream f(path, std::ios::binary);
    f << binary_stl(unit_cube(), "solid exported").substr(0, 683);
  }
  const std::string e = error_of(nbv::read_stl, path);
  EXPECT_EQ(e.rfind("cannot read STL '" + path + "': line 1: ", 0), 0u) << e;
  {
    std::ofstream f(path, std::ios::binary);
    f << ascii_stl(unit_cube());
  }
  expect_cube(nbv::read_stl(path));
  std::remove(path.c_str());
}
