// Triangle meshes: loading through assimp, validation, area-weighted surface sampling.
#pragma once

#include "nbv/common.hpp"

#include <cstdint>
#include <string>

namespace nbv {

/// A triangle soup in metres: vertices (N, 3) float64 and faces (M, 3) int32 (0-based).
/// Invariants (checked by validate()): at least one triangle, finite vertices, indices in range.
struct Mesh {
  Points vertices;
  Faces faces;

  /// Builds a mesh from arrays and validates it (std::invalid_argument on bad input, or when its
  /// triangles have no area: all degenerate).
  static Mesh from_arrays(const PointsRef& vertices, const Eigen::Ref<const Faces>& faces);

  void validate() const;
  /// Per-triangle areas (M,), m^2.
  Eigen::VectorXd triangle_areas() const;
  double area() const;
  Eigen::AlignedBox3d bounds() const;

  /// `n` points uniformly distributed over the surface (area-weighted triangle choice, uniform
  /// barycentric inside it), deterministic for a given seed. If `face_ids` is given it receives
  /// the source triangle of each point.
  Points sample_surface(std::size_t n, std::uint64_t seed,
                        Eigen::VectorXi* face_ids = nullptr) const;
};

/// Largest mesh file load_mesh reads (bytes): 2 GiB.
constexpr std::uintmax_t kMaxMeshFileBytes = std::uintmax_t(2) << 30;

/// Largest rounding (m, after scale) accepted from a file read through assimp in float32:
/// 1 mm, i.e. coordinates below 32768 (2^15) at scale 1.
constexpr double kMaxFloat32RoundingMetres = 1e-3;

/// Loads every mesh of a file (OBJ, STL, PLY, DAE, glTF/GLB, ... whatever assimp reads; PLY and
/// OBJ through nbvkit's own readers in double precision, nbv/ply.hpp and nbv/obj.hpp), with each
/// node's transform applied, merged into one triangle soup. Files read through assimp arrive in
/// float32: a mesh whose coordinates float32 rounds by more than kMaxFloat32RoundingMetres is
/// refused (std::invalid_argument saying why and how to fix it). Every file assimp opens (the
/// mesh file and any file it names: materials, buffers) must be a regular file of at most
/// kMaxMeshFileBytes, else the mesh is refused naming that file. `up` names the file's up axis: 'z'
/// (kept) or 'y' (rotated so file +y becomes +z: (x, y, z) -> (x, -z, y)). `scale` multiplies all
/// coordinates after the rotation. Throws FileNotFound for a missing path and
/// std::invalid_argument naming the file for unreadable or triangle-less files.
Mesh load_mesh(const std::string& path, double scale = 1.0, char up = 'z');

}  // namespace nbv
