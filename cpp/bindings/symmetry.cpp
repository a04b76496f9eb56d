// Bindings of the symmetry detection and prediction core (nbv/symmetry.hpp).
#include "nbv/symmetry.hpp"
#include "bindings.hpp"
#include "options.hpp"

#include <cmath>
#include <string>

namespace nbv::bind {

template <>
struct OptionField<SymmetryKeypoints> {
  static py::object get(SymmetryKeypoints k) { return py::str(to_string(k)); }
  static SymmetryKeypoints set(const py::handle& h, const std::string& name) {
    if (!py::isinstance<py::str>(h))
      throw py::value_error("option '" + name + "' must be 'sift', 'iss' or 'uniform'");
    try {
      return symmetry_keypoints_from_string(h.cast<std::string>());
    } catch (const std::invalid_argument& e) {
      throw py::value_error(e.what());
    }
  }
};

namespace {

py::dict timings_dict(const StageTimes& t) {
  py::dict d;
  double total = 0;
  for (const auto& [name, s] : t) {
    d[py::str(name)] = s;
    total += s;
  }
  d["total"] = total;
  return d;
}

Eigen::Vector4d plane_arg(const py::handle& obj, const char* what) {
  py::array_t<double, py::array::c_style | py::array::forcecast> a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  } catch (const py::error_already_set&) {
    a = {};
  }
  if (!a || a.size() != 4 || a.ndim() != 1)
    throw py::value_error(std::string(what) + " must be 4 numbers [nx, ny, nz, d]");
  Eigen::Vector4d p(a.data()[0], a.data()[1], a.data()[2], a.data()[3]);
  if (!p.allFinite()) throw py::value_error(std::string(what) + " must be finite");
  if (!(p.head<3>().norm() > 1e-12))
    throw py::value_error(std::string(what) + " has a zero normal");
  return p;
}

}  // namespace

