#include "nbv/sensors.hpp"
#include "nbv/parallel.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace nbv {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

void require(bool ok, const std::string& msg) {
  if (!ok) throw std::invalid_argument(msg);
}

// A sensor's mount: finite, its offset from the body a usable position.
void check_mount(const Eigen::Isometry3d& mount, const std::string& sensor) {
  require(mount.matrix().allFinite(), sensor + " mount contains NaN or infinite values");
  require_representable(mount.translation(), sensor + " mount: offset");
}

// Gathers rays flagged 1 (hit) or 2 (free) into a Scan, in ray order (deterministic).
void compact(const std::vector<std::uint8_t>& state, const std::vector<Eigen::Vector3d>& pts,
             Scan& out) {
  Eigen::Index nh = 0, nf = 0;
  for (auto s : state) nh += s == 1, nf += s == 2;
  out.hits.resize(nh, 3);
  out.free_ends.resize(nf, 3);
  out.hit_rays.resize(nh);
  out.free_rays.resize(nf);
  Eigen::Index ih = 0, jf = 0;
  for (std::size_t i = 0; i < state.size(); ++i) {
    if (state[i] == 1) {
      out.hits.row(ih) = pts[i];
      out.hit_rays[ih++] = static_cast<int>(i);
    } else if (state[i] == 2) {
      out.free_ends.row(jf) = pts[i];
      out.free_rays[jf++] = static_cast<int>(i);
    }
  }
}

}  // namespace

void check_sensor_pose(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite())
    throw std::invalid_argument("sensor pose T_world_sensor contains NaN or infinite values");
  require_representable(T.translation(), "sensor pose: position");
}

