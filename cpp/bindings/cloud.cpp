#include "bindings.hpp"
#include "nbv/ply.hpp"
#include "nbv/point_cloud.hpp"
#include "options.hpp"

namespace nbv::bind {

void init_cloud(py::module_& m) {
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
over the union of everything added. Points with z < min_z (ground removal; -inf disables it) or,
with crop=True, outside the box [crop_min, crop_max] are not registered. Points come out in the
order their voxels were first seen (deterministic).

options: SurfaceCloudOptions (or a dict, or None for the defaults) with keyword overrides:
voxel_size, min_z, crop, crop_min, crop_max (a keyword set to None keeps the value). Defaults
follow the authors: voxel_size 0.02 m for the RGB-D camera (use 0.1 m for the laser's profile
cloud), min_z 0.3 m.)doc")
      .def(py::init([](const py::object& options, const py::kwargs& kw) {
             return std::make_shared<SurfaceCloud>(
                 options_with_keywords<SurfaceCloudOptions>(options, kw));
           }),
           py::arg("options") = py::none())
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
          "options", [](const SurfaceCloud& c) { return SurfaceCloudOptions(c.options()); },
          "the SurfaceCloudOptions the cloud was made with (a copy)")
      .def_property_readonly(
          "voxel_size", [](const SurfaceCloud& c) { return c.options().voxel_size; },
          "voxel-grid cell size, metres")
      .def_property_readonly(
          "min_z", [](const SurfaceCloud& c) { return c.options().min_z; },
          "ground removal height in metres (points below are dropped); -inf: none")
      .def_property_readonly("bytes", &SurfaceCloud::bytes,
                             "bytes the cloud holds (its voxel index, sums and counts)")
      .def("clear", &SurfaceCloud::clear, "Remove every point (the options stay).")
      .def("__len__", &SurfaceCloud::size);

  m.def(
      "stack_points",
      [](const std::vector<const SurfaceCloud*>& clouds, std::int64_t start,
         const std::optional<std::int64_t>& stop) {
        check_clouds(clouds);
        if (start < 0 || (stop && *stop < 0))
          throw py::value_error("stack_points: start and stop must be >= 0");
        py::gil_scoped_release release;
        return stack_points(clouds, std::size_t(start),
                            stop ? std::size_t(*stop) : std::numeric_limits<std::size_t>::max());
      },
      py::arg("clouds"), py::arg("start") = 0, py::arg("stop") = py::none(),
      "(N, 3) float64: the clouds' points one cloud after the other, in one array (the same as "
      "numpy.vstack of their points, without a copy per cloud). start, stop: only rows "
      "[start, stop) of that stack (clamped to it), e.g. to write a large cloud a part at a "
      "time.");
  m.def(
      "voxelgrid_sampling",
      [](const py::handle& points, double voxel_size) {
        auto a = points_arg(points, "points", /*allow_nonfinite=*/true);  // the core checks
        py::gil_scoped_release release;
        return voxelgrid_sampling(a.map(), voxel_size);
      },
      py::arg("points"), py::arg("voxel_size"),
      "(K, 3) float64 voxel-grid centroids of (N, 3) points: one point per cell "
      "floor(p / voxel_size) (grid anchored at the origin), the mean of the points in it, in the "
      "order the cells are first seen. ValueError for a non-positive voxel size or a non-finite "
      "point.");

  m.def(
      "voxelgrid_sampling_of",
      [](const std::vector<const SurfaceCloud*>& clouds, double voxel_size) {
        check_clouds(clouds);
        py::gil_scoped_release release;
        return voxelgrid_sampling(clouds, voxel_size);
      },
      py::arg("clouds"), py::arg("voxel_size"),
      "voxelgrid_sampling(stack_points(clouds), voxel_size): the same centroids, in the same "
      "order, reading the clouds a part at a time instead of holding their stack.");

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
