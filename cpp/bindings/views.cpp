// Bindings of view scoring (nbv/views.hpp), camera observations (nbv/surface_observations.hpp)
// and navigation (nbv/navigation.hpp).
#include "nbv/views.hpp"
#include "bindings.hpp"
#include "nbv/frame_integration.hpp"
#include "nbv/navigation.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/surface_observations.hpp"
#include "options.hpp"

#include <cmath>
#include <limits>
#include <mutex>
#include <optional>
#include <string>

namespace nbv::bind {
namespace {

/// The camera observations a collision check may read (None: the map alone).
using SurfacePtr = std::shared_ptr<SurfaceObservations>;

/// A FreeComponent and the camera observations it was flooded with, which its contains reads.
struct BoundComponent {
  FreeComponent component;
  SurfacePtr surface;
};

/// An A* search's path floor (GridView::path_floor): None for none, else a finite height.
double floor_arg(const py::handle& floor) {
  if (floor.is_none()) return -std::numeric_limits<double>::infinity();
  const double z = real_arg(floor, "path floor");
  if (!std::isfinite(z))
    throw py::value_error("path floor must be finite, got " + std::to_string(z));
  return z;
}

/// The grid view an A* search reads: the map's (with the camera observations, when given) and
/// the path floor.
GridView path_grid(const OccupancyMap& map, const SurfaceObservations* surface, double floor) {
  GridView g = grid_view(map, surface);
  g.path_floor = floor;
  return g;
}

/// An (nx, ny, nz) Fortran-ordered copy of a per-cell value, get(grid id), of a grid layout.
template <typename T, typename Get>
py::array_t<T, py::array::f_style> per_cell(const GridLayout& layout, const Get& get,
                                            std::shared_mutex& mutex) {
  const auto& d = layout.dims;
  py::array_t<T, py::array::f_style> a(std::vector<py::ssize_t>{d[0], d[1], d[2]});
  T* p = a.mutable_data();
  {
    Reading lock(mutex);
    for (int k = 0; k < d[2]; ++k)
      for (int j = 0; j < d[1]; ++j)
        for (int i = 0; i < d[0]; ++i) *p++ = get(std::int64_t(layout.id(i, j, k)));
  }
  return a;
}

/// One candidate's share of a CandidateRays (CandidateRays.view(k)).
struct CandidateRaysView {
  std::shared_ptr<const CandidateRays> rays;
  Eigen::Index k;
  Eigen::Index begin() const { return Eigen::Index(rays->offsets[k]); }
  Eigen::Index size() const { return Eigen::Index(rays->offsets[k + 1] - rays->offsets[k]); }
};

/// The per-cell arrays of CandidateRays (all rows: k < 0) or of one candidate's view, as
/// properties of `cls` whose instances are `self`.
template <class Class, class Get>
void def_cell_arrays(Class& cls, Get get) {
  // get(self) -> (rays, first row, rows)
  cls.def_property_readonly(
         "index",
         [get](const py::object& self) {
           auto [r, b, n] = get(self);
           return owned_array(self, r->index.data() + b, n);
         },
         "(N,) int64 flat workspace index i + nx * (j + ny * k) of each cell "
         "(OccupancyMap.index_of's)")
      .def_property_readonly(
          "centers",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->centers.data() + 3 * b, n, 3);
          },
          "(N, 3) float64 cell centres, world frame (m)")
      .def_property_readonly(
          "probability",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->probability.data() + b, n);
          },
          "(N,) float64 occupancy probability, sigmoid of the map's log-odds; unknown cells 0.5 "
          "(the map's prior)")
      .def_property_readonly(
          "logodds",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->logodds.data() + b, n);
          },
          "(N,) float32 the map's log-odds as it holds them (unknown 0): compare with the "
          "map's float32 clamping thresholds exactly")
      .def_property_readonly(
          "state",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->state.data() + b, n);
          },
          "(N,) int8 CellState: -1 unknown, 0 free, 1 occupied (predicted cells by their "
          "probability)")
      .def_property_readonly(
          "range",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->range.data() + b, n);
          },
          "(N,) float64 metres from the camera to where a ray entered the cell, the smallest "
          "over its rays (0 for the camera's own cell)")
      .def_property_readonly(
          "incidence",
          [get](const py::object& self) {
            auto [r, b, n] = get(self);
            return owned_array(self, r->incidence.data() + b, n);
          },
          "(N,) float64 radians in [0, pi/2]: the angle between the ray of the smallest range "
          "and the cell's normal (an occupied cell's surface normal from its open faces, as "
          "the surface utility estimates it; otherwise the face the ray entered through); NaN "
          "for the camera's own cell")
      .def_property_readonly(
          "seen",
          [get](const py::object& self) -> py::object {
            auto [r, b, n] = get(self);
            if (!r->observed) return py::none();
            return owned_array(self, r->seen.data() + b, n);
          },
          "(N,) uint32 direction-bin masks the camera has seen each cell from (surface= given), "
          "else None")
      .def_property_readonly(
          "hits",
          [get](const py::object& self) -> py::object {
            auto [r, b, n] = get(self);
            if (!r->observed) return py::none();
            return owned_array(self, r->hits.data() + b, n);
          },
          "(N,) uint16 camera hits in each cell (surface= given), else None");
}

