// Bindings of view scoring (nbv/views.hpp), camera observations (nbv/surface_observations.hpp)
// and navigation (nbv/navigation.hpp).
#include "nbv/views.hpp"
#include "bindings.hpp"
#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/surface_observations.hpp"
#include "options.hpp"

#include <mutex>

namespace nbv::bind {
namespace {

using Candidates = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;

/// An (nx, ny, nz) Fortran-ordered copy of a per-cell array stored in a grid layout.
template <typename T>
py::array_t<T, py::array::f_style> per_cell(const GridLayout& layout, const T* data,
                                            std::shared_mutex& mutex) {
  const auto& d = layout.dims;
  py::array_t<T, py::array::f_style> a(std::vector<py::ssize_t>{d[0], d[1], d[2]});
  T* p = a.mutable_data();
  {
    Reading lock(mutex);
    for (int k = 0; k < d[2]; ++k)
      for (int j = 0; j < d[1]; ++j)
        for (int i = 0; i < d[0]; ++i) *p++ = data[layout.id(i, j, k)];
  }
  return a;
}

}  // namespace

void init_views(py::module_& m) {
  {
    OptionsClass<ViewCameraModel> binder(m, "ViewCameraModel", R"doc(
The camera model view scoring casts its rays with: a pinhole grid of rays_x x rays_y rays over
the field of view, to max_range depth along the optical axis, mounted on the vehicle by mount
(T_body_sensor). ViewCameraModel.for_resolution(hfov_deg, vfov_deg, max_range, resolution)
gives one ray per map cell on the far plane (the authors' 47 x 34 at 0.2 m).)doc");
    using S = ViewCameraModel;
    NBV_VIEW_CAMERA_OPTIONS(NBV_BIND_FIELD)
    binder.finish().def_static("for_resolution", &ViewCameraModel::for_resolution,
                               py::arg("hfov_deg"), py::arg("vfov_deg"), py::arg("max_range"),
                               py::arg("resolution"));
  }
  {
    OptionsClass<UtilityOptions> binder(m, "UtilityOptions", R"doc(
Which utility scores a view and its parameters (nbv/views.hpp; each utility's exact definition
is documented in cpp/src/utilities/<name>.hpp and in nbvkit.planning).)doc");
    using S = UtilityOptions;
    NBV_UTILITY_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  {
    OptionsClass<ValidityOptions> binder(m, "ValidityOptions", R"doc(
When a candidate view is valid: inside the navigation bounds, its collision sphere in known
free space, and (blocked_path 'reject') its straight flight from the current pose clear.)doc");
    using S = ValidityOptions;
    NBV_VALIDITY_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  m.attr("VIEW_STATUS_NAMES") = py::cast(view_status_names());
  m.def("utility_names", &utility_names, "Names of the registered view utilities.");

  py::class_<SurfaceObservations, std::shared_ptr<SurfaceObservations>>(m, "SurfaceObservations",
                                                                        R"doc(
What the camera has seen of each workspace cell of an OccupancyMap: the bitmask of the 26
direction bins (cube faces, edges, corners) it was seen from, and the number of camera hits in
it. SurfaceObservations(map); add_scan(scan) after integrating each camera scan. Read by the
surface and four_term utilities and by surface_targets.)doc")
      .def(py::init(
               [](const OccupancyMap& map) { return std::make_shared<SurfaceObservations>(map); }),
           py::arg("map"))
      .def(
          "add_scan",
          [](SurfaceObservations& s, const Scan& scan) {
            Writing lock(s);
            return s.add_scan(scan.origin, scan.hits);
          },
          py::arg("scan"),
          "Record a camera Scan (its hits, seen from its origin). Returns the number of cells "
          "the camera saw for the first time.")
      .def(
          "add_points",
          [](SurfaceObservations& s, const py::handle& origin, const py::handle& hits) {
            const Eigen::Vector3d o = vec3_arg(origin, "origin");
            auto h = points_arg(hits, "hits");
            auto hm = h.map();
            Writing lock(s);
            return s.add_scan(o, hm);
          },
          py::arg("origin"), py::arg("hits"), "add_scan from an origin (3,) and hits (N, 3).")
      .def("clear",
           [](SurfaceObservations& s) {
             Writing lock(s);
             s.clear();
           })
      .def(
          "seen_cells",
          [](const SurfaceObservations& s) {
            Reading lock(s);
            return s.seen_cells();
          },
          "Number of cells seen from at least one direction.")
      .def(
          "seen_grid",
          [](const SurfaceObservations& s) {
            return per_cell<std::uint32_t>(s.layout(), s.seen_data(), s.access_lock());
          },
          "(nx, ny, nz) uint32 direction-bin masks, Fortran order (copy).")
      .def(
          "hits_grid",
          [](const SurfaceObservations& s) {
            return per_cell<std::uint16_t>(s.layout(), s.hits_data(), s.access_lock());
          },
          "(nx, ny, nz) uint16 camera hits per cell, Fortran order (copy).");
  m.def(
      "direction_bin", [](const py::handle& d) { return direction_bin(vec3_arg(d, "direction")); },
      py::arg("direction"), "The direction bin (0..25) of a vector.");
  m.def("bin_direction", &bin_direction, py::arg("bin"), "Unit vector of a direction bin.");
  m.def("bin_cone", &bin_cone, py::arg("bin"), py::arg("cone_deg"),
        "Bitmask of the bins within cone_deg of a bin.");

  py::class_<ViewMemo, std::shared_ptr<ViewMemo>> view_memo(m, "ViewMemo", R"doc(
What the paper's IG walks of candidate views found, kept from one evaluate_views call to the next
(pass it as memo=). A view scored again at the same pose (bit for bit) whose walk still holds -
every cell its rays reached has kept its occupancy, every neutral brick they stepped over is
still neutral - is scored from its record: the same gain, cells and occupied_seen, without
walking its rays. Entries that none of the last keep_calls calls used are dropped; a call with
another camera or grid geometry clears it. Used by the ig and ig_distance utilities on the grid
backend; the others walk every view.)doc");
  view_memo.def(py::init<int>(), py::arg("keep_calls") = 8);
  def_memo_members(view_memo);

  m.def(
      "evaluate_views",
      [](const OccupancyMap& map, const py::handle& candidates, const py::handle& current,
         const py::object& camera, const py::object& utility, const py::object& validity,
         const std::shared_ptr<SurfaceObservations>& surface, const std::string& backend,
         const std::shared_ptr<ViewMemo>& memo) {
        auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(candidates);
        if (!c || c.ndim() != 2 || c.shape(1) != 4)
          throw py::value_error("candidates must have shape (K, 4): rows x, y, z, yaw");
        Eigen::Map<const Candidates> cm(c.data(), c.shape(0), 4);
        if (!cm.allFinite()) throw py::value_error("candidates contain NaN or infinite values");
        const Pose cur = pose_arg(current, "current pose");
        const ViewCameraModel cam = OptionsClass<ViewCameraModel>::from(camera, "camera");
        const UtilityOptions u = OptionsClass<UtilityOptions>::from(utility, "utility");
        const ValidityOptions v = OptionsClass<ValidityOptions>::from(validity, "validity");
        if (backend != "grid" && backend != "octree")
          throw py::value_error("unknown backend '" + backend + "' (known: grid, octree)");
        if (memo && backend != "grid")
          throw py::value_error("memo= is for the grid backend (the octree one is the reference)");
        ViewScores s;
        {
          Reading2 reading(map, surface.get());
          std::unique_lock<std::mutex> lock;  // one call at a time per memo
          if (memo) lock = std::unique_lock<std::mutex>(memo->mutex());
          s = backend == "octree"
                  ? evaluate_views_octree(map, cm, cur, cam, u, v, surface.get())
                  : evaluate_views(grid_view(map, surface.get()), cm, cur, cam, u, v, memo.get());
        }
        py::dict out;
        out["utility"] = s.utility;
        out["gain"] = s.gain;
        out["cells"] = s.cells;
        out["occupied_seen"] = s.occupied_seen;
        out["status"] = s.status;
        return out;
      },
      py::arg("map"), py::arg("candidates"), py::arg("current"), py::arg("camera") = py::none(),
      py::arg("utility") = py::none(), py::arg("validity") = py::none(),
      py::arg("surface") = nullptr, py::arg("backend") = "grid", py::arg("memo") = nullptr,
      R"doc(Score K candidate vehicle poses (K, 4) [x, y, z, yaw] from the current pose, in one
call. camera / utility / validity: a ViewCameraModel / UtilityOptions / ValidityOptions, a dict
of their fields, or None for the defaults. surface: the map's SurfaceObservations (needed by the
surface and four_term utilities). memo: a ViewMemo kept across calls (the same scores, fewer
walks).

Returns a dict of (K,) arrays: utility (the score to maximise, -inf where invalid), gain (the
utility's own value before any distance weight), cells (cells that added to it), occupied_seen
(rays that reached an occupied cell), status (0 valid, 1 out of bounds, 2 collision: an
occupied/unknown cell within the collision radius, 3 straight path blocked, 4 sees no occupied
cell; names in VIEW_STATUS_NAMES). backend "grid" walks the map's workspace grid (3D-DDA);
"octree" reads every visited cell through OctoMap's search, as the authors did (same answer,
slower).)doc");

  m.def(
      "sphere_is_free",
      [](const OccupancyMap& map, const py::handle& c, double r) {
        const Eigen::Vector3d p = vec3_arg(c, "centre");
        if (!(r >= 0) || !std::isfinite(r)) throw py::value_error("radius must be finite and >= 0");
        Reading lock(map);
        return sphere_is_free(grid_view(map), p, r);
      },
      py::arg("map"), py::arg("center"), py::arg("radius"),
      "True if every workspace cell touching the sphere is known and not occupied.");
  m.def(
      "segment_is_free",
      [](const OccupancyMap& map, const py::handle& a, const py::handle& b, double r) {
        const Eigen::Vector3d pa = vec3_arg(a, "segment start"), pb = vec3_arg(b, "segment end");
        if (!(r >= 0) || !std::isfinite(r)) throw py::value_error("radius must be finite and >= 0");
        Reading lock(map);
        return segment_is_free(grid_view(map), pa, pb, r);
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"),
      "True if the sphere swept along a-b stays in known free space.");
  m.def(
      "plan_path",
      [](const OccupancyMap& map, const py::handle& a, const py::handle& b, double r,
         std::size_t max_expansions, bool reference) {
        const Eigen::Vector3d pa = vec3_arg(a, "path start"), pb = vec3_arg(b, "path end");
        if (!(r >= 0) || !std::isfinite(r)) throw py::value_error("radius must be finite and >= 0");
        std::vector<Eigen::Vector3d> path;
        {
          Reading lock(map);
          path = reference ? plan_path_reference(grid_view(map), pa, pb, r, max_expansions)
                           : plan_path(grid_view(map), pa, pb, r, max_expansions);
        }
        Points out(static_cast<Eigen::Index>(path.size()), 3);
        for (std::size_t i = 0; i < path.size(); ++i)
          out.row(static_cast<Eigen::Index>(i)) = path[i];
        return out;
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"),
      py::arg("max_expansions") = 200000, py::arg("reference") = false,
      "A* through known free space; (P, 3) waypoints from a to b, or (0, 3) when there is none.\n"
      "reference=True runs the first implementation (the same path, slower), for tests and\n"
      "benchmarks.");
  py::class_<FreeComponent>(m, "FreeComponent", R"doc(
The cells plan_path can reach from `start` through known free space (collision sphere of
`radius`), found by one flood. Valid while `map` is unchanged: ask it about many targets of one
planning step instead of searching a path to each.)doc")
      .def(py::init([](const OccupancyMap& map, const py::handle& a, double r) {
             const Eigen::Vector3d pa = vec3_arg(a, "start");
             if (!(r >= 0) || !std::isfinite(r))
               throw py::value_error("radius must be finite and >= 0");
             Reading lock(map);
             return FreeComponent(grid_view(map), pa, r);
           }),
           py::arg("map"), py::arg("start"), py::arg("radius"))
      .def(
          "contains",
          [](const FreeComponent& c, const OccupancyMap& map, const py::handle& targets) {
            const PointsArg t = points_arg(targets, "targets");
            std::vector<std::uint8_t> ok;
            {
              Reading lock(map);
              ok = c.contains(grid_view(map), t.map());
            }
            py::array_t<bool> out(static_cast<py::ssize_t>(ok.size()));
            auto o = out.mutable_unchecked<1>();
            for (std::size_t i = 0; i < ok.size(); ++i) o(py::ssize_t(i)) = ok[i] != 0;
            return out;
          },
          py::arg("map"), py::arg("targets"),
          "(N,) bool per target (N, 3) of the same, unchanged map: True where plan_path can reach\n"
          "it (straight, or its cell in the component and in sight of it); False where it cannot.");
  m.def("viewable_cells", &viewable_cells, py::arg("hfov_deg"), py::arg("vfov_deg"),
        py::arg("min_range"), py::arg("max_range"), py::arg("resolution"),
        py::arg("count_partial") = true,
        "C_view of Eq. 5: V_frustum / V_cell, or with count_partial the cells the frustum "
        "touches\nincluding partial boundary cells: vol(frustum (+) cell) / V_cell.");
}

}  // namespace nbv::bind
