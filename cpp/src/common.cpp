#include "nbv/common.hpp"
#include "nbv/parallel.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>

namespace nbv {

Eigen::Isometry3d pose_to_transform(const Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.x, p.y, p.z);
  return T;
}

Eigen::Isometry3d mount_transform(const Eigen::Vector3d& xyz, double roll_deg, double pitch_deg,
                                  double yaw_deg) {
  const double d2r = M_PI / 180.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  // R = Rz(yaw) * Ry(pitch) * Rx(roll); Ry(+pitch) turns +x toward -z, i.e. pitch > 0 looks down.
  T.linear() = (Eigen::AngleAxisd(yaw_deg * d2r, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch_deg * d2r, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_deg * d2r, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = xyz;
  return T;
}

FileWriteError::FileWriteError(const std::string& path, int error)
    : std::runtime_error("cannot write '" + printable_ascii(path) + "': " + std::strerror(error)),
      path_(path),
      error_(error) {}

void write_file(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  const auto fail = [&](int error) {
    std::remove(tmp.c_str());
    throw FileWriteError(path, error ? error : EIO);
  };
  std::ofstream f;
  errno = 0;
  f.open(tmp, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!f.is_open()) fail(errno);
  try {
    write(f);
  } catch (...) {
    f.close();
    std::remove(tmp.c_str());
    throw;
  }
  errno = 0;
  f.flush();
  if (!f) fail(errno);
  f.close();  // the last buffered bytes: a full disk may only show here
  if (!f) fail(errno);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) fail(errno);
}

std::string printable_ascii(const std::string& s) {
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (unsigned char c : s)
    if (c >= 32 && c < 127) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  return out;
}

void require_representable(const Eigen::Vector3d& p, const std::string& what) {
  if (p.allFinite() && p.cwiseAbs().maxCoeff() <= kMaxCoordinate) return;
  std::ostringstream s;
  s.precision(6);
  s << what << " (" << p.x() << ", " << p.y() << ", " << p.z() << ") is not a usable position: "
    << "coordinates must be finite and within +-" << kMaxCoordinate << " m";
  throw std::invalid_argument(s.str());
}

void require_finite(const PointsRef& points, const char* what) {
  if (!points.allFinite())
    throw std::invalid_argument(std::string(what) + " contains NaN or infinite values");
}

Eigen::Isometry3d to_rigid(const Eigen::Matrix4d& M, const char* what) {
  if (!M.allFinite())
    throw std::invalid_argument(std::string(what) + " contains NaN or infinite values");
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || R.determinant() < 0)
    throw std::invalid_argument(std::string(what) +
                                " is not a rigid transform (rotation part is not a rotation)");
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    throw std::invalid_argument(std::string(what) + " last row must be [0, 0, 0, 1]");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

namespace {
// The arena is shared: core_arena() hands out a reference-counted handle, so set_num_threads
// replaces the arena without freeing it under a parallel loop that another thread is running in
// it (that loop keeps the old arena alive until it returns; the next loop gets the new one).
std::mutex g_arena_mutex;
int g_threads = 0;
std::shared_ptr<tbb::task_arena> g_arena;
}  // namespace

void set_num_threads(int n) {
  if (n < 0) throw std::invalid_argument("number of threads must be >= 0 (0 = all)");
  std::shared_ptr<tbb::task_arena> old;  // released outside the lock
  std::lock_guard<std::mutex> lock(g_arena_mutex);
  if (n == g_threads && g_arena) return;  // unchanged: keep the arena (and its threads)
  g_threads = n;
  old = std::move(g_arena);
}

int get_num_threads() { return core_arena()->max_concurrency(); }

std::shared_ptr<tbb::task_arena> core_arena() {
  std::lock_guard<std::mutex> lock(g_arena_mutex);
  if (!g_arena) {
    g_arena = g_threads > 0 ? std::make_shared<tbb::task_arena>(g_threads)
                            : std::make_shared<tbb::task_arena>();
    g_arena->initialize();
  }
  return g_arena;
}

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace nbv
