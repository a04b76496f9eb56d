#include "nbv/mesh.hpp"
#include "bindings.hpp"

#include <limits>
#include <string>

namespace nbv::bind {

namespace {
// A numpy array that cannot be written: changing a copy of a mesh's arrays would look like
// changing the mesh, which it does not.
py::object read_only(py::object a) {
  a.attr("flags").attr("writeable") = false;
  return a;
}
}  // namespace

void init_mesh(py::module_& m) {
  py::class_<Mesh, std::shared_ptr<Mesh>>(m, "Mesh", R"doc(
A triangle soup in metres, world frame, z up.

vertices: (N, 3) float64; faces: (M, 3) int32, 0-based. Build with nbvkit.load_mesh(path),
Mesh(vertices, faces) or Mesh.from_open3d(o3d_mesh).)doc")
      .def(py::init([](const py::handle& v, const py::handle& f) {
             auto va = points_arg(v, "mesh vertices");
             const auto fa = integer_array<std::int32_t>(f, "mesh faces");
             if (fa.ndim() != 2 || fa.shape(1) != 3)
               throw py::value_error("mesh faces must have shape (M, 3) of integer indices");
             Eigen::Map<const Faces> fm(fa.data(), fa.shape(0), 3);
             return std::make_shared<Mesh>(Mesh::from_arrays(va.map(), fm));
           }),
           py::arg("vertices"), py::arg("faces"))
      .def_property_readonly(
          "vertices", [](const Mesh& s) { return read_only(py::cast(s.vertices)); },
          "(N, 3) float64 vertex positions, metres (a read-only copy: a Mesh never changes; "
          "build a new one with Mesh(vertices, faces), which checks them)")
      .def_property_readonly(
          "faces", [](const Mesh& s) { return read_only(py::cast(s.faces)); },
          "(M, 3) int32 vertex indices (a read-only copy: a Mesh never changes; build a new one "
          "with Mesh(vertices, faces), which checks them)")
      .def_property_readonly("num_triangles", [](const Mesh& s) { return s.faces.rows(); })
      .def_property_readonly("num_vertices", [](const Mesh& s) { return s.vertices.rows(); })
      .def("triangle_areas", &Mesh::triangle_areas, "(M,) triangle areas, m^2")
      .def_property_readonly("area", &Mesh::area, "total surface area, m^2")
      .def_property_readonly(
          "bounds",
          [](const Mesh& s) {
            auto b = s.bounds();
            Eigen::Matrix<double, 2, 3, Eigen::RowMajor> out;
            out.row(0) = b.min();
            out.row(1) = b.max();
            return out;
          },
          "(2, 3): [min xyz, max xyz] of the triangles' vertices")
      .def(
          "sample_surface",
          [](const Mesh& s, long long n, const py::object& seed_obj,
             bool return_faces) -> py::object {
            if (n < 0) throw py::value_error("number of samples must be >= 0");
            constexpr long long kMaxSamples = 200'000'000;  // 4.8 GB of points (int32 ids)
            if (n > kMaxSamples)  // (it asked for 48 GB at 2e9, the OOM killer's to stop)
              throw py::value_error(
                  "number of samples must be at most 200,000,000 (4.8 GB of "
                  "points), got " +
                  std::to_string(n));
            const std::uint64_t seed = seed_arg(seed_obj);
            Eigen::VectorXi fid;
            Points p;
            {
              py::gil_scoped_release release;
              p = s.sample_surface(static_cast<std::size_t>(n), seed,
                                   return_faces ? &fid : nullptr);
            }
            if (return_faces) return py::make_tuple(p, fid);
            return py::cast(p);
          },
          py::arg("n"), py::arg("seed") = 0, py::arg("return_faces") = false,
          "n points uniformly over the surface (area-weighted), (n, 3) float64; deterministic per "
          "seed.\n"
          "With return_faces=True also returns the (n,) int32 source triangle of each point.")
      .def("__repr__", [](const Mesh& s) {
        auto b = s.bounds();
        Eigen::Vector3d e = b.sizes();
        return "<nbvkit.Mesh " + std::to_string(s.faces.rows()) + " triangles, " +
               std::to_string(e.x()) + " x " + std::to_string(e.y()) + " x " +
               std::to_string(e.z()) + " m>";
      });

  m.def(
      "_load_mesh",
      [](const py::object& path_obj, double scale, const std::string& up) {
        // The path as the OS's bytes (os.fsencode of a str, bytes or os.PathLike): any path the
        // OS accepts, also one that is not UTF-8.
        const std::string path = py::bytes(py::module_::import("os").attr("fsencode")(path_obj));
        if (up.size() != 1)
          throw py::value_error("mesh up axis must be 'y' or 'z', got '" + up + "'");
        std::shared_ptr<Mesh> mesh;
        std::string error;
        {
          py::gil_scoped_release release;
          try {
            mesh = std::make_shared<Mesh>(load_mesh(path, scale, up[0]));
          } catch (const std::invalid_argument& e) {
            error = e.what();
          }
        }
        if (!error.empty())  // the message names the path: its bytes need not be UTF-8
          throw py::value_error(
              py::bytes(error).attr("decode")("utf-8", "backslashreplace").cast<std::string>());
        return mesh;
      },
      py::arg("path"), py::arg("scale") = 1.0, py::arg("up") = "z");
}

}  // namespace nbv::bind
