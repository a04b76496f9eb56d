// Bindings of the coverage-planning blocks (nbv/coverage.hpp) and tours (nbv/tour.hpp).
#include "bindings.hpp"
#include "nbv/coverage.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/placement.hpp"
#include "nbv/surface_observations.hpp"
#include "nbv/tour.hpp"
#include "nbv/tour_plan.hpp"
#include "options.hpp"

#include <limits>
#include <optional>
#include <string>

namespace nbv::bind {
namespace {

template <class T>
using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;

template <class T>
Array<T> vector_arg(const py::dict& coverage, const char* key) {
  const std::string what = std::string("coverage['") + key + "']";
  Array<T> a;
  if constexpr (std::is_integral_v<T>)
    a = integer_array<T>(coverage[key], what);
  else
    a = Array<T>::ensure(coverage[key]);
  if (!a || a.ndim() != 1) throw py::value_error(what + " must be a 1-D numeric array");
  return a;
}

template <class T>
Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>> as_vector(const Array<T>& a) {
  return {a.data(), Eigen::Index(a.size())};
}

/// Throws ValueError unless the CSR arrays of `c` agree (K + 1 offsets from 0 to the element
/// count, never decreasing; one weight per element).
void check_coverage(const CoverageRef& c) {
  const Eigen::Index n = c.offsets.size();
  bool ok = n == c.status.size() + 1 && c.elements.size() == c.weights.size() &&
            (n == 0 || (c.offsets[0] == 0 && c.offsets[n - 1] == c.elements.size()));
  for (Eigen::Index i = 1; ok && i < n; ++i) ok = c.offsets[i] >= c.offsets[i - 1];
  if (!ok) throw py::value_error("coverage arrays are inconsistent");
}

/// Coverage sets, read in place: a CoverageSets (view_coverage's), or a dict of its arrays as
/// a script builds them (offsets, elements, weights, status; pooled_from and pool_cap), checked;
/// numpy arrays of the right type are not copied (a plant's plan: 50 M elements).
struct CoverageArg {
  explicit CoverageArg(const py::handle& coverage) {
    if (py::isinstance<ViewCoverage>(coverage)) {
      owner = py::reinterpret_borrow<py::object>(coverage);
      ref.emplace(coverage.cast<const ViewCoverage&>());
      return;
    }
    if (!py::isinstance<py::dict>(coverage))
      throw py::type_error(
          "coverage must be a CoverageSets (view_coverage's) or a dict of its "
          "arrays, got " +
          std::string(py::str(py::type::of(coverage))));
    const auto d = py::reinterpret_borrow<py::dict>(coverage);
    offsets = vector_arg<std::int64_t>(d, "offsets");
    elements = vector_arg<std::int32_t>(d, "elements");
    weights = vector_arg<float>(d, "weights");
    status = vector_arg<std::int8_t>(d, "status");
    ref.emplace(as_vector(offsets), as_vector(elements), as_vector(weights), as_vector(status));
    if (d.contains("pool_cap") && d.contains("pooled_from"))
      pooled(*ref, d["pooled_from"].cast<std::int64_t>(), d["pool_cap"].cast<double>());
    check_coverage(*ref);
    for (Eigen::Index i = 0; i < ref->elements.size(); ++i) {  // a script's: each value checked
      if (ref->elements[i] < 0)
        throw py::value_error("coverage elements must be >= 0 (cell id * 2 + side), got " +
                              std::to_string(ref->elements[i]));
      const float w = ref->weights[i];
      if (!(std::isfinite(w) && w >= 0.0f))
        throw py::value_error("coverage weights must be finite and >= 0, got " + fmt(w) +
                              " at element " + std::to_string(i));
    }
  }
  /// Sets the pooled elements of `c` (pooled_from -1 or pool_cap 0: none), checked.
  static void pooled(CoverageRef& c, std::int64_t pooled_from, double pool_cap) {
    if (!(std::isfinite(pool_cap) && pool_cap >= 0.0))
      throw py::value_error("coverage pool_cap must be a finite number >= 0");
    if (pool_cap > 0.0 && pooled_from < 0)
      throw py::value_error("coverage pooled_from must be >= 0 with a pool_cap above 0");
    c.pool_cap = pool_cap;
    c.pooled_from = pool_cap > 0.0 ? pooled_from : ViewCoverage::kNotPooled;
  }
  py::object owner;  // (kept alive for ref)
  Array<std::int64_t> offsets;
  Array<std::int32_t> elements;
  Array<float> weights;
  Array<std::int8_t> status;
  std::optional<CoverageRef> ref;
};

/// select_tours over the arguments of select_tour and select_tours, checked, without the GIL:
/// a (views, gains) tuple per charge.
std::vector<py::tuple> tours_arg(const py::handle& coverage, const py::handle& positions,
                                 const py::handle& start, double rate, double min_gain,
                                 int max_views, const std::vector<bool>& charges) {
  const CoverageArg cov(coverage);
  auto p = points_arg(positions, "candidate positions");
  const Eigen::Vector3d st = vec3_arg(start, "tour start");
  if (max_views < 0) throw py::value_error("max_views must be >= 0");
  auto pm = p.map();
  std::vector<CoverSelection> s;
  {
    py::gil_scoped_release release;
    s = select_tours(*cov.ref, pm, st, rate, min_gain, max_views, charges);
  }
  std::vector<py::tuple> out;
  for (const CoverSelection& t : s)
    out.push_back(py::make_tuple(py::cast(t.views), py::cast(t.gains)));
  return out;
}

/// TourPlanOptions from the keywords of plan_tour and plan_tour_over.
TourPlanOptions plan_options(const std::string& selection, double min_gain, double rate,
                             double cell_area, int max_views) {
  if (selection != "insertion" && selection != "cover")
    throw py::value_error("selection must be 'insertion' or 'cover', got '" + selection + "'");
  TourPlanOptions o;
  o.insertion = selection == "insertion";
  o.min_gain = min_gain;
  o.rate = rate;
  o.cell_area = cell_area;
  o.max_views = max_views;
  o.validate();  // std::invalid_argument: pybind11 raises ValueError
  return o;
}

/// view_coverage over candidates `cm` from `cur`, its options from Python, checked; the map
/// and the camera observations read-locked and the memo held, without the GIL.
ViewCoverage coverage_call(const OccupancyMap& map, const SurfaceObservations& surface,
                           const ViewPosesRef& cm, const Pose& cur, const py::object& camera,
                           const py::object& utility, const py::object& validity,
                           const std::shared_ptr<CoverageMemo>& memo, double min_gain,
                           int coarse_stride, bool pool_unknown, double coarse_margin) {
  const auto cam = OptionsClass<ViewCameraModel>::from(camera, "camera");
  auto u = OptionsClass<UtilityOptions>::from(utility, "utility");
  const auto v = OptionsClass<ValidityOptions>::from(validity, "validity");
  Reading2 reading(map, &surface);
  std::unique_lock<std::mutex> lock;  // one call at a time per memo
  if (memo) lock = std::unique_lock<std::mutex>(memo->mutex());
  return view_coverage(grid_view(map, &surface), cm, cur, cam, u, v, memo.get(), min_gain,
                       coarse_stride, pool_unknown, coarse_margin);
}

/// A read-only array property of a bound class: its member `field` (a vector, an Eigen vector or
/// an Eigen (N, C) row-major matrix), viewed in place.
template <class C, class V>
void def_array_view(py::class_<C, std::shared_ptr<C>>& cls, const char* name, V C::*field,
                    const char* doc) {
  cls.def_property_readonly(
      name,
      [field](const py::object& self) {
        const V& v = self.cast<const C&>().*field;
        if constexpr (std::is_base_of_v<Eigen::EigenBase<V>, V>) {
          if constexpr (V::ColsAtCompileTime != 1)
            return owned_array(self, v.data(), v.rows(), v.cols());
        }
        return owned_array(self, v.data(), py::ssize_t(v.size()));
      },
      doc);
}

/// A vector as a numpy array of its type (an int index array even when empty).
template <class T>
py::array_t<T> array_of(const std::vector<T>& v) {
  return py::array_t<T>(static_cast<py::ssize_t>(v.size()), v.data());
}

/// The first three columns of candidate views: their positions.
Points positions_of(const ViewPosesRef& views) {
  Points p(views.rows(), 3);
  for (Eigen::Index k = 0; k < views.rows(); ++k) p.row(k) = views.block<1, 3>(k, 0);
  return p;
}

/// The targets within `within` metres of the map's occupied cells (near_points).
SurfaceTargets near_surface(const OccupancyMap& map, const SurfaceTargets& t, double within) {
  const std::vector<std::uint8_t> keep =
      near_points(map.occupied_cells(false), t.positions, within, map.resolution());
  const auto n = Eigen::Index(std::count(keep.begin(), keep.end(), std::uint8_t(1)));
  SurfaceTargets out;
  out.positions.resize(n, 3);
  out.normals.resize(n, 3);
  out.kind.resize(n);
  out.weight.resize(n);
  for (Eigen::Index r = 0, i = 0; r < t.positions.rows(); ++r) {
    if (!keep[std::size_t(r)]) continue;
    out.positions.row(i) = t.positions.row(r);
    out.normals.row(i) = t.normals.row(r);
    out.kind[i] = t.kind[r];
    out.weight[i++] = t.weight[r];
  }
  return out;
}

}  // namespace

void init_planning(py::module_& m) {
  {
    OptionsClass<SurfaceTargetOptions> binder(m, "SurfaceTargetOptions",
                                              "Which cells surface_targets reports, and how.");
    using S = SurfaceTargetOptions;
    NBV_SURFACE_TARGET_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  py::class_<SurfaceTargets, std::shared_ptr<SurfaceTargets>> targets(m, "SurfaceTargets", R"doc(
Cells to place views at (surface_targets, exploration_targets), in grid order: positions (T, 3)
(cell centres), normals (T, 3) (unit: the direction from which the cell can still add surface),
kind (T,) int8 (0 observed surface not yet covered from an open side, 1 predicted, 2 frontier:
unknown between known free space and surface, 3 exploration: unknown space on the face of known
free space, away from the surface) and weight (T,) (1, the predicted probability, or
frontier_weight). The arrays are read-only views into this object (no copy); len() is T. Built
from arrays (a script's own targets): SurfaceTargets(positions, normals, weight[, kind]),
copied and checked (finite, normals not zero and scaled to unit length, weights >= 0, kind 0-3,
default 0).)doc");
  targets
      .def(py::init([](const py::handle& positions, const py::handle& normals,
                       const py::handle& weight, const py::object& kind) {
             auto t = std::make_shared<SurfaceTargets>();
             t->positions = points_arg(positions, "positions").map();
             t->normals = points_arg(normals, "normals").map();
             const Eigen::Index n = t->positions.rows();
             if (t->normals.rows() != n)
               throw py::value_error("SurfaceTargets: " + std::to_string(n) + " positions but " +
                                     std::to_string(t->normals.rows()) + " normals");
             for (Eigen::Index i = 0; i < n; ++i) {  // unit, as the planner's own
               const double len = t->normals.row(i).norm();
               if (!(len > 1e-9))
                 throw py::value_error("SurfaceTargets: normal " + std::to_string(i) +
                                       " is zero: each is the direction its cell is seen from");
               t->normals.row(i) /= len;
             }
             const auto w = Array<double>::ensure(weight);
             if (!w || w.ndim() != 1 || w.shape(0) != n)
               throw py::value_error("SurfaceTargets: weight must be (" + std::to_string(n) +
                                     ",) numbers, one per position");
             t->weight = Eigen::Map<const Eigen::VectorXd>(w.data(), n);
             if (!(t->weight.array().isFinite() && t->weight.array() >= 0).all())
               throw py::value_error("SurfaceTargets: weights must be finite and >= 0");
             t->kind.setZero(n);
             if (!kind.is_none()) {
               const auto k = integer_array<std::int64_t>(kind, "SurfaceTargets: kind");
               if (k.ndim() != 1 || k.shape(0) != n)
                 throw py::value_error("SurfaceTargets: kind must be (" + std::to_string(n) +
                                       ",) integers, one per position");
               for (Eigen::Index i = 0; i < n; ++i) {
                 if (k.at(i) < 0 || k.at(i) > std::int64_t(TargetKind::Exploration))
                   throw py::value_error("SurfaceTargets: kind " + std::to_string(k.at(i)) +
                                         " is not 0-3");
                 t->kind[i] = std::int8_t(k.at(i));
               }
             }
             return t;
           }),
           py::arg("positions"), py::arg("normals"), py::arg("weight"),
           py::arg("kind") = py::none())
      .def("__len__", [](const SurfaceTargets& t) { return t.weight.size(); })
      .def("__repr__", [](const SurfaceTargets& t) {
        return "SurfaceTargets(" + std::to_string(t.weight.size()) + " cells)";
      });
  def_array_view(targets, "positions", &SurfaceTargets::positions,
                 "(T, 3) float64: the cells' centres");
  def_array_view(targets, "normals", &SurfaceTargets::normals,
                 "(T, 3) float64: unit directions from which each cell can still add surface");
  def_array_view(targets, "kind", &SurfaceTargets::kind,
                 "(T,) int8: 0 observed, 1 predicted, 2 frontier, 3 exploration");
  def_array_view(targets, "weight", &SurfaceTargets::weight, "(T,) float64: each cell's weight");
  m.def(
      "surface_targets",
      [](const OccupancyMap& map, const SurfaceObservations& surface, const py::object& options) {
        const auto o = OptionsClass<SurfaceTargetOptions>::from(options, "options");
        auto t = std::make_shared<SurfaceTargets>();
        {
          Reading2 reading(map, &surface);
          *t = surface_targets(grid_view(map, &surface), o);
        }
        return t;
      },
      py::arg("map"), py::arg("surface"), py::arg("options") = py::none(),
      R"doc(Cells whose surface still needs observing, in grid order, as a SurfaceTargets (kinds 0
observed surface not yet covered from an open side, 1 predicted, 2 frontier).)doc");
  m.def(
      "exploration_targets",
      [](const OccupancyMap& map, const py::object& lo, const py::object& hi,
         std::optional<double> within) {
        if (lo.is_none() != hi.is_none())
          throw py::value_error("exploration_targets: give both lo and hi, or neither");
        Eigen::Vector3i a = Eigen::Vector3i::Zero(), b = Eigen::Vector3i::Zero();
        if (!lo.is_none()) {
          const Eigen::Vector3d la = vec3_arg(lo, "lo"), hb = vec3_arg(hi, "hi");
          for (int k = 0; k < 3; ++k) {
            // cell indices: clamp before the cast (a box far outside the grid is empty)
            a[k] = int(std::clamp(std::floor(la[k]), -1.0, 1e9));
            b[k] = int(std::clamp(std::floor(hb[k]), -1.0, 1e9));
          }
        }
        auto out = std::make_shared<SurfaceTargets>();
        {
          Reading lock(map);  // releases the GIL
          const GridView g = grid_view(map);
          if (lo.is_none() && !structure_extent(g, a, b)) a = b = Eigen::Vector3i::Zero();
          *out = exploration_as_targets(exploration_targets(g, a, b), map.bounds_min(), a,
                                        map.resolution());
          if (within) *out = near_surface(map, *out, *within);
        }
        return out;
      },
      py::arg("map"), py::arg("lo") = py::none(), py::arg("hi") = py::none(),
      py::arg("within") = py::none(),
      R"doc(The unknown space a view could open, in one pass over the map's bricks: unknown cells
with a known free face neighbour and no occupied or predicted one, among the cells of the box
[lo, hi) (cell indices, clipped to the grid; neighbours outside it count as neither). Without a
box, the box of the cells known occupied or predicted grown by one cell (empty when there are
none). A SurfaceTargets of kind 3 (exploration), weight 1: each cell's centre, looked at from the
unit sum of the directions to its free face neighbours (cells free on opposite faces only, with
no such side, are left out). within (metres): only the cells near the surface the map shows, as
near_surface keeps them.)doc");
  m.def(
      "near_surface",
      [](const OccupancyMap& map, const py::handle& points, double within) {
        const PointsArg pts = points_arg(points, "points");
        std::vector<std::uint8_t> keep;
        {
          Reading lock(map);  // releases the GIL
          keep = near_points(map.occupied_cells(false), pts.map(), within, map.resolution());
        }
        py::array_t<bool> out(static_cast<py::ssize_t>(keep.size()));
        std::copy(keep.begin(), keep.end(), out.mutable_data());
        return out;
      },
      py::arg("map"), py::arg("points"), py::arg("within"),
      R"doc((N,) bool: whether each point (N, 3) lies within about `within` metres (> 0) of a cell
the map holds occupied (its observed and predicted surface; none: all False). Distances are
measured on a grid of max(within / 4, resolution) cells, from a point's cell to the nearest
occupied one (as scipy's distance_transform_edt measures them there: exact to a quarter of
`within` times the square root of 3).)doc");
  py::class_<CoverageMemo, std::shared_ptr<CoverageMemo>> coverage_memo(m, "CoverageMemo", R"doc(
What view_coverage's walks found, kept from one call to the next over the same map and surface
record (pass it as memo=). A view asked for again at the same pose and pitch (bit for bit) is
answered from its record while none of the bricks of 4 x 4 x 4 cells that meet its frustum (the
camera's field of view out to max_range) has changed in the camera observations since, and none
within one brick of them in the map: the same coverage set and status, without walking its rays.
Validity is checked anew each call.
Entries that none of the last keep_calls calls used are dropped, and beyond max_bytes (default
256 MiB) those used longest ago; another map, record, camera or utility clears it.)doc");
  coverage_memo
      .def(py::init<int, std::size_t>(), py::arg("keep_calls") = 3,
           py::arg("max_bytes") = CoverageMemo::kDefaultMaxBytes)
      .def_property_readonly("max_bytes", &CoverageMemo::max_bytes);
  def_memo_members(coverage_memo, true);

  py::class_<ViewCoverage, std::shared_ptr<ViewCoverage>> sets(m, "CoverageSets", R"doc(
What candidate views would newly cover (view_coverage): view k's elements (cell id * 2 + the
side of the cell seen; past every cell's, pooled bricks of unknown space) and their weights are
entries offsets[k]:offsets[k + 1] of elements and weights. The arrays are read-only views into
this object (no copy). len() is the number of views. Built from arrays (a script's own sets, or
sets with elements added): CoverageSets(offsets, elements, weights, status[, pooled_from,
pool_cap]), copied and checked; each valid view's gain is then the sum of its weights.)doc");
  sets.def(py::init([](const py::handle& offsets, const py::handle& elements,
                       const py::handle& weights, const py::handle& status,
                       std::int64_t pooled_from, double pool_cap) {
             py::dict d;
             d["offsets"] = offsets;
             d["elements"] = elements;
             d["weights"] = weights;
             d["status"] = status;
             d["pooled_from"] = pooled_from;
             d["pool_cap"] = pool_cap;
             const CoverageArg arg(d);
             const CoverageRef& r = *arg.ref;
             auto c = std::make_shared<ViewCoverage>();
             c->offsets = r.offsets;
             c->elements = r.elements;
             c->weights = r.weights;
             c->status = r.status;
             c->pooled_from = r.pooled_from;
             c->pool_cap = r.pool_cap;
             const Eigen::Index k = r.status.size();
             c->pruned.setZero(k);
             c->gain.setZero(k);
             for (Eigen::Index v = 0; v < k; ++v)
               if (r.status[v] == 0)
                 for (std::int64_t e = r.offsets[v]; e < r.offsets[v + 1]; ++e)
                   c->gain[v] += r.weights[e];
             return c;
           }),
           py::arg("offsets"), py::arg("elements"), py::arg("weights"), py::arg("status"),
           py::arg("pooled_from") = -1, py::arg("pool_cap") = 0.0)
      .def("__len__", [](const ViewCoverage& c) { return c.status.size(); })
      .def_property_readonly(
          "pruned",
          [](const py::object& self) {
            const auto& c = self.cast<const ViewCoverage&>();
            static_assert(sizeof(bool) == sizeof(std::uint8_t), "bool is a byte");
            return owned_array(self, reinterpret_cast<const bool*>(c.pruned.data()),
                               c.pruned.size());
          },
          "(K,) bool: valid views left unwalked on their coarse estimate (their sets empty)")
      .def_property_readonly(
          "pooled_from",
          [](const ViewCoverage& c) { return c.pool_cap > 0.0 ? c.pooled_from : std::int64_t(-1); },
          "the first pooled element (-1: none pooled)")
      .def_readonly("pool_cap", &ViewCoverage::pool_cap, "the weight a pooled brick holds at most")
      .def("__repr__", [](const ViewCoverage& c) {
        return "CoverageSets(" + std::to_string(c.status.size()) + " views, " +
               std::to_string(c.elements.size()) + " elements)";
      });

  def_array_view(sets, "offsets", &ViewCoverage::offsets,
                 "(K + 1,) int64: view k's entries are offsets[k]:offsets[k + 1]");
  def_array_view(sets, "elements", &ViewCoverage::elements,
                 "int32: cell id * 2 + the side seen; pooled bricks from pooled_from on");
  def_array_view(sets, "weights", &ViewCoverage::weights,
                 "float32: what each element adds to the view's gain");
  def_array_view(sets, "status", &ViewCoverage::status,
                 "(K,) int8: evaluate_views' status of each view (0 valid)");
  def_array_view(
      sets, "gain", &ViewCoverage::gain,
      "(K,) float64: a valid view's gain in cells (a pruned one's estimate); 0 otherwise");

  m.def(
      "view_coverage",
      [](const OccupancyMap& map, const SurfaceObservations& surface, const py::handle& candidates,
         const py::handle& current, const py::object& camera, const py::object& utility,
         const py::object& validity, const std::shared_ptr<CoverageMemo>& memo, double min_gain,
         int coarse_stride, bool pool_unknown, double coarse_margin) {
        const ViewPosesArg c = view_poses_arg(candidates, "candidates");
        ViewCoverage cov =
            coverage_call(map, surface, c.map(), pose_arg(current, "current pose"), camera, utility,
                          validity, memo, min_gain, coarse_stride, pool_unknown, coarse_margin);
        return std::make_shared<ViewCoverage>(std::move(cov));  // handed to numpy as it is
      },
      py::arg("map"), py::arg("surface"), py::arg("candidates"), py::arg("current"),
      py::arg("camera") = py::none(), py::arg("utility") = py::none(),
      py::arg("validity") = py::none(), py::arg("memo") = nullptr, py::arg("min_gain") = 0.0,
      py::arg("coarse_stride") = 0, py::arg("pool_unknown") = false, py::arg("coarse_margin") = 1.0,
      R"doc(What each candidate view ((K, 4) rows x, y, z, yaw, or (K, 5) with the gimbal's pitch,
as evaluate_views) would newly cover, as the surface utility credits it
(utility: its priors and cone; the name is ignored), a CoverageSets: CSR arrays offsets (K +
1,), elements (int32: cell id * 2 + the side of the cell seen, see nbv/coverage.hpp) and
weights, and status (K,) as evaluate_views. memo: a CoverageMemo kept across calls over this map
and surface record (the same arrays, fewer walks). min_gain > 0 (in cells, as select_tours takes
it): a valid candidate whose weights sum below it keeps its status and an empty set;
select_tours at that min_gain or above chooses the same. coarse_stride > 0 with min_gain > 0: a
candidate is first walked along every coarse_stride-th ray across and down, and one whose gain
so estimated (the rays' gain plus one cell, times all rays over those) is below coarse_margin x
min_gain gets an empty set without its whole walk: pruned (K,) bool marks them (an estimate:
surface near the camera, reached by several rays a cell, is estimated high; with stride 1 and
margin 1, the arrays are those without it; a margin above 1 walks fewer views, leaving out a few
that would reach min_gain). gain (K,) float64: a valid view's gain in cells (its walk's sum, as
its weights'; a pruned view's estimate), 0 for the others. pool_unknown: the credits of unknown
cells at the utility's unknown_prior (not next to surface; most of a view's elements, little of
its weight) are pooled per brick of 4 x 4 x 4 cells, one element each (2 x the grid's storage
cells + the brick, past every cell's element), weighing their sum: the same gains and status,
far fewer elements. pooled_from (int; -1 when not pooled) and pool_cap (float): the first pooled
element, and the weight a brick holds at most; select_cover and select_tours count a pooled
brick's cover as a share of it (nbv/coverage.hpp).)doc");
  m.def(
      "select_cover",
      [](const py::handle& coverage, double min_gain, int max_views) {
        const CoverageArg cov(coverage);
        if (max_views < 0) throw py::value_error("max_views must be >= 0");
        CoverSelection s;
        {
          py::gil_scoped_release release;
          s = select_cover(*cov.ref, min_gain, max_views);
        }
        return py::make_tuple(py::cast(s.views), py::cast(s.gains));
      },
      py::arg("coverage"), py::arg("min_gain") = 1.0, py::arg("max_views") = 1000,
      R"doc(Greedy weighted set cover over a view_coverage result: (views, gains), the chosen
candidate indices in the order chosen and each one's marginal gain, until the best adds less
than min_gain or max_views are chosen.)doc");
  m.def(
      "select_tour",
      [](const py::handle& coverage, const py::handle& positions, const py::handle& start,
         double rate, double min_gain, int max_views, bool charge_transit) {
        const auto tour =
            tours_arg(coverage, positions, start, rate, min_gain, max_views, {charge_transit});
        return tour[0];
      },
      py::arg("coverage"), py::arg("positions"), py::arg("start"), py::arg("rate"),
      py::arg("min_gain") = 1.0, py::arg("max_views") = 1000, py::arg("charge_transit") = true,
      R"doc(Prize-collecting tour over a view_coverage result by greedy cheapest insertion:
(views, gains) in tour order from start. A candidate (positions (K, 3)) enters where it lengthens
the open tour least, the one maximising its new coverage - rate x that extra length first, until
none adds min_gain with a positive value. rate: coverage weight per metre. charge_transit=False:
the first view enters free of the flight from start to it, so that a far cluster that pays for
its transit only as a whole can form (judge the transit afterwards, e.g. by prize
collection).)doc");
  m.def(
      "select_tours",
      [](const py::handle& coverage, const py::handle& positions, const py::handle& start,
         double rate, double min_gain, int max_views, const std::vector<bool>& charges) {
        return tours_arg(coverage, positions, start, rate, min_gain, max_views, charges);
      },
      py::arg("coverage"), py::arg("positions"), py::arg("start"), py::arg("rate"),
      py::arg("min_gain") = 1.0, py::arg("max_views") = 1000,
      py::arg("charges") = std::vector<bool>{true, false},
      R"doc(select_tour once for each of `charges` (its charge_transit), over one inverse of the
coverage built once, the tours in parallel: [(views, gains), ...], the same as a select_tour call
each.)doc");
  m.def(
      "place_patch_views",
      [](const py::handle& centers, const py::handle& normals,
         const std::vector<double>& horizontal, const std::vector<double>& reach, double half,
         double mount, double mount_yaw, double spread, bool gimbal, double lo_pitch,
         double hi_pitch) {
        auto c = points_arg(centers, "patch centers");
        auto n = points_arg(normals, "patch normals");
        const PlacementGeometry geometry{half,   mount,    mount_yaw, spread,
                                         gimbal, lo_pitch, hi_pitch,  reach};
        PlacedViews v;
        {
          py::gil_scoped_release release;
          v = place_patch_views(c.map(), n.map(), horizontal, geometry);
        }
        return py::make_tuple(std::move(v.poses), py::array(py::cast(v.owner)), std::move(v.bands));
      },
      py::arg("centers"), py::arg("normals"), py::arg("horizontal"), py::arg("reach"),
      py::arg("half"), py::arg("mount"), py::arg("mount_yaw"), py::arg("spread"), py::arg("gimbal"),
      py::arg("lo_pitch"), py::arg("hi_pitch"),
      R"doc(The views placement.place_views aims at patches (centers, unit normals (P, 3);
horizontal (P,): math.hypot of each normal's x and y), before they are moved into the
navigation space: (poses (K, 5) x, y, z, yaw, pitch; owner (K,) the patch of each; bands (K, 2)
the lowest and highest elevation in view, radians). reach: the stand-offs (m); half: half the
vertical field of view less the elevation margin; mount, mount_yaw: the mount's pitch (> 0
down) and yaw; spread: the side views' azimuth either side of the normal (0: none); gimbal:
also face by the gimbal's pitch, within [lo_pitch, hi_pitch], patches a level view cannot.)doc");
  m.def(
      "solve_tour",
      [](const py::handle& points, const py::handle& start, bool improve) {
        auto p = points_arg(points, "tour points");
        const Eigen::Vector3d st = vec3_arg(start, "tour start");
        auto pm = p.map();
        Tour t;
        {
          py::gil_scoped_release release;
          t = solve_tour(pm, st, improve);
        }
        return py::make_tuple(py::cast(t.order), t.length);
      },
      py::arg("points"), py::arg("start"), py::arg("improve") = true,
      R"doc(Open tour from start through every point (N, 3): (order, length). Nearest neighbour,
then (improve) 2-opt and Or-opt moves until none shortens it. Deterministic.)doc");
  m.def(
      "solve_tour_matrix",
      [](const Eigen::MatrixXd& D, bool improve) {
        Tour t;
        {
          py::gil_scoped_release release;
          t = solve_tour_matrix(D, improve);
        }
        return py::make_tuple(py::cast(t.order), t.length);
      },
      py::arg("distances"), py::arg("improve") = true,
      R"doc(The same over a symmetric distance matrix (N + 1, N + 1) whose row/column 0 is the
start (inf: impassable). order indexes the N views (matrix index - 1).)doc");
  py::class_<TourPlan>(m, "TourPlan", R"doc(
A coverage tour's plan (plan_tour, plan_tour_over): the candidates the selection took, each with
the area it adds, and the flight order of those prize collection kept.)doc")
      .def_property_readonly(
          "chosen", [](const TourPlan& p) { return array_of(p.chosen); },
          "(C,) candidate indices: an insertion tour's in its insertion order, a set cover's as it "
          "took them")
      .def_property_readonly(
          "gains", [](const TourPlan& p) { return array_of(p.gains); },
          "(C,) m^2 each chosen view adds, when it was taken")
      .def_property_readonly(
          "order", [](const TourPlan& p) { return array_of(p.order); },
          "(V,) the flight order of the views kept: indices into chosen")
      .def_property_readonly(
          "flight", [](const TourPlan& p) { return array_of(p.flight()); },
          "(V,) the candidate indices of the kept views in flight order: chosen[order]")
      .def_readonly("value", &TourPlan::value,
                    "m^2: the kept views' gains - rate x the kept tour's length")
      .def_readonly("length", &TourPlan::length,
                    "m: from the start through the kept views, in order (0 with none)")
      .def_readonly("unpaid", &TourPlan::unpaid,
                    "with no view kept: the views adding min_gain that no tour paid for")
      .def_readonly("unpaid_area", &TourPlan::unpaid_area, "m^2 those unpaid views add")
      .def("__repr__", [](const TourPlan& p) {
        return "TourPlan(" + std::to_string(p.order.size()) + " of " +
               std::to_string(p.chosen.size()) + " chosen views kept, " + std::to_string(p.length) +
               " m, value " + std::to_string(p.value) + " m^2)";
      });
  m.def(
      "plan_tour",
      [](const OccupancyMap& map, const SurfaceObservations& surface, const py::handle& candidates,
         const py::handle& current, const py::object& camera, const py::object& utility,
         const py::object& validity, const std::shared_ptr<CoverageMemo>& memo,
         const std::string& selection, double min_gain, double rate, int max_views,
         int coarse_stride, double coarse_margin, bool pool_unknown) {
        const ViewPosesArg c = view_poses_arg(candidates, "candidates");
        const auto cm = c.map();
        const Pose cur = pose_arg(current, "current pose");
        const double cell = map.resolution() * map.resolution();
        const TourPlanOptions o = plan_options(selection, min_gain, rate, cell, max_views);
        const Points positions = positions_of(cm);
        const ViewCoverage cov =
            coverage_call(map, surface, cm, cur, camera, utility, validity, memo, o.min_gain / cell,
                          coarse_stride, pool_unknown, coarse_margin);
        py::gil_scoped_release release;
        return plan_tour(CoverageRef(cov), positions, Eigen::Vector3d(cur.x, cur.y, cur.z), o);
      },
      py::arg("map"), py::arg("surface"), py::arg("candidates"), py::arg("current"),
      py::arg("camera") = py::none(), py::arg("utility") = py::none(),
      py::arg("validity") = py::none(), py::arg("memo") = nullptr,
      py::arg("selection") = "insertion", py::arg("min_gain") = 0.0, py::arg("rate") = 0.0,
      py::arg("max_views") = 1000, py::arg("coarse_stride") = 0, py::arg("coarse_margin") = 1.0,
      py::arg("pool_unknown") = false,
      R"doc(A coverage tour's plan over candidate views from the vehicle's pose `current`, in one
call: what each would newly cover (view_coverage, with the map, the surface record, camera,
utility, validity, memo, coarse_stride, coarse_margin and pool_unknown as it takes them, at
min_gain), then the views chosen and their flight order (plan_tour_over). min_gain: m^2 a view
must add; rate: m^2 per metre of flight a view must pay for; a coverage weight of 1 is the
map's cell face. Returns a TourPlan; the coverage sets are freed before it returns.)doc");
  m.def(
      "plan_tour_over",
      [](const py::handle& coverage, const py::handle& positions, const py::handle& start,
         double cell_area, const std::string& selection, double min_gain, double rate,
         int max_views) {
        const CoverageArg cov(coverage);
        auto p = points_arg(positions, "candidate positions");
        const Eigen::Vector3d st = vec3_arg(start, "tour start");
        const TourPlanOptions o = plan_options(selection, min_gain, rate, cell_area, max_views);
        auto pm = p.map();
        py::gil_scoped_release release;
        return plan_tour(*cov.ref, pm, st, o);
      },
      py::arg("coverage"), py::arg("positions"), py::arg("start"), py::arg("cell_area"),
      py::arg("selection") = "insertion", py::arg("min_gain") = 0.0, py::arg("rate") = 0.0,
      py::arg("max_views") = 1000,
      R"doc(A coverage tour's plan over view_coverage's sets (a dict, as select_tours takes it) of
candidates at positions (K, 3), from start. selection 'insertion': the select_tours tours (the
first transit charged, and free), each ordered by the shorter of its insertion order and
solve_tour over its views, then prize-collected (prize_collect); the one worth more is the plan
(ties: the one charged its transit). 'cover': select_cover's views, solve_tour, prize
collection. min_gain (m^2), rate (m^2 per metre) and cell_area (m^2 of a weight of 1). With no
view kept, unpaid and unpaid_area give what select_cover takes at min_gain. A TourPlan.)doc");
  m.def(
      "prize_collect",
      [](const py::handle& start, const py::handle& points, const std::vector<double>& gains,
         const std::vector<int>& order, double rate) {
        const Eigen::Vector3d st = vec3_arg(start, "tour start");
        auto p = points_arg(points, "tour points");
        if (!std::isfinite(rate)) throw py::value_error("rate must be finite");
        return prize_collect(st, p.map(), gains, order, rate);
      },
      py::arg("start"), py::arg("points"), py::arg("gains"), py::arg("order"), py::arg("rate"),
      R"doc(Drops stretches of the open tour `order` (indices into points (N, 3); gains (N,) m^2)
from start while some run of consecutive views adds less than rate m^2 per metre of the flight
its removal saves (a single view's detour, or a far cluster's transit there and back), the worst
deficit (rate x saving - gain) first: the kept order (a list).)doc");
}

}  // namespace nbv::bind
