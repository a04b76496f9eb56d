#include "nbv/stl.hpp"
#include "nbv/mesh.hpp"
#include "nbv/polygon.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <random>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace nbv {

namespace {

constexpr std::uint64_t kHeaderBytes = 84;  // 80 bytes of header, the uint32 facet count
constexpr std::uint64_t kFacetBytes = 50;   // normal, three vertices (3 float32 each), uint16
constexpr std::size_t kMaxVertices = std::numeric_limits<std::int32_t>::max();

[[noreturn]] void fail(const std::string& why) { throw std::invalid_argument(why); }

[[noreturn]] void fail(std::size_t line, const std::string& why) {
  fail("line " + std::to_string(line) + ": " + why);
}

std::string quote(std::string_view tok) {
  return "'" + printable_ascii(std::string(tok.substr(0, 40))) + "'";
}

// What the parser found instead of what it expected: a token, quoted, or the end of the file.
std::string found(std::string_view tok) { return tok.empty() ? "the end of the file" : quote(tok); }

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

bool iequals(std::string_view tok, std::string_view keyword) {
  if (tok.size() != keyword.size()) return false;
  for (std::size_t i = 0; i < tok.size(); ++i) {
    const char c = tok[i] >= 'A' && tok[i] <= 'Z' ? static_cast<char>(tok[i] - 'A' + 'a') : tok[i];
    if (c != keyword[i]) return false;
  }
  return true;
}

bool parse_double(std::string_view t, double& v) {
  if (!t.empty() && t[0] == '+') {
    t.remove_prefix(1);
    if (!t.empty() && t[0] == '-') return false;
  }
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  return !t.empty() && r.ec == std::errc() && r.ptr == t.data() + t.size();
}

std::uint32_t le32(const std::uint8_t* b) {
  return static_cast<std::uint32_t>(b[0]) | static_cast<std::uint32_t>(b[1]) << 8 |
         static_cast<std::uint32_t>(b[2]) << 16 | static_cast<std::uint32_t>(b[3]) << 24;
}

float le_float(const std::uint8_t* b) {
  const std::uint32_t u = le32(b);
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

// The merged vertices: identical positions (exact doubles, -0.0 equal to 0.0) share one index,
// in order of first use; a position with a NaN coordinate is a vertex of its own. An open
// addressing table of indices into xyz, kept at most half full.
// The hash is keyed by a random seed drawn per table: a file crafted so that its distinct
// positions collide under a fixed hash made merging quadratic (8 MB: 23 s).
class VertexTable {
 public:
  std::vector<double> xyz;  // 3 per vertex

  VertexTable() {
    std::random_device rd;
    seed_ = (std::uint64_t(rd()) << 32 | rd()) | 1;
  }

  std::int32_t add(const double p[3]) {
    if (std::isnan(p[0]) || std::isnan(p[1]) || std::isnan(p[2])) return append(p);
    if (2 * (used_ + 1) > slots_.size()) grow();
    for (std::size_t s = hash(p) & mask_;; s = (s + 1) & mask_) {
      const std::int32_t v = slots_[s];
      if (v < 0) {
        slots_[s] = append(p);
        ++used_;
        return slots_[s];
      }
      const double* q = &xyz[3 * static_cast<std::size_t>(v)];
      if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) return v;
    }
  }

 private:
  static std::uint64_t bits(double x) {
    if (x == 0) x = 0;  // -0.0 hashes as 0.0
    std::uint64_t u;
    std::memcpy(&u, &x, sizeof u);
    return u;
  }

  std::size_t hash(const double p[3]) const {
    std::uint64_t h = seed_;
    for (int k = 0; k < 3; ++k) {
      h ^= bits(p[k]);
      h *= 0xBF58476D1CE4E5B9ull;
      h ^= h >> 31;
      h *= 0x94D049BB133111EBull;
      h ^= h >> 29;
    }
    return static_cast<std::size_t>(h);
  }

  std::int32_t append(const double p[3]) {
    const std::size_t n = xyz.size() / 3;
    if (n >= kMaxVertices) fail("more than 2^31 - 1 vertices");
    xyz.insert(xyz.end(), p, p + 3);
    return static_cast<std::int32_t>(n);
  }

  void grow() {
    std::vector<std::int32_t> old(std::max<std::size_t>(1024, 2 * slots_.size()), -1);
    old.swap(slots_);
    mask_ = slots_.size() - 1;
    for (const std::int32_t v : old)
      if (v >= 0)
        for (std::size_t s = hash(&xyz[3 * static_cast<std::size_t>(v)]) & mask_;;
             s = (s + 1) & mask_)
          if (slots_[s] < 0) {
            slots_[s] = v;
            break;
          }
  }

  std::vector<std::int32_t> slots_;  // -1: empty; a power of two of them
  std::uint64_t seed_ = 0;
  std::size_t mask_ = 0;
  std::size_t used_ = 0;
};

StlData finish(VertexTable& table, const std::vector<std::int32_t>& tri, bool binary) {
  StlData out;
  out.binary = binary;
  out.vertices.resize(static_cast<Eigen::Index>(table.xyz.size() / 3), 3);
  std::copy(table.xyz.begin(), table.xyz.end(), out.vertices.data());
  out.faces.resize(static_cast<Eigen::Index>(tri.size() / 3), 3);
  std::copy(tri.begin(), tri.end(), out.faces.data());
  return out;
}

StlData parse_binary(const std::uint8_t* data, std::uint32_t n) {
  VertexTable table;
  std::vector<std::int32_t> tri;
  tri.reserve(3 * static_cast<std::size_t>(n));  // the size was checked: n records are there
  for (std::uint32_t f = 0; f < n; ++f) {
    const std::uint8_t* rec = data + kHeaderBytes + kFacetBytes * f + 12;  // past the normal
    for (int k = 0; k < 3; ++k) {
      const double p[3] = {le_float(rec + 12 * k), le_float(rec + 12 * k + 4),
                           le_float(rec + 12 * k + 8)};
      tri.push_back(table.add(p));
    }
  }
  return finish(table, tri, true);
}

// The tokens of an ASCII STL, separated by whitespace, with the line each starts on (LF, CRLF
// and a lone CR each end a line).
class Lexer {
 public:
  Lexer(const char* p, std::size_t n, std::size_t pos) : p_(p), n_(n), pos_(pos) {}

