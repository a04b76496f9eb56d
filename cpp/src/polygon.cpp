#include "nbv/polygon.hpp"

#include <cmath>
#include <cstddef>
#include <string>

namespace nbv {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct V2 {
  double x, y;
};

double cross(const V2& o, const V2& a, const V2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

}  // namespace

bool triangulate_polygon(const std::int32_t* poly, std::size_t n, const double* xyz,
                         std::vector<std::int32_t>& out) {
  const auto fan = [&](const std::vector<std::size_t>& L) {
    for (std::size_t i = 1; i + 1 < L.size(); ++i)
      out.insert(out.end(), {poly[L[0]], poly[L[i]], poly[L[i + 1]]});
  };
  std::vector<std::size_t> L(n);
  for (std::size_t i = 0; i < n; ++i) L[i] = i;
  if (n == 3) {
    fan(L);
    return true;
  }
  // Coordinates relative to the first vertex (georeferenced files keep their digits), the
  // polygon's Newell normal, and its projection onto the plane of the normal's largest axis.
  const auto P = [&](std::size_t i, int k) {
    return xyz[3 * static_cast<std::size_t>(poly[i]) + k] -
           xyz[3 * static_cast<std::size_t>(poly[0]) + k];
  };
  double N[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = (i + 1) % n;
    for (int k = 0; k < 3; ++k) {
      const int a = (k + 1) % 3, b = (k + 2) % 3;
      N[k] += (P(i, a) - P(j, a)) * (P(i, b) + P(j, b));
    }
  }
  int k = 0;
  for (int c = 1; c < 3; ++c)
    if (std::abs(N[c]) > std::abs(N[k])) k = c;
  if (!(std::abs(N[k]) > 0) || !std::isfinite(N[k])) {  // no area: any triangulation will do
    fan(L);
    return true;
  }
  const int a = (k + 1) % 3, b = (k + 2) % 3;
  const double s = N[k] > 0 ? 1.0 : -1.0;  // counter-clockwise in the (a, b) plane after this
  std::vector<V2> q(n);
  for (std::size_t i = 0; i < n; ++i) q[i] = {P(i, a), s * P(i, b)};

  // Convex (every turn to the left or straight, turning once around): a fan is exact.
  bool convex = true;
  double turning = 0;
  for (std::size_t i = 0; i < n && convex; ++i) {
    const V2 &p = q[(i + n - 1) % n], &c = q[i], &d = q[(i + 1) % n];
    const double ex = c.x - p.x, ey = c.y - p.y, fx = d.x - c.x, fy = d.y - c.y;
    const double cr = ex * fy - ey * fx, dt = ex * fx + ey * fy;
    if (cr < -1e-12 * std::hypot(ex, ey) * std::hypot(fx, fy)) convex = false;
    turning += std::atan2(cr, dt);
  }
  if (convex && std::abs(turning - 2 * kPi) < 1e-6) {
    fan(L);
    return true;
  }
  if (n > kMaxEarClipVertices) return false;

  // Ear clipping: cut off a convex corner whose triangle holds no other remaining vertex.
  const auto inside = [&](const V2& p, const V2& A, const V2& B, const V2& C) {
    return cross(A, B, p) >= 0 && cross(B, C, p) >= 0 && cross(C, A, p) >= 0;
  };
  const auto same = [](const V2& u, const V2& v) { return u.x == v.x && u.y == v.y; };
  std::size_t i = 0, misses = 0;
  while (L.size() > 3) {
    const std::size_t m = L.size();
    const std::size_t ia = L[(i + m - 1) % m], ib = L[i % m], ic = L[(i + 1) % m];
    const V2 &A = q[ia], &B = q[ib], &C = q[ic];
    bool ear = cross(A, B, C) > 0;
    for (std::size_t j = 0; ear && j < m; ++j) {
      const V2& p = q[L[j]];
      if (L[j] == ia || L[j] == ib || L[j] == ic || same(p, A) || same(p, B) || same(p, C))
        continue;
      ear = !inside(p, A, B, C);
    }
    if (ear) {
      out.insert(out.end(), {poly[ia], poly[ib], poly[ic]});
      L.erase(L.begin() + static_cast<std::ptrdiff_t>(i % m));
      i = i % (m - 1);
      misses = 0;
    } else {
      i = (i + 1) % m;
      if (++misses > m) break;  // self-intersecting or degenerate: fan what is left
    }
  }
  fan(L);
  return true;
}

std::string polygon_too_large(std::size_t n) {
  return "a non-convex polygon of " + std::to_string(n) +
         " vertices: nbvkit triangulates non-convex polygons of at most " +
         std::to_string(kMaxEarClipVertices) + " (triangulate the mesh before exporting it)";
}

}  // namespace nbv
