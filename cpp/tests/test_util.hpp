// Helpers shared by the GoogleTest files.
#pragma once

#include <Eigen/Dense>

#include <array>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

namespace nbv_test {

/// The message of the std::invalid_argument that f(args...) throws, or "" when it returns (any
/// other exception escapes, failing the test).
template <class F, class... Args>
std::string error_of(F&& f, Args&&... args) {
  try {
    std::invoke(std::forward<F>(f), std::forward<Args>(args)...);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/// The corners of triangle `i` of a mesh reader's output (`d.faces` into `d.vertices`).
template <class Data>
std::array<Eigen::Vector3d, 3> corners(const Data& d, Eigen::Index i) {
  return {d.vertices.row(d.faces(i, 0)).transpose(), d.vertices.row(d.faces(i, 1)).transpose(),
          d.vertices.row(d.faces(i, 2)).transpose()};
}

/// The summed area of a mesh reader's triangles (ObjData, PlyData, StlData).
template <class Data>
double area_of(const Data& d) {
  double a = 0;
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {
    const auto [p0, p1, p2] = corners(d, i);
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

/// The signed volume a closed mesh encloses: positive when its triangles face outwards.
template <class Data>
double volume_of(const Data& d) {
  double v = 0;
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {
    const auto [p0, p1, p2] = corners(d, i);
    v += p0.dot(p1.cross(p2)) / 6;
  }
  return v;
}

}  // namespace nbv_test
