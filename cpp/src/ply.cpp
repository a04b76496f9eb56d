#include "nbv/ply.hpp"
#include "nbv/mesh.hpp"
#include "nbv/polygon.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <vector>

namespace nbv {
namespace {

enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

struct Property {
  std::string name;
  Type type = Type::F32;
  bool list = false;
  Type count_type = Type::U8;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> props;
};

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

std::size_t type_size(Type t) {
  switch (t) {
    case Type::I8:
    case Type::U8:
      return 1;
    case Type::I16:
    case Type::U16:
      return 2;
    case Type::I32:
    case Type::U32:
    case Type::F32:
      return 4;
    case Type::F64:
      return 8;
  }
  return 1;
}

bool is_integer(Type t) { return t != Type::F32 && t != Type::F64; }

Type parse_type(const std::string& s) {
  if (s == "char" || s == "int8") return Type::I8;
  if (s == "uchar" || s == "uint8") return Type::U8;
  if (s == "short" || s == "int16") return Type::I16;
  if (s == "ushort" || s == "uint16") return Type::U16;
  if (s == "int" || s == "int32") return Type::I32;
  if (s == "uint" || s == "uint32") return Type::U32;
  if (s == "float" || s == "float32") return Type::F32;
  if (s == "double" || s == "float64") return Type::F64;
  fail("unknown PLY property type '" + s + "'");
}

std::vector<std::string> split_words(const std::string& line) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    std::size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

std::string trim(const std::string& s) {
  const auto words = split_words(s);
  std::string out;
  for (const auto& w : words) out += (out.empty() ? "" : " ") + w;
  return out;
}

// Reads values one at a time from the body, ASCII or binary, never past its end.
class Body {
 public:
  Body(const std::uint8_t* p, std::size_t n, int mode) : p_(p), n_(n), mode_(mode) {}
  std::size_t left() const { return n_ - pos_; }

