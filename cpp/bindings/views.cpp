#include "nbv/views.hpp"
#include "bindings.hpp"
#include "nbv/occupancy_map.hpp"

namespace nbv::bind {

void init_views(py::module_& m) {
  using Candidates = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;
  const UtilityOptions ud;
  const ValidityOptions vd;

  m.def(
      "evaluate_views",
      [](const OccupancyMap& map, const py::handle& candidates, const py::handle& current,
         int rays_x, int rays_y, double hfov_deg, double vfov_deg, double max_range,
         const py::object& mount, const std::string& utility, double distance_lambda,
         bool require_occupied, double require_occupied_probability, double collision_radius,
         const py::object& bounds_min, const py::object& bounds_max, bool check_segment,
         const std::string& backend) {
        auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(candidates);
        if (!c || c.ndim() != 2 || c.shape(1) != 4)
          throw py::value_error("candidates must have shape (K, 4): rows x, y, z, yaw");
        Eigen::Map<const Candidates> cm(c.data(), c.shape(0), 4);
        if (!cm.allFinite()) throw py::value_error("candidates contain NaN or infinite values");
        const Pose cur = pose_arg(current, "current pose");
        ViewCameraModel cam;
        cam.rays_x = rays_x;
        cam.rays_y = rays_y;
        cam.hfov_deg = hfov_deg;
        cam.vfov_deg = vfov_deg;
        cam.max_range = max_range;
        if (!mount.is_none()) cam.mount = transform_arg(mount, "camera mount");
        UtilityOptions u;
        if (utility == "ig")
          u.kind = UtilityOptions::Kind::InformationGain;
        else if (utility == "ig_distance")
          u.kind = UtilityOptions::Kind::InformationGainDistance;
        else
          throw py::value_error("unknown utility '" + utility + "' (known: ig, ig_distance)");
        u.distance_lambda = distance_lambda;
        u.require_occupied = require_occupied;
        u.require_occupied_probability = require_occupied_probability;
        if (!(require_occupied_probability >= 0 && require_occupied_probability < 1))
          throw py::value_error("require_occupied_probability must be in [0, 1)");
        ValidityOptions v;
        v.collision_radius = collision_radius;
        v.check_segment = check_segment;
        if (!bounds_min.is_none()) v.bounds_min = bounds_min.cast<Eigen::Vector3d>();
        if (!bounds_max.is_none()) v.bounds_max = bounds_max.cast<Eigen::Vector3d>();
        if (backend != "mirror" && backend != "octree")
          throw py::value_error("unknown backend '" + backend + "' (known: mirror, octree)");
        ViewScores s;
        {
          py::gil_scoped_release release;
          s = backend == "octree" ? evaluate_views_octree(map, cm, cur, cam, u, v)
                                  : evaluate_views(grid_view(map), cm, cur, cam, u, v);
        }
        py::dict out;
        out["utility"] = s.utility;
        out["gain"] = s.gain;
        out["cells_seen"] = s.cells_seen;
        out["occupied_seen"] = s.occupied_seen;
        out["status"] = s.status;
        return out;
      },
      py::arg("map"), py::arg("candidates"), py::arg("current"), py::arg("rays_x") = 47,
      py::arg("rays_y") = 34, py::arg("hfov_deg") = 60.0, py::arg("vfov_deg") = 45.0,
      py::arg("max_range") = 8.0, py::arg("mount") = py::none(), py::arg("utility") = "ig",
      py::arg("distance_lambda") = ud.distance_lambda,
      py::arg("require_occupied") = ud.require_occupied,
      py::arg("require_occupied_probability") = ud.require_occupied_probability,
      py::arg("collision_radius") = vd.collision_radius, py::arg("bounds_min") = py::none(),
      py::arg("bounds_max") = py::none(), py::arg("check_segment") = vd.check_segment,
      py::arg("backend") = "mirror",
      R"doc(Score K candidate vehicle poses (K, 4) [x, y, z, yaw] from the current pose, in one
call.

Returns a dict of (K,) arrays: utility (-inf where invalid), gain (sum of the entropies of the
distinct workspace cells the camera's rays visit, stopping at the first occupied cell inclusive),
cells_seen, occupied_seen (rays ending on an occupied cell), status (0 valid, 1 out of bounds,
2 collision: an occupied/unknown cell within the collision radius, 3 straight path blocked,
4 sees no occupied cell). backend "mirror" walks the dense workspace mirror (3D-DDA); "octree"
reads every visited cell through OctoMap's search, as the authors did (same answer, slower).)doc");

  m.def(
      "sphere_is_free",
      [](const OccupancyMap& map, const Eigen::Vector3d& c, double r) {
        if (!c.allFinite() || !(r >= 0))
          throw py::value_error("centre must be finite and radius >= 0");
        return sphere_is_free(grid_view(map), c, r);
      },
      py::arg("map"), py::arg("center"), py::arg("radius"),
      "True if every workspace cell touching the sphere is known and not occupied.");
  m.def(
      "segment_is_free",
      [](const OccupancyMap& map, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
        if (!a.allFinite() || !b.allFinite() || !(r >= 0))
          throw py::value_error("segment ends must be finite and radius >= 0");
        return segment_is_free(grid_view(map), a, b, r);
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"));
  m.def(
      "plan_path",
      [](const OccupancyMap& map, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r,
         std::size_t max_expansions) {
        if (!a.allFinite() || !b.allFinite() || !(r >= 0))
          throw py::value_error("path ends must be finite and radius >= 0");
        std::vector<Eigen::Vector3d> path;
        {
          py::gil_scoped_release release;
          path = plan_path(grid_view(map), a, b, r, max_expansions);
        }
        Points out(static_cast<Eigen::Index>(path.size()), 3);
        for (std::size_t i = 0; i < path.size(); ++i)
          out.row(static_cast<Eigen::Index>(i)) = path[i];
        return out;
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"),
      py::arg("max_expansions") = 200000,
      "A* through known free space; (P, 3) waypoints from a to b, or (0, 3) when there is none.");
  m.def("viewable_cells", &viewable_cells, py::arg("hfov_deg"), py::arg("vfov_deg"),
        py::arg("min_range"), py::arg("max_range"), py::arg("resolution"),
        py::arg("count_partial") = true,
        "C_view of Eq. 5: V_frustum / V_cell, or with count_partial the cells the frustum touches\n"
        "including partial boundary cells: vol(frustum (+) cell) / V_cell.");
  m.def(
      "view_ray_grid",
      [](double hfov, double vfov, double max_range, double res) {
        auto c = ViewCameraModel::for_resolution(hfov, vfov, max_range, res);
        return py::make_tuple(c.rays_x, c.rays_y);
      },
      py::arg("hfov_deg"), py::arg("vfov_deg"), py::arg("max_range"), py::arg("resolution"),
      "Rays (x, y) of one per map-resolution step on the far plane (47 x 34 at 0.2 m, 8 m, 60 x 45 "
      "deg).");
}

}  // namespace nbv::bind
