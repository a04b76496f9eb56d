#include "nbv/obj.hpp"
#include "nbv/mesh.hpp"
#include "nbv/polygon.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace nbv {

namespace {

[[noreturn]] void fail(std::size_t line, const std::string& why) {
  throw std::invalid_argument("line " + std::to_string(line) + ": " + why);
}

std::string quote(std::string_view tok) {
  return "'" + printable_ascii(std::string(tok.substr(0, 40))) + "'";
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

// Splits `s` at whitespace into `out` (views into s).
void tokens(std::string_view s, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    const std::size_t j = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    if (i > j) out.push_back(s.substr(j, i - j));
  }
}

bool parse_double(std::string_view t, double& v) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  return !t.empty() && r.ec == std::errc() && r.ptr == t.data() + t.size();
}

bool parse_int(std::string_view t, long long& v) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  return !t.empty() && r.ec == std::errc() && r.ptr == t.data() + t.size();
}

}  // namespace

ObjData parse_obj(const char* data, std::size_t size) {
  std::vector<double> xyz;              // 3 per vertex, file order
  std::vector<std::int32_t> index;      // polygons' vertex indices (0-based, resolved)
  std::vector<std::size_t> start;       // polygon p is index[start[p], start[p + 1])
  std::vector<std::size_t> first_line;  // the line of each polygon (for messages)
  long long max_index = 0;              // the largest positive index (1-based) and its line
  std::size_t max_index_line = 0;
  std::vector<std::string_view> tok;
  std::string joined;  // a line continued by backslashes
  std::size_t line_no = 0, pos = 0;
  constexpr long long kMaxVertices = std::numeric_limits<std::int32_t>::max();
  if (size >= 3 && std::string_view(data, 3) == "\xEF\xBB\xBF") pos = 3;  // a UTF-8 BOM

  while (pos < size) {
    // The next logical line: physical lines joined where one ends in a backslash.
    std::size_t eol = pos;
    while (eol < size && data[eol] != '\n') ++eol;
    std::string_view line(data + pos, eol - pos);
    pos = eol + 1;
    const std::size_t this_line = ++line_no;
    auto rstrip = [](std::string_view v) {
      while (!v.empty() && is_space(v.back())) v.remove_suffix(1);
      return v;
    };
    if (!rstrip(line).empty() && rstrip(line).back() == '\\') {
      joined.clear();
      while (true) {
        std::string_view l = rstrip(line);
        if (l.empty() || l.back() != '\\') {
          joined.append(l);
          break;
        }
        l.remove_suffix(1);
        joined.append(l).push_back(' ');
        if (pos >= size) break;
        eol = pos;
        while (eol < size && data[eol] != '\n') ++eol;
        line = std::string_view(data + pos, eol - pos);
        pos = eol + 1;
        ++line_no;
      }
      line = joined;
    }
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    tokens(line, tok);
    if (tok.empty()) continue;
    if (tok[0] == "v") {
      if (tok.size() < 4) fail(this_line, "a vertex needs three coordinates (v x y z)");
      if (static_cast<long long>(xyz.size() / 3) >= kMaxVertices)
        fail(this_line, "more than 2^31 - 1 vertices");
      for (int k = 1; k <= 3; ++k) {
        double v;
        if (!parse_double(tok[k], v))
          fail(this_line, "vertex coordinate " + quote(tok[k]) + " is not a number");
        xyz.push_back(v);
      }
    } else if (tok[0] == "f") {
      const long long nv = static_cast<long long>(xyz.size() / 3);
      if (tok.size() < 4) continue;  // a line or a point: not a surface (as assimp)
      start.push_back(index.size());
      first_line.push_back(this_line);
      for (std::size_t t = 1; t < tok.size(); ++t) {
        const std::string_view v = tok[t].substr(0, tok[t].find('/'));
        long long i = 0;
        if (!parse_int(v, i))
          fail(this_line, "face vertex " + quote(tok[t]) + " does not start with an integer index");
        if (i == 0) fail(this_line, "face vertex index 0 (OBJ counts from 1)");
        if (i < 0) {
          if (-i > nv)
            fail(this_line, "face vertex index " + std::to_string(i) +
                                " reaches before the first vertex (" + std::to_string(nv) +
                                " read so far)");
          index.push_back(static_cast<std::int32_t>(nv + i));
        } else {
          if (i > kMaxVertices)
            fail(this_line, "face vertex index " + std::to_string(i) + " is out of range");
          if (i > max_index) max_index = i, max_index_line = this_line;
          index.push_back(static_cast<std::int32_t>(i - 1));
        }
      }
    }
  }
  start.push_back(index.size());
  const long long nv = static_cast<long long>(xyz.size() / 3);
  if (max_index > nv)
    fail(max_index_line, "face vertex index " + std::to_string(max_index) +
                             " is out of range: the file has " + std::to_string(nv) + " vertices");

  // The vertices faces use, renumbered in file order (finiteness is the loader's check).
  std::vector<std::int32_t> remap(static_cast<std::size_t>(nv), -1);
  for (const std::int32_t i : index) remap[static_cast<std::size_t>(i)] = 0;
  std::size_t kept = 0;
  for (std::int32_t& r : remap)
    if (r == 0) r = static_cast<std::int32_t>(kept++);

  std::vector<std::int32_t> tri;
  tri.reserve(3 * (index.size() - 2 * (start.size() - 1)));
  for (std::size_t p = 0; p + 1 < start.size(); ++p) {
    const std::size_t n = start[p + 1] - start[p];
    if (!triangulate_polygon(&index[start[p]], n, xyz.data(), tri))
      fail(first_line[p], polygon_too_large(n));
  }
  ObjData out;
  out.vertices.resize(static_cast<Eigen::Index>(kept), 3);
  out.file_number.resize(kept);
  for (std::size_t v = 0; v < remap.size(); ++v)
    if (remap[v] >= 0) {
      for (int k = 0; k < 3; ++k) out.vertices(remap[v], k) = xyz[3 * v + k];
      out.file_number[static_cast<std::size_t>(remap[v])] = static_cast<std::int64_t>(v) + 1;
    }
  out.faces.resize(static_cast<Eigen::Index>(tri.size() / 3), 3);
  for (std::size_t t = 0; t < tri.size(); ++t)
    out.faces(static_cast<Eigen::Index>(t / 3), static_cast<Eigen::Index>(t % 3)) =
        remap[static_cast<std::size_t>(tri[t])];
  return out;
}

ObjData read_obj(const std::string& path) {
  const std::string text = read_whole_file(path, "OBJ", kMaxMeshFileBytes);
  try {
    return parse_obj(text.data(), text.size());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("cannot read OBJ '" + path + "': " + e.what());
  }
}

}  // namespace nbv