/// A path's waypoints as (P, 3) rows.
Points path_rows(const std::vector<Eigen::Vector3d>& path) {
  Points out(static_cast<Eigen::Index>(path.size()), 3);
  for (std::size_t i = 0; i < path.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = path[i];
  return out;
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
  m.attr("DEFAULT_PATH_EXPANSIONS") = kDefaultPathExpansions;
  m.def("utility_names", &utility_names, "Names of the registered view utilities.");

  py::class_<SurfaceObservations, std::shared_ptr<SurfaceObservations>>(m, "SurfaceObservations",
                                                                        R"doc(
What the camera has seen of each workspace cell of an OccupancyMap: the bitmask of the 26
direction bins (cube faces, edges, corners) it was seen from, and the number of camera hits in
it. SurfaceObservations(map); add_scan(scan) after integrating each camera scan. Read by the
surface and four_term utilities and by surface_targets. saturation_hits > 0: a scan that puts at
least that many hits in a cell, none in a 0.05 m square (a quarter of the map's resolution) that
held none before, marks the cell saturated; a later scan that adds a square clears the mark. The
surface utility credits no view for a saturated cell and surface_targets leaves it out.)doc")
      .def(py::init([](const OccupancyMap& map, int saturation_hits) {
             return std::make_shared<SurfaceObservations>(map, saturation_hits);
           }),
           py::arg("map"), py::arg("saturation_hits") = 0)
      .def_property_readonly("saturation_hits", &SurfaceObservations::saturation_hits)
      .def_property_readonly_static(
          "MAX_SATURATION_HITS",
          [](const py::object&) { return SurfaceObservations::kMaxSaturationHits; },
          "the largest saturation_hits")
      .def(
          "saturated_cells",
          [](const SurfaceObservations& s) {
            Reading lock(s);
            return s.saturated_cells();
          },
          "Number of cells marked saturated.")
      .def(
          "add_scan",
          [](SurfaceObservations& s, const Scan& scan) {
            Writing lock(s);
            return s.add_scan(scan.origin, scan.hits, scan.sparse_hits);
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
      .def(
          "novel_hits",
          [](const SurfaceObservations& s, const py::handle& origin, const py::handle& hits,
             double cone_deg) {
            const Eigen::Vector3d o = vec3_arg(origin, "origin");
            auto h = points_arg(hits, "hits");
            auto hm = h.map();
            Reading lock(s);
            return s.novel_hits(o, hm, cone_deg);
          },
          py::arg("origin"), py::arg("hits"), py::arg("cone_deg"),
          "How many of the hits (N, 3) seen from origin (3,) would add to the record: in a cell "
          "whose side facing the sensor (no direction bin within cone_deg of theirs) is unseen, "
          "or marking a square no earlier hit marked. Reads only (a preview of a frame).")
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
      .def_property_readonly(
          "allocated_bricks",
          [](const SurfaceObservations& s) {
            Reading lock(s);
            return s.allocated_bricks();
          },
          "Bricks of 4 x 4 x 4 cells holding records: the record grows with the surface the "
          "camera hit, not with the workspace box.")
      .def_property_readonly(
          "bytes",
          [](const SurfaceObservations& s) {
            Reading lock(s);
            return s.bytes();
          },
          "Bytes held by the records (brick table and blocks).")
      .def(
          "seen_grid",
          [](const SurfaceObservations& s) {
            return per_cell<std::uint32_t>(
                s.layout(), [&](std::int64_t i) { return s.seen(i); }, s.access_lock());
          },
          "(nx, ny, nz) uint32 direction-bin masks, Fortran order (copy).")
      .def(
          "hits_grid",
          [](const SurfaceObservations& s) {
            return per_cell<std::uint16_t>(
                s.layout(), [&](std::int64_t i) { return s.hits(i); }, s.access_lock());
          },
          "(nx, ny, nz) uint16 camera hits per cell, Fortran order (copy).")
      .def(
          "patches_grid",
          [](const SurfaceObservations& s) {
            return per_cell<std::uint64_t>(
                s.layout(), [&](std::int64_t i) { return s.patches(i); }, s.access_lock());
          },
          "(nx, ny, nz) uint64 masks of where each cell's hits fell, Fortran order (copy): bit "
          "16 a + 4 u + v for the square (u, v) of the cell seen along axis a (quarters of the "
          "cell along the other two axes, in increasing order).");
  m.def(
      "direction_bin",
      [](const py::handle& d) {
        const Eigen::Vector3d v = vec3_arg(d, "direction");
        if (v.isZero(0.0))  // (it has none: it was given bin 12)
          throw py::value_error("direction must not be the zero vector");
        return direction_bin(v);
      },
      py::arg("direction"), "The direction bin (0..25) of a nonzero vector.");
  m.def("bin_direction", &bin_direction, py::arg("bin"), "Unit vector of a direction bin.");
  m.def("bin_cone", &bin_cone, py::arg("bin"), py::arg("cone_deg"),
        "Bitmask of the bins within cone_deg of a bin.");

  py::class_<FrameIntegration>(m, "FrameIntegration", "What one integrate_frame call changed.")
      .def_readonly("map", &FrameIntegration::map, "the map's IntegrationStats")
      .def_readonly("cloud_voxels", &FrameIntegration::cloud_voxels,
                    "voxels the camera cloud gained")
      .def_readonly("new_cells", &FrameIntegration::new_cells,
                    "cells the camera saw for the first time")
      .def_readonly("next_scan", &FrameIntegration::next_scan,
                    "the next frame's Scan where one was asked for (next_camera, next_pose), "
                    "else None")
      .def("__repr__", [](const FrameIntegration& f) {
        return "<FrameIntegration new_cells=" + std::to_string(f.new_cells) +
               " cloud_voxels=" + std::to_string(f.cloud_voxels) +
               " traced_rays=" + std::to_string(f.map.traced_rays) + ">";
      });
  m.def(
      "integrate_frame",
      [](OccupancyMap& map, SurfaceCloud& cloud, SurfaceObservations& surface, const Scan& scan,
         double max_range, const DepthCamera* next_camera, const py::handle& next_pose) {
        std::optional<Pose> pose;
        if (!next_pose.is_none()) pose = pose_arg(next_pose, "next_pose");
        py::gil_scoped_release release;
        std::unique_lock<std::shared_mutex> a(map.access_lock()), b(surface.access_lock());
        return integrate_frame(map, cloud, surface, scan, max_range, next_camera,
                               pose ? &*pose : nullptr);
      },
      py::arg("map"), py::arg("cloud"), py::arg("surface"), py::arg("scan"),
      py::arg("max_range") = std::numeric_limits<double>::infinity(),
      py::arg("next_camera") = nullptr, py::arg("next_pose") = py::none(),
      "A camera Scan integrated into the map, the camera cloud and the camera observations at "
      "once: map.integrate(scan, max_range), cloud.add(scan.hits) and surface.add_scan(scan), "
      "with their results, the map's update beside the other two. With next_camera (a "
      "DepthCamera) and next_pose (x, y, z, yaw[, pitch]), the next frame is cast meanwhile "
      "(next_camera.scan_pose(next_pose)) and returned as next_scan. A frame any of them would "
      "refuse (a non-finite or unaddressable origin, a non-finite point, a hit beyond the "
      "cloud's range, a bad next pose) raises ValueError before anything changes. Returns a "
      "FrameIntegration.");
  m.def(
      "refine_frame",
      [](const DepthCamera& camera, const Scan& coarse, const py::handle& pose,
         const SurfaceObservations& surface, double cone_deg) {
        const Pose p = pose_arg(pose, "frame pose");
        py::gil_scoped_release release;
        std::shared_lock<std::shared_mutex> lock(surface.access_lock());
        return refine_frame(camera, coarse, p, surface, cone_deg);
      },
      py::arg("camera"), py::arg("coarse"), py::arg("pose"), py::arg("surface"),
      py::arg("cone_deg"),
      "A frame taken at 1/N of camera's pixels on each axis (coarse: the Scan of a camera of the "
      "same field of view, range and mount at width/N x height/N, from pose (x, y, z, yaw[, "
      "pitch])), refined to camera's full resolution where it could see something new: each "
      "coarse hit with which a denser frame could add to the camera observations (a side unseen "
      "within cone_deg, a square unmarked, or a cell none of whose projections along the axes "
      "has all its squares marked) has the block of full-resolution pixels its coarse pixel "
      "spans, and the 8 neighbouring blocks, cast again (camera.scan_pixels), replacing their "
      "coarse rays; elsewhere the coarse rays stand. Returns one Scan: the coarse hits kept then "
      "the refined pixels' hits, the coarse free ends kept then the refined ones (hit_rays, "
      "free_rays: full-resolution pixels), depth (height, width). Reads surface only. ValueError "
      "for a coarse frame finer than the camera's or a "
      "pose the camera cannot take.");

  py::class_<ViewMemo, std::shared_ptr<ViewMemo>> view_memo(m, "ViewMemo", R"doc(
What the paper's IG walks of candidate views found, kept from one evaluate_views call to the next
(pass it as memo=). A view scored again at the same pose and pitch (bit for bit) whose walk still
holds - every cell its rays reached has kept its occupancy, every neutral brick they stepped over
is still neutral - is scored from its record: the same gain, cells and occupied_seen, without
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
        const ViewPosesArg c = view_poses_arg(candidates, "candidates");
        const auto cm = c.map();
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
      R"doc(Score K candidate views from the current pose, in one call: (K, 4) rows [x, y, z,
yaw] (a level camera) or (K, 5) rows [x, y, z, yaw, pitch], pitch the camera gimbal's in radians
(> 0 looks down, |pitch| <= pi/2): the camera's rays leave from gimbal_transform(view,
camera.mount). A (K, 4) array scores exactly as the (K, 5) one with pitch 0. camera / utility /
validity: a ViewCameraModel / UtilityOptions / ValidityOptions, a dict of their fields, or None
for the defaults. surface: the map's SurfaceObservations (needed by the
surface and four_term utilities). memo: a ViewMemo kept across calls (the same scores, fewer
walks).

Returns a dict of (K,) arrays: utility (the score to maximise, -inf where invalid), gain (the
utility's own value before any distance weight), cells (cells that added to it), occupied_seen
(rays that reached an occupied cell), status (0 valid, 1 out of bounds, 2 collision: an
occupied/unknown cell within the collision radius, 3 straight path blocked, 4 sees no occupied
cell; names in VIEW_STATUS_NAMES). backend "grid" walks the map's workspace grid (3D-DDA);
"octree" reads every visited cell through OctoMap's search, as the authors did (same answer,
slower).)doc");

  // the view first: CandidateRays.view returns one (and its signature names it)
  py::class_<CandidateRaysView> rays_view(m, "CandidateRaysView", R"doc(
One candidate's cells of a CandidateRays (CandidateRays.view(k)): the same per-cell arrays,
its rows only (read-only views), with its status and occupied_seen. len() is its cell count.)doc");
  def_cell_arrays(rays_view, [](const py::object& self) {
    const auto& v = self.cast<const CandidateRaysView&>();
    return std::make_tuple(v.rays, v.begin(), v.size());
  });
  rays_view.def_readonly("k", &CandidateRaysView::k, "the candidate's row")
      .def_property_readonly(
          "status", [](const CandidateRaysView& v) { return int(v.rays->status[v.k]); },
          "evaluate_views' status code of the candidate (0 valid)")
      .def_property_readonly(
          "occupied_seen", [](const CandidateRaysView& v) { return v.rays->occupied_seen[v.k]; },
          "rays of the candidate that ended at an occupied cell")
      .def("__len__", &CandidateRaysView::size)
      .def("__repr__", [](const CandidateRaysView& v) {
        return "CandidateRaysView(k=" + std::to_string(v.k) + ", " + std::to_string(v.size()) +
               " cells, status " + std::to_string(int(v.rays->status[v.k])) + ")";
      });

  py::class_<CandidateRays, std::shared_ptr<CandidateRays>> rays(m, "CandidateRays", R"doc(
What the camera rays of K candidate views reach (candidate_rays): per candidate the DISTINCT
workspace cells its rays entered, each ray walked exactly as evaluate_views walks it (ending at
its first occupied cell inclusive, at the camera's max_range depth or where it leaves the
workspace). Candidate k's cells are rows offsets[k]:offsets[k + 1] of the (N,) / (N, 3) per-cell
arrays, in the order its rays first reached them; view(k) gives them as their own arrays. The
arrays are read-only views into this object (no copy). len() is K.)doc");
  def_cell_arrays(rays, [](const py::object& self) {
    const auto& r = self.cast<const std::shared_ptr<CandidateRays>&>();
    return std::make_tuple(r, Eigen::Index(0), Eigen::Index(r->num_cells()));
  });
  rays.def_property_readonly(
          "offsets",
          [](const py::object& self) {
            const auto& r = self.cast<const CandidateRays&>();
            return owned_array(self, r.offsets.data(), r.offsets.size());
          },
          "(K + 1,) int64: candidate k's cells are rows offsets[k]:offsets[k + 1]")
      .def_property_readonly(
          "status",
          [](const py::object& self) {
            const auto& r = self.cast<const CandidateRays&>();
            return owned_array(self, r.status.data(), r.status.size());
          },
          "(K,) int8 evaluate_views' status: 0 valid, 1 out of bounds, 2 collision, 3 path "
          "blocked (1-3 not walked: no cells), 4 sees no occupied cell (walked: its cells kept)")
      .def_property_readonly(
          "occupied_seen",
          [](const py::object& self) {
            const auto& r = self.cast<const CandidateRays&>();
            return owned_array(self, r.occupied_seen.data(), r.occupied_seen.size());
          },
          "(K,) int32 rays that ended at an occupied cell (evaluate_views' occupied_seen)")
      .def_property_readonly(
          "num_cells", [](const CandidateRays& r) { return r.num_cells(); },
          "N, the cells of all candidates together")
      .def("__len__", [](const CandidateRays& r) { return r.size(); })
      .def(
          "view",
          [](const std::shared_ptr<CandidateRays>& r, Eigen::Index k) {
            const Eigen::Index K = r->size();
            if (k < -K || k >= K)
              throw py::index_error("candidate " + std::to_string(k) + " out of range for " +
                                    std::to_string(K) + " candidates");
            return CandidateRaysView{r, k < 0 ? k + K : k};
          },
          py::arg("k"),
          "Candidate k's cells (k < 0 counts from the end): a CandidateRaysView whose arrays are "
          "the rows offsets[k]:offsets[k + 1]; IndexError outside [-K, K).")
      .def("__repr__", [](const CandidateRays& r) {
        return "CandidateRays(" + std::to_string(r.size()) + " candidates, " +
               std::to_string(r.num_cells()) + " cells)";
      });

  m.def(
      "candidate_rays",
      [](const OccupancyMap& map, const py::handle& candidates, const py::handle& current,
         const py::object& camera, const py::object& validity,
         const std::shared_ptr<SurfaceObservations>& surface, const py::object& utility) {
        const ViewPosesArg c = view_poses_arg(candidates, "candidates");
        const auto cm = c.map();
        const Pose cur = pose_arg(current, "current pose");
        const ViewCameraModel cam = OptionsClass<ViewCameraModel>::from(camera, "camera");
        const UtilityOptions u = OptionsClass<UtilityOptions>::from(utility, "utility");
        const ValidityOptions v = OptionsClass<ValidityOptions>::from(validity, "validity");
        std::shared_ptr<CandidateRays> out;
        {
          Reading2 reading(map, surface.get());
          out = std::make_shared<CandidateRays>(
              candidate_rays(grid_view(map, surface.get()), cm, cur, cam, u, v));
        }
        return out;
      },
      py::arg("map"), py::arg("candidates"), py::arg("current"), py::arg("camera") = py::none(),
      py::arg("validity") = py::none(), py::arg("surface") = nullptr,
      py::arg("utility") = py::none(),
      R"doc(What the camera rays of K candidate views reach, for a view utility written in
Python: one C++ call over all candidates (in parallel, without the GIL, under the map's reading
lock). candidates, current, camera, validity, surface as for evaluate_views: (K, 4) rows
[x, y, z, yaw] or (K, 5) rows [x, y, z, yaw, pitch], world frame (m, rad). Each view's rays are
walked exactly as evaluate_views walks them: the same rays, each ending at its first occupied
cell (inclusive), at camera.max_range depth or where it leaves the workspace.

utility: UtilityOptions (or a dict, or None for the defaults) of which only require_occupied and
require_occupied_probability are read: they decide status 4 and occupied_seen as in
evaluate_views. surface: the map's SurfaceObservations, to also get each cell's seen / hits.

Returns a CandidateRays: offsets (K + 1,) int64; per cell, candidate by candidate, index (N,)
int64, centers (N, 3) float64 world, probability (N,) float64 (unknown 0.5), logodds (N,)
float32, state (N,) int8 (-1 unknown, 0 free, 1 occupied), range (N,) float64 m (smallest over
the rays), incidence (N,) float64 rad (NaN for the camera's own cell), seen / hits (or None);
per candidate status (K,) int8 (0 valid; 1-3 not walked: no cells; 4 sees no occupied cell: its
cells kept) and occupied_seen (K,) int32. The distinct cells of nonzero map entropy among a
valid view's cells are exactly those evaluate_views' ig utility counts (its `cells`).
ValueError for a bad shape, non-finite values or bad options.)doc");

  m.def(
      "sphere_is_free",
      [](const OccupancyMap& map, const py::handle& c, double r, const SurfacePtr& surface) {
        const Eigen::Vector3d p = vec3_arg(c, "centre");
        check_radius(r);
        Reading2 lock(map, surface.get());
        return sphere_is_free(grid_view(map, surface.get()), p, r);
      },
      py::arg("map"), py::arg("center"), py::arg("radius"), py::arg("surface") = nullptr,
      "True if every workspace cell touching the sphere is known and not occupied, and (with the\n"
      "camera observations `surface`) holds no camera hit: the collision checks' rule.");
  m.def(
      "spheres_are_free",
      [](const OccupancyMap& map, const py::handle& c, double r, const SurfacePtr& surface) {
        const PointsArg centres = points_arg(c, "centres");
        check_radius(r);
        const auto pts = centres.map();
        py::array_t<bool> out(static_cast<py::ssize_t>(pts.rows()));
        auto o = out.mutable_unchecked<1>();
        Reading2 lock(map, surface.get());  // releases the GIL
        const GridView grid = grid_view(map, surface.get());
        for (Eigen::Index i = 0; i < pts.rows(); ++i)
          o(py::ssize_t(i)) = sphere_is_free(grid, pts.row(i).transpose(), r);
        return out;
      },
      py::arg("map"), py::arg("centres"), py::arg("radius"), py::arg("surface") = nullptr,
      "(N,) bool per centre (N, 3): sphere_is_free of each (one call for many views).");
  m.def(
      "segment_is_free",
      [](const OccupancyMap& map, const py::handle& a, const py::handle& b, double r,
         const SurfacePtr& surface) {
        const Eigen::Vector3d pa = vec3_arg(a, "segment start"), pb = vec3_arg(b, "segment end");
        check_radius(r);
        Reading2 lock(map, surface.get());
        return segment_is_free(grid_view(map, surface.get()), pa, pb, r);
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"), py::arg("surface") = nullptr,
      "True if the sphere swept along a-b stays in known free space.");
  m.def(
      "plan_path",
      [](const OccupancyMap& map, const py::handle& a, const py::handle& b, double r,
         std::size_t max_expansions, bool reference, const SurfacePtr& surface,
         const py::handle& floor) {
        const Eigen::Vector3d pa = vec3_arg(a, "path start"), pb = vec3_arg(b, "path end");
        check_radius(r);
        const double fz = floor_arg(floor);
        std::vector<Eigen::Vector3d> path;
        {
          Reading2 lock(map, surface.get());
          const GridView g = path_grid(map, surface.get(), fz);
          path = reference ? plan_path_reference(g, pa, pb, r, max_expansions)
                           : plan_path(g, pa, pb, r, max_expansions);
        }
        return path_rows(path);
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"),
      py::arg("max_expansions") = kDefaultPathExpansions, py::arg("reference") = false,
      py::arg("surface") = nullptr, py::arg("floor") = py::none(),
      "A* through known free space; (P, 3) waypoints from a to b, or (0, 3) when there is none.\n"
      "floor: a height its cells keep above (their tops; the waypoints within half a cell), the\n"
      "views' ground clearance; None: none. reference=True runs the first implementation (the\n"
      "same path, slower), for tests and benchmarks.");
  struct PathSearch {
    Points path;
    PathSearchStats stats;
  };
  py::class_<PathSearch>(m, "PathSearch", R"doc(
One A* search of search_path: its path, and why it found none (read `capped`).)doc")
      .def_readonly("path", &PathSearch::path,
                    "(P, 3) waypoints from a to b, or (0, 3) when the search found none")
      .def_property_readonly(
          "expansions", [](const PathSearch& s) { return s.stats.expansions; }, "cells expanded")
      .def_property_readonly(
          "flood_ended", [](const PathSearch& s) { return s.stats.flood_ended; },
          "the flood from b ended the search: b's free component is closed without a")
      .def_property_readonly(
          "cells_cost",
          [](const PathSearch& s) {
            // a searched path has 3 points at least (the straight flight, 2, was not free)
            return s.path.rows() > 2 ? s.stats.cost : std::numeric_limits<double>::quiet_NaN();
          },
          "the cost (m) of the cells' path the path was shortened from (NaN where the straight\n"
          "flight was free or there is no path)")
      .def_property_readonly(
          "capped", [](const PathSearch& s) { return s.stats.capped; },
          "the search stopped at max_expansions with cells left to expand: a longer search may\n"
          "find a path; any other failure is final")
      .def("__repr__", [](const PathSearch& s) {
        return "<nbvkit.PathSearch " + std::to_string(s.path.rows()) + " waypoints, " +
               std::to_string(s.stats.expansions) + " expansions" +
               (s.stats.capped ? ", capped>" : ">");
      });
  m.def(
      "search_path",
      [](const OccupancyMap& map, const py::handle& a, const py::handle& b, double r,
         std::size_t max_expansions, const SurfacePtr& surface, const py::handle& floor) {
        const Eigen::Vector3d pa = vec3_arg(a, "path start"), pb = vec3_arg(b, "path end");
        check_radius(r);
        const double fz = floor_arg(floor);
        PathSearch out;
        std::vector<Eigen::Vector3d> path;
        {
          Reading2 lock(map, surface.get());
          path =
              plan_path(path_grid(map, surface.get(), fz), pa, pb, r, max_expansions, &out.stats);
        }
        out.path = path_rows(path);
        return out;
      },
      py::arg("map"), py::arg("a"), py::arg("b"), py::arg("radius"),
      py::arg("max_expansions") = kDefaultPathExpansions, py::arg("surface") = nullptr,
      py::arg("floor") = py::none(),
      "plan_path's search with what it did: a PathSearch (path, expansions, flood_ended,\n"
      "capped). A failed search that is not capped is final: no path exists.");
  struct PathsTo {
    std::vector<Points> paths;
    Eigen::VectorXd cells_cost;
    std::size_t expansions = 0;
    bool capped = false;
  };
  py::class_<PathsTo>(m, "PathsToGoal", R"doc(
The paths of plan_paths_to: one per start, from one search.)doc")
      .def_readonly(
          "paths", &PathsTo::paths,
          "per start, (P, 3) waypoints from it to the goal, or (0, 3) where there is none")
      .def_readonly("cells_cost", &PathsTo::cells_cost,
                    "(N,) per start, the cost (m) of the cells' path its path was shortened from\n"
                    "(NaN where the straight flight is free or there is no path)")
      .def_readonly("expansions", &PathsTo::expansions, "cells the search expanded")
      .def_readonly("capped", &PathsTo::capped,
                    "the search stopped at max_expansions with starts still to reach")
      .def("__repr__", [](const PathsTo& p) {
        std::size_t found = 0;
        for (const Points& q : p.paths) found += q.rows() > 0;
        return "<nbvkit.PathsToGoal " + std::to_string(found) + " of " +
               std::to_string(p.paths.size()) + " found, " + std::to_string(p.expansions) +
               " expansions" + (p.capped ? ", capped>" : ">");
      });
  m.def(
      "plan_paths_to",
      [](const OccupancyMap& map, const py::handle& starts, const py::handle& goal, double r,
         std::size_t max_expansions, const SurfacePtr& surface, const py::handle& floor) {
        const PointsArg a = points_arg(starts, "starts");
        const Eigen::Vector3d pb = vec3_arg(goal, "goal");
        check_radius(r);
        const double fz = floor_arg(floor);
        PathsToGoal found;
        {
          Reading2 lock(map, surface.get());
          found = plan_paths_to(path_grid(map, surface.get(), fz), a.map(), pb, r, max_expansions);
        }
        PathsTo out;
        for (const auto& p : found.paths) out.paths.push_back(path_rows(p));
        out.cells_cost = Eigen::Map<const Eigen::VectorXd>(found.cells_cost.data(),
                                                           Eigen::Index(found.cells_cost.size()));
        out.expansions = found.expansions;
        out.capped = found.capped;
        return out;
      },
      py::arg("map"), py::arg("starts"), py::arg("goal"), py::arg("radius"),
      py::arg("max_expansions") = 0, py::arg("surface") = nullptr, py::arg("floor") = py::none(),
      "What plan_path finds from each start (N, 3) to `goal` with no cap, by one search from the\n"
      "goal (a cheapest path where several tie may differ from plan_path's): a PathsToGoal.\n"
      "max_expansions: cells the search expands at most (0: until every start is reached or\n"
      "none is left to reach).");
  py::class_<BoundComponent>(m, "FreeComponent", R"doc(
The cells plan_path can reach from `start` through known free space (collision sphere of
`radius`; with the camera observations `surface`, off every cell the camera has hit; above
plan_path's `floor`), found by
one flood. Valid while `map` and `surface` are unchanged: ask it about many targets of one
planning step instead of searching a path to each.)doc")
      .def(
          py::init([](const OccupancyMap& map, const py::handle& a, double r,
                      const SurfacePtr& surface, const py::handle& floor) {
            const Eigen::Vector3d pa = vec3_arg(a, "start");
            check_radius(r);
            const double fz = floor_arg(floor);
            Reading2 lock(map, surface.get());
            return BoundComponent{FreeComponent(path_grid(map, surface.get(), fz), pa, r), surface};
          }),
          py::arg("map"), py::arg("start"), py::arg("radius"), py::arg("surface") = nullptr,
          py::arg("floor") = py::none())
      .def(
          "contains",
          [](const BoundComponent& c, const OccupancyMap& map, const py::handle& targets) {
            const PointsArg t = points_arg(targets, "targets");
            std::vector<std::uint8_t> ok;
            {
              Reading2 lock(map, c.surface.get());
              ok = c.component.contains(grid_view(map, c.surface.get()), t.map());
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
