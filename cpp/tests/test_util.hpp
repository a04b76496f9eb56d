// Helpers shared by the GoogleTest files.
#pragma once

#include <Eigen/Dense>

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

/// The summed area of a mesh reader's triangles (`d.faces` into `d.vertices`: ObjData, PlyData).
template <class Data>
double area_of(const Data& d) {
  double a = 0;
  for (Eigen::Index i = 0; i < d.faces.rows(); ++i) {
    const Eigen::Vector3d p0 = d.vertices.row(d.faces(i, 0)), p1 = d.vertices.row(d.faces(i, 1)),
                          p2 = d.vertices.row(d.faces(i, 2));
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

}  // namespace nbv_test