double counter_normal(std::uint64_t seed, std::uint64_t frame, std::uint64_t index) {
  const std::uint64_t a = splitmix64(seed ^ splitmix64(frame * 0xD1B54A32D192ED03ull + index));
  const std::uint64_t b = splitmix64(a);
  const double u1 = (static_cast<double>(a >> 11) + 0.5) * 0x1.0p-53;
  const double u2 = static_cast<double>(b >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// ---------------------------------------------------------------------------- camera

void DepthCameraOptions::validate() const {
  require(width > 0 && height > 0, "camera width and height must be positive");
  require(static_cast<std::int64_t>(width) * height <= kMaxCameraPixels,
          "camera width x height = " + std::to_string(width) + " x " + std::to_string(height) +
              " is more than " + std::to_string(kMaxCameraPixels) + " pixels");
  require(std::isfinite(hfov_deg) && hfov_deg > 0 && hfov_deg < 180,
          "camera hfov_deg must be in (0, 180)");
  require(std::isfinite(vfov_deg) && vfov_deg > 0 && vfov_deg < 180,
          "camera vfov_deg must be in (0, 180)");
  require(std::isfinite(min_range) && min_range >= 0, "camera min_range must be >= 0");
  require(std::isfinite(max_range) && max_range > min_range,
          "camera max_range must exceed min_range");
  require(max_range <= kMaxCoordinate,
          "camera max_range must be at most " + fmt(kMaxCoordinate) + " m, got " + fmt(max_range));
  require(std::isfinite(noise_k) && noise_k >= 0, "camera noise_k must be >= 0");
  // (noise_k 1e308 put depths at +-inf; a noise wider than the depth itself measures nothing)
  require(noise_k * max_range <= 1.0,
          "camera noise_k = " + fmt(noise_k) + " gives a depth noise sigma of " +
              fmt(noise_k * max_range * max_range) + " m at max_range " + fmt(max_range) +
              " m: it must not exceed the depth (noise_k <= 1 / max_range)");
  check_mount(mount, "camera");
}

DepthCamera::DepthCamera(std::shared_ptr<const RaycastScene> scene,
                         const DepthCameraOptions& options)
    : scene_(std::move(scene)), opt_(options) {
  if (!scene_) throw std::invalid_argument("camera needs a scene");
  opt_.validate();
  const int W = opt_.width, H = opt_.height;
  fx_ = (W / 2.0) / std::tan(opt_.hfov_deg * M_PI / 360.0);
  fy_ = (H / 2.0) / std::tan(opt_.vfov_deg * M_PI / 360.0);
  dirs_.resize(static_cast<Eigen::Index>(W) * H, 3);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      Eigen::Vector3d d(1.0, -(u + 0.5 - W / 2.0) / fx_, -(v + 0.5 - H / 2.0) / fy_);
      dirs_.row(static_cast<Eigen::Index>(v) * W + u) = d.normalized();
    }
  // Reorder into 4x4 tiles: one Embree packet of 16 rays per tile.
  tile_dirs_.resize(dirs_.rows(), 3);
  pixel_to_tile_.resize(dirs_.rows());
  tile_tfar_.resize(dirs_.rows());
  Eigen::Index k = 0;
  for (int tv = 0; tv < H; tv += 4)
    for (int tu = 0; tu < W; tu += 4)
      for (int v = tv; v < std::min(tv + 4, H); ++v)
        for (int u = tu; u < std::min(tu + 4, W); ++u) {
          const Eigen::Index p = static_cast<Eigen::Index>(v) * W + u;
          pixel_to_tile_[p] = static_cast<int>(k);
          tile_dirs_.row(k) = dirs_.row(p);
          tile_tfar_[k] = opt_.max_range / dirs_(p, 0);  // depth limit -> distance along the ray
          ++k;
        }
  cos_ = dirs_.col(0);
}

double DepthCamera::frustum_volume() const {
  const double a =
      4.0 * std::tan(opt_.hfov_deg * M_PI / 360.0) * std::tan(opt_.vfov_deg * M_PI / 360.0);
  return a / 3.0 * (std::pow(opt_.max_range, 3) - std::pow(opt_.min_range, 3));
}

void DepthCamera::reset_noise(std::uint64_t seed) {
  opt_.seed = seed;
  frame_ = 0;
}

double DepthCamera::pixel_depth(double t, Eigen::Index p, std::uint64_t frame, bool& free) const {
  free = !std::isfinite(t);
  if (free) return kInf;
  double z = t * cos_[p];
  if (opt_.noise_k > 0)
    z += opt_.noise_k * z * z * counter_normal(opt_.seed, frame, static_cast<std::uint64_t>(p));
  return in_range(z) ? z : kInf;
}

Scan DepthCamera::scan_pixels(const Eigen::Isometry3d& T,
                              const Eigen::Ref<const Eigen::VectorXi>& pixels) const {
  check_sensor_pose(T);
  const Eigen::Index n = pixels.size(), npix = dirs_.rows();
  Points d(n, 3);
  Eigen::VectorXd tfar(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const int p = pixels[i];
    if (p < 0 || p >= npix)
      throw std::invalid_argument("camera pixel " + std::to_string(p) + " is outside the " +
                                  std::to_string(opt_.width) + " x " + std::to_string(opt_.height) +
                                  " image");
    d.row(i) = dirs_.row(p);
    tfar[i] = opt_.max_range / dirs_(p, 0);
  }
  const Eigen::Vector3d o = T.translation();
  const Eigen::Matrix3d R = T.linear();
  Eigen::VectorXd t;
  scene_->intersect_coherent(o, R, d, tfar, t);
  const std::uint64_t frame = frame_++;
  Scan out;
  out.origin = o;
  out.depth.resize(1, n);
  std::vector<bool> free(static_cast<std::size_t>(n));
  Eigen::Index hits = 0, frees = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    bool f = false;
    out.depth(0, i) = pixel_depth(t[i], pixels[i], frame, f);
    free[std::size_t(i)] = f;
    frees += f;
    hits += std::isfinite(out.depth(0, i));
  }
  out.hits.resize(hits, 3);
  out.free_ends.resize(frees, 3);
  out.hit_rays.resize(hits);
  out.free_rays.resize(frees);
  for (Eigen::Index i = 0, ih = 0, jf = 0; i < n; ++i) {
    const double cx = d(i, 0);
    if (free[std::size_t(i)]) {
      out.free_ends.row(jf) = o + R * d.row(i).transpose() * (opt_.max_range / cx);
      out.free_rays[jf++] = pixels[i];
    } else if (std::isfinite(out.depth(0, i))) {
      out.hits.row(ih) = o + R * d.row(i).transpose() * (out.depth(0, i) / cx);
      out.hit_rays[ih++] = pixels[i];
    }
  }
  return out;
}

