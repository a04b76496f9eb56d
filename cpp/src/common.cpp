#include "nbv/common.hpp"
#include "nbv/parallel.hpp"

#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <emmintrin.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <ostream>
#include <sstream>
#include <streambuf>

namespace nbv {

Eigen::Isometry3d pose_to_transform(const Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.x, p.y, p.z);
  return T;
}

void require_pitch(double pitch, const std::string& what) {
  if (std::isfinite(pitch) && std::abs(pitch) <= kMaxGimbalPitch) return;
  std::string deg = fmt(pitch * 180 / M_PI);  // all the digits only where 6 read +-90
  if (deg == "90" || deg == "-90") deg = fmt_exact(pitch * 180 / M_PI);
  throw std::invalid_argument(
      what + ": pitch must be finite and within +-pi/2 rad (+-90 deg), got " + fmt_exact(pitch) +
      " rad" + (std::isfinite(pitch) ? " (" + deg + " deg)" : ""));
}

Eigen::Isometry3d gimbal_mount(double pitch, const Eigen::Isometry3d& mount) {
  if (pitch == 0) return mount;  // -0.0 too: the level camera's mount, untouched
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  G.linear() = Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix();
  return G * mount;
}

Eigen::Isometry3d gimbal_sensor_transform(const Pose& pose, const Eigen::Isometry3d& mount) {
  return pose_to_transform(pose) * gimbal_mount(pose.pitch, mount);
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

namespace {
/// A stream buffer writing to a file descriptor that keeps the errno of the first failed write
/// (std::ofstream loses it: a full disk read as EIO).
class FdBuf : public std::streambuf {
 public:
  explicit FdBuf(int fd) : fd_(fd) { setp(buf_, buf_ + sizeof buf_); }
  int error() const { return error_; }

 protected:
  int overflow(int c) override {
    if (sync() != 0) return traits_type::eof();
    if (c != traits_type::eof()) {
      *pptr() = char(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  int sync() override {
    if (error_) return -1;
    const char* p = pbase();
    std::size_t n = std::size_t(pptr() - pbase());
    while (n > 0) {
      const ssize_t w = ::write(fd_, p, n);
      if (w < 0) {
        if (errno == EINTR) continue;
        error_ = errno;
        return -1;
      }
      p += w;
      n -= std::size_t(w);
    }
    setp(buf_, buf_ + sizeof buf_);
    return 0;
  }

 private:
  int fd_;
  int error_ = 0;
  char buf_[1 << 16];
};
}  // namespace

void write_file(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw FileWriteError(path, errno);
  const auto fail = [&](int error) {
    ::close(fd);
    std::remove(tmp.c_str());
    throw FileWriteError(path, error ? error : EIO);
  };
  auto buf = std::make_unique<FdBuf>(fd);
  std::ostream out(buf.get());
  try {
    write(out);
  } catch (...) {
    ::close(fd);
    std::remove(tmp.c_str());
    throw;
  }
  out.flush();
  if (buf->error() || !out) fail(buf->error());
  if (::close(fd) != 0) {  // some file systems report a full disk only here
    const int e = errno;
    std::remove(tmp.c_str());
    throw FileWriteError(path, e ? e : EIO);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    throw FileWriteError(path, e);
  }
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

std::string why_not_readable(unsigned st_mode, std::uintmax_t size, std::uintmax_t max_bytes) {
  if (!S_ISREG(st_mode))
    return std::string("it is ") +
           (S_ISDIR(st_mode)    ? "a directory"
            : S_ISFIFO(st_mode) ? "a FIFO (named pipe)"
            : S_ISCHR(st_mode)  ? "a character device"
            : S_ISBLK(st_mode)  ? "a block device"
            : S_ISSOCK(st_mode) ? "a socket"
                                : "not a regular file") +
           ": nbvkit reads regular files only";
  if (size > max_bytes)
    return std::to_string(size) + " bytes, more than the " + std::to_string(max_bytes) +
           " bytes nbvkit reads";
  return "";
}

namespace {
// At most `limit` bytes of `path` (read_whole_file, read_file_head).
std::string read_file(const std::string& path, std::size_t limit, const std::string& what,
                      std::uintmax_t max_bytes) {
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("cannot read " + what + " '" + path + "': " + why);
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) throw FileNotFound(path);
    fail(std::strerror(errno));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) != 0) fail(std::strerror(errno));
  const std::string why =
      why_not_readable(st.st_mode, static_cast<std::uintmax_t>(st.st_size), max_bytes);
  if (!why.empty()) fail(why);
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  const auto read_some = [&](char* buf, std::size_t n) {
    ssize_t r;
    while ((r = ::read(fd, buf, n)) < 0 && errno == EINTR) {
    }
    if (r < 0) fail(std::strerror(errno));
    return static_cast<std::size_t>(r);
  };
  std::string out(std::min<std::uintmax_t>(limit, static_cast<std::uintmax_t>(st.st_size)), '\0');
  std::size_t got = 0;
  for (std::size_t r = 1; got < out.size() && r > 0; got += r)
    r = read_some(&out[got], out.size() - got);
  out.resize(got);
  char more[4096];  // a file that grew since fstat: read on to its end, within the limits
  for (std::size_t r = 1; got < limit && r > 0; got += r) {
    r = read_some(more, std::min(sizeof more, limit - got));
    out.append(more, r);
    if (out.size() > max_bytes) fail(why_not_readable(st.st_mode, out.size(), max_bytes));
  }
  return out;
}
}  // namespace

std::string read_whole_file(const std::string& path, const std::string& what,
                            std::uintmax_t max_bytes) {
  return read_file(path, std::numeric_limits<std::size_t>::max(), what, max_bytes);
}

std::string read_file_head(const std::string& path, std::size_t n, const std::string& what,
                           std::uintmax_t max_bytes) {
  return read_file(path, n, what, max_bytes);
}

void require_cell_size(double v, const std::string& what) {
  if (!(v >= kMinCellSize && v <= kMaxCellSize))
    throw std::invalid_argument(what + " must be within [" + fmt(kMinCellSize) + ", " +
                                fmt(kMaxCellSize) + "] m, got " + fmt(v));
}

void require_representable(const Eigen::Vector3d& p, const std::string& what) {
  if (p.allFinite() && p.cwiseAbs().maxCoeff() <= kMaxCoordinate) return;
  std::ostringstream s;
  s.precision(6);
  s << what << " (" << p.x() << ", " << p.y() << ", " << p.z() << ") is not a usable position: "
    << "coordinates must be finite and within +-" << kMaxCoordinate << " m";
  throw std::invalid_argument(s.str());
}

namespace {
// Whether |x| <= bound for every coordinate x of the points (false for NaN): a branch-free test
// over blocks of coordinates, two a step in SSE2 (Eigen's all() tests one at a time).
bool all_within(const PointsRef& points, double bound) {
  const auto block = [bound](const double* x, std::size_t n) {
    const __m128d b = _mm_set1_pd(bound), sign = _mm_set1_pd(-0.0);
    __m128d ok = _mm_cmpeq_pd(b, b);  // all bits set (bound is not NaN)
    std::size_t i = 0;
    for (; i + 2 <= n; i += 2)  // an ordered compare: false for NaN
      ok = _mm_and_pd(ok, _mm_cmple_pd(_mm_andnot_pd(sign, _mm_loadu_pd(x + i)), b));
    bool all = _mm_movemask_pd(ok) == 3;
    for (; i < n; ++i) all &= std::fabs(x[i]) <= bound;
    return all;
  };
  const std::size_t rows = std::size_t(points.rows());
  if (points.outerStride() == 3) {  // contiguous rows: one run of 3 rows coordinates
    const std::size_t n = 3 * rows, kBlock = 3072;
    for (std::size_t b = 0; b < n; b += kBlock)
      if (!block(points.data() + b, std::min(kBlock, n - b))) return false;
    return true;
  }
  for (std::size_t r = 0; r < rows; ++r)
    if (!block(points.data() + r * std::size_t(points.outerStride()), 3)) return false;
  return true;
}
}  // namespace

void require_coordinates(const PointsRef& points, const char* what) {
  if (all_within(points, kMaxCoordinate)) return;
  require_finite(points, what);
  throw std::invalid_argument(std::string(what) + " lie beyond +-" +
                              std::to_string(long(kMaxCoordinate)) +
                              " m of the origin: not usable positions");
}

void require_finite(const PointsRef& points, const char* what) {
  if (!all_within(points, std::numeric_limits<double>::max()))
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

bool release_free_memory() {
#ifdef __GLIBC__
  return malloc_trim(0) != 0;
#else
  return false;
#endif
}

void set_num_threads(int n) {
  if (n < 0 || n > kMaxThreads)
    throw std::invalid_argument("number of threads must be in [0, " + std::to_string(kMaxThreads) +
                                "] (0 = all hardware threads), got " + std::to_string(n));
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

std::string fmt_exact(double v) {
  if (!std::isfinite(v)) return fmt(v);
  for (int digits = 6;; ++digits) {  // the shortest that reads back as v: 1.5707963705062866
    std::ostringstream s;
    s.precision(digits);
    s << v;
    if (digits >= 17 || std::strtod(s.str().c_str(), nullptr) == v) return s.str();
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace nbv