  // The next token ("" at the end of the data); line() is its line.
  std::string_view next() {
    while (pos_ < n_ && is_space(p_[pos_])) {
      if (p_[pos_] == '\n' || (p_[pos_] == '\r' && (pos_ + 1 == n_ || p_[pos_ + 1] != '\n')))
        ++line_;
      ++pos_;
    }
    const std::size_t start = pos_;
    while (pos_ < n_ && !is_space(p_[pos_])) ++pos_;
    if (pos_ > start) token_line_ = line_;
    return std::string_view(p_ + start, pos_ - start);
  }

  // Skips a solid's name: the rest of its line, or up to a keyword of `stop` found on it (a
  // whole file written on one line).
  void skip_name(std::initializer_list<std::string_view> stop) {
    while (pos_ < n_ && p_[pos_] != '\n' && p_[pos_] != '\r') {
      if (is_space(p_[pos_])) {
        ++pos_;
        continue;
      }
      const std::size_t start = pos_;
      while (pos_ < n_ && !is_space(p_[pos_])) ++pos_;
      const std::string_view tok(p_ + start, pos_ - start);
      if (std::any_of(stop.begin(), stop.end(), [&](auto k) { return iequals(tok, k); })) {
        pos_ = start;
        return;
      }
    }
  }

  // The line of the last token read (at the end of the data: of the last token in the file).
  std::size_t line() const { return token_line_; }