  double value(Type t, const std::string& where) {
    if (mode_ == 0) return ascii(where);
    const std::size_t k = type_size(t);
    if (k > left()) fail("truncated in " + where);
    std::uint8_t b[8];
    std::memcpy(b, p_ + pos_, k);
    pos_ += k;
    if (mode_ == 2) std::reverse(b, b + k);  // big endian (the reader runs on little-endian x86)
    switch (t) {
      case Type::I8:
        return static_cast<std::int8_t>(b[0]);
      case Type::U8:
        return b[0];
      case Type::I16: {
        std::int16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case Type::U16: {
        std::uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case Type::I32: {
        std::int32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::U32: {
        std::uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::F32: {
        float v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::F64: {
        double v;
        std::memcpy(&v, b, 8);
        return v;
      }
    }
    return 0;
  }

  void skip_bytes(std::size_t k, const std::string& where) {
    if (k > left()) fail("truncated in " + where);
    pos_ += k;
  }

  // ASCII: the end of a record's line (one record a line, ended by LF, CRLF or CR): more values
  // on it throw, naming the record, as a record running onto the next line does (ascii). Binary:
  // nothing to check.
  void end_record(std::uint64_t r, const std::string& where) {
    if (mode_ != 0) return;
    while (pos_ < n_ && (p_[pos_] == ' ' || p_[pos_] == '\t')) ++pos_;
    if (pos_ < n_ && p_[pos_] != '\n' && p_[pos_] != '\r')
      fail(where + ", record " + std::to_string(r) +
           ": more values than its properties (an ASCII PLY holds one record a line; are the "
           "header's counts and properties right?)");
    record_ = r + 1;
    in_record_ = false;
  }

  // After the last element: only whitespace may follow (a line end, padding). More data means
  // the header declares fewer records than the file holds: read alone, half a cloud would load.
  void check_end() const {
    std::size_t i = pos_;
    while (i < n_ && std::isspace(p_[i])) ++i;
    if (i < n_)
      fail(std::to_string(n_ - pos_) +
           " bytes of data after the last record the header "
           "declares (are its element counts right?)");
  }

  // An element's records begin (ASCII messages count its records from 0).
  void start_element() {
    record_ = 0;
    in_record_ = false;
  }

 private:
  double ascii(const std::string& where) {
    bool crossed = false;  // a line's end between two values of one record
    for (; pos_ < n_ && std::isspace(p_[pos_]); ++pos_)
      crossed = crossed || p_[pos_] == '\n' || p_[pos_] == '\r';
    if (pos_ == n_) fail("truncated in " + where);
    if (in_record_ && crossed)
      fail(where + ", record " + std::to_string(record_) +
           ": fewer values than its properties (an ASCII PLY holds one record a line; are the "
           "header's counts and properties right?)");
    in_record_ = true;
    std::size_t e = pos_;
    while (e < n_ && !std::isspace(p_[e])) ++e;
    if (e - pos_ > 64) fail("bad number in " + where);
    char buf[72];
    std::memcpy(buf, p_ + pos_, e - pos_);
    buf[e - pos_] = '\0';
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(buf, &end);
    if (end == buf || *end != '\0')
      fail("non-numeric value '" + printable_ascii(buf) + "' in " + where);
    pos_ = e;
    return v;
  }

  const std::uint8_t* p_;
  std::size_t n_, pos_ = 0;
  int mode_;                  // 0 ascii, 1 binary little endian, 2 binary big endian
  std::uint64_t record_ = 0;  // ASCII: the record being read (its element's), for messages
  bool in_record_ = false;    // ASCII: a value of the record was read
};

// Smallest number of bytes one record of `e` takes in the body.
std::size_t min_record_bytes(const Element& e, int mode) {
  std::size_t s = 0;
  for (const auto& p : e.props)
    s += mode == 0 ? 2 : (p.list ? type_size(p.count_type) : type_size(p.type));
  return s;
}

std::int64_t list_count(double c, const std::string& where) {
  if (!(c >= 0) || c != std::floor(c) || c > 1e9) fail("bad list length in " + where);
  return static_cast<std::int64_t>(c);
}

}  // namespace

PlyData parse_ply(const std::uint8_t* data, std::size_t size, bool read_faces) {
  // ---- header: lines up to "end_header"
  if (size < 4 || std::memcmp(data, "ply", 3) != 0 || (data[3] != '\n' && data[3] != '\r'))
    fail("not a PLY file (it does not start with 'ply')");
  std::size_t pos = 0;
  int mode = -1;
  std::vector<Element> elements;
  bool ended = false;
  bool first = true;
  while (pos < size) {
    std::size_t e = pos;
    while (e < size && data[e] != '\n') ++e;
    std::string line(reinterpret_cast<const char*>(data + pos), e - pos);
    const bool unterminated = e == size;
    pos = e < size ? e + 1 : e;
    for (char c : line)
      if (static_cast<unsigned char>(c) >= 128 || (c < 32 && c != '\t' && c != '\r'))
        fail("the PLY header is not ASCII text");
    if (first) {
      first = false;
      continue;  // "ply"
    }
    const auto tok = split_words(line);
    if (unterminated && (tok.empty() || tok[0] != "end_header"))
      break;  // a header cut short: "no end_header" below
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") {
      ended = true;
      break;
    }
    if (tok[0] == "format") {
      if (tok.size() < 2) fail("unknown PLY format line '" + trim(line) + "'");
      if (tok[1] == "ascii")
        mode = 0;
      else if (tok[1] == "binary_little_endian")
        mode = 1;
      else if (tok[1] == "binary_big_endian")
        mode = 2;
      else
        fail("unknown PLY format line '" + trim(line) + "'");
    } else if (tok[0] == "element") {
      if (tok.size() != 3 || tok[2].empty() || tok[2].size() > 19 ||
          tok[2].find_first_not_of("0123456789") != std::string::npos)
        fail("bad PLY element line '" + trim(line) + "'");
      Element el;
      el.name = tok[1];
      el.count = std::strtoull(tok[2].c_str(), nullptr, 10);
      elements.push_back(el);
    } else if (tok[0] == "property") {
      if (elements.empty()) fail("PLY property before any element");
      Property p;
      if (tok.size() == 5 && tok[1] == "list") {
        p.list = true;
        p.count_type = parse_type(tok[2]);
        p.type = parse_type(tok[3]);
        p.name = tok[4];
        if (!is_integer(p.count_type)) fail("PLY list count type must be an integer type");
      } else if (tok.size() == 3) {
        p.type = parse_type(tok[1]);
        p.name = tok[2];
      } else {
        fail("bad PLY property line '" + trim(line) + "'");
      }
      elements.back().props.push_back(p);
    } else {
      fail("unexpected PLY header line '" + trim(line) + "'");
    }
  }
  if (!ended) fail("no 'end_header' line: not a PLY file or truncated");
  if (mode < 0) fail("the PLY header has no 'format' line");

  // ---- declared counts against the file size (before any allocation)
  const std::size_t body_size = size - pos;
  {
    long double need = 0;
    for (const auto& el : elements) {
      if (el.props.empty()) continue;  // records without properties take no bytes
      need += static_cast<long double>(el.count) * min_record_bytes(el, mode);
      if (need > static_cast<long double>(body_size) + 1)
        fail("truncated: element '" + el.name + "' declares " + std::to_string(el.count) +
             " records, more than the " + std::to_string(body_size) + " bytes of data can hold");
    }
  }

  PlyData out;
  out.vertices.resize(0, 3);
  out.faces.resize(0, 3);
  bool have_vertices = false;
  Body body(data + pos, body_size, mode);
  std::vector<std::int32_t> tri;  // flat triangles
  // Faces read before the vertex element, cut once the vertices are read: their n - 2
  // triangles' place in tri, their face number and their vertices in `polys`.
  struct Pending {
    std::size_t at;
    std::uint64_t face;
    std::size_t first, n;
  };
  std::vector<Pending> pending;
  std::vector<std::int32_t> polys;
  std::int64_t nv = -1;
  // A face's polygon (indices in range of 32 bits) into tri: cut now when the vertices are read
  // (indices checked against them), else its slots kept for later.
  const auto add_face = [&](const std::vector<std::int32_t>& idx, std::uint64_t face) {
    const std::size_t n = idx.size();
    if (!have_vertices) {
      pending.push_back({tri.size(), face, polys.size(), n});
      polys.insert(polys.end(), idx.begin(), idx.end());
      tri.resize(tri.size() + 3 * (n - 2));
      return;
    }
    for (const std::int32_t v : idx)
      if (v >= nv)
        fail("face " + std::to_string(face) + ": vertex index " + std::to_string(v) +
             " out of range (" + std::to_string(nv) + " vertices)");
    if (!triangulate_polygon(idx.data(), n, out.vertices.data(), tri))
      fail("face " + std::to_string(face) + ": " + polygon_too_large(n));
  };
  bool read_all = true;  // every element's records read (not stopped after the vertices)
  for (const auto& el : elements) {
    if (!read_faces && have_vertices) {
      read_all = false;
      break;
    }
    if (el.props.empty() || el.count == 0) {
      if (el.name == "vertex") {
        for (const char* a : {"x", "y", "z"})
          if (std::none_of(el.props.begin(), el.props.end(),
                           [&](const Property& p) { return p.name == a; }))
            fail(std::string("the PLY vertex element has no '") + a + "' property");
        have_vertices = true;
        nv = 0;
      }
      continue;
    }
    const auto count = static_cast<Eigen::Index>(el.count);
    const std::string where = "element '" + el.name + "'";
    if (el.name == "vertex") {
      if (have_vertices) fail("the PLY file has two vertex elements");
      int col[3] = {-1, -1, -1};
      for (std::size_t i = 0; i < el.props.size(); ++i) {
        for (int a = 0; a < 3; ++a)
          if (el.props[i].name == std::string(1, static_cast<char>('x' + a)))
            col[a] = static_cast<int>(i);
        if (el.props[i].list) fail("PLY vertex elements with list properties are not supported");
      }
      for (int a = 0; a < 3; ++a)
        if (col[a] < 0)
          fail(std::string("the PLY vertex element has no '") + static_cast<char>('x' + a) +
               "' property");
      out.vertices.resize(count, 3);
      body.start_element();
      for (Eigen::Index r = 0; r < count; ++r) {
        for (std::size_t i = 0; i < el.props.size(); ++i) {
          const double v = body.value(el.props[i].type, where);
          for (int a = 0; a < 3; ++a)
            if (col[a] == static_cast<int>(i)) out.vertices(r, a) = v;
        }
        body.end_record(static_cast<std::uint64_t>(r), where);
      }
      have_vertices = true;
      nv = count;
      continue;
    }
    const bool faces = read_faces && el.name == "face";
    int idx = -1;
    if (faces)
      for (std::size_t i = 0; i < el.props.size(); ++i)
        if (el.props[i].list &&
            (el.props[i].name == "vertex_indices" || el.props[i].name == "vertex_index"))
          idx = static_cast<int>(i);
    if (faces && idx < 0) fail("the PLY face element has no 'vertex_indices' list");
    if (faces && !is_integer(el.props[static_cast<std::size_t>(idx)].type))
      fail("PLY face indices must be of an integer type");
    std::vector<std::int32_t> poly;
    body.start_element();
    for (std::uint64_t r = 0; r < el.count; ++r) {
      for (std::size_t i = 0; i < el.props.size(); ++i) {
        const Property& p = el.props[i];
        if (!p.list) {
          if (mode == 0)
            body.value(p.type, where);
          else
            body.skip_bytes(type_size(p.type), where);
          continue;
        }
        const std::int64_t k = list_count(body.value(p.count_type, where), where);
        if (static_cast<int>(i) != idx) {
          if (mode == 0)
            for (std::int64_t j = 0; j < k; ++j) body.value(p.type, where);
          else
            body.skip_bytes(static_cast<std::size_t>(k) * type_size(p.type), where);
          continue;
        }
        poly.clear();
        for (std::int64_t j = 0; j < k; ++j) {
          const double v = body.value(p.type, where);
          if (v != std::floor(v)) fail("non-integer face index in " + where);
          if (v < 0 || v > 2147483647.0)
            fail("face " + std::to_string(r) + ": vertex index " +
                 std::to_string(static_cast<long long>(v)) + " out of range");
          poly.push_back(static_cast<std::int32_t>(v));
        }
        if (k >= 3) add_face(poly, r);  // points and lines dropped
      }
      body.end_record(r, where);
    }
  }
  if (read_all) body.check_end();
  if (!tri.empty()) {
    if (!have_vertices) fail("the PLY file has faces but no vertex element");
    std::vector<std::int32_t> cut, idx;
    for (const Pending& p : pending) {  // the faces before the vertices, in their places
      const auto first = polys.begin() + static_cast<std::ptrdiff_t>(p.first);
      idx.assign(first, first + static_cast<std::ptrdiff_t>(p.n));
      cut.clear();
      cut.swap(tri);  // tri empty: add_face appends the face's triangles there
      add_face(idx, p.face);
      tri.swap(cut);  // cut: those triangles; tri: all of them, their slots waiting
      std::copy(cut.begin(), cut.end(), tri.begin() + static_cast<std::ptrdiff_t>(p.at));
    }
    out.faces.resize(static_cast<Eigen::Index>(tri.size() / 3), 3);
    std::copy(tri.begin(), tri.end(), out.faces.data());
  }
  return out;
}

PlyData read_ply(const std::string& path, bool read_faces) {
  const std::string data = read_whole_file(path, "PLY", kMaxMeshFileBytes);
  try {
    return parse_ply(reinterpret_cast<const std::uint8_t*>(data.data()), data.size(), read_faces);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("cannot read PLY '" + path + "': " + e.what());
  }
}

}  // namespace nbv
