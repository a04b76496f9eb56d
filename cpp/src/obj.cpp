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

ObjData polygons_to_mesh(const std::vector<double>& xyz, const std::vector<std::int32_t>& index,
                         const std::vector<std::size_t>& start,
                         const std::vector<std::size_t>& first_line, std::int64_t first_number);

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
  return polygons_to_mesh(xyz, index, start, first_line, 1);
}

namespace {

// The triangles of polygons (vertex `index`es in [0, xyz.size() / 3), polygon p being
// index[start[p], start[p + 1]), on line first_line[p]), keeping only the vertices they use,
// renumbered in file order; `first_number` is the file's number of its first vertex.
ObjData polygons_to_mesh(const std::vector<double>& xyz, const std::vector<std::int32_t>& index,
                         const std::vector<std::size_t>& start,
                         const std::vector<std::size_t>& first_line, std::int64_t first_number) {
  const long long nv = static_cast<long long>(xyz.size() / 3);
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
      out.file_number[static_cast<std::size_t>(remap[v])] =
          static_cast<std::int64_t>(v) + first_number;
    }
  out.faces.resize(static_cast<Eigen::Index>(tri.size() / 3), 3);
  for (std::size_t t = 0; t < tri.size(); ++t)
    out.faces(static_cast<Eigen::Index>(t / 3), static_cast<Eigen::Index>(t % 3)) =
        remap[static_cast<std::size_t>(tri[t])];
  return out;
}

// The next logical line of OFF text from `pos` (comments after '#' removed) split into `tok`;
// false at the end of the text. Blank lines are skipped; `line_no` counts physical lines.
bool next_tokens(const char* data, std::size_t size, std::size_t& pos, std::size_t& line_no,
                 std::vector<std::string_view>& tok) {
  while (pos < size) {
    std::size_t eol = pos;
    while (eol < size && data[eol] != '\n') ++eol;
    std::string_view line(data + pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    tokens(line, tok);
    if (!tok.empty()) return true;
  }
  return false;
}

long long off_count(std::string_view t, std::size_t line, const char* what) {
  long long v = 0;
  if (!parse_int(t, v) || v < 0)
    fail(line, std::string(what) + " count " + quote(t) + " is not a non-negative integer");
  return v;
}

}  // namespace

ObjData parse_off(const char* data, std::size_t size) {
  std::vector<std::string_view> tok;
  std::size_t pos = 0, line = 0;
  if (size >= 3 && std::string_view(data, 3) == "\xEF\xBB\xBF") pos = 3;  // a UTF-8 BOM
  if (!next_tokens(data, size, pos, line, tok)) fail(1, "empty file (no OFF header)");
  // [ST][C][N]OFF: texture coordinates, colours, normals after a vertex's x y z (ignored)
  const std::string_view key = tok[0];
  const bool off = key.size() >= 3 && key.substr(key.size() - 3) == "OFF" &&
                   key.substr(0, key.size() - 3).find_first_not_of("STCN") == std::string::npos;
  if (!off)
    fail(line, "the first word is " + quote(key) +
                   ", not an OFF header (OFF, COFF, NOFF, STOFF, ...; 4OFF and nOFF are not read)");
  std::size_t at = 1;
  if (tok.size() > 1 && tok[1] == "BINARY") fail(line, "binary OFF is not read (text OFF only)");
  if (tok.size() == 1) {  // the counts on their own line
    if (!next_tokens(data, size, pos, line, tok)) fail(line, "no vertex and face counts");
    at = 0;
  }
  if (tok.size() < at + 2) fail(line, "the header needs vertex and face counts (V F [E])");
  const long long nv = off_count(tok[at], line, "vertex");
  const long long nf = off_count(tok[at + 1], line, "face");
  if (nv > std::numeric_limits<std::int32_t>::max()) fail(line, "more than 2^31 - 1 vertices");
  // at least a few bytes a vertex and a face: a count the file cannot hold allocates nothing
  if (static_cast<double>(nv) + static_cast<double>(nf) > static_cast<double>(size))
    fail(line, "the header declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                   " faces, more than the file's " + std::to_string(size) + " bytes hold");
  std::vector<double> xyz;
  xyz.reserve(3 * static_cast<std::size_t>(nv));
  for (long long v = 0; v < nv; ++v) {
    if (!next_tokens(data, size, pos, line, tok))
      fail(line, "the file ends after " + std::to_string(v) + " of its " + std::to_string(nv) +
                     " vertices");
    if (tok.size() < 3) fail(line, "a vertex needs three coordinates (x y z)");
    for (int k = 0; k < 3; ++k) {
      double c;
      if (!parse_double(tok[k], c))
        fail(line, "vertex coordinate " + quote(tok[k]) + " is not a number");
      xyz.push_back(c);
    }
  }
  std::vector<std::int32_t> index;
  std::vector<std::size_t> start, first_line;
  for (long long f = 0; f < nf; ++f) {
    if (!next_tokens(data, size, pos, line, tok))
      fail(line,
           "the file ends after " + std::to_string(f) + " of its " + std::to_string(nf) + " faces");
    long long n = 0;
    if (!parse_int(tok[0], n) || n < 0)
      fail(line, "a face's vertex count " + quote(tok[0]) + " is not a non-negative integer");
    if (static_cast<long long>(tok.size()) < n + 1)
      fail(line, "a face of " + std::to_string(n) + " vertices lists " +
                     std::to_string(tok.size() - 1) + " indices");
    if (n < 3) continue;  // a point or a line: not a surface (as the OBJ reader)
    start.push_back(index.size());
    first_line.push_back(line);
    for (long long k = 1; k <= n; ++k) {  // a colour may follow the indices: ignored
      long long i = 0;
      if (!parse_int(tok[static_cast<std::size_t>(k)], i))
        fail(line,
             "face vertex index " + quote(tok[static_cast<std::size_t>(k)]) + " is not an integer");
      if (i < 0 || i >= nv)
        fail(line, "face vertex index " + std::to_string(i) + " is out of range: the file has " +
                       std::to_string(nv) + " vertices (OFF counts from 0)");
      index.push_back(static_cast<std::int32_t>(i));
    }
  }
  if (next_tokens(data, size, pos, line, tok))
    fail(line, "more data after the " + std::to_string(nf) + " faces the header declares");
  start.push_back(index.size());
  return polygons_to_mesh(xyz, index, start, first_line, 0);
}

ObjData read_off(const std::string& path) {
  const std::string text = read_whole_file(path, "OFF", kMaxMeshFileBytes);
  try {
    return parse_off(text.data(), text.size());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("cannot read OFF '" + path + "': " + e.what());
  }
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
