// Shared helpers of the pybind11 bindings: argument conversion with shape checks.
#pragma once

#include "nbv/common.hpp"
#include "nbv/views.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>

namespace nbv {
class SurfaceCloud;
}  // namespace nbv

namespace nbv::bind {

namespace py = pybind11;

/// A read-only numpy view of `n` rows (each `row` values) of T at `data`, kept alive by `owner`.
template <typename T>
inline py::array owned_array(const py::handle& owner, const T* data, py::ssize_t n,
                             py::ssize_t row = 0) {
  std::vector<py::ssize_t> shape{n};
  if (row) shape.push_back(row);
  // no storage to point into when empty
  py::array a =
      n ? py::array(py::dtype::of<T>(), shape, data, owner) : py::array(py::dtype::of<T>(), shape);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

/// Throws ValueError naming `what` if `given` holds complex numbers (numpy's cast would keep the
/// real parts with only a warning) or bools (a mask is not numbers: True read as 1).
inline void require_real_dtype(const py::array& given, const std::string& what) {
  const char kind = given.dtype().kind();
  if (kind == 'c' || kind == 'b')
    throw py::value_error(what + " must be " +
                          (kind == 'c' ? "real numbers, got complex" : "numbers, got bools") +
                          " (dtype " + std::string(py::str(given.dtype())) + ")");
}

/// An array-like of integers as a C-contiguous array of T: an array of T as it is (no copy, no
/// pass); any other integer dtype (any width, either byte order) and whole-number floats
/// converted once every value is checked to fit T. A fraction, a non-finite or complex value, a
/// value T cannot hold (numpy's cast would wrap or truncate it without a word) or a non-numeric
/// array raises ValueError naming `what`.
template <typename T>
py::array_t<T, py::array::c_style | py::array::forcecast> integer_array(const py::handle& obj,
                                                                        const std::string& what) {
  using Out = py::array_t<T, py::array::c_style | py::array::forcecast>;
  py::array given;
  try {
    given = py::array::ensure(obj);
  } catch (const py::error_already_set&) {
  }
  if (!given) throw py::value_error(what + " must be an array of integers");
  if (given.dtype().kind() == 'b')  // a mask is not indices: True read as 1
    throw py::value_error(what + " must be integers, got bools (dtype bool)");
  // an array of T (its dtype equal, not only the same object: a pickled array's is another)
  if (py::isinstance<py::array_t<T>>(given)) {
    if (Out out = Out::ensure(given)) return out;
    PyErr_Clear();
    throw py::value_error(what + " could not be read as integers");
  }
  const auto refuse = [&](const std::string& v, const std::string& why) {
    throw py::value_error(what + ": " + v + " " + why);
  };
  const std::string fits = std::string("does not fit ") + (sizeof(T) == 1   ? "int8"
                                                           : sizeof(T) == 4 ? "int32"
                                                                            : "int64");
  // the values are checked in the array they are cast from (wider ints or float64)
  py::array checked;
  const char kind = given.dtype().kind();
  if (kind == 'u') {
    const auto u =
        py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(given);
    for (py::ssize_t i = 0; u && i < u.size(); ++i)
      if (u.data()[i] > static_cast<std::uint64_t>(std::numeric_limits<T>::max()))
        refuse(std::to_string(u.data()[i]), fits);
    checked = u;
  } else if (kind == 'i') {
    const auto v =
        py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(given);
    for (py::ssize_t i = 0; v && i < v.size(); ++i)
      if (v.data()[i] < std::numeric_limits<T>::min() ||
          v.data()[i] > std::numeric_limits<T>::max())
        refuse(std::to_string(v.data()[i]), fits);
    checked = v;
  } else if (kind == 'f') {
    const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(given);
    // [-2^(b-1), 2^(b-1)): both bounds exact in double (T's max itself may round up to 2^63)
    const double lo = static_cast<double>(std::numeric_limits<T>::min()), hi = -lo;
    for (py::ssize_t i = 0; d && i < d.size(); ++i) {
      const double x = d.data()[i];
      if (!std::isfinite(x) || x != std::floor(x))
        refuse(py::str(py::float_(x)), "is not an integer");
      if (x < lo || x >= hi) refuse(py::str(py::float_(x)), fits);
    }
    checked = d;
  } else {
    throw py::value_error(what + " must be integers, got an array of dtype " +
                          std::string(py::str(given.dtype())));
  }
  Out out;
  if (checked) out = Out::ensure(checked);
  if (!out) {
    PyErr_Clear();
    throw py::value_error(what + " could not be read as integers");
  }
  return out;
}

/// A C-contiguous float64 array holding an (N, 3) point set; `map()` views it without a copy.
struct PointsArg {
  py::array_t<double, py::array::c_style | py::array::forcecast> array;
  Eigen::Map<const Points> map() const {
    return {array.data(), static_cast<Eigen::Index>(array.shape(0)), 3};
  }
};

/// Converts any array-like to (N, 3) float64, raising ValueError that names `what` otherwise.
/// Non-finite values are rejected unless allow_nonfinite.
PointsArg points_arg(const py::handle& obj, const char* what, bool allow_nonfinite = false);

/// Converts a 4x4 array-like to a rigid transform (ValueError naming `what` if it is not one).
Eigen::Isometry3d transform_arg(const py::handle& obj, const char* what);

/// Converts 3 numbers ((3,) or (1, 3)) to a point (ValueError naming `what` if not 3 finite
/// numbers).
Eigen::Vector3d vec3_arg(const py::handle& obj, const char* what);

/// Converts (x, y, z, yaw) or (x, y, z, yaw, pitch) to a Pose, pitch 0 for 4 numbers
/// (ValueError naming `what` if not 4 or 5 finite numbers, a position beyond +-kMaxCoordinate, or
/// a pitch beyond +-pi/2).
Pose pose_arg(const py::handle& obj, const char* what);

/// A C-contiguous float64 (K, 4) or (K, 5) array of candidate views; `map()` views it.
struct ViewPosesArg {
  py::array_t<double, py::array::c_style | py::array::forcecast> array;
  Eigen::Map<const ViewPoses> map() const {
    return {array.data(), static_cast<Eigen::Index>(array.shape(0)),
            static_cast<Eigen::Index>(array.shape(1))};
  }
};
/// Converts candidate views, (K, 4) rows x, y, z, yaw or (K, 5) rows x, y, z, yaw, pitch
/// (ValueError naming `what` for another shape, non-finite values or a pitch beyond +-pi/2).
ViewPosesArg view_poses_arg(const py::handle& obj, const char* what = "candidates");

/// A random seed: a Python int in [0, 2^64) (ValueError naming `what` otherwise).
std::uint64_t seed_arg(const py::handle& obj, const char* what = "seed");

/// A radius as the navigation and proximity calls take it: ValueError unless finite, >= 0.
void check_radius(double r);

/// A real number (int, float, NumPy's) as a double; TypeError naming `what` for anything else,
/// a bool included (pybind's double took True as 1: OccupancyMap(True) was a 1 m map).
double real_arg(const py::handle& obj, const char* what);

/// A whole number in [lo, hi] as an int; TypeError naming `what` for anything else (a bool
/// included), ValueError naming the range for one outside it.
int int_arg(const py::handle& obj, const char* what, long long lo, long long hi);

/// ValueError if a list of SurfaceClouds from Python holds None.
void check_clouds(const std::vector<const SurfaceCloud*>& clouds);

/// Holds an object's AccessLock (shared: Lock = std::shared_lock, exclusive: std::unique_lock)
/// for a call that runs without the GIL: the GIL is released first and taken back after the lock
/// is released, so a thread waiting for the lock never holds the GIL that the holder may need.
template <template <class> class Lock>
class Unlocked {
 public:
  explicit Unlocked(std::shared_mutex& m) : lock_(m) {}
  template <class T>
  explicit Unlocked(const T& object) : lock_(object.access_lock()) {}

 private:
  py::gil_scoped_release release_;  // declared first: released before locking
  Lock<std::shared_mutex> lock_;
};
/// Shared access to a map (queries) without the GIL.
using Reading = Unlocked<std::shared_lock>;
/// Exclusive access to a map (updates) without the GIL.
using Writing = Unlocked<std::unique_lock>;

/// Shared access to two objects (a map and its SurfaceObservations), in that order, without the
/// GIL. (Always map first, then surface: the one lock order.)
class Reading2 {
 public:
  template <class A, class B>
  Reading2(const A& a, const B* b)
      : a_(a.access_lock()),
        b_(b ? std::shared_lock<std::shared_mutex>(b->access_lock())
             : std::shared_lock<std::shared_mutex>()) {}

 private:
  py::gil_scoped_release release_;
  std::shared_lock<std::shared_mutex> a_, b_;
};

void init_common(py::module_& m);
void init_mesh(py::module_& m);
void init_sensors(py::module_& m);
void init_map(py::module_& m);
void init_cloud(py::module_& m);
void init_evaluation(py::module_& m);
void init_views(py::module_& m);
void init_symmetry(py::module_& m);
void init_planning(py::module_& m);
void init_observability(py::module_& m);

/// What a memo of walks (ViewMemo, CoverageMemo) shows Python besides its constructor: stats,
/// entries, bytes, keep_calls and clear; `evicts`: a memo held within a size (its stats count
/// the records it dropped).
template <class Memo>
void def_memo_members(py::class_<Memo, std::shared_ptr<Memo>>& c, bool evicts = false) {
  c.def(
       "stats",
       [evicts](const Memo& memo) {
         const auto s = memo.stats();
         py::dict d;
         d["reused"] = s.reused;
         d["stale"] = s.stale;
         d["walked"] = s.walked;
         if (evicts) {
           d["evicted"] = s.evicted;
           d["estimated"] = s.estimated;
         }
         return d;
       },
       "Views so far: reused (answered from their record, without a walk), stale (a record "
       "that no longer held, then walked), walked (walked and recorded, stale ones included) and, "
       "for a memo held within max_bytes, evicted (records dropped to stay within it) and "
       "estimated (left unwalked on the estimate their record kept, without its coarse walk).")
      .def_property_readonly("entries", &Memo::entries, "Poses held.")
      .def_property_readonly("bytes", &Memo::bytes, "Memory held by the records.")
      .def_property_readonly("keep_calls", &Memo::keep_calls)
      .def("clear", &Memo::clear, "Drops every record.");
}

}  // namespace nbv::bind
