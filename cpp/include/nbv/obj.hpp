// nbvkit's own Wavefront OBJ geometry reader, in double precision.
//
// assimp (Debian's build) keeps coordinates in float32: a georeferenced vertex at 5,000,000.3 m
// came out 5,000,000.5 m before mesh.shift could bring it near the origin. This reader keeps the
// file's digits as doubles. It reads `v x y z [...]` (the first three numbers; `w` and vertex
// colours are ignored) and `f` faces (`v`, `v/vt`, `v//vn`, `v/vt/vn`; negative indices count back
// from the last vertex read; forward references are allowed). Polygons are triangulated keeping
// their winding (triangulate_polygon: convex ones as fans, non-convex ones of up to
// kMaxEarClipVertices vertices by ear clipping in their plane). Faces of fewer than three vertices
// (lines, points) and every other statement (vt, vn, o, g, s, usemtl, mtllib, l, p, ...) are
// ignored: no other file is ever opened. A trailing backslash continues a line; `#` starts a
// comment.
//
// Only vertices used by a triangle are kept, in file order; whether they are finite is left to
// the mesh loader (load_mesh checks every format's face vertices the same way). Every problem
// throws std::invalid_argument naming the line (read_obj adds the file name).
#pragma once

#include "nbv/common.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace nbv {

struct ObjData {
  Points vertices;  ///< (N, 3) the used vertices, in file order, as the file's digits (float64)
  Faces faces;      ///< (M, 3) triangles; may be empty
  std::vector<std::int64_t> file_number;  ///< each vertex's number in the file (1: the first `v`)
};

/// Parses OBJ text held in memory.
ObjData parse_obj(const char* data, std::size_t size);

/// Reads (read_whole_file: a regular file of at most kMaxMeshFileBytes) and parses an OBJ file;
/// FileNotFound for a missing path, std::invalid_argument ("cannot read OBJ 'path': reason") for
/// anything else.
ObjData read_obj(const std::string& path);

}  // namespace nbv
