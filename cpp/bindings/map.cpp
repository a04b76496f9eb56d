// Bindings of nbv::OccupancyMap (nbvkit.OccupancyMap) and its options.
#include "bindings.hpp"
#include "nbv/occupancy_map.hpp"
#include "options.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace nbv::bind {
namespace {

using CArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// Points of shape (..., 3) (or (3,) for one point) as an (N, 3) view plus the leading shape.
struct NdPoints {
  CArray array;
  std::vector<py::ssize_t> lead;
  Eigen::Map<const Points> map() const {
    return {array.data(), static_cast<Eigen::Index>(array.size() / 3), 3};
  }
};

NdPoints nd_points(const py::handle& obj, const char* what) {
  if (obj.is_none())
    throw py::value_error(std::string(what) + " must be an (N, 3) array, got None");
  CArray a;
  try {
    const py::array given = py::array::ensure(obj);
    if (given) require_real_dtype(given, what);
    a = CArray::ensure(obj);
  } catch (const py::error_already_set&) {
    a = {};
  }
  if (!a) throw py::value_error(std::string(what) + " must be an (N, 3) array of numbers");
  NdPoints out;
  if (a.ndim() == 1 && a.shape(0) == 0) {  // an empty list: zero points
    out.array = CArray(std::vector<py::ssize_t>{0, 3});
    out.lead = {0};
    return out;
  }
  if (a.ndim() < 1 || a.shape(a.ndim() - 1) != 3) {
    std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
    throw py::value_error(std::string(what) + " must have shape (N, 3) (or (..., 3)), got " +
                          std::string(py::str(py::tuple(py::cast(shape)))));
  }
  out.lead.assign(a.shape(), a.shape() + a.ndim() - 1);
  out.array = a;
  if (!out.map().allFinite())
    throw py::value_error(std::string(what) + " contains NaN or infinite values");
  return out;
}

template <typename T>
py::array_t<T> shaped(const std::vector<py::ssize_t>& lead, const T* data, std::size_t extra = 1) {
  std::vector<py::ssize_t> shape = lead;
  if (extra > 1) shape.push_back(py::ssize_t(extra));
  py::array_t<T> out(shape);
  if (out.size() > 0) std::memcpy(out.mutable_data(), data, sizeof(T) * std::size_t(out.size()));
  return out;
}

std::string path_arg(const py::handle& obj) {
  const bool pathlike = py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__");
  py::object p = pathlike ? py::module_::import("os").attr("fspath")(obj) : py::none();
  if (!py::isinstance<py::str>(p))
    throw py::type_error("map file path must be a str or os.PathLike of str, got " +
                         std::string(py::str(py::type::of(obj).attr("__name__"))));
  const std::string s = p.cast<std::string>();
  if (s.find('\0') != std::string::npos)
    throw py::value_error("map file path holds a NUL byte: no file has such a name");
  return s;
}

IntegrationStats integrate_any(OccupancyMap& m, const py::handle& scan_or_origin,
                               const py::handle& hits, const py::handle& free_ends,
                               double max_range, bool exact) {
  if (py::isinstance<Scan>(scan_or_origin)) {
    if (!hits.is_none() || !free_ends.is_none())
      throw py::type_error("pass either a Scan, or origin, hits and free_ends - not both");
    const Scan& s = scan_or_origin.cast<const Scan&>();
    Writing lock(m);
    return exact ? m.integrate_exact(s.origin, s.hits, s.free_ends, max_range)
                 : m.integrate(s, max_range);
  }
  if (hits.is_none() && free_ends.is_none())
    throw py::value_error(
        "integrate needs an nbvkit.Scan, or a sensor origin with hits and/or free_ends");
  const Eigen::Vector3d origin = vec3_arg(scan_or_origin, "sensor origin");
  const PointsArg empty = points_arg(py::list(), "hits");
  const PointsArg h = hits.is_none() ? empty : points_arg(hits, "hit points");
  const PointsArg f = free_ends.is_none() ? empty : points_arg(free_ends, "free-space ray ends");
  auto hm = h.map();
  auto fm = f.map();
  Writing lock(m);
  return exact ? m.integrate_exact(origin, hm, fm, max_range)
               : m.integrate(origin, hm, fm, max_range);
}

py::dict counts_dict(const CellCounts& c) {
  py::dict d;
  d["free"] = c.free;
  d["occupied"] = c.occupied;
  d["unknown"] = c.unknown;
  d["predicted"] = c.predicted;
  return d;
}

/// An (nx, ny, nz) Fortran-ordered array of f(grid id) per cell.
template <typename T, typename F>
py::array_t<T, py::array::f_style> grid(const OccupancyMap& m, const F& f) {
  const auto& d = m.dims();
  py::array_t<T, py::array::f_style> out(std::vector<py::ssize_t>{d[0], d[1], d[2]});
  T* p = out.mutable_data();
  const GridLayout& layout = m.grid().layout();
  {
    Reading lock(m);
    for (int k = 0; k < d[2]; ++k)
      for (int j = 0; j < d[1]; ++j)
        for (int i = 0; i < d[0]; ++i) *p++ = f(std::int64_t(layout.id(i, j, k)));
  }
  return out;
}

/// An int64 (...) array of id(i, j, k) of the workspace cell holding each point, -1 outside.
template <typename F>
py::array_t<std::int64_t> cell_ids(const OccupancyMap& m, const py::handle& points, const F& id) {
  auto p = nd_points(points, "query points");
  auto pm = p.map();
  std::vector<std::int64_t> out(std::size_t(pm.rows()));
  for (Eigen::Index r = 0; r < pm.rows(); ++r) {
    OccupancyMap::Key k;
    const bool in = m.coord_to_key(pm.row(r).transpose(), k) && m.in_workspace(k);
    out[std::size_t(r)] =
        in ? id(k[0] - m.min_key()[0], k[1] - m.min_key()[1], k[2] - m.min_key()[2]) : -1;
  }
  return shaped(p.lead, out.data());
}

const char* kIntegrateDoc = R"doc(
Integrate one scan: integrate(scan) or integrate(origin, hits, free_ends=None, max_range=inf).

scan: an nbvkit.Scan (world frame), or the sensor origin (3,) when hits / free_ends are given.
hits: (N, 3) float64 surface points; each end cell is a hit, the cells from the origin up to (not
including) it are misses. free_ends: (M, 3) ends of rays that hit nothing; every cell from the
origin to the end cell inclusive is a miss. max_range (metres, inf = none): longer rays are cut
there and clear only the cells before the cut (OctoMap's maxrange rule). Per scan each cell is
updated once; a cell both hit and passed through counts as hit (OctoMap's computeUpdate). A
predicted cell that is observed restarts from unknown first.
Fast path: end points are grouped per end cell and sub-cell (options.end_point_subdivision per
axis) and one ray per group is traced (from the end point nearest the sub-cell centre), in
parallel, with OctoMap's DDA; cells are de-duplicated through a stamp array and the octree is
updated once per cell. Agrees with OctoMap's insertPointCloud (integrate_exact) on > 99 % of the
touched cells, ~10-15x faster on a 640x480 frame (bench/bench_map.cpp); with
deduplicate_end_points=False every ray is traced and the result is identical.
Returns an IntegrationStats. Releases the GIL; calls on one map from several threads take turns
(see OccupancyMap: thread safety).)doc";

}  // namespace

void init_map(py::module_& m) {
  {
    OptionsClass<OccupancyMapOptions> binder(m, "OccupancyMapOptions", R"doc(
Parameters of an OccupancyMap (defaults: OctoMap's sensor model, the authors' threshold and
entropy rule); each field is documented in OccupancyMapOptions.fields().)doc");
    using S = OccupancyMapOptions;
    NBV_OCCUPANCY_MAP_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }

  py::class_<IntegrationStats>(m, "IntegrationStats", "What one OccupancyMap.integrate call did.")
      .def_readonly("rays", &IntegrationStats::rays, "input rays (hits + free-space rays)")
      .def_readonly("traced_rays", &IntegrationStats::traced_rays,
                    "rays walked after de-duplicating end cells")
      .def_readonly("occupied_cells", &IntegrationStats::occupied_cells, "cells updated as hit")
      .def_readonly("free_cells", &IntegrationStats::free_cells, "cells updated as miss")
      .def("__repr__", [](const IntegrationStats& s) {
        return "<IntegrationStats rays=" + std::to_string(s.rays) +
               " traced=" + std::to_string(s.traced_rays) +
               " occupied=" + std::to_string(s.occupied_cells) +
               " free=" + std::to_string(s.free_cells) + ">";
      });

  py::class_<OccupancyMap, std::shared_ptr<OccupancyMap>> cls(m, "OccupancyMap", R"doc(
Probabilistic occupancy map: an OctoMap octree (the map of record: integration, .ot/.bt files)
plus a mirror of the workspace box (fast queries, incrementally maintained totals), which holds
cells only for the bricks of 4 x 4 x 4 cells the sensors reached (grid_bricks).

OccupancyMap(resolution=0.2, bounds_min=(-20, -20, 0), bounds_max=(20, 20, 10), options=None,
             **option_overrides)
resolution: cell edge in metres (default OccupancyMap.DEFAULT_RESOLUTION). bounds: the workspace
box in metres (world frame; default OccupancyMap.DEFAULT_BOUNDS_MIN / _MAX); the workspace is the
cells of OctoMap's origin-anchored grid (cell = floor(c / resolution)) that cover [bounds_min,
bounds_max) - 200 x 200 x 50 = 2,000,000 cells for the defaults. Cells outside it are
kept in the octree but count in no total. options: an OccupancyMapOptions or a dict; keyword
overrides (prob_hit=..., entropy_unit='bits', ...) are applied on top (one set to None keeps the
value); an unknown name raises ValueError.

Cell states: OccupancyMap.FREE (0), OCCUPIED (1), UNKNOWN (-1) (also nbvkit.CellState). Unknown
cells have p = 0.5. Query points are (..., 3) float64 (world frame, metres); results keep the
leading shape. Points are rounded to float32 before they are filed, exactly as OctoMap does.

Grids (log_odds_grid() etc.) are (nx, ny, nz) Fortran-ordered copies: grid[i, j, k] is the cell
with centre bounds_min + (i + 0.5, j + 0.5, k + 0.5) * resolution; the C++ flat index of that
cell is i + nx * (j + ny * k) == grid.ravel(order='F') position.

Thread safety: a map may be used from several Python threads. Every call holds the map's lock
(shared by queries, which run together; exclusive for integrate*, update_cells,
mark_free_segment, set_unknown_cells, save, verify_mirror and the octree figures), taken
without the GIL; so concurrent integrations take turns and give the map the serial calls would
have built, in the order they got the lock. evaluate_views, view_coverage, surface_targets,
plan_path and the collision checks read a map under the same lock.)doc");
  cls.attr("UNKNOWN") = int(CellState::Unknown);
  cls.attr("FREE") = int(CellState::Free);
  cls.attr("OCCUPIED") = int(CellState::Occupied);
  cls.attr("DEFAULT_RESOLUTION") = OccupancyMap::kDefaultResolution;
  const auto& dmin = OccupancyMap::kDefaultBoundsMin;
  const auto& dmax = OccupancyMap::kDefaultBoundsMax;
  cls.attr("DEFAULT_BOUNDS_MIN") = py::make_tuple(dmin[0], dmin[1], dmin[2]);
  cls.attr("DEFAULT_BOUNDS_MAX") = py::make_tuple(dmax[0], dmax[1], dmax[2]);
  cls.def(py::init([](const py::handle& res, const py::handle& bmin, const py::handle& bmax,
                      const py::object& options, const py::kwargs& kw) {
            const double resolution = real_arg(res, "resolution");
            const OccupancyMapOptions o = options_with_keywords<OccupancyMapOptions>(options, kw);
            const Eigen::Vector3d lo = vec3_arg(bmin, "bounds_min"),
                                  hi = vec3_arg(bmax, "bounds_max");
            py::gil_scoped_release release;
            return std::make_shared<OccupancyMap>(resolution, lo, hi, o);
          }),
          py::arg("resolution") = OccupancyMap::kDefaultResolution,
          py::arg("bounds_min") = cls.attr("DEFAULT_BOUNDS_MIN"),
          py::arg("bounds_max") = cls.attr("DEFAULT_BOUNDS_MAX"), py::arg("options") = py::none())
      .def(
          "integrate",
          [](OccupancyMap& m, const py::handle& scan, const py::handle& hits,
             const py::handle& free_ends, double max_range) {
            return integrate_any(m, scan, hits, free_ends, max_range, false);
          },
          py::arg("scan"), py::arg("hits") = py::none(), py::arg("free_ends") = py::none(),
          py::arg("max_range") = std::numeric_limits<double>::infinity(), kIntegrateDoc)
      .def(
          "integrate_exact",
          [](OccupancyMap& m, const py::handle& scan, const py::handle& hits,
             const py::handle& free_ends,
             double max_range) { return integrate_any(m, scan, hits, free_ends, max_range, true); },
          py::arg("scan"), py::arg("hits") = py::none(), py::arg("free_ends") = py::none(),
          py::arg("max_range") = std::numeric_limits<double>::infinity(),
          "Same arguments and semantics as integrate, through OctoMap's own code: computeUpdate "
          "(the key\n"
          "sets insertPointCloud builds), free rays via computeRayKeys, then insertPointCloud's "
          "update\n"
          "loop. The reference the fast path is measured against (about 10-20x slower).")
      .def(
          "update_cells",
          [](OccupancyMap& m, const py::handle& points, bool occupied) {
            auto p = points_arg(points, "points");
            auto pm = p.map();
            Writing lock(m);
            return m.update_cells(pm, occupied);
          },
          py::arg("points"), py::arg("occupied").noconvert() = false,
          "One miss (or hit, occupied=True) update of every distinct cell holding one of points "
          "(N, 3),\n"
          "e.g. to clear the space a vehicle has flown through. Predictions are discarded first, "
          "as by\n"
          "integrate. Returns the number of distinct cells updated.")
      .def(
          "mark_free_segment",
          [](OccupancyMap& m, const py::handle& a, const py::handle& b, double radius) {
            const Eigen::Vector3d pa = vec3_arg(a, "segment start"),
                                  pb = vec3_arg(b, "segment end");
            Writing lock(m);
            return m.mark_free_segment(pa, pb, radius);
          },
          py::arg("a"), py::arg("b"), py::arg("radius"),
          "One miss update of every cell whose centre lies within radius (m) of the segment a-b, "
          "and of\n"
          "the cells holding a and b (the space a vehicle has flown through). Returns the cell "
          "count.")
      .def(
          "set_unknown_cells",
          [](OccupancyMap& m, const py::handle& points, double probability) {
            auto p = points_arg(points, "predicted points");
            auto pm = p.map();
            Writing lock(m);
            return m.set_unknown_cells(pm, probability);
          },
          py::arg("points"), py::arg("probability") = 0.6,
          "Every UNKNOWN workspace cell holding at least one of points (N, 3) gets occupancy "
          "probability\n"
          "(0.6: the paper's symmetry prediction; clamped to the clamping thresholds) and is "
          "flagged\n"
          "predicted; a later observation of the cell discards the prediction (restarts from "
          "unknown).\n"
          "Returns the number of cells set.")
      .def(
          "state",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            Eigen::Matrix<std::int8_t, Eigen::Dynamic, 1> r;
            {
              Reading lock(m);
              r = m.states(p.map());
            }
            return shaped(p.lead, r.data());
          },
          py::arg("points"), "int8 (...) cell states: 0 free, 1 occupied, -1 unknown.")
      .def(
          "probability",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            Eigen::VectorXd r;
            {
              Reading lock(m);
              r = m.probabilities(p.map());
            }
            return shaped(p.lead, r.data());
          },
          py::arg("points"), "float64 (...) occupancy probabilities, 0.5 for unknown cells.")
      .def(
          "entropy",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            Eigen::VectorXd r;
            {
              Reading lock(m);
              r = m.entropies(p.map());
            }
            return shaped(p.lead, r.data());
          },
          py::arg("points"),
          "float64 (...) cell entropies in the map's unit (unknown: ln 2 nats / 1 bit; clamped "
          "cells 0\n"
          "with clamped_entropy_zero).")
      .def(
          "is_predicted",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            Eigen::Matrix<bool, Eigen::Dynamic, 1> r;
            {
              Reading lock(m);
              r = m.predicted(p.map());
            }
            return shaped(p.lead, r.data());
          },
          py::arg("points"),
          "bool (...): the cell holds a prediction (set_unknown_cells), not an observation.")
      .def(
          "key",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            auto pm = p.map();
            std::vector<std::int32_t> out(std::size_t(pm.rows()) * 3);
            for (Eigen::Index r = 0; r < pm.rows(); ++r) {
              OccupancyMap::Key k;
              if (!m.coord_to_key(pm.row(r).transpose(), k))
                throw py::value_error("query point outside OctoMap's addressable range");
              for (int a = 0; a < 3; ++a) out[std::size_t(r) * 3 + std::size_t(a)] = k[a];
            }
            return shaped(p.lead, out.data(), 3);
          },
          py::arg("points"),
          "int32 (..., 3) OctoMap keys: floor(float32(c) / resolution) + 32768 per axis.")
      .def(
          "cell_center",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            auto pm = p.map();
            std::vector<double> out(std::size_t(pm.rows()) * 3);
            for (Eigen::Index r = 0; r < pm.rows(); ++r) {
              OccupancyMap::Key k;
              if (!m.coord_to_key(pm.row(r).transpose(), k))
                throw py::value_error("query point outside OctoMap's addressable range");
              const Eigen::Vector3d c = m.key_to_coord(k);
              for (int a = 0; a < 3; ++a) out[std::size_t(r) * 3 + std::size_t(a)] = c[a];
            }
            return shaped(p.lead, out.data(), 3);
          },
          py::arg("points"), "float64 (..., 3) centres of the cells holding the points.")
      .def(
          "index_of",
          [](const OccupancyMap& m, const py::handle& points) {
            const auto& d = m.dims();
            return cell_ids(m, points, [&](int i, int j, int k) {
              return std::int64_t(i) + std::int64_t(d[0]) * (j + std::int64_t(d[1]) * k);
            });
          },
          py::arg("points"),
          "int64 (...) flat workspace index i + nx * (j + ny * k) of each point's cell, -1 "
          "outside.")
      .def(
          "storage_index",
          [](const OccupancyMap& m, const py::handle& points) {
            const GridLayout& layout = m.grid().layout();
            return cell_ids(m, points,
                            [&](int i, int j, int k) { return std::int64_t(layout.id(i, j, k)); });
          },
          py::arg("points"),
          "int64 (...) where each point's cell is stored in the workspace grid (its bricks of "
          "4 x 4 x 4 cells): the cell ids of view_coverage's elements (element // 2); -1 "
          "outside.")
      .def(
          "in_workspace",
          [](const OccupancyMap& m, const py::handle& points) {
            auto p = nd_points(points, "query points");
            auto pm = p.map();
            std::vector<std::uint8_t> out(std::size_t(pm.rows()));
            for (Eigen::Index r = 0; r < pm.rows(); ++r) {
              OccupancyMap::Key k;
              out[std::size_t(r)] = m.coord_to_key(pm.row(r).transpose(), k) && m.in_workspace(k);
            }
            return shaped(p.lead, out.data()).attr("astype")("bool");
          },
          py::arg("points"), "bool (...): the point's cell is in the workspace.")
      .def(
          "total_entropy",
          [](const OccupancyMap& m) {
            Reading lock(m);
            return m.total_entropy();
          },
          "Total workspace entropy in the map's unit (unknown cells at p = 0.5). O(1): maintained\n"
          "incrementally in 2^-50-nat fixed point, equal to recompute_total_entropy().")
      .def(
          "recompute_total_entropy",
          [](const OccupancyMap& m) {
            Reading lock(m);
            return m.recompute_total_entropy();
          },
          "Total workspace entropy by a full sweep over the mirror (for checks).")
      .def(
          "counts",
          [](const OccupancyMap& m) {
            CellCounts c;
            {
              Reading lock(m);
              c = m.counts();
            }
            return counts_dict(c);
          },
          "dict of workspace cell counts: free, occupied, unknown (and predicted, a subset of the "
          "first two).")
      .def(
          "recompute_counts",
          [](const OccupancyMap& m) {
            CellCounts c;
            {
              Reading lock(m);
              c = m.grid().recompute_counts();
            }
            return counts_dict(c);
          },
          "counts() by a full sweep (for checks).")
      .def(
          "occupied_cells",
          [](const OccupancyMap& m) {
            Reading lock(m);
            return m.occupied_cells();
          },
          "(M, 3) float64 centres of the occupied workspace cells, in flat-index order.")
      .def(
          "verify_mirror",
          [](const OccupancyMap& m) {
            Writing lock(m);  // brings the octree up to date
            return m.verify_mirror();
          },
          "Number of workspace cells whose dense mirror disagrees with the octree (0 = in sync).")
      .def(
          "log_odds_grid",
          [](const OccupancyMap& m) {
            return grid<float>(m, [&](std::int64_t i) { return m.grid().logodds(i); });
          },
          "(nx, ny, nz) float32 log-odds (0 for unknown cells), Fortran order (copy).")
      .def(
          "state_grid",
          [](const OccupancyMap& m) {
            return grid<std::int8_t>(
                m, [&](std::int64_t i) { return std::int8_t(m.grid().state(i)); });
          },
          "(nx, ny, nz) int8 states (0 free, 1 occupied, -1 unknown), Fortran order (copy).")
      .def(
          "flag_grid",
          [](const OccupancyMap& m) {
            return grid<std::uint8_t>(
                m, [&](std::int64_t i) { return std::uint8_t(m.grid().flag(i)); });
          },
          "(nx, ny, nz) uint8 flags (0 unknown, 1 observed, 2 predicted), Fortran order (copy).")
      .def(
          "entropy_grid",
          [](const OccupancyMap& m) {
            return grid<float>(m, [&](std::int64_t i) { return m.grid().entropy(i); });
          },
          "(nx, ny, nz) float32 cell entropies in the map's unit, Fortran order (copy).")
      .def(
          "save",
          [](const OccupancyMap& m, const py::handle& path) {
            const std::string p = path_arg(path);
            Writing lock(m);  // brings the octree up to date
            m.save(p);
          },
          py::arg("path"),
          "Write the octree: '.ot' (full probabilities) or '.bt' (free/occupied only); octovis "
          "reads both.")
      .def_static(
          "load",
          [](const py::handle& path, const py::object& bmin, const py::object& bmax,
             const py::object& options, const py::kwargs& kw) {
            const std::string p = path_arg(path);
            const OccupancyMapOptions o = options_with_keywords<OccupancyMapOptions>(options, kw);
            std::optional<Eigen::Vector3d> lo, hi;
            if (!bmin.is_none()) lo = vec3_arg(bmin, "bounds_min");
            if (!bmax.is_none()) hi = vec3_arg(bmax, "bounds_max");
            py::gil_scoped_release release;
            return std::make_shared<OccupancyMap>(OccupancyMap::load(p, lo, hi, o));
          },
          py::arg("path"), py::arg("bounds_min") = py::none(), py::arg("bounds_max") = py::none(),
          py::arg("options") = py::none(),
          "Read a '.ot' / '.bt' file. Without bounds the workspace is the tree's bounding box. "
          "Every\n"
          "cell read is flagged observed. FileNotFoundError if missing; ValueError naming the file "
          "if\n"
          "the extension is unknown or the data unreadable.")
      .def_property_readonly("resolution", &OccupancyMap::resolution, "cell edge (metres)")
      .def_property_readonly("num_cells", &OccupancyMap::num_cells, "cells in the workspace")
      .def_property_readonly(
          "shape",
          [](const OccupancyMap& m) {
            return py::make_tuple(m.dims()[0], m.dims()[1], m.dims()[2]);
          },
          "(nx, ny, nz) workspace cells per axis")
      .def_property_readonly(
          "bounds",
          [](const OccupancyMap& m) {
            return py::make_tuple(Eigen::Vector3d(m.bounds_min()), Eigen::Vector3d(m.bounds_max()));
          },
          "(min (3,), max (3,)): the cell-aligned workspace box in metres")
      .def_property_readonly(
          "min_key",
          [](const OccupancyMap& m) {
            return py::make_tuple(m.min_key()[0], m.min_key()[1], m.min_key()[2]);
          },
          "OctoMap key of workspace cell (0, 0, 0)")
      .def_property_readonly(
          "options", [](const OccupancyMap& m) { return OccupancyMapOptions(m.options()); },
          "the map's OccupancyMapOptions (a copy)")
      .def_property_readonly("entropy_unit",
                             [](const OccupancyMap& m) {
                               return OptionField<EntropyUnit>::get(m.options().entropy_unit);
                             })
      .def_property_readonly(
          "octree_num_nodes",
          [](const OccupancyMap& m) {
            Writing lock(m);  // brings the octree up to date
            return m.octree().size();
          },
          "nodes in the octree (all depths)")
      .def_property_readonly("octree_memory_bytes",
                             [](const OccupancyMap& m) {
                               Writing lock(m);
                               return m.octree().memoryUsage();
                             })
      .def_property_readonly(
          "grid_bricks",
          [](const OccupancyMap& m) {
            std::size_t allocated, total;
            {
              Reading lock(m);  // (without the GIL: no Python object made under it)
              allocated = m.grid().allocated_bricks();
              total = m.grid().layout().num_bricks();
            }
            return py::make_tuple(allocated, total);
          },
          "(allocated, total) bricks of 4 x 4 x 4 cells of the workspace grid: a brick holds "
          "cells of its own once written (and when it holds padding past the grid's upper "
          "faces); the others read as unknown from one shared brick")
      .def_property_readonly(
          "grid_memory_bytes",
          [](const OccupancyMap& m) {
            Reading lock(m);
            return m.grid().bytes();
          },
          "bytes the workspace grid holds: its allocated bricks' cells and its per-brick tables")
      .def("__repr__", [](const OccupancyMap& m) {
        CellCounts c;
        {
          Reading lock(m);
          c = m.counts();
        }
        std::ostringstream s;
        s << "<nbvkit.OccupancyMap " << m.resolution() << " m, " << m.dims()[0] << "x"
          << m.dims()[1] << "x" << m.dims()[2] << " cells: " << c.free << " free, " << c.occupied
          << " occupied, " << c.unknown << " unknown>";
        return s.str();
      });
}

}  // namespace nbv::bind