Scan DepthCamera::scan(const Eigen::Isometry3d& T) const {
  check_sensor_pose(T);
  const int W = opt_.width, H = opt_.height;
  const Eigen::Index n = static_cast<Eigen::Index>(W) * H;
  const Eigen::Vector3d o = T.translation();
  const Eigen::Matrix3d R = T.linear();
  Eigen::VectorXd t;
  scene_->intersect_coherent(o, R, tile_dirs_, tile_tfar_, t);

  const std::uint64_t frame = frame_++;
  Scan out;
  out.origin = o;
  out.depth.resize(H, W);
  double* depth = out.depth.data();  // row-major: pixel p = v * W + u
  // 1. Each pixel's outcome, by blocks of pixels in parallel (its ray read from tile order):
  // 1 a return at depth z (kept in `depth`), 2 nothing within max depth (a free ray to the far
  // plane), 0 a return out of range; each block counts its hits and free rays.
  std::vector<std::uint8_t> state(static_cast<std::size_t>(n), 0);
  const bool noisy = opt_.noise_k > 0;
  const int* tile_of = pixel_to_tile_.data();
  const double* cosine = cos_.data();
  const std::size_t block = 8192, nb = (static_cast<std::size_t>(n) + block - 1) / block;
  std::vector<Eigen::Index> first_hit(nb + 1, 0), first_free(nb + 1, 0);
  parallel_chunks(nb, 1, [&](std::size_t bb, std::size_t be) {
    for (std::size_t b = bb; b < be; ++b) {
      Eigen::Index hits = 0, frees = 0;
      const std::size_t e = std::min<std::size_t>(n, (b + 1) * block);
      if (noisy) {
        for (std::size_t p = b * block; p < e; ++p) {
          const auto pi = static_cast<Eigen::Index>(p);
          bool free = false;
          depth[p] = pixel_depth(t[tile_of[p]], pi, frame, free);
          state[p] = free ? 2 : std::isfinite(depth[p]) ? 1 : 0;
        }
      } else {  // pixel_depth without noise, inline: the depth along the optical axis, in range
        for (std::size_t p = b * block; p < e; ++p) {
          const double tp = t[tile_of[p]], z = tp * cosine[p];
          const bool free = !std::isfinite(tp);
          depth[p] = free || !in_range(z) ? kInf : z;
          state[p] = std::uint8_t(free ? 2 : std::isfinite(depth[p]) ? 1 : 0);
        }
      }
      for (std::size_t p = b * block; p < e; ++p) {
        frees += state[p] == 2;
        hits += state[p] == 1;
      }
      first_hit[b + 1] = hits;
      first_free[b + 1] = frees;
    }
  });
  // 2. The end points in pixel order, written in parallel: each block writes from its offset
  // (the order of a serial gather, deterministic).
  for (std::size_t b = 0; b < nb; ++b) {
    first_hit[b + 1] += first_hit[b];
    first_free[b + 1] += first_free[b];
  }
  out.hits.resize(first_hit[nb], 3);
  out.free_ends.resize(first_free[nb], 3);
  out.hit_rays.resize(first_hit[nb]);
  out.free_rays.resize(first_free[nb]);
  // (a free ray's end: its distance to the far plane, tile_tfar_, the same max_range / cosine)
  const double* far = tile_tfar_.data();
  double* hits = out.hits.data();
  double* free_ends = out.free_ends.data();
  int* hit_rays = out.hit_rays.data();
  int* free_rays = out.free_rays.data();
  parallel_chunks(nb, 1, [&](std::size_t bb, std::size_t be) {
    for (std::size_t b = bb; b < be; ++b) {
      Eigen::Index ih = first_hit[b], jf = first_free[b];
      for (std::size_t p = b * block, e = std::min<std::size_t>(n, p + block); p < e; ++p) {
        if (!state[p]) continue;
        const auto pi = static_cast<Eigen::Index>(p);
        const Eigen::Vector3d dw = R * dirs_.row(pi).transpose();
        const bool hit = state[p] == 1;
        const Eigen::Vector3d q = o + dw * (hit ? depth[p] / cosine[p] : far[tile_of[p]]);
        double* row = hit ? hits + 3 * ih : free_ends + 3 * jf;
        row[0] = q.x();
        row[1] = q.y();
        row[2] = q.z();
        if (hit)
          hit_rays[ih++] = static_cast<int>(p);
        else
          free_rays[jf++] = static_cast<int>(p);
      }
    }
  });
  return out;
}

