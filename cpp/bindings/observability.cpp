#include "nbv/observability.hpp"
#include "bindings.hpp"
#include "options.hpp"

namespace nbv::bind {

void init_observability(py::module_& m) {
  {
    OptionsClass<ObservabilityOptions> binder(m, "ObservabilityOptions", R"doc(
Options of observable_samples; each field is documented in ObservabilityOptions.fields().)doc");
    using S = ObservabilityOptions;
    NBV_OBSERVABILITY_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  py::class_<ObservabilityResult>(m, "ObservabilityResult",
                                  "Result of observable_samples (nbvkit.observable_surface).")
      .def_property_readonly("observable",
                             [](const ObservabilityResult& r) {
                               py::array_t<bool> out(static_cast<py::ssize_t>(r.observable.size()));
                               auto* p = out.mutable_data();
                               for (std::size_t i = 0; i < r.observable.size(); ++i)
                                 p[i] = r.observable[i] != 0;
                               return out;
                             })
      .def_readonly("poses", &ObservabilityResult::poses)
      .def_readonly("lattice_points", &ObservabilityResult::lattice_points)
      .def_readonly("colliding", &ObservabilityResult::colliding)
      .def_readonly("unreachable", &ObservabilityResult::unreachable)
      .def_readonly("timings_s", &ObservabilityResult::timings_s);

  m.def(
      "observable_samples",
      [](const RaycastScene& scene, const py::handle& points, const py::handle& normals,
         const DepthCamera& camera, const py::handle& nav_min, const py::handle& nav_max,
         const py::object& options, const py::kwargs& kw) {
        auto p = points_arg(points, "points");
        auto n = points_arg(normals, "normals");
        const Eigen::Vector3d lo = vec3_arg(nav_min, "nav_min");
        const Eigen::Vector3d hi = vec3_arg(nav_max, "nav_max");
        const auto o = options_with_keywords<ObservabilityOptions>(options, kw);
        const DepthCameraOptions cam = camera.options();
        py::gil_scoped_release release;
        return observable_samples(scene, p.map(), n.map(), cam, lo, hi, o);
      },
      py::arg("scene"), py::arg("points"), py::arg("normals"), py::arg("camera"),
      py::arg("nav_min"), py::arg("nav_max"), py::arg("options") = py::none(),
      "Which surface samples (N, 3) with normals (N, 3) the depth camera could see from some\n"
      "collision-free, reachable vehicle position of the box [nav_min, nav_max] (any yaw); one\n"
      "Embree call; `options` (ObservabilityOptions, a dict or None) with keyword overrides.\n"
      "See nbvkit.observable_surface for the method.");
}

}  // namespace nbv::bind
