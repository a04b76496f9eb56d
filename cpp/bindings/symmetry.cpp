// Bindings of the symmetry detection and prediction core (nbv/symmetry.hpp).
#include "nbv/symmetry.hpp"
#include "bindings.hpp"

#include <functional>
#include <map>
#include <string>

namespace nbv::bind {
namespace {

template <typename Opt>
using Setters = std::map<std::string, std::function<void(Opt&, const py::handle&)>>;

template <typename T>
T cast_value(const py::handle& v, const std::string& key) {
  if constexpr (std::is_same_v<T, bool>) {
    if (!py::isinstance<py::bool_>(v))
      throw py::value_error("option '" + key + "' must be True or False");
    return v.cast<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    if (py::isinstance<py::bool_>(v) ||
        !(py::isinstance<py::int_>(v) || py::hasattr(v, "__index__")))
      throw py::value_error("option '" + key + "' must be an integer");
    return py::reinterpret_borrow<py::object>(v).cast<T>();
  } else {
    if (py::isinstance<py::bool_>(v))
      throw py::value_error("option '" + key + "' must be a number");
    try {
      return py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>();
    } catch (const py::error_already_set&) {
      throw py::value_error("option '" + key + "' must be a number");
    }
  }
}

template <typename Opt, typename T>
void add(Setters<Opt>& s, const char* name, T Opt::*field) {
  const std::string key = name;
  s[key] = [field, key](Opt& o, const py::handle& v) { o.*field = cast_value<T>(v, key); };
}

const Setters<SymmetryOptions>& detect_setters() {
  static const Setters<SymmetryOptions> s = [] {
    Setters<SymmetryOptions> s;
    using O = SymmetryOptions;
    add(s, "voxel_size", &O::voxel_size);
    add(s, "normal_k", &O::normal_k);
    add(s, "normal_radius", &O::normal_radius);
    s["keypoints"] = [](O& o, const py::handle& v) {
      if (!py::isinstance<py::str>(v))
        throw py::value_error("option 'keypoints' must be 'sift', 'iss' or 'uniform'");
      o.keypoints = symmetry_keypoints_from_string(v.cast<std::string>());
    };
    add(s, "sift_min_scale", &O::sift_min_scale);
    add(s, "sift_octaves", &O::sift_octaves);
    add(s, "sift_scales_per_octave", &O::sift_scales_per_octave);
    add(s, "sift_min_contrast", &O::sift_min_contrast);
    add(s, "iss_salient_radius", &O::iss_salient_radius);
    add(s, "iss_non_max_radius", &O::iss_non_max_radius);
    add(s, "uniform_leaf", &O::uniform_leaf);
    add(s, "fpfh_radius", &O::fpfh_radius);
    add(s, "mirror_descriptors", &O::mirror_descriptors);
    add(s, "max_descriptor_distance", &O::max_descriptor_distance);
    add(s, "min_pair_distance", &O::min_pair_distance);
    add(s, "max_normal_angle_deg", &O::max_normal_angle_deg);
    add(s, "matches_per_keypoint", &O::matches_per_keypoint);
    add(s, "bandwidth", &O::bandwidth);
    add(s, "mean_shift_seeds", &O::mean_shift_seeds);
    add(s, "mean_shift_max_iterations", &O::mean_shift_max_iterations);
    add(s, "candidate_modes", &O::candidate_modes);
    add(s, "refine_iterations", &O::refine_iterations);
    add(s, "refine_max_distance", &O::refine_max_distance);
    add(s, "refine_max_points", &O::refine_max_points);
    add(s, "consistency_radius", &O::consistency_radius);
    add(s, "consistency_tolerance", &O::consistency_tolerance);
    add(s, "facing_angle_deg", &O::facing_angle_deg);
    add(s, "min_support", &O::min_support);
    add(s, "min_confidence", &O::min_confidence);
    return s;
  }();
  return s;
}

const Setters<SymmetricPredictionOptions>& predict_setters() {
  static const Setters<SymmetricPredictionOptions> s = [] {
    Setters<SymmetricPredictionOptions> s;
    using O = SymmetricPredictionOptions;
    add(s, "voxel_size", &O::voxel_size);
    add(s, "normal_k", &O::normal_k);
    add(s, "icp", &O::icp);
    add(s, "icp_point_to_plane", &O::icp_point_to_plane);
    add(s, "icp_max_correspondence", &O::icp_max_correspondence);
    add(s, "icp_transformation_epsilon", &O::icp_transformation_epsilon);
    add(s, "icp_fitness_epsilon", &O::icp_fitness_epsilon);
    add(s, "icp_max_iterations", &O::icp_max_iterations);
    add(s, "max_correction_angle_deg", &O::max_correction_angle_deg);
    add(s, "max_correction_offset", &O::max_correction_offset);
    add(s, "explained_tolerance", &O::explained_tolerance);
    return s;
  }();
  return s;
}

template <typename Opt>
Opt options_from(const py::kwargs& kw, const Setters<Opt>& setters, const char* what) {
  Opt o;
  for (const auto& item : kw) {
    const std::string key = py::str(item.first);
    const auto it = setters.find(key);
    if (it == setters.end()) {
      std::string known;
      for (const auto& [k, f] : setters) known += (known.empty() ? "" : ", ") + k;
      throw py::value_error(std::string("unknown ") + what + " option '" + key +
                            "'; known: " + known);
    }
    if (item.second.is_none()) continue;  // None: keep the default
    try {
      it->second(o, item.second);
    } catch (const py::cast_error&) {
      throw py::value_error("option '" + key + "' has the wrong type");
    }
  }
  o.validate();
  return o;
}

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
  py::class_<SymmetryOptions>(m, "SymmetryOptions",
                              "Defaults of detect_symmetry (see its docstring).")
      .def(py::init<>())
      .def_readonly("voxel_size", &SymmetryOptions::voxel_size)
      .def_readonly("normal_k", &SymmetryOptions::normal_k)
      .def_readonly("normal_radius", &SymmetryOptions::normal_radius)
      .def_property_readonly("keypoints",
                             [](const SymmetryOptions& o) { return to_string(o.keypoints); })
      .def_readonly("sift_min_scale", &SymmetryOptions::sift_min_scale)
      .def_readonly("sift_octaves", &SymmetryOptions::sift_octaves)
      .def_readonly("sift_scales_per_octave", &SymmetryOptions::sift_scales_per_octave)
      .def_readonly("sift_min_contrast", &SymmetryOptions::sift_min_contrast)
      .def_readonly("iss_salient_radius", &SymmetryOptions::iss_salient_radius)
      .def_readonly("iss_non_max_radius", &SymmetryOptions::iss_non_max_radius)
      .def_readonly("uniform_leaf", &SymmetryOptions::uniform_leaf)
      .def_readonly("fpfh_radius", &SymmetryOptions::fpfh_radius)
      .def_readonly("mirror_descriptors", &SymmetryOptions::mirror_descriptors)
      .def_readonly("max_descriptor_distance", &SymmetryOptions::max_descriptor_distance)
      .def_readonly("min_pair_distance", &SymmetryOptions::min_pair_distance)
      .def_readonly("max_normal_angle_deg", &SymmetryOptions::max_normal_angle_deg)
      .def_readonly("matches_per_keypoint", &SymmetryOptions::matches_per_keypoint)
      .def_readonly("bandwidth", &SymmetryOptions::bandwidth)
      .def_readonly("mean_shift_seeds", &SymmetryOptions::mean_shift_seeds)
      .def_readonly("mean_shift_max_iterations", &SymmetryOptions::mean_shift_max_iterations)
      .def_readonly("candidate_modes", &SymmetryOptions::candidate_modes)
      .def_readonly("refine_iterations", &SymmetryOptions::refine_iterations)
      .def_readonly("refine_max_distance", &SymmetryOptions::refine_max_distance)
      .def_readonly("refine_max_points", &SymmetryOptions::refine_max_points)
      .def_readonly("consistency_radius", &SymmetryOptions::consistency_radius)
      .def_readonly("consistency_tolerance", &SymmetryOptions::consistency_tolerance)
      .def_readonly("facing_angle_deg", &SymmetryOptions::facing_angle_deg)
      .def_readonly("min_support", &SymmetryOptions::min_support)
      .def_readonly("min_confidence", &SymmetryOptions::min_confidence);

