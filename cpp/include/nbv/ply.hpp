// One strict PLY reader for meshes and point clouds (ASCII, binary little and big endian).
//
// Nothing is allocated before it is known to fit the file: every element's declared count is
// checked against the bytes left (binary: the element's smallest record; ASCII: one token per
// property). Face indices are range-checked. Every problem throws std::invalid_argument with
// the reason (the caller adds the file name).
#pragma once

#include "nbv/common.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

namespace nbv {

struct PlyData {
  Points vertices;  ///< (N, 3) x y z of the "vertex" element; (0, 3) if the file has none
  Faces faces;      ///< (M, 3) triangles of the "face" element (triangulate_polygon); may be empty
};

/// Parses a PLY file held in memory. With `read_faces` false the reader stops after the vertex
/// element (a point cloud). Throws std::invalid_argument naming the problem.
PlyData parse_ply(const std::uint8_t* data, std::size_t size, bool read_faces = true);

/// Reads (read_whole_file: a regular file of at most kMaxMeshFileBytes) and parses a PLY file;
/// FileNotFound for a missing path, std::invalid_argument ("cannot read PLY 'path': reason") for
/// anything else.
PlyData read_ply(const std::string& path, bool read_faces = true);

}  // namespace nbv