void init_symmetry(py::module_& m) {
  const SymmetryOptions sd;
  {
    OptionsClass<SymmetryOptions> binder(m, "SymmetryOptions", R"doc(
Options of detect_symmetry, by pipeline step; each field is documented in
SymmetryOptions.fields().)doc");
    using S = SymmetryOptions;
    NBV_SYMMETRY_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  {
    OptionsClass<SymmetricPredictionOptions> binder(m, "SymmetricPredictionOptions", R"doc(
Options of predict_symmetric; each field is documented in
SymmetricPredictionOptions.fields().)doc");
    using S = SymmetricPredictionOptions;
    NBV_SYMMETRIC_PREDICTION_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }

  py::class_<SymmetryResult>(m, "SymmetryResult", R"doc(
Result of detect_symmetry.

plane: (4,) [nx, ny, nz, d], unit normal, n . p = d on the plane, sign canonical (largest |n_i|
positive); NaN when no keypoint pair survived matching. Reported for diagnostics even when not
accepted; use it only when `accepted`.
support: pairs voting for it; vote_share: support / pairs; confidence: mirror consistency in
[0, 1]; accepted: support >= min_support and confidence >= min_confidence; reason: why not.
keypoints (K, 3) world frame; pairs (P, 2) int32 indices into keypoints; pair_planes (P, 4);
pair_distances (P,) descriptor distances; inliers (P,) bool; timings: dict stage -> seconds.)doc")
      .def_property_readonly("plane", [](const SymmetryResult& r) { return r.plane; })
      .def_readonly("support", &SymmetryResult::support)
      .def_readonly("vote_share", &SymmetryResult::vote_share)
      .def_readonly("confidence", &SymmetryResult::confidence)
      .def_readonly("consistency_all", &SymmetryResult::consistency_all)
      .def_readonly("facing_fraction", &SymmetryResult::facing_fraction)
      .def_readonly("accepted", &SymmetryResult::accepted)
      .def_readonly("reason", &SymmetryResult::reason)
      .def_readonly("num_points", &SymmetryResult::num_points)
      .def_readonly("scale", &SymmetryResult::scale)
      .def_property_readonly("keypoints", [](const SymmetryResult& r) { return r.keypoints; })
      .def_property_readonly("pairs", [](const SymmetryResult& r) { return r.pairs; })
      .def_property_readonly("pair_distances",
                             [](const SymmetryResult& r) { return r.pair_distances; })
      .def_property_readonly("pair_planes", [](const SymmetryResult& r) { return r.pair_planes; })
      .def_property_readonly("inliers", [](const SymmetryResult& r) { return r.inliers; })
      .def_property_readonly("modes", [](const SymmetryResult& r) { return r.modes; })
      .def_property_readonly("mode_support", [](const SymmetryResult& r) { return r.mode_support; })
      .def_property_readonly("mode_confidence",
                             [](const SymmetryResult& r) { return r.mode_confidence; })
      .def_property_readonly("timings",
                             [](const SymmetryResult& r) { return timings_dict(r.timings); })
      .def("__repr__", [](const SymmetryResult& r) {
        return "SymmetryResult(plane=" +
               std::string(py::str(py::cast(r.plane).attr("round")(4).attr("tolist")())) +
               ", support=" + std::to_string(r.support) +
               ", confidence=" + std::to_string(r.confidence) +
               ", accepted=" + (r.accepted ? "True" : "False") + ")";
      });

  py::class_<SymmetricPrediction>(m, "SymmetricPrediction", R"doc(
Result of predict_symmetric: predicted (M, 3) world-frame points (reflections not explained by an
observed point), plane (4,) the corrected plane, input_plane (4,), transform 4x4 (ICP o
reflection, an improper isometry), icp_converged, icp_applied, icp_fitness (m^2),
residual_rotation_deg, timings (dict stage -> seconds).)doc")
      .def_property_readonly("predicted", [](const SymmetricPrediction& r) { return r.predicted; })
      .def_property_readonly("plane", [](const SymmetricPrediction& r) { return r.plane; })
      .def_property_readonly("input_plane",
                             [](const SymmetricPrediction& r) { return r.input_plane; })
      .def_property_readonly("transform", [](const SymmetricPrediction& r) { return r.transform; })
      .def_readonly("icp_converged", &SymmetricPrediction::icp_converged)
      .def_readonly("icp_applied", &SymmetricPrediction::icp_applied)
      .def_readonly("icp_fitness", &SymmetricPrediction::icp_fitness)
      .def_readonly("residual_rotation_deg", &SymmetricPrediction::residual_rotation_deg)
      .def_property_readonly("timings",
                             [](const SymmetricPrediction& r) { return timings_dict(r.timings); })
      .def(
          "__iter__",
          [](const SymmetricPrediction& r) {
            return py::iter(
                py::make_tuple(py::cast(r.predicted), py::cast(Eigen::Vector4d(r.plane))));
          },
          "Unpacks as (predicted, plane).")
      .def("__repr__", [](const SymmetricPrediction& r) {
        return "SymmetricPrediction(predicted=" + std::to_string(r.predicted.rows()) +
               " points, plane=" +
               std::string(
                   py::str(py::cast(Eigen::Vector4d(r.plane)).attr("round")(4).attr("tolist")())) +
               ", icp_applied=" + (r.icp_applied ? "True" : "False") + ")";
      });

  py::class_<PlaneClusters>(m, "PlaneClusters",
                            "Result of mean_shift_planes: plane (4,), support, inliers (P,) bool, "
                            "modes (M, 4) most support first, mode_support (M,).")
      .def_property_readonly("plane", [](const PlaneClusters& r) { return r.plane; })
      .def_readonly("support", &PlaneClusters::support)
      .def_property_readonly("inliers", [](const PlaneClusters& r) { return r.inliers; })
      .def_property_readonly("modes", [](const PlaneClusters& r) { return r.modes; })
      .def_property_readonly("mode_support", [](const PlaneClusters& r) { return r.mode_support; });

  m.def(
      "detect_symmetry",
      [](const py::handle& points, const py::object& options, const py::kwargs& kw) {
        const auto a = points_arg(points, "points");
        const auto o = options_with_keywords<SymmetryOptions>(options, kw);
        py::gil_scoped_release release;
        return detect_symmetry(a.map(), o);
      },
      py::arg("points"), py::arg("options") = py::none(), "See nbvkit.detect_symmetry.");

  m.def(
      "predict_symmetric",
      [](const py::handle& points, const py::handle& plane, const py::object& options,
         const py::kwargs& kw) {
        const auto a = points_arg(points, "points");
        const Eigen::Vector4d pl = plane_arg(plane, "plane");
        const auto o = options_with_keywords<SymmetricPredictionOptions>(options, kw);
        py::gil_scoped_release release;
        return predict_symmetric(a.map(), pl, o);
      },
      py::arg("points"), py::arg("plane"), py::arg("options") = py::none(),
      "See nbvkit.predict_symmetric.");

  m.def(
      "mean_shift_planes",
      [](const py::handle& planes, const Eigen::Vector3d& center, double scale, double bandwidth,
         int seeds, int max_iterations) {
        auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(planes);
        if (!a || a.ndim() != 2 || a.shape(1) != 4)
          throw py::value_error("planes must have shape (P, 4)");
        const Planes P = Eigen::Map<const Planes>(a.data(), a.shape(0), 4);
        py::gil_scoped_release release;
        return mean_shift_planes(P, center, scale, bandwidth, seeds, max_iterations);
      },
      py::arg("planes"), py::arg("center"), py::arg("scale"), py::arg("bandwidth") = sd.bandwidth,
      py::arg("seeds") = sd.mean_shift_seeds,
      py::arg("max_iterations") = sd.mean_shift_max_iterations,
      "Mean shift over planes (P, 4) [nx, ny, nz, d]; see nbvkit.symmetry.mean_shift_planes.");

  m.def(
      "plane_from_pair",
      [](const Eigen::Vector3d& p, const Eigen::Vector3d& q) { return plane_from_pair(p, q); },
      py::arg("p"), py::arg("q"), "Perpendicular-bisector plane [nx, ny, nz, d] of two points.");
  m.def(
      "canonical_plane",
      [](const py::handle& pl) { return canonical_plane(plane_arg(pl, "plane")); },
      py::arg("plane"), "Unit normal, largest |n_i| positive.");
  m.def(
      "reflection_matrix",
      [](const py::handle& pl) { return reflection_matrix(plane_arg(pl, "plane")); },
      py::arg("plane"), "4x4 homogeneous reflection about a plane.");
  m.def(
      "reflect_points",
      [](const py::handle& points, const py::handle& pl) {
        const auto a = points_arg(points, "points");
        return reflect_points(a.map(), plane_arg(pl, "plane"));
      },
      py::arg("points"), py::arg("plane"),
      "(N, 3) points reflected about a plane [nx, ny, nz, d].");
  m.def(
      "plane_from_improper_isometry",
      [](const Eigen::Matrix4d& M) {
        double residual = 0;
        const Eigen::Vector4d p = plane_from_improper_isometry(M, &residual);
        return py::make_tuple(p, residual);
      },
      py::arg("transform"), "(plane, residual_rotation_deg) of a 4x4 improper isometry.");
  m.def(
      "mirror_fpfh",
      [](const Eigen::Ref<const Eigen::MatrixXf>& d) {
        if (d.cols() != 33) throw py::value_error("descriptors must have shape (K, 33)");
        return mirror_fpfh(Fpfh(d));
      },
      py::arg("descriptors"), "FPFH of the mirror images of points, from their FPFH (K, 33).");
  m.def(
      "compute_fpfh",
      [](const py::handle& points, std::vector<int> indices, int normal_k, double radius) {
        const auto a = points_arg(points, "points");
        const Eigen::Index n = a.map().rows();
        for (int i : indices)
          if (i < 0 || i >= n)
            throw py::value_error("index " + std::to_string(i) + " out of range");
        if (normal_k < 3 || !(radius > 0) || !std::isfinite(radius))
          throw py::value_error("normal_k must be >= 3 and radius a finite number > 0");
        py::gil_scoped_release release;
        if (!indices.empty()) detail::check_neighbourhoods(a.map(), radius, "radius");
        const auto nc = detail::estimate_normals(a.map(), normal_k, 0.0);
        return detail::compute_fpfh(a.map(), nc.normals, indices, radius);
      },
      py::arg("points"), py::arg("indices"), py::arg("normal_k") = sd.normal_k,
      py::arg("radius") = sd.fpfh_radius,
      "(K, 33) float32 FPFH (PCL) at points[indices], every point as search surface; normals from "
      "normal_k neighbours oriented away from the centroid. For tests and diagnostics.");
}

}  // namespace nbv::bind