  py::class_<SymmetricPredictionOptions>(m, "SymmetricPredictionOptions",
                                         "Defaults of predict_symmetric (see its docstring).")
      .def(py::init<>())
      .def_readonly("voxel_size", &SymmetricPredictionOptions::voxel_size)
      .def_readonly("normal_k", &SymmetricPredictionOptions::normal_k)
      .def_readonly("icp", &SymmetricPredictionOptions::icp)
      .def_readonly("icp_point_to_plane", &SymmetricPredictionOptions::icp_point_to_plane)
      .def_readonly("icp_max_correspondence", &SymmetricPredictionOptions::icp_max_correspondence)
      .def_readonly("icp_transformation_epsilon",
                    &SymmetricPredictionOptions::icp_transformation_epsilon)
      .def_readonly("icp_fitness_epsilon", &SymmetricPredictionOptions::icp_fitness_epsilon)
      .def_readonly("icp_max_iterations", &SymmetricPredictionOptions::icp_max_iterations)
      .def_readonly("max_correction_angle_deg",
                    &SymmetricPredictionOptions::max_correction_angle_deg)
      .def_readonly("max_correction_offset", &SymmetricPredictionOptions::max_correction_offset)
      .def_readonly("explained_tolerance", &SymmetricPredictionOptions::explained_tolerance);

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
      [](const py::handle& points, const py::kwargs& kw) {
        const auto a = points_arg(points, "points");
        const SymmetryOptions o = options_from(kw, detect_setters(), "detect_symmetry");
        py::gil_scoped_release release;
        return detect_symmetry(a.map(), o);
      },
      py::arg("points"), "See nbvkit.detect_symmetry.");

  m.def(
      "predict_symmetric",
      [](const py::handle& points, const py::handle& plane, const py::kwargs& kw) {
        const auto a = points_arg(points, "points");
        const Eigen::Vector4d pl = plane_arg(plane, "plane");
        const SymmetricPredictionOptions o =
            options_from(kw, predict_setters(), "predict_symmetric");
        py::gil_scoped_release release;
        return predict_symmetric(a.map(), pl, o);
      },
      py::arg("points"), py::arg("plane"), "See nbvkit.predict_symmetric.");

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
        if (normal_k < 3 || !(radius > 0))
          throw py::value_error("normal_k must be >= 3 and radius > 0");
        py::gil_scoped_release release;
        const auto nc = detail::estimate_normals(a.map(), normal_k, 0.0);
        return detail::compute_fpfh(a.map(), nc.normals, indices, radius);
      },
      py::arg("points"), py::arg("indices"), py::arg("normal_k") = sd.normal_k,
      py::arg("radius") = sd.fpfh_radius,
      "(K, 33) float32 FPFH (PCL) at points[indices], every point as search surface; normals from "
      "normal_k neighbours oriented away from the centroid. For tests and diagnostics.");
}

}  // namespace nbv::bind
