// Common types of the nbvkit core: point arrays, vehicle poses, errors, threading.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <shared_mutex>
#include <stdexcept>
#include <string>

namespace nbv {

/// (N, 3) float64 row-major: points or directions, one per row.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// (M, 3) int32 row-major: triangle vertex indices.
using Faces = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// Read-only view of a row-major (N, 3) float64 array (maps numpy without a copy).
using PointsRef = Eigen::Ref<const Points>;

/// A view: a vehicle pose, position in the world frame (metres) and yaw about world +z
/// (radians), and the pitch of the camera's gimbal (radians, in [-pi/2, pi/2]). The body frame
/// is x forward, y left, z up; it is the world frame rotated by `yaw` about z (the body never
/// pitches). The gimbal turns the camera mount about the body's y axis: pitch > 0 looks DOWN
/// (REP-103's Ry(+pitch) turns +x toward -z, the sign of mount_transform's pitch); 0 is level.
/// Only the camera rides the gimbal; the laser keeps its fixed mount on the body.
struct Pose {
  double x = 0, y = 0, z = 0, yaw = 0;
  double pitch = 0;
};

/// T_world_body of a vehicle pose (position and yaw; the gimbal's pitch plays no part).
Eigen::Isometry3d pose_to_transform(const Pose& pose);

/// The largest |pitch| of a gimbal, radians (straight down or straight up).
constexpr double kMaxGimbalPitch = M_PI / 2;
/// Throws std::invalid_argument (-> ValueError) naming `what` and the value unless `pitch` is
/// finite and within +-kMaxGimbalPitch (radians).
void require_pitch(double pitch, const std::string& what);

/// T_world_sensor of a sensor on the gimbal: T(x, y, z) Rz(yaw) Ry(pitch) * mount, evaluated as
/// pose_to_transform(pose) * (Ry(pitch) * mount). At pitch 0 (either sign) it is
/// pose_to_transform(pose) * mount bit for bit, and a pitched pose gives exactly what a level
/// pose gives with the mount Ry(pitch) * mount (gimbal_mount).
Eigen::Isometry3d gimbal_sensor_transform(const Pose& pose, const Eigen::Isometry3d& mount);
/// Ry(pitch) * mount: the mount as the gimbal at `pitch` (radians) carries it; `mount` itself at
/// pitch 0.
Eigen::Isometry3d gimbal_mount(double pitch, const Eigen::Isometry3d& mount);

/// A fixed sensor mount T_body_sensor from a translation (metres) and roll/pitch/yaw in degrees
/// (REP-103: x forward, y left, z up; positive pitch tilts the sensor's +x axis DOWN).
Eigen::Isometry3d mount_transform(const Eigen::Vector3d& xyz, double roll_deg, double pitch_deg,
                                  double yaw_deg);

/// Raised when a file does not exist; crosses into Python as FileNotFoundError.
class FileNotFound : public std::runtime_error {
 public:
  explicit FileNotFound(const std::string& path)
      : std::runtime_error("no such file: '" + path + "'"), path_(path) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// Raised when a file cannot be written whole (a full disk, a missing folder, no permission);
/// crosses into Python as OSError(errno, strerror, path).
class FileWriteError : public std::runtime_error {
 public:
  FileWriteError(const std::string& path, int error);
  const std::string& path() const { return path_; }
  int error() const { return error_; }

