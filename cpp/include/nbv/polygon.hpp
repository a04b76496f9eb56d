// Polygons of mesh files as triangles, one rule for every reader (OBJ, PLY): convex polygons as
// fans from their first vertex, non-convex ones by ear clipping in their plane, keeping the
// polygon's winding. A polygon of n vertices always gives n - 2 triangles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace nbv {

/// Non-convex polygons with more vertices than this are refused (ear clipping is quadratic).
constexpr std::size_t kMaxEarClipVertices = 256;

/// Appends the n - 2 triangles of polygon `poly` (n >= 3 indices into xyz: x, y, z of vertex i
/// at xyz[3 i ..]) to `out`, keeping its winding. Returns false (nothing appended) for a
/// non-convex polygon of more than kMaxEarClipVertices vertices.
bool triangulate_polygon(const std::int32_t* poly, std::size_t n, const double* xyz,
                         std::vector<std::int32_t>& out);

/// The reason a reader gives for a polygon triangulate_polygon refused.
std::string polygon_too_large(std::size_t n);

}  // namespace nbv