 private:
  const char* p_;
  std::size_t n_, pos_;
  std::size_t line_ = 1, token_line_ = 1;
};

void expect(Lexer& lex, std::string_view keyword, const char* after = nullptr) {
  const std::string_view tok = lex.next();
  if (!iequals(tok, keyword))
    fail(lex.line(), "expected '" + std::string(keyword) + "'" +
                         (after ? std::string(" after '") + after + "'" : std::string()) +
                         ", found " + found(tok));
}

double number(Lexer& lex, const char* what) {
  const std::string_view tok = lex.next();
  double v;
  if (tok.empty())
    fail(lex.line(), std::string("expected a ") + what + ", found the end of the file");
  if (!parse_double(tok, v))
    fail(lex.line(), std::string(what) + " " + quote(tok) + " is not a number");
  return v;
}

StlData parse_ascii(const char* data, std::size_t size, std::size_t start) {
  Lexer lex(data, size, start);
  VertexTable table;
  std::vector<std::int32_t> tri, poly;
  std::size_t facet = 0;  // facets read so far, for messages (1: the first)
  std::string_view tok = lex.next();
  while (true) {
    if (!iequals(tok, "solid"))  // the first token is "solid" (ascii_start)
      fail(lex.line(),
           "expected 'solid' or the end of the file after 'endsolid', found " + quote(tok));
    lex.skip_name({"facet", "endsolid"});
    while (true) {
      tok = lex.next();
      if (iequals(tok, "endsolid")) break;
      if (!iequals(tok, "facet"))
        fail(lex.line(), "expected 'facet' or 'endsolid', found " + found(tok));
      ++facet;
      const std::size_t facet_line = lex.line();
      expect(lex, "normal", "facet");
      for (int k = 0; k < 3; ++k) number(lex, "facet normal component");
      expect(lex, "outer");
      expect(lex, "loop", "outer");
      poly.clear();
      while (true) {
        tok = lex.next();
        if (iequals(tok, "endloop")) break;
        if (!iequals(tok, "vertex"))
          fail(lex.line(), "expected 'vertex' or 'endloop', found " + found(tok));
        double p[3];
        for (double& c : p) c = number(lex, "vertex coordinate");
        poly.push_back(table.add(p));
      }
      if (poly.size() < 3)
        fail(facet_line, "facet " + std::to_string(facet) + " has " + std::to_string(poly.size()) +
                             " vertices (a facet needs at least 3)");
      expect(lex, "endfacet");
      if (!triangulate_polygon(poly.data(), poly.size(), table.xyz.data(), tri))
        fail(facet_line, "facet " + std::to_string(facet) + ": " + polygon_too_large(poly.size()));
    }
    lex.skip_name({"solid"});
    tok = lex.next();
    while (!tok.empty() && tok.find_first_not_of('\0') == std::string_view::npos)
      tok = lex.next();  // NUL padding after the last solid, as some exporters write
    if (tok.empty()) break;
  }
  return finish(table, tri, false);
}

// Where an ASCII STL's first token starts (after a UTF-8 BOM and whitespace) if that token is
// "solid" (any case) followed by whitespace or the end; else npos.
std::size_t ascii_start(const char* data, std::size_t size) {
  std::size_t i = size >= 3 && std::memcmp(data, "\xEF\xBB\xBF", 3) == 0 ? 3 : 0;
  const std::size_t bom = i;
  while (i < size && is_space(data[i])) ++i;
  if (size - i < 5 || !iequals(std::string_view(data + i, 5), "solid")) return std::string::npos;
  if (size - i > 5 && !is_space(data[i + 5])) return std::string::npos;
  return bom;
}

// Whether the file holds control bytes that no text file does (binary data).
bool has_binary_bytes(const std::uint8_t* data, std::size_t size) {
  for (std::size_t i = 0; i < size; ++i)
    if ((data[i] < 0x20 && !is_space(static_cast<char>(data[i]))) || data[i] == 0x7f) return true;
  return false;
}

// What a file of `size` bytes is as binary STL: its facet count, the size that takes, and how
// the file differs.
std::string as_binary(std::uint32_t n, std::uint64_t expected, std::size_t size) {
  const std::string facets = std::to_string(n) + " facets";
  return std::string(size < expected ? "it is truncated"
                                     : "it holds more bytes than its " + facets) +
         " (its header declares " + facets + ", 84 + 50 x " + std::to_string(n) + " = " +
         std::to_string(expected) + " bytes, but the file has " + std::to_string(size) + " bytes)";
}

}  // namespace

StlData parse_stl(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);
  std::uint32_t n = 0;
  std::uint64_t expected = 0;
  if (size >= kHeaderBytes) {
    n = le32(data + 80);
    expected = kHeaderBytes + kFacetBytes * n;  // at most 84 + 50 (2^32 - 1): no overflow
    if (static_cast<std::uint64_t>(size) == expected) return parse_binary(data, n);
  }
  const std::size_t start = ascii_start(text, size);
  if (start == std::string::npos) {
    if (size < kHeaderBytes)
      fail("neither binary nor ASCII STL: as binary STL it is too short (" + std::to_string(size) +
           " bytes, fewer than the 84 of the header and facet count); as ASCII STL it does not "
           "start with 'solid'");
    fail("neither binary nor ASCII STL: as binary STL " + as_binary(n, expected, size) +
         "; as ASCII STL it does not start with 'solid'");
  }
  try {
    return parse_ascii(text, size, start);
  } catch (const std::invalid_argument& e) {
    // A binary STL whose header starts with "solid" and whose size is wrong: say so too.
    if (size < kHeaderBytes || !has_binary_bytes(data, size)) throw;
    fail(std::string(e.what()) +
         " (the file starts with 'solid' as ASCII STL does but holds binary bytes: as binary STL " +
         as_binary(n, expected, size) + ")");
  }
}

StlData read_stl(const std::string& path) {
  const std::string data = read_whole_file(path, "STL", kMaxMeshFileBytes);
  try {
    return parse_stl(reinterpret_cast<const std::uint8_t*>(data.data()), data.size());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("cannot read STL '" + path + "': " + e.what());
  }
}

}  // namespace nbv
