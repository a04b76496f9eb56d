#include "nbv/evaluation.hpp"
#include "bindings.hpp"
#include "nbv/mesh.hpp"
#include "options.hpp"

namespace nbv::bind {

void init_evaluation(py::module_& m) {
  {
    OptionsClass<EvaluationOptions> binder(
        m, "EvaluationOptions",
        "Options of nbvkit.evaluate; each field is documented in EvaluationOptions.fields().");
    using S = EvaluationOptions;
    NBV_EVALUATION_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }

  py::class_<EvaluationResult>(
      m, "EvaluationResult",
      "Raw result of the core's evaluation (nbvkit.evaluate returns a dict).")
      .def_readonly("resolutions", &EvaluationResult::resolutions)
      .def_readonly("taus", &EvaluationResult::taus)
      .def_readonly("coverage", &EvaluationResult::coverage)
      .def_readonly("area_coverage", &EvaluationResult::area_coverage)
      .def_readonly("precision", &EvaluationResult::precision)
      .def_readonly("gt_cells", &EvaluationResult::gt_cells)
      .def_readonly("cloud_cells", &EvaluationResult::cloud_cells)
      .def_readonly("covered_cells", &EvaluationResult::covered_cells)
      .def_readonly("has_observable", &EvaluationResult::has_observable)
      .def_readonly("coverage_observable", &EvaluationResult::coverage_observable)
      .def_readonly("area_coverage_observable", &EvaluationResult::area_coverage_observable)
      .def_readonly("area_coverage_observable_cells",
                    &EvaluationResult::area_coverage_observable_cells)
      .def_readonly("observable_fraction", &EvaluationResult::observable_fraction)
      .def_readonly("observable_cells", &EvaluationResult::observable_cells)
      .def_readonly("covered_observable_cells", &EvaluationResult::covered_observable_cells)
      .def_readonly("observable_area_fraction", &EvaluationResult::observable_area_fraction)
      .def_readonly("completeness", &EvaluationResult::completeness)
      .def_readonly("accuracy", &EvaluationResult::accuracy)
      .def_readonly("fscore", &EvaluationResult::fscore)
      .def_property_readonly("chamfer",
                             [](const EvaluationResult& r) -> py::object {
                               return r.has_chamfer ? py::object(py::float_(r.chamfer))
                                                    : py::none();
                             })
      .def_property_readonly("mean_cloud_to_gt",
                             [](const EvaluationResult& r) -> py::object {
                               return r.has_chamfer ? py::object(py::float_(r.mean_cloud_to_gt))
                                                    : py::none();
                             })
      .def_property_readonly("mean_gt_to_cloud",
                             [](const EvaluationResult& r) -> py::object {
                               return r.has_chamfer ? py::object(py::float_(r.mean_gt_to_cloud))
                                                    : py::none();
                             })
      .def_readonly("n_points", &EvaluationResult::n_points)
      .def_readonly("n_gt_points", &EvaluationResult::n_gt_points)
      .def_readonly("from_mesh", &EvaluationResult::from_mesh)
      .def_readonly("gt_density", &EvaluationResult::gt_density)
      .def_readonly("gt_area", &EvaluationResult::gt_area)
      .def_readonly("seed", &EvaluationResult::seed)
      .def_readonly("warnings", &EvaluationResult::warnings)
      .def_readonly("timings_s", &EvaluationResult::timings_s);

  py::class_<Evaluator, std::shared_ptr<Evaluator>>(
      m, "_Evaluator", "Ground truth prepared once (nbvkit.Evaluator wraps it).")
      .def(py::init([](const py::handle& gt, const py::object& options, const py::kwargs& kw) {
             const auto o = options_with_keywords<EvaluationOptions>(options, kw);
             if (py::isinstance<Mesh>(gt)) {
               const Mesh& mesh = gt.cast<const Mesh&>();
               py::gil_scoped_release release;
               return std::make_shared<Evaluator>(mesh, o);
             }
             auto g = points_arg(gt, "ground truth");
             py::gil_scoped_release release;
             return std::make_shared<Evaluator>(g.map(), o);
           }),
           py::arg("gt"), py::arg("options") = py::none(),
           "gt: a Mesh (sampled at gt_density points per m^2) or (M, 3) float64 reference points;\n"
           "options: EvaluationOptions (or a dict, or None) with keyword overrides of its fields.")
      .def_property_readonly(
          "options", [](const Evaluator& e) { return EvaluationOptions(e.options()); },
          "the EvaluationOptions used (a copy)")
      .def(
          "evaluate",
          [](const Evaluator& e, const py::handle& cloud) {
            auto c = points_arg(cloud, "cloud");
            py::gil_scoped_release release;
            return e.evaluate(c.map());
          },
          py::arg("cloud"))
      .def(
          "evaluate_of",
          [](const Evaluator& e, const std::vector<const SurfaceCloud*>& clouds) {
            check_clouds(clouds);
            py::gil_scoped_release release;
            return e.evaluate(clouds);
          },
          py::arg("clouds"),
          "evaluate of SurfaceClouds' points, one cloud after the other, without a stacked copy "
          "held while scoring.")
      .def(
          "evaluate_cells",
          [](const Evaluator& e, const py::handle& cloud) {
            auto c = points_arg(cloud, "cloud");
            py::gil_scoped_release release;
            return e.evaluate_cells(c.map());
          },
          py::arg("cloud"),
          "Coverage, area coverage and precision alone (no kd-tree, no distances).")
      .def(
          "evaluate_cells_of",
          [](const Evaluator& e, const std::vector<const SurfaceCloud*>& clouds) {
            check_clouds(clouds);
            py::gil_scoped_release release;
            return e.evaluate_cells(clouds);
          },
          py::arg("clouds"),
          "evaluate_cells of SurfaceClouds' points, one cloud after the other, read in place.")
      .def(
          "set_observable",
          [](Evaluator& e, const py::array_t<bool, py::array::c_style | py::array::forcecast>& m) {
            if (m.ndim() != 1) throw py::value_error("observable mask must be one-dimensional");
            std::vector<std::uint8_t> v(static_cast<std::size_t>(m.shape(0)));
            for (std::size_t i = 0; i < v.size(); ++i) v[i] = m.data()[i] ? 1 : 0;
            py::gil_scoped_release release;
            e.set_observable(v);
          },
          py::arg("mask"),
          "(M,) bool per ground-truth sample (gt_points order): coverage is also reported\n"
          "relative to the observable samples. An empty mask clears it.")
      .def(
          "nearest_to_gt",
          [](const Evaluator& e, const py::handle& queries) {
            auto q = points_arg(queries, "queries");
            py::gil_scoped_release release;
            return Eigen::VectorXd(nearest_distances(e.gt_tree(), q.map()));
          },
          py::arg("queries"),
          "(Q,) exact distance from each query to its nearest ground-truth point: "
          "nearest_distances(gt_points, queries) without building the ground truth's tree again.")
      .def_property_readonly("has_observable", &Evaluator::has_observable)
      .def_property_readonly(
          "gt_points", [](const Evaluator& e) { return e.gt_points(); },
          "(M, 3) the ground-truth samples (a copy)")
      .def_property_readonly("num_gt_points", &Evaluator::num_gt_points)
      .def_property_readonly("gt_info", [](const Evaluator& e) { return e.gt_info(); });

  py::class_<CoverageTracker>(m, "CoverageTracker", R"doc(
The cell figures of _Evaluator.evaluate_cells_of(clouds), kept up to date between calls on
growing SurfaceClouds: each call looks again only at the voxels added or moved since the last
(a mission's progress refreshes; nbvkit.Evaluator.coverage uses one). The same figures as
evaluate_cells_of to the last bit. Keeps the evaluator alive.)doc")
      .def(py::init<const Evaluator&>(), py::arg("evaluator"), py::keep_alive<1, 2>())
      .def(
          "update",
          [](CoverageTracker& t, const std::vector<const SurfaceCloud*>& clouds) {
            check_clouds(clouds);
            py::gil_scoped_release release;
            return t.update(clouds);
          },
          py::arg("clouds"), "evaluate_cells_of(clouds) for the clouds as they are now.")
      .def_property_readonly("bytes", &CoverageTracker::bytes, "bytes of per-point and cell state");

  m.def(
      "cell_keys",
      [](const py::handle& points, double resolution) {
        auto p = points_arg(points, "points");
        std::vector<std::uint64_t> keys;
        {
          py::gil_scoped_release release;
          keys = point_cell_keys(p.map(), resolution, "points");
        }
        py::array_t<std::uint64_t> out(static_cast<py::ssize_t>(keys.size()));
        std::copy(keys.begin(), keys.end(), out.mutable_data());
        return out;
      },
      py::arg("points"), py::arg("resolution"),
      "(N,) uint64: the key of each of the (N, 3) points' cell on the evaluation's grid of cell\n"
      "`resolution` (m) anchored at the origin, as evaluate counts cells: a coordinate on a cell\n"
      "boundary, up to rounding, is in the cell above. Two points share a cell exactly when\n"
      "their keys are equal. ValueError for a point too far from the origin for the grid (2^20\n"
      "cells per axis) or a resolution that is not a positive number.");

  m.def(
      "nearest_distances",
      [](const py::handle& targets, const py::handle& queries) {
        auto t = points_arg(targets, "targets");
        auto q = points_arg(queries, "queries");
        py::gil_scoped_release release;
        return nearest_distances(t.map(), q.map());
      },
      py::arg("targets"), py::arg("queries"),
      "(Q,) float64: exact Euclidean distance (metres) from each of the (Q, 3) queries to the "
      "nearest\n"
      "of the (T, 3) targets (inf when there are no targets). A kd-tree, parallel over queries.");
}

}  // namespace nbv::bind