// ---------------------------------------------------------------------------- laser

int LaserScannerOptions::num_beams() const {
  const double n = std::floor(fov_deg / resolution_deg + 1e-9) + 1;
  if (!(n <= kMaxLaserBeams))
    throw std::invalid_argument("laser resolution_deg = " + fmt(resolution_deg) +
                                " gives more than " + std::to_string(kMaxLaserBeams) +
                                " beams over fov_deg = " + fmt(fov_deg));
  return static_cast<int>(n);
}

void LaserScannerOptions::validate() const {
  require(std::isfinite(fov_deg) && fov_deg > 0 && fov_deg <= 360,
          "laser fov_deg must be in (0, 360]");
  require(std::isfinite(resolution_deg) && resolution_deg > 0 && resolution_deg <= fov_deg,
          "laser resolution_deg must be in (0, fov_deg]");
  require(std::isfinite(min_range) && min_range >= 0, "laser min_range must be >= 0");
  require(std::isfinite(max_range) && max_range > min_range,
          "laser max_range must exceed min_range");
  require(max_range <= kMaxCoordinate,
          "laser max_range must be at most " + fmt(kMaxCoordinate) + " m, got " + fmt(max_range));
  require(std::isfinite(noise_sigma) && noise_sigma >= 0, "laser noise_sigma must be >= 0");
  require(noise_sigma <= max_range, "laser noise_sigma = " + fmt(noise_sigma) +
                                        " m must not exceed max_range = " + fmt(max_range) + " m");
  num_beams();  // throws naming resolution_deg if the beam count is out of bounds
  check_mount(mount, "laser");
}

LaserScanner::LaserScanner(std::shared_ptr<const RaycastScene> scene,
                           const LaserScannerOptions& options)
    : scene_(std::move(scene)), opt_(options) {
  if (!scene_) throw std::invalid_argument("laser needs a scene");
  opt_.validate();
  const int nb = opt_.num_beams();
  angles_.resize(nb);
  dirs_.resize(nb, 3);
  tfar_.setConstant(nb, opt_.max_range);
  const double res = opt_.resolution_deg * M_PI / 180.0;
  const double start = -opt_.fov_deg * M_PI / 360.0;
  for (int i = 0; i < nb; ++i) {
    angles_[i] = start + i * res;
    dirs_.row(i) = Eigen::Vector3d(std::cos(angles_[i]), std::sin(angles_[i]), 0.0);
  }
}

void LaserScanner::reset_noise(std::uint64_t seed) {
  opt_.seed = seed;
  frame_ = 0;
}

Scan LaserScanner::scan(const Eigen::Isometry3d& T) const {
  check_sensor_pose(T);
  const Eigen::Index n = dirs_.rows();
  const Eigen::Vector3d o = T.translation();
  const Eigen::Matrix3d R = T.linear();
  Eigen::VectorXd t;
  scene_->intersect_coherent(o, R, dirs_, tfar_, t, /*parallel=*/false);
  const std::uint64_t frame = frame_++;
  Scan out;
  out.origin = o;
  out.depth.setConstant(1, n, kInf);
  std::vector<std::uint8_t> state(static_cast<std::size_t>(n), 0);
  std::vector<Eigen::Vector3d> pts(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d dw = R * dirs_.row(i).transpose();
    if (!std::isfinite(t[i])) {
      state[i] = 2;
      pts[i] = o + dw * opt_.max_range;
      continue;
    }
    double r = t[i];
    if (opt_.noise_sigma > 0)
      r += opt_.noise_sigma * counter_normal(opt_.seed, frame, static_cast<std::uint64_t>(i));
    if (r < opt_.min_range * (1 - 1e-9) || r > opt_.max_range * (1 + 1e-9)) continue;
    state[i] = 1;
    pts[i] = o + dw * r;
    out.depth(0, i) = r;
  }
  compact(state, pts, out);
  return out;
}

}  // namespace nbv