 private:
  std::string path_;
  int error_;
};

/// Writes `path` whole or not at all: `write` fills a stream on a temporary file beside it,
/// which is flushed, checked and renamed over `path`; on any failure the temporary file is
/// removed and FileWriteError (with the system's reason, e.g. ENOSPC) is thrown, leaving an
/// existing `path` as it was.
void write_file(const std::string& path, const std::function<void(std::ostream&)>& write);

/// `s` with every byte outside printable ASCII written as \xNN: text quoted from a file into an
/// error message must be valid UTF-8 to cross into Python.
std::string printable_ascii(const std::string& s);

/// Why a file of stat mode `st_mode` and `size` bytes is not one nbvkit reads, or "" if it is: a
/// regular file (a FIFO would block a reader forever, a device such as /dev/zero never ends) of
/// at most `max_bytes` (what a file may make a reader allocate grows with its size). Reads e.g.
/// "it is a FIFO (named pipe): nbvkit reads regular files only".
std::string why_not_readable(unsigned st_mode, std::uintmax_t size, std::uintmax_t max_bytes);

/// The bytes of the file `path`: all of them (read_whole_file) or its first `n` (read_file_head;
/// fewer if the file is shorter). The file must pass why_not_readable; it is opened without
/// blocking and checked on the open descriptor, so a FIFO or a device (even one swapped in for
/// the path after a check) can neither block nor flood the reader. Throws FileNotFound for a
/// missing path and std::invalid_argument "cannot read WHAT 'PATH': REASON" for anything else
/// (not a regular file, too large, no permission, a read error).
std::string read_whole_file(const std::string& path, const std::string& what,
                            std::uintmax_t max_bytes);
std::string read_file_head(const std::string& path, std::size_t n, const std::string& what,
                           std::uintmax_t max_bytes);

/// A number as an error message shows it (shortest round-trip-ish form, "inf", "nan").
std::string fmt(double v);
/// A number in the fewest digits (6 at least) that read back as it: a value refused by a hair
/// (a float32 pi/2) shows why.
std::string fmt_exact(double v);

/// Seconds elapsed since `t0` (steady clock), for the stage timings results report.
double seconds_since(std::chrono::steady_clock::time_point t0);

/// Largest |coordinate| (metres) a position may have: the ray caster works in float32, whose
/// spacing at 1e9 m is already 64 m, and Embree asserts on origins near 2e18.
constexpr double kMaxCoordinate = 1e9;
/// Smallest and largest length (m) of a voxel grid's cell, a coverage resolution or a distance
/// threshold: beyond, a unit's mistake (1e308 m read as 100 % coverage; 1e-300 m put every point
/// beyond the grid's keys).
constexpr double kMinCellSize = 1e-6, kMaxCellSize = 1e3;
/// Throws std::invalid_argument (-> ValueError) "`what` must be within [1e-06, 1000] m, got v"
/// unless kMinCellSize <= v <= kMaxCellSize.
void require_cell_size(double v, const std::string& what);
/// Throws std::invalid_argument (-> ValueError) naming `what` and the value if `p` holds NaN, inf
/// or a coordinate beyond +-kMaxCoordinate.
void require_representable(const Eigen::Vector3d& p, const std::string& what);

/// Throws std::invalid_argument (-> ValueError) naming `what` if any entry is NaN or inf.
void require_finite(const PointsRef& points, const char* what);
/// As require_finite, and also if any entry lies beyond +-kMaxCoordinate (points given as
/// positions: single precision, which OctoMap and Embree work in, would make them infinite).
void require_coordinates(const PointsRef& points, const char* what);
/// Converts a 4x4 homogeneous matrix to a rigid transform; throws std::invalid_argument naming
/// `what` if it holds non-finite values, its rotation part is not a rotation, or its last row is
/// not [0, 0, 0, 1].
Eigen::Isometry3d to_rigid(const Eigen::Matrix4d& M, const char* what);

/// The reader-writer lock of an object that several threads may share (OccupancyMap,
/// SurfaceObservations): the Python bindings hold it shared around every query and exclusively
/// around every update, so calls from several Python threads (which release the GIL) are
/// serialised where they must be. A member that moves with its object: the moved-to object gets
/// a fresh, unlocked lock (moving an object that is in use is a bug anyway).
class AccessLock {
 public:
  AccessLock() = default;
  AccessLock(AccessLock&&) noexcept {}
  AccessLock& operator=(AccessLock&&) noexcept { return *this; }
  std::shared_mutex& mutex() const { return m_; }

 private:
  mutable std::shared_mutex m_;
};

/// Number of worker threads used by the core's parallel loops (0 = all hardware threads).
/// Process-wide; safe to call while other threads run parallel loops: those finish on the
/// threads they started with, and every later loop uses the new count.
/// The most threads set_num_threads accepts (TBB's arena fails far above it).
constexpr int kMaxThreads = 4096;
void set_num_threads(int n);
int get_num_threads();

/// Hands the heap's free pages back to the OS (glibc's malloc_trim; nothing elsewhere). A plan
/// on a large structure gathers and frees millions of small coverage sets across the worker
/// threads' arenas; without this the process keeps their pages resident. True if any went back.
bool release_free_memory();

}  // namespace nbv
