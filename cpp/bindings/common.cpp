#include "bindings.hpp"

#include <cmath>
#include <cstring>

namespace nbv::bind {

namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// `obj` as a C-contiguous float64 array; an empty one (false) if it cannot be read as real
// numbers. Complex or bool input raises ValueError naming `what` (require_real_dtype).
DoubleArray double_array(const py::handle& obj, const std::string& what) {
  py::array given;
  try {
    given = py::array::ensure(obj);
  } catch (const py::error_already_set&) {
    return {};
  }
  if (!given) {
    PyErr_Clear();
    return {};
  }
  require_real_dtype(given, what);
  try {
    return DoubleArray::ensure(given);
  } catch (const py::error_already_set&) {
    return {};
  }
}

}  // namespace

PointsArg points_arg(const py::handle& obj, const char* what, bool allow_nonfinite) {
  if (obj.is_none())
    throw py::value_error(std::string(what) + " must be an (N, 3) array, got None");
  DoubleArray a = double_array(obj, what);
  if (!a) throw py::value_error(std::string(what) + " must be an (N, 3) array of numbers");
  if (a.ndim() == 1 && a.shape(0) == 0) {  // an empty list: zero points
    a = py::array_t<double, py::array::c_style | py::array::forcecast>(
        std::vector<py::ssize_t>{0, 3});
  }
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + " must have shape (N, 3), got " +
                          std::string(py::str(py::tuple(py::cast(
                              std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()))))));
  PointsArg out{a};
  if (!allow_nonfinite && !out.map().allFinite())
    throw py::value_error(std::string(what) + " contains NaN or infinite values");
  return out;
}

Eigen::Isometry3d transform_arg(const py::handle& obj, const char* what) {
  DoubleArray a = double_array(obj, what);
  if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(std::string(what) + " must be a 4x4 homogeneous transform");
  Eigen::Matrix4d M = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(a.data());
  return to_rigid(M, what);
}

Pose pose_arg(const py::handle& obj, const char* what) {
  DoubleArray a = double_array(obj, what);
  if (!a || a.ndim() != 1 || (a.shape(0) != 4 && a.shape(0) != 5))
    throw py::value_error(std::string(what) +
                          " must be 4 numbers (x, y, z, yaw) or 5 (x, y, z, yaw, pitch)");
  const double* d = a.data();
  for (int i = 0; i < 4; ++i)
    if (!std::isfinite(d[i]))
      throw py::value_error(std::string(what) + " contains NaN or infinite values");
  require_representable(Eigen::Vector3d(d[0], d[1], d[2]), what);
  const double pitch = a.shape(0) == 5 ? d[4] : 0.0;
  require_pitch(pitch, what);  // names the pitch: non-finite, or beyond +-pi/2
  return Pose{d[0], d[1], d[2], d[3], pitch};
}

ViewPosesArg view_poses_arg(const py::handle& obj, const char* what) {
  DoubleArray a = double_array(obj, what);
  if (!a || a.ndim() != 2 || (a.shape(1) != 4 && a.shape(1) != 5)) {
    std::string got = "not an array of numbers";
    if (a) {
      got = "shape (";
      for (py::ssize_t i = 0; i < a.ndim(); ++i)
        got += (i ? ", " : "") + std::to_string(a.shape(i));
      got += a.ndim() == 1 ? ",)" : ")";
    }
    throw py::value_error(std::string(what) +
                          " must have shape (K, 4): rows x, y, z, yaw, or (K, 5): rows x, y, z, "
                          "yaw, pitch; got " +
                          got);
  }
  ViewPosesArg out{a};
  if (!out.map().leftCols(4).allFinite())
    throw py::value_error(std::string(what) + " contain NaN or infinite values");
  if (a.shape(1) == 5) {
    const auto m = out.map();
    for (Eigen::Index k = 0; k < m.rows(); ++k)
      require_pitch(m(k, 4), std::string(what) + " row " + std::to_string(k));
  }
  return out;
}

std::string short_repr(const py::handle& obj) {
  return py::module_::import("nbvkit.limits").attr("shorten")(obj).cast<std::string>();
}

std::uint64_t seed_arg(const py::handle& obj, const char* what) {
  if (py::isinstance<py::bool_>(obj) || !py::isinstance<py::int_>(obj))
    throw py::value_error(std::string(what) + " must be an integer >= 0, got " + short_repr(obj));
  const py::int_ v = py::reinterpret_borrow<py::int_>(obj);
  if (v < py::int_(0) || v >= py::int_(py::module_::import("builtins").attr("pow")(2, 64)))
    throw py::value_error(std::string(what) + " must be an integer in [0, 2**64), got " +
                          short_repr(obj));
  return v.cast<std::uint64_t>();
}

void check_radius(double r) {
  if (!(r >= 0) || !std::isfinite(r)) throw py::value_error("radius must be finite and >= 0");
}

double real_arg(const py::handle& obj, const char* what) {
  // a real number: not a bool (True read as 1), a string (float('0.2') parses it), a complex
  // (its imaginary part dropped) or an array of another kind or size
  const py::module_ np = py::module_::import("numpy");
  bool real = PyNumber_Check(obj.ptr()) && !py::isinstance<py::bool_>(obj) &&
              !py::isinstance(obj, np.attr("bool_")) && !PyComplex_Check(obj.ptr()) &&
              !py::isinstance(obj, np.attr("complexfloating"));
  if (real && py::isinstance<py::array>(obj)) {
    const py::array a = py::reinterpret_borrow<py::array>(obj);
    const char kind = a.dtype().kind();
    real = a.ndim() == 0 && (kind == 'i' || kind == 'u' || kind == 'f');
  }
  if (!real) throw py::type_error(std::string(what) + " must be a number, got " + short_repr(obj));
  PyObject* f = PyNumber_Float(obj.ptr());
  if (!f) {  // (an int past a double's range, a number type of its own that fails)
    PyErr_Clear();
    throw py::value_error(std::string(what) + " must be a number a double holds, got " +
                          short_repr(obj));
  }
  const double v = PyFloat_AS_DOUBLE(f);
  Py_DECREF(f);
  return v;
}

