// nbvkit's own Wavefront OBJ (and OFF, parse_off) geometry readers, in double precision.
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

/// Parses OFF text held in memory (the Geomview/Princeton format: an `OFF` header, optionally
/// `C`/`N`/`ST`-prefixed, whose per-vertex extras are ignored; `V F [E]` counts; V vertex lines
/// `x y z ...`; F face lines `n i0 .. i(n-1) [colour]`, indices from 0). Polygons are
/// triangulated as OBJ's; faces of fewer than three vertices are ignored. Every index out of
/// range, a count the file does not hold, and data after the last face throw naming the line.
/// file_number holds each vertex's 0-based OFF index.
ObjData parse_off(const char* data, std::size_t size);

/// read_obj for OFF files ("cannot read OFF 'path': reason").
ObjData read_off(const std::string& path);

/// Reads (read_whole_file: a regular file of at most kMaxMeshFileBytes) and parses an OBJ file;
/// FileNotFound for a missing path, std::invalid_argument ("cannot read OBJ 'path': reason") for
/// anything else.
ObjData read_obj(const std::string& path);

}  // namespace nbv
