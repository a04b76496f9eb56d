// nbvkit's own strict STL reader, binary and ASCII, in double precision.
//
// assimp kept ASCII STL coordinates in float32, loaded a facet of four `vertex` lines as one
// triangle (the fourth dropped), and said only "Failed to determine STL storage representation"
// for an upper-case ASCII file, one starting with a blank line, or a binary file whose facet
// count disagrees with its size. This reader keeps the file's digits and says what is wrong.
//
// Binary: an 80-byte header, a uint32 facet count N, then N records of 50 bytes (a normal and
// three vertices, 3 float32 each, and a uint16 attribute), all little-endian. A file is binary
// when its size is exactly 84 + 50 N, even if its header begins with "solid" (many exporters
// write that; ASCII text, holding no NUL byte, cannot declare a count that matches its size
// within kMaxMeshFileBytes). Any other size is refused (naming N, the size expected and the size
// found) unless the file is ASCII STL: nothing is allocated from N before it is checked.
//
// ASCII: the first word (after an optional UTF-8 BOM and whitespace) is "solid" followed by
// whitespace or the end. Keywords are case-insensitive and any whitespace (spaces, tabs, LF,
// CRLF, a lone CR, blank lines) separates the tokens of
//   solid [name]  { facet normal nx ny nz  outer loop  vertex x y z (3 or more)  endloop
//   endfacet }  endsolid [name]
// with one or more solids one after another and nothing but whitespace or NUL bytes (padding)
// after the last. A name is the rest of its line (it may be empty or hold spaces), up to a
// 'facet' or 'endsolid' on that line (a file written on one line). Numbers are read as doubles
// (std::from_chars; nan and inf are numbers here, the mesh loader refuses non-finite vertices of
// faces). The facet normal is read and ignored: the vertices' winding is the truth. A facet of
// more than three vertices is triangulated keeping its winding (triangulate_polygon); one of
// fewer is refused. Every problem throws std::invalid_argument naming the line and what was
// expected (read_stl adds the file name).
//
// Identical positions are merged into one vertex (STL repeats each vertex in every facet that
// uses it), comparing the exact doubles, -0.0 equal to 0.0; a vertex with a NaN coordinate is
// never merged. Vertices are kept in the order of their first use, every index fits int32; the
// merging's hash is keyed by a random seed (the result does not depend on it), so no file can
// make it quadratic.
#pragma once

#include "nbv/common.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

namespace nbv {

struct StlData {
  Points vertices;      ///< (N, 3) the merged vertices, in order of first use (float64)
  Faces faces;          ///< (M, 3) triangles, in file order; empty for a file of no facets
  bool binary = false;  ///< whether the file was binary STL (float32 coordinates) or ASCII
};

/// Parses an STL file (binary or ASCII) held in memory. Throws std::invalid_argument naming the
/// problem (and, for ASCII, the line).
StlData parse_stl(const std::uint8_t* data, std::size_t size);

/// Reads (read_whole_file: a regular file of at most kMaxMeshFileBytes) and parses an STL file;
/// FileNotFound for a missing path, std::invalid_argument ("cannot read STL 'path': reason") for
/// anything else.
StlData read_stl(const std::string& path);

}  // namespace nbv