int int_arg(const py::handle& obj, const char* what, long long lo, long long hi) {
  if (py::isinstance<py::bool_>(obj) ||
      !py::isinstance(obj, py::module_::import("numbers").attr("Integral")))
    throw py::type_error(std::string(what) + " must be a whole number, got " + short_repr(obj));
  const py::int_ v = py::module_::import("operator").attr("index")(obj);
  if (v < py::int_(lo) || v > py::int_(hi))
    throw py::value_error(std::string(what) + " must be in [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "], got " + short_repr(obj));
  return static_cast<int>(v.cast<long long>());
}

void check_clouds(const std::vector<const SurfaceCloud*>& clouds) {
  for (const SurfaceCloud* c : clouds)
    if (!c) throw py::value_error("clouds must be SurfaceCloud objects, not None");
}

Eigen::Vector3d vec3_arg(const py::handle& obj, const char* what) {
  DoubleArray a = double_array(obj, what);
  if (!a || a.size() != 3 || (a.ndim() != 1 && !(a.ndim() == 2 && a.shape(0) == 1)))
    throw py::value_error(std::string(what) + " must be 3 numbers (x, y, z)");
  Eigen::Vector3d v(a.data()[0], a.data()[1], a.data()[2]);
  if (!v.allFinite()) throw py::value_error(std::string(what) + " contains NaN or infinite values");
  return v;
}

void init_common(py::module_& m) {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FileNotFound& e) {
      py::object err =
          py::module_::import("builtins").attr("FileNotFoundError")(2, "No such file", e.path());
      PyErr_SetObject(PyExc_FileNotFoundError, err.ptr());
    } catch (const FileWriteError& e) {
      // OSError(errno, strerror, path) picks its subclass from errno, as Python's own writers
      py::object err = py::module_::import("builtins")
                           .attr("OSError")(e.error(), std::strerror(e.error()), e.path());
      PyErr_SetObject(err.get_type().ptr(), err.ptr());
    }
  });
  m.attr("MAX_COORDINATE") = kMaxCoordinate;
  m.attr("MAX_THREADS") = kMaxThreads;
  m.def(
      "set_num_threads",
      [](const py::handle& n) { set_num_threads(int_arg(n, "number of threads", 0, kMaxThreads)); },
      py::arg("n"),
      "Worker threads of the core's parallel loops (0 = all hardware threads; at most\n"
      "MAX_THREADS, else ValueError). Process-wide;\n"
      "safe to call while other threads scan or score views: their running calls finish on\n"
      "the threads they started with, later calls use the new count.");
  m.def("get_num_threads", &get_num_threads);
  m.def("release_free_memory", &release_free_memory,
        "Hands the heap's free pages back to the OS (glibc malloc_trim): after a plan on a large\n"
        "structure, whose transient coverage sets leave the worker threads' arenas resident.\n"
        "True if any pages went back.");
  m.def(
      "pose_to_transform",
      [](const py::handle& pose) { return pose_to_transform(pose_arg(pose, "pose")).matrix(); },
      py::arg("pose"),
      "T_world_body (4x4) of a vehicle pose (x, y, z, yaw) or view (x, y, z, yaw, pitch): the\n"
      "body does not pitch (the pitch is the camera gimbal's, see gimbal_transform).");
  m.def(
      "gimbal_transform",
      [](const py::handle& pose, const py::handle& mount) {
        const Pose p = pose_arg(pose, "pose");
        const Eigen::Isometry3d M =
            mount.is_none() ? Eigen::Isometry3d::Identity() : transform_arg(mount, "mount");
        return gimbal_sensor_transform(p, M).matrix();
      },
      py::arg("pose"), py::arg("mount") = py::none(),
      "T_world_sensor (4x4) of a sensor on the camera gimbal at a view (x, y, z, yaw[, pitch]):\n"
      "T(x, y, z) Rz(yaw) Ry(pitch) mount (pitch in radians, > 0 looks down, as mount_transform's\n"
      "pitch; mount: 4x4 T_body_sensor at pitch 0, default identity). The camera's scan_pose and\n"
      "view scoring use it; the laser does not ride the gimbal.");
  m.def(
      "mount_transform",
      [](const Eigen::Vector3d& xyz, double roll, double pitch, double yaw) {
        if (!xyz.allFinite() || !std::isfinite(roll) || !std::isfinite(pitch) ||
            !std::isfinite(yaw))
          throw py::value_error("mount_transform arguments must be finite");
        require_representable(xyz, "mount_transform: xyz");
        return mount_transform(xyz, roll, pitch, yaw).matrix();
      },
      py::arg("xyz") = Eigen::Vector3d::Zero(), py::arg("roll_deg") = 0.0,
      py::arg("pitch_deg") = 0.0, py::arg("yaw_deg") = 0.0,
      "T_body_sensor (4x4) from a translation and roll/pitch/yaw in degrees (pitch > 0 looks "
      "down).");
}

}  // namespace nbv::bind
