#include "bindings.hpp"
#include "nbv/ply.hpp"
#include "nbv/point_cloud.hpp"
#include "options.hpp"

#include <cmath>
#include <limits>

namespace nbv::bind {

namespace {

double min_z_arg(const py::object& min_z) {
  if (min_z.is_none()) return -std::numeric_limits<double>::infinity();
  double z;
  try {
    z = min_z.cast<double>();
  } catch (const py::cast_error&) {
    throw py::value_error("min_z must be a number of metres or None");
  }
  if (std::isnan(z) || z == std::numeric_limits<double>::infinity())
    throw py::value_error("min_z must be a number of metres, -inf or None (no ground removal)");
  return z;
}

void bounds_arg(const py::object& bounds, SurfaceCloudOptions& o) {
  o.crop = false;
  if (bounds.is_none()) return;
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(bounds);
  if (!a || a.ndim() != 2 || a.shape(0) != 2 || a.shape(1) != 3)
    throw py::value_error("bounds must be a (2, 3) array [[xmin, ymin, zmin], [xmax, ymax, zmax]]");
  const double* d = a.data();
  o.crop = true;
  o.crop_min = Eigen::Vector3d(d[0], d[1], d[2]);
  o.crop_max = Eigen::Vector3d(d[3], d[4], d[5]);
}

}  // namespace

void init_cloud(py::module_& m) {
  const SurfaceCloudOptions def;
  {
    OptionsClass<SurfaceCloudOptions> binder(
        m, "SurfaceCloudOptions",
        "Options of the surface point cloud (the authors' settings); each field is documented in "
        "SurfaceCloudOptions.fields().");
    using S = SurfaceCloudOptions;
    NBV_SURFACE_CLOUD_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }

  py::class_<SurfaceCloud, std::shared_ptr<SurfaceCloud>>(m, "SurfaceCloud", R"doc(
Observed surface points, world frame, with an incremental voxel-grid filter.

One point per voxel of `voxel_size` metres (cell = floor(p / voxel_size), anchored at the origin):
the running centroid of every registered point that fell in it, i.e. what PCL's VoxelGrid gives
over the union of everything added. Points with z < min_z (ground removal; None disables) or
outside `bounds` ((2, 3) [min, max] crop box; None disables) are not registered. Points come
out in the order their voxels were first seen (deterministic).

Defaults follow the authors: voxel_size 0.02 m for the RGB-D camera (use 0.1 m for the laser's
profile cloud), min_z 0.3 m.)doc")
      .def(py::init([](double voxel_size, const py::object& min_z, const py::object& bounds) {
             SurfaceCloudOptions o;
             o.voxel_size = voxel_size;
             o.min_z = min_z_arg(min_z);
             bounds_arg(bounds, o);
             return std::make_shared<SurfaceCloud>(o);
           }),
           py::arg("voxel_size") = def.voxel_size, py::arg("min_z") = def.min_z,
           py::arg("bounds") = py::none())
      .def(
          "add",
          [](SurfaceCloud& c, const py::handle& points) {
            auto a = points_arg(points, "points", /*allow_nonfinite=*/true);  // the core checks
            return c.add(a.map());
          },
          py::arg("points"),
          "Register (N, 3) float64 world-frame points. Returns the number of new voxels.\n"
          "Raises ValueError (registering nothing) if any point is NaN or infinite.")
      .def_property_readonly(
          "points", &SurfaceCloud::points,
          "(K, 3) float64 voxel centroids, world frame, in voxel creation order (a copy)")
      .def_property_readonly("counts", &SurfaceCloud::counts,
                             "(K,) int64 number of registered points in each voxel")
      .def_property_readonly("num_registered", &SurfaceCloud::num_registered,
                             "total points registered (after ground removal and cropping)")
      .def_property_readonly(
          "voxel_size", [](const SurfaceCloud& c) { return c.options().voxel_size; },
          "voxel-grid cell size, metres")
      .def_property_readonly(
          "min_z",
          [](const SurfaceCloud& c) -> py::object {
            const double z = c.options().min_z;
            if (z == -std::numeric_limits<double>::infinity()) return py::none();
            return py::float_(z);
          },
          "ground removal height in metres (points below are dropped), or None")
      .def_property_readonly(
          "bounds",
          [](const SurfaceCloud& c) -> py::object {
            const auto& o = c.options();
            if (!o.crop) return py::none();
            Eigen::Matrix<double, 2, 3, Eigen::RowMajor> b;
            b.row(0) = o.crop_min;
            b.row(1) = o.crop_max;
            return py::cast(b);
          },
          "(2, 3) crop box [min, max] or None")
      .def("clear", &SurfaceCloud::clear, "Remove every point (the options stay).")
      .def("__len__", &SurfaceCloud::size);

  m.def(
      "_lzf_decompress",
      [](const py::bytes& data, std::size_t out_size) {
        const std::string s = data;
        std::vector<std::uint8_t> out;
        {
          py::gil_scoped_release release;
          out = lzf_decompress(reinterpret_cast<const std::uint8_t*>(s.data()), s.size(), out_size);
        }
        return py::bytes(reinterpret_cast<const char*>(out.data()), out.size());
      },
      py::arg("data"), py::arg("out_size"),
      "Decompress an LZF block (PCD binary_compressed) to exactly out_size bytes.");

  m.def(
      "_parse_ply",
      [](const py::bytes& data, bool faces) {
        const std::string s = data;
        PlyData ply;
        {
          py::gil_scoped_release release;
          ply = parse_ply(reinterpret_cast<const std::uint8_t*>(s.data()), s.size(), faces);
        }
        return py::make_tuple(py::cast(std::move(ply.vertices)), py::cast(std::move(ply.faces)));
      },
      py::arg("data"), py::arg("faces") = true,
      "Parse a PLY file's bytes with nbvkit's strict reader (nbv/ply.hpp): (vertices (N, 3), "
      "faces (M, 3)). faces=False stops after the vertex element. ValueError naming the problem.");
}

}  // namespace nbv::bind
